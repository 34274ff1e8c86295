// Fuzz target: an EditBatch (what ApplyEdits receives and replays record) applied to a running
// world. The first byte chooses the world (fuzz_worlds.h), the rest is the batch. Checks: a
// refused batch names what it refused and leaves the world exactly as it was (state hash,
// tick, bodies, shapes); an accepted one leaves a world that passes check_world before and
// after a few ticks.
#include "edit_convert.h"
#include "fuzz_support.h"
#include "fuzz_worlds.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace fulcrum;
  if (size == 0) return 0;
  v1::EditBatch batch;
  if (!batch.ParseFromArray(data + 1, static_cast<int>(size - 1))) return 0;
  fuzz::print(batch);
  World w = fuzz::base_world(data[0]);
  const uint64_t hash = w.state_hash();
  const int bodies = w.body_count();
  const int shapes = w.shape_count();
  Result<EditOutcome> applied = apply_edit_batch(&w, batch, fuzz::limits());
  if (!applied.ok()) {
    fuzz::check_refusal(applied.status(), "apply_edit_batch");
    fuzz::check(w.state_hash() == hash && w.body_count() == bodies && w.shape_count() == shapes,
                "a refused batch changed the world: " + applied.status().message());
    return 0;
  }
  fuzz::step_and_check(w, 2, "edited world");
  return 0;
}
