// lockstep ADDRESS SCENE.json TICKS: creates a world from the scene on the fulcrum-server at
// ADDRESS and steps it TICKS times there, steps its own copy of the scene as many times, and
// prints both state hashes. Exit 0 when they agree: the server and this program run the same
// deterministic engine.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "fulcrum/client.h"
#include "fulcrum/convert/scene_convert.h"
#include "fulcrum/scene.h"
#include "fulcrum/world.h"

namespace {

int fail(const fulcrum::Status& status) {
  std::fprintf(stderr, "%s\n", status.to_string().c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: lockstep ADDRESS SCENE.json TICKS\n");
    return 2;
  }
  const fulcrum::Result<fulcrum::SceneDef> scene = fulcrum::load_scene_json(argv[2]);
  if (!scene.ok()) return fail(scene.status());
  const auto ticks = static_cast<uint32_t>(std::strtoul(argv[3], nullptr, 10));

  fulcrum::client::ClientOptions options;
  options.address = argv[1];
  std::unique_ptr<fulcrum::client::Client> client = fulcrum::client::Client::connect(options);
  const fulcrum::Result<fulcrum::client::WorldSummary> remote = client->create_world(*scene);
  if (!remote.ok()) return fail(remote.status());
  const fulcrum::Result<fulcrum::client::StepResult> stepped = client->step(remote->id, ticks);
  if (!stepped.ok()) return fail(stepped.status());

  fulcrum::Result<fulcrum::World> local = fulcrum::build_world(*scene);
  if (!local.ok()) return fail(local.status());
  for (uint32_t i = 0; i < ticks; ++i) local->step();

  const uint64_t local_hash = local->state_hash();
  std::printf("server: tick %lld, state hash %s\n", static_cast<long long>(stepped->tick),
              fulcrum::World::hash_text(stepped->state_hash).c_str());
  std::printf("local:  tick %lld, state hash %s\n", static_cast<long long>(local->tick()),
              fulcrum::World::hash_text(local_hash).c_str());
  return stepped->state_hash == local_hash && stepped->tick == local->tick() ? 0 : 1;
}
