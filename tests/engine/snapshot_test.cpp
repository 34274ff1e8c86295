// Snapshots: a world restored from a snapshot continues bit for bit, and a snapshot that breaks
// any rule is refused with a message naming the record, leaving the target world unchanged.
#include <gtest/gtest.h>

#include <vector>

#include "fulcrum/state.h"
#include "fulcrum/world.h"
#include "scene_fixture.h"

namespace fulcrum {
namespace {

using testing::build;

// Steps both worlds `ticks` times and returns the first tick whose hashes differ (-1: none).
int64_t first_divergence(World& a, World& b, int ticks) {
  for (int i = 0; i < ticks; ++i) {
    a.step();
    b.step();
    if (a.state_hash() != b.state_hash()) return a.tick();
  }
  return -1;
}

// Scenes that between them use every record: stacks and contacts (pyramid), joints with limits
// and motors (ragdolls, tumbler), particles (rope, cloth), sleeping bodies (vertical_stack
// after settling) and sensors and mixed shapes (mixed).
class SnapshotRoundTrip : public ::testing::TestWithParam<const char*> {};

TEST_P(SnapshotRoundTrip, RestoredWorldContinuesBitForBit) {
  World original = build(GetParam());
  for (int i = 0; i < 120; ++i) original.step();
  WorldSnapshot snap = original.snapshot();
  World copy;
  ASSERT_TRUE(copy.restore(snap).ok()) << copy.restore(snap).message();
  EXPECT_EQ(copy.state_hash(), original.state_hash());
  EXPECT_EQ(copy.tick(), original.tick());
  EXPECT_EQ(first_divergence(original, copy, 300), -1);
  // The restored world's own snapshot is the same snapshot again.
  EXPECT_EQ(copy.snapshot().state_hash, original.snapshot().state_hash);
}

INSTANTIATE_TEST_SUITE_P(Scenes, SnapshotRoundTrip,
                         ::testing::Values("many_pyramids", "ragdolls", "rope", "cloth", "bounce",
                                           "mixed", "vertical_stack", "bridge"));

// Rollback: save at T, step to T + k, restore T, step again: every tick's hash repeats.
TEST(Snapshot, RollbackRepeatsEveryTick) {
  World w = build("ragdolls");
  for (int i = 0; i < 60; ++i) w.step();
  WorldSnapshot at_t = w.snapshot();
  std::vector<uint64_t> first;
  for (int i = 0; i < 90; ++i) {
    w.step();
    first.push_back(w.state_hash());
  }
  ASSERT_TRUE(w.restore(at_t).ok());
  EXPECT_EQ(w.tick(), 60);
  for (int i = 0; i < 90; ++i) {
    w.step();
    ASSERT_EQ(w.state_hash(), first[i]) << "tick " << w.tick();
  }
}

// Handles issued after a restore are the ones the original world would issue.
TEST(Snapshot, RestoredWorldIssuesTheSameHandles) {
  World a = build("many_pyramids");
  ASSERT_TRUE(a.destroy_body(a.bodies()[3]).ok());
  World b;
  ASSERT_TRUE(b.restore(a.snapshot()).ok());
  BodyDef def;
  def.type = BodyType::kDynamic;
  auto ha = a.create_body(def);
  auto hb = b.create_body(def);
  ASSERT_TRUE(ha.ok() && hb.ok());
  EXPECT_EQ(*ha, *hb);
  EXPECT_EQ(a.state_hash(), b.state_hash());
}

// Each corruption is refused, the message names what is wrong, and the world is unchanged.
TEST(Snapshot, CorruptSnapshotsAreRefusedAndChangeNothing) {
  World source = build("ragdolls");
  for (int i = 0; i < 150; ++i) source.step();
  const WorldSnapshot good = source.snapshot();
  ASSERT_FALSE(good.contacts.empty());

  World target = build("many_pyramids");
  const uint64_t before = target.state_hash();
  struct Case {
    const char* expect;  // a piece of the message
    void (*corrupt)(WorldSnapshot&);
  };
  const Case cases[] = {
      {"state_hash", [](WorldSnapshot& s) { s.state_hash ^= 1; }},
      {"state_hash", [](WorldSnapshot& s) { s.bodies[1].v.x() += 1e-9; }},
      {"not finite", [](WorldSnapshot& s) { s.bodies[1].w = std::nan(""); }},
      {"free_bodies", [](WorldSnapshot& s) { s.free_bodies.push_back(0); }},
      {"shape_boxes", [](WorldSnapshot& s) { s.shape_boxes.pop_back(); }},
      {"body", [](WorldSnapshot& s) { s.shapes[2].body = 100000; }},
      {"contact_count", [](WorldSnapshot& s) { s.bodies[1].contact_count += 1; }},
      {"manifold.count",
       [](WorldSnapshot& s) {
         for (Contact& c : s.contacts) {
           if (c.alive) c.manifold.count = 3;
         }
       }},
      {"joint", [](WorldSnapshot& s) { s.joints[0].body_b = s.joints[0].body_a; }},
      {"settings", [](WorldSnapshot& s) { s.settings.dt = -1.0; }},
      {"awake_bodies", [](WorldSnapshot& s) { s.awake_bodies.push_back(-4); }},
      {"type", [](WorldSnapshot& s) { s.bodies[1].type = static_cast<BodyType>(9); }},
  };
  for (const Case& c : cases) {
    WorldSnapshot bad = good;
    c.corrupt(bad);
    Status st = target.restore(bad);
    ASSERT_FALSE(st.ok()) << c.expect;
    EXPECT_EQ(st.code(), StatusCode::kDataLoss) << st.message();
    EXPECT_NE(st.message().find(c.expect), std::string::npos) << st.message();
    EXPECT_EQ(target.state_hash(), before) << c.expect;
  }
}

}  // namespace
}  // namespace fulcrum
