// Fuzz target: scene JSON, as the CLI reads scene files and clients send them, into a world.
// Checks: a refusal has a message; an accepted scene builds a world that passes check_world
// before and after a few ticks; written back as JSON (scene_to_json, what `fulcrum export`
// writes) it reads back into a world with the same hash.
#include "fuzz_support.h"
#include "scene_convert.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace fulcrum;
  Result<SceneDef> scene = parse_scene_json(fuzz::bytes(data, size));
  if (!scene.ok()) {
    fuzz::check_refusal(scene.status(), "parse_scene_json");
    return 0;
  }
  const std::optional<uint64_t> hash = fuzz::run_scene(*scene, "scene");
  if (!hash) return 0;
  Result<SceneDef> again = parse_scene_json(scene_to_json(*scene));
  fuzz::check(again.ok(), "the exported scene does not read back: " + again.status().message());
  Result<World> rebuilt = build_world(*again, fuzz::limits());
  fuzz::check(rebuilt.ok(), "the exported scene does not build: " + rebuilt.status().message());
  fuzz::check(rebuilt->state_hash() == *hash, "the exported scene builds another world");
  return 0;
}
