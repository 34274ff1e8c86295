// Frames for one reader: the full list first, then only what changed (bit for bit), bodies
// destroyed or whose slot was reused, and a full list again after a restore.
#include "frames.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/world.h"
#include "quantize.h"

namespace fulcrum::server {
namespace {

BodyMotion motion(int32_t index, uint32_t generation, double x) {
  BodyMotion m;
  m.id.index = index;
  m.id.generation = generation;
  m.position = Vec2(x, 0.0);
  return m;
}

PublishedFrame frame(int64_t tick, std::vector<BodyMotion> bodies, uint64_t epoch = 0) {
  PublishedFrame f;
  f.world_id = 3;
  f.tick = tick;
  f.state_hash = 0xabc + static_cast<uint64_t>(tick);
  f.epoch = epoch;
  f.bodies = std::move(bodies);
  return f;
}

TEST(Frames, FirstFrameIsFull) {
  const PublishedFrame a = frame(5, {motion(0, 1, 0.0), motion(1, 1, 1.0)});
  v1::Frame out;
  frame_to_proto(a, nullptr, v1::FRAME_BODIES_CHANGED, 0, 1, &out);
  EXPECT_TRUE(out.full());
  EXPECT_EQ(out.bodies_size(), 2);
  EXPECT_EQ(out.tick(), 5);
  EXPECT_EQ(out.world_id(), 3u);
  EXPECT_EQ(out.state_hash(), 0xabcu + 5);
}

TEST(Frames, ChangedSendsOnlyDifferencesAndDestroyedBodies) {
  const PublishedFrame a =
      frame(1, {motion(0, 1, 0.0), motion(1, 1, 1.0), motion(2, 1, 2.0), motion(4, 1, 4.0)});
  // Body 1 moved, body 2 destroyed, slot 4 reused by a new body, body 5 created.
  const PublishedFrame b =
      frame(2, {motion(0, 1, 0.0), motion(1, 1, 1.5), motion(4, 2, 4.0), motion(5, 1, 5.0)});
  v1::Frame out;
  frame_to_proto(b, &a, v1::FRAME_BODIES_CHANGED, 3, 2, &out);
  EXPECT_FALSE(out.full());
  ASSERT_EQ(out.bodies_size(), 3);
  EXPECT_EQ(out.bodies(0).body().index(), 1);
  EXPECT_EQ(out.bodies(0).position().x(), 1.5);
  EXPECT_EQ(out.bodies(1).body().index(), 4);
  EXPECT_EQ(out.bodies(1).body().generation(), 2u);
  EXPECT_EQ(out.bodies(2).body().index(), 5);
  ASSERT_EQ(out.destroyed_size(), 2);
  EXPECT_EQ(out.destroyed(0).index(), 2);
  EXPECT_EQ(out.destroyed(1).index(), 4);
  EXPECT_EQ(out.destroyed(1).generation(), 1u);
  EXPECT_EQ(out.skipped_frames(), 3u);
  EXPECT_EQ(out.skipped_ticks(), 6);
}

TEST(Frames, NegativeZeroIsAChange) {
  // Bit-for-bit comparison: -0.0 == 0.0 numerically but is another state.
  const PublishedFrame a = frame(1, {motion(0, 1, 0.0)});
  const PublishedFrame b = frame(2, {motion(0, 1, -0.0)});
  v1::Frame out;
  frame_to_proto(b, &a, v1::FRAME_BODIES_CHANGED, 0, 1, &out);
  EXPECT_EQ(out.bodies_size(), 1);
}

TEST(Frames, RestoreSendsEverything) {
  const PublishedFrame a = frame(10, {motion(0, 1, 0.0)}, 0);
  const PublishedFrame b = frame(4, {motion(0, 1, 0.0)}, 1);
  v1::Frame out;
  frame_to_proto(b, &a, v1::FRAME_BODIES_CHANGED, 0, 1, &out);
  EXPECT_TRUE(out.restored());
  EXPECT_TRUE(out.full());
  EXPECT_EQ(out.bodies_size(), 1);
}

TEST(Frames, NoneSendsCountsOnly) {
  PublishedFrame a = frame(1, {motion(0, 1, 0.0), motion(1, 1, 1.0)});
  a.awake_body_count = 1;
  v1::Frame out;
  frame_to_proto(a, nullptr, v1::FRAME_BODIES_NONE, 0, 1, &out);
  EXPECT_EQ(out.bodies_size(), 0);
  EXPECT_EQ(out.body_count(), 2);
  EXPECT_EQ(out.awake_body_count(), 1);
}

// Every frame carries the world's budgets at its tick, captured from the world: a heavy chain's
// island runs 7 substeps (docs/solver.md, Budgets).
TEST(Frames, CarryTheBudgetsOfTheirTick) {
  Result<SceneDef> scene = scenes::builtin("heavy_chain");
  ASSERT_TRUE(scene.ok());
  Result<World> world = build_world(*scene);
  ASSERT_TRUE(world.ok());
  world->step();
  std::shared_ptr<const PublishedFrame> f = capture_frame(*world, 1, 0);
  v1::Frame out;
  frame_to_proto(*f, nullptr, v1::FRAME_BODIES_NONE, 0, 1, &out);
  EXPECT_EQ(out.budget_islands(), 1);
  EXPECT_EQ(out.max_substeps(), 7);
  EXPECT_EQ(out.max_relax_iterations(), 1);
  // Boxes created overlapping by a quarter: the pyramid recovers with three relax passes.
  Result<World> overlapping = build_world(*scenes::builtin("overlap_recovery"));
  ASSERT_TRUE(overlapping.ok());
  overlapping->step();
  frame_to_proto(*capture_frame(*overlapping, 1, 0), nullptr, v1::FRAME_BODIES_NONE, 0, 1, &out);
  EXPECT_EQ(out.budget_islands(), 1);
  EXPECT_EQ(out.max_substeps(), 4);
  EXPECT_EQ(out.max_relax_iterations(), 3);
}

// Decoding as frames.proto says: value = units * step.
BodyMotion decode(const v1::QuantizedBodyFrame& q) {
  BodyMotion m;
  m.id.index = q.index();
  m.id.generation = q.generation();
  m.position = Vec2(q.x() * kPositionStep, q.y() * kPositionStep);
  m.angle = q.angle() * kAngleStep;
  m.linear_velocity = Vec2(q.vx() * kLinearVelocityStep, q.vy() * kLinearVelocityStep);
  m.angular_velocity = q.angular_velocity() * kAngularVelocityStep;
  m.awake = q.awake();
  return m;
}

TEST(QuantizedFrames, DecodedStatesAreWithinTheStatedBounds) {
  // Bodies spread over the range the bounds are stated for, with irrational-looking values.
  std::vector<BodyMotion> bodies;
  for (int i = 0; i < 2000; ++i) {
    BodyMotion m = motion(i, 1, -500000.0 + 500.123456789 * i);
    m.position = Vec2(m.position.x(), std::sin(i * 0.7) * 1000.0);
    m.angle = std::remainder(i * 0.377, 6.283185307179586);
    m.linear_velocity = Vec2(std::cos(i * 1.3) * 300.0, -i * 0.0371);
    m.angular_velocity = std::sin(i * 0.11) * 50.0;
    m.awake = i % 2 == 0;
    bodies.push_back(m);
  }
  const PublishedFrame a = frame(7, bodies);
  v1::Frame out;
  frame_to_proto(a, nullptr, v1::FRAME_BODIES_ALL, 0, 1, &out, true);
  ASSERT_EQ(out.quantized_bodies_size(), 2000);
  EXPECT_EQ(out.bodies_size(), 0);
  EXPECT_EQ(out.state_hash(), a.state_hash);  // the exact hash, not one of quantized values
  // Half a step, plus the rounding of value / step for the angle (its step is not a power of
  // two: a relative 2^-52 of the angle, < 1e-15 rad).
  const double pos_bound = kPositionStep / 2;
  const double angle_bound = kAngleStep / 2 + 1e-15;
  const double vel_bound = kLinearVelocityStep / 2;
  for (int i = 0; i < 2000; ++i) {
    const BodyMotion d = decode(out.quantized_bodies(i));
    const BodyMotion& e = bodies[i];
    EXPECT_EQ(d.id, e.id);
    EXPECT_LE(std::abs(d.position.x() - e.position.x()), pos_bound) << i;
    EXPECT_LE(std::abs(d.position.y() - e.position.y()), pos_bound) << i;
    EXPECT_LE(std::abs(d.angle - e.angle), angle_bound) << i;
    EXPECT_LE(std::abs(d.linear_velocity.x() - e.linear_velocity.x()), vel_bound) << i;
    EXPECT_LE(std::abs(d.linear_velocity.y() - e.linear_velocity.y()), vel_bound) << i;
    EXPECT_LE(std::abs(d.angular_velocity - e.angular_velocity), kAngularVelocityStep / 2) << i;
    EXPECT_EQ(d.awake, e.awake);
  }
}

TEST(QuantizedFrames, OutOfRangeBodiesFallBackToFullPrecision) {
  BodyMotion far = motion(1, 1, 600000.0);  // beyond +-524287 m
  BodyMotion fast = motion(2, 1, 0.0);
  fast.linear_velocity = Vec2(3.0e6, 0.0);  // beyond +-2097151 m/s
  BodyMotion nan = motion(3, 1, 0.0);
  nan.angular_velocity = std::numeric_limits<double>::infinity();
  const PublishedFrame a = frame(1, {motion(0, 1, 1.0), far, fast, nan, motion(4, 1, 2.0)});
  v1::Frame out;
  frame_to_proto(a, nullptr, v1::FRAME_BODIES_ALL, 0, 1, &out, true);
  ASSERT_EQ(out.quantized_bodies_size(), 2);
  EXPECT_EQ(out.quantized_bodies(0).index(), 0);
  EXPECT_EQ(out.quantized_bodies(1).index(), 4);
  ASSERT_EQ(out.bodies_size(), 3);
  EXPECT_EQ(out.bodies(0).position().x(), 600000.0);  // exact, bit for bit
  EXPECT_EQ(out.bodies(1).linear_velocity().x(), 3.0e6);
  EXPECT_TRUE(std::isinf(out.bodies(2).angular_velocity()));
}

TEST(QuantizedFrames, ChangedResendsOnlyWhenAQuantizedValueChanges) {
  // Body 0 moves by less than half a step (same units): not re-sent, and the reader's copy is
  // still within the bound of the new exact state. Body 1 moves by a step: re-sent.
  const PublishedFrame a = frame(1, {motion(0, 1, 1.0), motion(1, 1, 2.0)});
  const PublishedFrame b =
      frame(2, {motion(0, 1, 1.0 + kPositionStep / 8), motion(1, 1, 2.0 + kPositionStep)});
  v1::Frame out;
  frame_to_proto(b, &a, v1::FRAME_BODIES_CHANGED, 0, 1, &out, true);
  ASSERT_EQ(out.quantized_bodies_size(), 1);
  EXPECT_EQ(out.quantized_bodies(0).index(), 1);
  EXPECT_EQ(out.quantized_bodies(0).x(), (2.0 + kPositionStep) * 4096);
  EXPECT_EQ(out.bodies_size(), 0);
}

TEST(QuantizedFrames, FewerBytesThanFullPrecision) {
  std::vector<BodyMotion> bodies;
  for (int i = 0; i < 100; ++i) {
    BodyMotion m = motion(i, 1, i * 1.1 - 50.0);
    m.position = Vec2(m.position.x(), 0.5 + i * 0.013);
    m.angle = 0.001 * i;
    m.linear_velocity = Vec2(0.25, -3.5);
    m.awake = true;
    bodies.push_back(m);
  }
  const PublishedFrame a = frame(1, bodies);
  v1::Frame full, quantized;
  frame_to_proto(a, nullptr, v1::FRAME_BODIES_ALL, 0, 1, &full, false);
  frame_to_proto(a, nullptr, v1::FRAME_BODIES_ALL, 0, 1, &quantized, true);
  // 7 doubles (63 bytes with tags) against 6 varints of 1 to 4 bytes: under half.
  EXPECT_LT(quantized.ByteSizeLong() * 2, full.ByteSizeLong());
}

// The bytes a reader gets (its part, then the shared encoding) parse to what frame_to_proto
// builds for that reader alone; readers with the same previous frame share one encoding.
TEST(SharedEncoding, ReaderPartPlusSharedBytesIsTheReadersFrame) {
  PublishedFrame a = frame(1, {motion(0, 1, 0.0), motion(1, 1, 1.0)});
  a.seq = 1;
  PublishedFrame b = frame(2, {motion(0, 1, 0.0), motion(1, 1, 1.5)});
  b.seq = 2;
  for (bool quantized : {false, true}) {
    for (v1::FrameBodies mode :
         {v1::FRAME_BODIES_ALL, v1::FRAME_BODIES_CHANGED, v1::FRAME_BODIES_NONE}) {
      v1::Frame expected;
      frame_to_proto(b, &a, mode, 4, 3, &expected, quantized);
      bool built_first = false, built_second = true;
      auto first = encode_shared(b, &a, mode, quantized, &built_first);
      auto second = encode_shared(b, &a, mode, quantized, &built_second);
      // Frames without bodies are the same bytes at either precision: built once.
      EXPECT_EQ(built_first, !(quantized && mode == v1::FRAME_BODIES_NONE));
      EXPECT_FALSE(built_second);
      EXPECT_EQ(first.get(), second.get());  // one encoding, shared
      v1::Frame got;
      ASSERT_TRUE(got.ParseFromString(encode_reader_part(4, 3) + *first));
      EXPECT_EQ(got.SerializeAsString(), expected.SerializeAsString());
    }
  }
  // Another base (a reader that skipped frames) gets its own encoding.
  PublishedFrame c = frame(0, {motion(0, 1, 0.5)});
  c.seq = 3;
  bool built = false;
  auto other = encode_shared(b, &c, v1::FRAME_BODIES_CHANGED, false, &built);
  EXPECT_TRUE(built);
  EXPECT_NE(other.get(), encode_shared(b, &a, v1::FRAME_BODIES_CHANGED, false).get());
}

}  // namespace
}  // namespace fulcrum::server
