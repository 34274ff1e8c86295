// Snapshots through protobuf: exact round trips, the checked envelope, deltas and the
// field-level comparison used by replay verification.
#include "snapshot_convert.h"

#include <gtest/gtest.h>

#include <vector>

#include "fulcrum/scenes.h"

namespace fulcrum {
namespace {

World build(const char* name) {
  Result<SceneDef> scene = scenes::builtin(name);
  EXPECT_TRUE(scene.ok()) << name;
  Result<World> world = build_world(*scene);
  EXPECT_TRUE(world.ok()) << name;
  return std::move(world).value();
}

// Steps both worlds and reports the first tick whose hashes differ (-1: none).
int64_t first_divergence(World& a, World& b, int ticks) {
  for (int i = 0; i < ticks; ++i) {
    a.step();
    b.step();
    if (a.state_hash() != b.state_hash()) return a.tick();
  }
  return -1;
}

class EncodedRoundTrip : public ::testing::TestWithParam<const char*> {};

// Through bytes and into a new world: the restored world steps to the same hash every tick.
TEST_P(EncodedRoundTrip, ContinuesBitForBit) {
  World original = build(GetParam());
  for (int i = 0; i < 100; ++i) original.step();
  std::string bytes = encode_snapshot(original);
  World copy;
  Status st = restore_encoded(&copy, bytes);
  ASSERT_TRUE(st.ok()) << st.message();
  EXPECT_EQ(first_divergence(original, copy, 200), -1);
  // And the encoding itself is reproducible.
  EXPECT_EQ(encode_snapshot(original), encode_snapshot(copy));
}

INSTANTIATE_TEST_SUITE_P(Scenes, EncodedRoundTrip,
                         ::testing::Values("many_pyramids", "ragdolls", "cloth", "mixed", "bridge",
                                           "bounce"));

// Constant forces and attractors travel in snapshots (and deltas) and a restored world
// continues bit for bit.
TEST(SnapshotFile, ConstantForcesAndAttractorsContinueBitForBit) {
  World original = build("ragdolls");
  for (int i = 0; i < 10; ++i) original.step();
  const v1::Snapshot base = snapshot_to_proto(original.snapshot());
  ASSERT_TRUE(original.set_constant_force(BodyId{5, 1}, Vec2(3.0, 40.0), -0.25).ok());
  AttractorDef pull;
  pull.point = Vec2(2.0, 12.0);
  pull.strength = 50.0;
  pull.falloff = Falloff::kInverseSquare;
  pull.min_distance = 1.0;
  pull.mask_bits = 0xFFFF;
  ASSERT_TRUE(original.set_attractors({pull}).ok());
  for (int i = 0; i < 20; ++i) original.step();
  std::string bytes = encode_snapshot(original);
  World copy;
  ASSERT_TRUE(restore_encoded(&copy, bytes).ok());
  ASSERT_EQ(copy.attractors().size(), 1u);
  EXPECT_EQ(copy.attractors()[0].mask_bits, 0xFFFFu);
  EXPECT_EQ(first_divergence(original, copy, 60), -1);
  // A delta from a base without them rebuilds them exactly.
  const v1::Snapshot next = snapshot_to_proto(original.snapshot());
  Result<v1::Snapshot> rebuilt = apply_delta(base, make_delta(base, next));
  ASSERT_TRUE(rebuilt.ok()) << rebuilt.status().message();
  EXPECT_EQ(rebuilt->SerializeAsString(), next.SerializeAsString());
}

TEST(SnapshotFile, NegativeZeroAndInfinitySurvive) {
  World w = build("bounce");
  WorldSnapshot s = w.snapshot();
  s.bodies[1].torque = -0.0;
  v1::Snapshot p = snapshot_to_proto(s);
  v1::Snapshot back;
  ASSERT_TRUE(back.ParseFromString(p.SerializeAsString()));
  Result<WorldSnapshot> r = snapshot_from_proto(back);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(std::signbit(r->bodies[1].torque));
}

// Truncation at any length, any flipped byte, another version or format: refused with a clear
// error, and the target world is unchanged.
TEST(SnapshotFile, DamagedFilesAreRefused) {
  World source = build("ragdolls");
  for (int i = 0; i < 50; ++i) source.step();
  const std::string good = encode_snapshot(source);
  World target = build("bounce");
  const uint64_t before = target.state_hash();

  for (size_t cut : {size_t{0}, size_t{1}, good.size() / 3, good.size() / 2, good.size() - 1}) {
    Status st = restore_encoded(&target, std::string_view(good).substr(0, cut));
    ASSERT_FALSE(st.ok()) << "cut at " << cut;
    EXPECT_EQ(st.code(), StatusCode::kDataLoss) << st.message();
    EXPECT_EQ(target.state_hash(), before);
  }
  // Flip one bit at many positions spread over the whole file.
  int refused = 0, tried = 0;
  for (size_t pos = 0; pos < good.size(); pos += good.size() / 97 + 1) {
    std::string bad = good;
    bad[pos] = static_cast<char>(bad[pos] ^ 0x10);
    ++tried;
    Status st = restore_encoded(&target, bad);
    if (!st.ok()) ++refused;
    EXPECT_EQ(target.state_hash(), before) << "flip at " << pos;
  }
  EXPECT_EQ(refused, tried);  // the checksum and envelope catch every flip

  v1::SnapshotFile file;
  ASSERT_TRUE(file.ParseFromString(good));
  file.set_version(kSnapshotVersion + 1);
  Status st = restore_encoded(&target, file.SerializeAsString());
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("snapshot.version: 2"), std::string::npos) << st.message();
  file.set_version(kSnapshotVersion);
  file.set_format("fulcrum.replay");
  st = restore_encoded(&target, file.SerializeAsString());
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("format"), std::string::npos) << st.message();
  EXPECT_EQ(target.state_hash(), before);
}

// A kept manifold (ManifoldCache) travels with its contact; one whose points do not match the
// manifold's is refused, naming the contact.
TEST(SnapshotFile, KeptManifoldsTravelAndBadOnesAreRefused) {
  World w = build("many_pyramids");
  for (int i = 0; i < 30; ++i) w.step();
  v1::Snapshot proto = snapshot_to_proto(w.snapshot());
  int kept = -1;
  for (int i = 0; i < proto.contacts_size() && kept < 0; ++i) {
    if (proto.contacts(i).has_cache()) kept = i;
  }
  ASSERT_GE(kept, 0);
  ASSERT_TRUE(snapshot_from_proto(proto).ok());
  proto.mutable_contacts(kept)->mutable_cache()->add_separations(0.0);
  Result<WorldSnapshot> bad = snapshot_from_proto(proto);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kDataLoss);
  EXPECT_NE(bad.status().message().find("contacts[" + std::to_string(kept) + "].cache"),
            std::string::npos)
      << bad.status().message();
}

// Deltas rebuild the next snapshot exactly; sleeping bodies cost nothing and a moving body
// about 64 bytes of body data.
TEST(SnapshotDelta, RebuildsExactlyAndIsCompact) {
  World w = build("many_pyramids");
  for (int i = 0; i < 30; ++i) w.step();
  v1::Snapshot base = snapshot_to_proto(w.snapshot());
  for (int i = 0; i < 5; ++i) w.step();
  v1::Snapshot next = snapshot_to_proto(w.snapshot());
  v1::SnapshotDelta delta = make_delta(base, next);
  Result<v1::Snapshot> rebuilt = apply_delta(base, delta);
  ASSERT_TRUE(rebuilt.ok()) << rebuilt.status().message();
  EXPECT_EQ(first_difference(next, *rebuilt), "");
  EXPECT_EQ(rebuilt->SerializeAsString(), next.SerializeAsString());
  World restored;
  Result<WorldSnapshot> records = snapshot_from_proto(*rebuilt);
  ASSERT_TRUE(records.ok());
  ASSERT_TRUE(restored.restore(*records).ok());
  EXPECT_EQ(first_divergence(w, restored, 60), -1);

  // Body part of the delta: a moving body's pose and velocity (7 doubles) plus its index and
  // framing; 64 bytes is the budget.
  ASSERT_GT(delta.moved_size(), 0);
  size_t body_bytes = 0;
  for (const v1::BodyMotion& m : delta.moved()) body_bytes += m.ByteSizeLong() + 2;
  EXPECT_LE(static_cast<double>(body_bytes) / delta.moved_size(), 64.0);

  // A delta against the wrong base is refused.
  v1::Snapshot other = next;
  other.set_state_hash(next.state_hash() + 1);
  EXPECT_EQ(apply_delta(other, delta).status().code(), StatusCode::kFailedPrecondition);
}

TEST(SnapshotDelta, SleepingWorldCostsAlmostNothing) {
  World w = build("vertical_stack");
  for (int i = 0; i < 600; ++i) w.step();
  ASSERT_EQ(w.metrics().awake_body_count, 0);
  v1::Snapshot base = snapshot_to_proto(w.snapshot());
  w.step();
  v1::SnapshotDelta delta = make_delta(base, snapshot_to_proto(w.snapshot()));
  EXPECT_EQ(delta.moved_size(), 0);
  EXPECT_LT(delta.ByteSizeLong(), 64u);  // header fields only
}

TEST(FirstDifference, NamesTheRecordAndField) {
  World w = build("ragdolls");
  for (int i = 0; i < 10; ++i) w.step();
  v1::Snapshot a = snapshot_to_proto(w.snapshot());
  v1::Snapshot b = a;
  EXPECT_EQ(first_difference(a, b), "");
  b.mutable_bodies(7)->mutable_linear_velocity()->set_y(a.bodies(7).linear_velocity().y() + 1);
  b.mutable_joints(2)->set_motor_impulse(5.0);
  std::string d = first_difference(a, b);
  EXPECT_EQ(d.rfind("bodies[7].linear_velocity.y: expected ", 0), 0u) << d;
}

}  // namespace
}  // namespace fulcrum
