// fulcrum snapshot get|restore: save a world on the server to a file, or roll it back (or fork
// a new world) from one.
#include <fstream>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

namespace {

int get(const Invocation& inv, client::Client* client, uint64_t world) {
  const std::optional<std::string> out = inv.args.value("out");
  if (!out) return inv.usage_error("get: missing --out FILE");
  Result<client::SnapshotResult> r = client->get_snapshot(world);
  if (!r.ok()) return inv.fail(r.status().message());
  std::ofstream file(*out, std::ios::binary | std::ios::trunc);
  file.write(r->bytes.data(), static_cast<std::streamsize>(r->bytes.size()));
  file.close();
  if (!file) return inv.fail(*out + ": cannot write");
  inv.out << "world " << world << " at tick " << r->tick << " (state hash " << hex64(r->state_hash)
          << "): " << r->bytes.size() << " bytes to " << *out << "\n";
  return kExitOk;
}

int restore(const Invocation& inv, client::Client* client, uint64_t world) {
  const std::optional<std::string> in = inv.args.value("file");
  if (!in) return inv.usage_error("restore: missing --file FILE");
  std::string error;
  std::optional<std::string> bytes = read_file(*in, &error);
  if (!bytes) return inv.fail(error);
  Result<client::RestoreResult> r = client->restore(world, *bytes);
  if (!r.ok()) return inv.fail(*in + ": " + r.status().message());
  inv.out << (world == 0 ? "forked new world " : "restored world ") << r->world_id << " to tick "
          << r->tick << ", state hash " << hex64(r->state_hash) << "\n";
  return kExitOk;
}

}  // namespace

int run_snapshot(const Invocation& inv) {
  const auto& positional = inv.args.positional();
  if (positional.empty()) return inv.usage_error("missing action (get or restore)");
  const std::string& action = positional[0];
  if (action != "get" && action != "restore") {
    return inv.usage_error("unknown action '" + action + "' (get or restore)");
  }
  int exit_code = kExitOk;
  uint64_t world = 0;
  // `snapshot restore new --file F` forks a new world.
  if (!(action == "restore" && positional.size() > 1 && positional[1] == "new")) {
    std::optional<uint64_t> id = world_arg(inv, 1, &exit_code);
    if (!id) return exit_code;
    world = *id;
  }
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  return action == "get" ? get(inv, client.get(), world) : restore(inv, client.get(), world);
}

}  // namespace fulcrum::cli
