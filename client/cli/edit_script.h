// Edit scripts in local runs (`fulcrum sim --edits`, `fulcrum replay record --edits`): loaded
// against the world just built from the scene, so that scene indices resolve to its handles and
// entries past the run are refused, then applied batch by batch at their ticks.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "edit_convert.h"
#include "fulcrum/status.h"
#include "fulcrum/world.h"

namespace fulcrum::cli {

class EditScriptRun {
 public:
  // Reads `path` for a run of `ticks` ticks of `world`, which build_world has just made.
  static Result<EditScriptRun> load(const std::string& path, const World& world, int64_t ticks);

  // Applies the batches due at the world's tick, in order, and appends them to *applied. An
  // error names the entry's tick.
  Status apply_due(World* world, std::vector<v1::EditBatch>* applied);

 private:
  v1::EditScript script_;
  int next_ = 0;
};

}  // namespace fulcrum::cli
