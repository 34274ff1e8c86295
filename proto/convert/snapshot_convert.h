// Snapshots on the wire and on disk (proto/fulcrum/v1/snapshot.proto): the engine's
// WorldSnapshot written field by field, every double exactly; the checked file envelope; the
// compact delta against a base snapshot; and a field-level comparison for replay verification.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "fulcrum/state.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/snapshot.pb.h"
#include "fulcrum/world.h"

namespace fulcrum {

inline constexpr uint32_t kSnapshotVersion = 1;
inline constexpr char kSnapshotFormat[] = "fulcrum.snapshot";
// Names the build in files it writes (for people; never checked).
inline constexpr char kWriterName[] = "fulcrum 0.2";

// 64-bit FNV-1a: the checksum of snapshot payloads and replay records.
uint64_t fnv1a64(std::string_view bytes);

v1::Snapshot snapshot_to_proto(const WorldSnapshot& snapshot);
// Checks what the engine's own check cannot see (enum values, repeated-field counts) and
// copies the records; World::restore checks the rest.
Result<WorldSnapshot> snapshot_from_proto(const v1::Snapshot& proto);

// The envelope: format name, version, writer, payload and its checksum.
v1::SnapshotFile wrap_snapshot(const v1::Snapshot& snapshot);
// Errors: DATA_LOSS for a damaged envelope or payload (truncated, flipped bytes), FAILED_
// PRECONDITION for another format or version.
Result<v1::Snapshot> unwrap_snapshot(const v1::SnapshotFile& file);

// Serialized SnapshotFile bytes for a world, and back into a world (unchanged on error).
std::string encode_snapshot(const World& world);
Status restore_encoded(World* world, std::string_view bytes);

// The compact form: what changed from `base` to `next`. apply_delta(base, delta) gives back
// `next` exactly (refused when the delta was made against another base).
v1::SnapshotDelta make_delta(const v1::Snapshot& base, const v1::Snapshot& next);
Result<v1::Snapshot> apply_delta(const v1::Snapshot& base, const v1::SnapshotDelta& delta);

// The first field, in record order (bodies before shapes, contacts and joints), whose value
// differs between two snapshots: e.g. "bodies[12].linear_velocity.y: expected 0.5, got
// 0.50000000000000011". Empty when the snapshots are equal.
std::string first_difference(const v1::Snapshot& expected, const v1::Snapshot& actual);

}  // namespace fulcrum
