// fulcrum create: a new world on the server from a scene file.
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_create(const Invocation& inv) {
  const std::optional<std::string> scene = inv.args.value("scene");
  if (!scene) return inv.usage_error("missing --scene FILE");
  std::string error;
  std::optional<std::string> json = read_file(*scene, &error);
  if (!json) return inv.fail(error);
  int exit_code = kExitOk;
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<client::WorldSummary> world = client->create_world_json(*json);
  if (!world.ok()) return inv.fail(*scene + ": " + world.status().message());
  inv.out << "world " << world->id << " created from " << *scene << ": " << world->body_count
          << " bodies, tick " << world->tick << ", state hash " << hex64(world->state_hash) << "\n";
  return kExitOk;
}

}  // namespace fulcrum::cli
