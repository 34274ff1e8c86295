// Edits (proto/fulcrum/v1/edit.proto) applied to a world: a batch at a time, all or nothing,
// at the world's current tick boundary. Replays record batches; the server applies them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/edit.pb.h"
#include "fulcrum/world.h"

namespace fulcrum {

// Handles of what a batch created, in the order its edits created them.
struct EditOutcome {
  std::vector<BodyId> bodies;
  std::vector<ShapeId> shapes;
  std::vector<JointId> joints;
};

// What one batch may do (WorkLimits, fulcrum/scene.h), and how many edits it may hold.
struct EditLimits : WorkLimits {
  size_t max_edits = 100000;  // edits per batch (max_edits)
};

// Applies the batch in order. If any edit is refused the world is put back exactly as it was
// (bit for bit, handles included) and the error names the edit and field, e.g.
// "edits[3].set_velocity.linear: must be finite (got nan)". A batch of more than max_edits
// edits is refused before anything is applied.
Result<EditOutcome> apply_edit_batch(World* world, const v1::EditBatch& batch,
                                     const EditLimits& limits);
Result<EditOutcome> apply_edit_batch(World* world, const v1::EditBatch& batch,
                                     size_t max_edits = 100000);

// The handles a world just built by build_world gave the scene's bodies and joints, in scene
// order: what an edit script's scene_index names.
struct SceneHandles {
  std::vector<BodyId> bodies;
  std::vector<JointId> joints;
};
SceneHandles scene_handles(const World& built);

struct EditScriptOptions {
  // Entries at this tick or later are refused: a batch applies before the step from its tick,
  // so they would never apply in a run that ends at end_tick. -1: no end.
  int64_t end_tick = -1;
  // Resolves handles given by scene_index (Handle.scene_index); null: they stay, and
  // apply_edit_batch refuses them.
  const SceneHandles* scene = nullptr;
};

// Reads an edit script (Protobuf JSON of v1::EditScript) and checks that every tick is >= 0
// (and before options.end_tick), and resolves scene indices to handles. Errors name the file
// and the entry in file order ("pokes.json: entries[2].batch.edits[0].set_velocity.body.
// scene_index: no body 300 in the scene (211 bodies)"). Entries come back sorted by tick,
// batches of the same tick in file order.
Result<v1::EditScript> load_edit_script(const std::string& path,
                                        const EditScriptOptions& options = {});

}  // namespace fulcrum
