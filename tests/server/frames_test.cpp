// Frames for one reader: the full list first, then only what changed (bit for bit), bodies
// destroyed or whose slot was reused, and a full list again after a restore.
#include "frames.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace fulcrum::server
