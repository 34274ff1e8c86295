// Fuzz target: snapshots from outside (RestoreSnapshot, `fulcrum snapshot restore`, replay
// keyframes) restored into a running world. The first byte chooses the world and the form:
//   0: the rest is a SnapshotFile (the envelope: format, version, checksum, payload);
//   1: the rest is a Snapshot payload, sent in a well-formed envelope, so that mutations reach
//      the record checks behind the checksum;
//   2: the rest is a SnapshotDelta applied to the world's own snapshot, then restored.
// Checks: a refusal names what it refused and leaves the world as it was; an accepted snapshot
// gives a world that passes check_world before and after a few ticks, and that encodes to a
// snapshot restoring with the same hash.
#include "fuzz_support.h"
#include "fuzz_worlds.h"
#include "snapshot_convert.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace fulcrum;
  if (size == 0) return 0;
  const int form = data[0] % 3;
  World w = fuzz::base_world(static_cast<uint8_t>(data[0] / 3));
  const uint64_t hash = w.state_hash();
  const std::string_view rest = fuzz::bytes(data + 1, size - 1);
  std::string file;
  if (form == 0) {
    file.assign(rest);
  } else if (form == 1) {
    v1::Snapshot payload;
    if (!payload.ParseFromArray(rest.data(), static_cast<int>(rest.size()))) return 0;
    fuzz::print(payload);
    file = wrap_snapshot(payload).SerializeAsString();
  } else {
    v1::SnapshotDelta delta;
    if (!delta.ParseFromArray(rest.data(), static_cast<int>(rest.size()))) return 0;
    fuzz::print(delta);
    Result<v1::Snapshot> next = apply_delta(snapshot_to_proto(w.snapshot()), delta);
    if (!next.ok()) {
      fuzz::check_refusal(next.status(), "apply_delta");
      return 0;
    }
    file = wrap_snapshot(*next).SerializeAsString();
  }
  Status restored = restore_encoded(&w, file);
  if (!restored.ok()) {
    fuzz::check_refusal(restored, "restore_encoded");
    fuzz::check(w.state_hash() == hash,
                "a refused snapshot changed the world: " + restored.message());
    return 0;
  }
  World again{WorldSettings{}};
  fuzz::check(restore_encoded(&again, encode_snapshot(w)).ok(), "a restored world re-encodes");
  fuzz::check(again.state_hash() == w.state_hash(), "a re-encoded snapshot has another hash");
  fuzz::step_and_check(w, 2, "restored world");
  return 0;
}
