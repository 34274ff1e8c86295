// fulcrum health: the standard gRPC health check of a fulcrum-server, for container
// HEALTHCHECKs, Kubernetes exec probes and scripts. Exit 0 when SERVING, 1 otherwise.
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_health(const Invocation& inv) {
  int exit_code = kExitOk;
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  const std::string service = inv.args.value("service").value_or("");
  Result<bool> serving = client->health(service);
  if (!serving.ok()) return inv.fail(serving.status().message());
  inv.out << (*serving ? "SERVING" : "NOT_SERVING") << "\n";
  return *serving ? kExitOk : kExitError;
}

}  // namespace fulcrum::cli
