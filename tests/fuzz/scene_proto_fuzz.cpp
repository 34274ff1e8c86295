// Fuzz target: a fulcrum.v1.Scene message, as CreateWorld receives it, into a world. Checks: a
// refusal has a message; an accepted scene builds a world that passes check_world before and
// after a few ticks; converted back to a message and again to a scene, it builds the same world.
#include "fuzz_support.h"
#include "scene_convert.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace fulcrum;
  v1::Scene message;
  if (!message.ParseFromArray(data, static_cast<int>(size))) return 0;
  fuzz::print(message);
  Result<SceneDef> scene = scene_from_proto(message);
  if (!scene.ok()) {
    fuzz::check_refusal(scene.status(), "scene_from_proto");
    return 0;
  }
  const std::optional<uint64_t> hash = fuzz::run_scene(*scene, "scene");
  if (!hash) return 0;
  Result<SceneDef> again = scene_from_proto(scene_to_proto(*scene));
  fuzz::check(again.ok(), "the scene's message does not convert back: " + again.status().message());
  Result<World> rebuilt = build_world(*again, fuzz::limits());
  fuzz::check(rebuilt.ok(), "the scene's message does not build: " + rebuilt.status().message());
  fuzz::check(rebuilt->state_hash() == *hash, "the scene's message builds another world");
  return 0;
}
