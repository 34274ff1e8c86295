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

// Reads an edit script (Protobuf JSON of v1::EditScript) and checks that every tick is >= 0.
// Entries come back sorted by tick, batches of the same tick in file order.
Result<v1::EditScript> load_edit_script(const std::string& path);

}  // namespace fulcrum
