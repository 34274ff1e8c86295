#include "edit_script.h"

namespace fulcrum::cli {

Result<EditScriptRun> EditScriptRun::load(const std::string& path, const World& world,
                                          int64_t ticks) {
  const SceneHandles scene = scene_handles(world);
  EditScriptOptions options;
  options.end_tick = world.tick() + ticks;
  options.scene = &scene;
  Result<v1::EditScript> script = load_edit_script(path, options);
  if (!script.ok()) return script.status();
  EditScriptRun run;
  run.script_ = std::move(script).value();
  // Entries before the world's tick would never apply either (a world built from a scene
  // starts at tick 0, and ticks are >= 0, so there are none today).
  return run;
}

Status EditScriptRun::apply_due(World* world, std::vector<v1::EditBatch>* applied) {
  for (; next_ < script_.entries_size() && script_.entries(next_).tick() <= world->tick();
       ++next_) {
    const v1::TimedEdits& e = script_.entries(next_);
    Result<EditOutcome> outcome = apply_edit_batch(world, e.batch());
    if (!outcome.ok()) {
      return outcome.status().with_prefix("edit script entry for tick " + std::to_string(e.tick()) +
                                          ": ");
    }
    if (applied != nullptr) applied->push_back(e.batch());
  }
  return {};
}

}  // namespace fulcrum::cli
