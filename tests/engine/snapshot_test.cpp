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

// copy_state: a copy continues bit for bit like its original, whatever the copy held before
// and whatever its thread count, and the two are independent afterwards.
TEST_P(SnapshotRoundTrip, CopiedWorldContinuesBitForBit) {
  World original = build(GetParam());
  for (int i = 0; i < 120; ++i) original.step();
  World copy = build("tumbler");  // different content, to be overwritten whole
  ASSERT_TRUE(copy.set_threads(2).ok());
  for (int i = 0; i < 10; ++i) copy.step();
  copy.copy_state(original);
  EXPECT_EQ(copy.state_hash(), original.state_hash());
  EXPECT_EQ(copy.tick(), original.tick());
  EXPECT_EQ(copy.threads(), 2);
  EXPECT_EQ(first_divergence(original, copy, 120), -1);
  // Independent: a kick to the copy leaves the original on a third world's path.
  World witness;
  witness.copy_state(original);
  const BodyId kicked = copy.bodies().back();
  ASSERT_TRUE(copy.set_linear_velocity(kicked, Vec2(0.0, 5.0)).ok());
  EXPECT_NE(copy.state_hash(), original.state_hash());
  EXPECT_EQ(first_divergence(original, witness, 30), -1);
}

INSTANTIATE_TEST_SUITE_P(Scenes, SnapshotRoundTrip,
                         ::testing::Values("many_pyramids", "ragdolls", "rope", "cloth", "bounce",
                                           "mixed", "vertical_stack", "bridge"));

// Every joint type's records (curves with their points, springs, motor targets) survive.
TEST(Snapshot, EveryJointTypeRoundTrips) {
  World w;
  BodyDef ground_def;
  BodyId ground = *w.create_body(ground_def);
  ShapeDef slab;
  slab.geometry = make_box(30.0, 0.5);
  ASSERT_TRUE(w.create_shape(ground, slab).ok());
  auto dynamic_box = [&](double x, double y) {
    BodyDef d;
    d.type = BodyType::kDynamic;
    d.position = Vec2(x, y);
    BodyId b = *w.create_body(d);
    ShapeDef s;
    s.geometry = make_box(0.3, 0.3);
    EXPECT_TRUE(w.create_shape(b, s).ok());
    return b;
  };
  BodyId chassis = dynamic_box(-8.0, 3.0), wheel = dynamic_box(-8.0, 2.0);
  WheelJointDef wheel_def;
  wheel_def.body_a = chassis;
  wheel_def.body_b = wheel;
  wheel_def.local_anchor_a = Vec2(0.0, -1.0);
  wheel_def.enable_motor = true;
  wheel_def.motor_speed = -3.0;
  wheel_def.max_motor_torque = 20.0;
  ASSERT_TRUE(w.create_wheel_joint(wheel_def).ok());
  MotorJointDef motor_def;
  motor_def.body_a = ground;
  motor_def.body_b = dynamic_box(-3.0, 4.0);
  motor_def.linear_offset = Vec2(-3.0, 4.0);
  motor_def.max_force = 500.0;
  motor_def.max_torque = 50.0;
  JointId motor = *w.create_motor_joint(motor_def);
  CurveJointDef curve_def;
  curve_def.body_a = ground;
  curve_def.body_b = dynamic_box(4.0, 6.0);
  curve_def.curve = CurveType::kPolyline;
  curve_def.points = {Vec2(1.0, 8.0), Vec2(4.0, 6.0), Vec2(7.0, 8.0)};
  ASSERT_TRUE(w.create_curve_joint(curve_def).ok());
  SpringDef spring_def;
  spring_def.body_a = ground;
  spring_def.body_b = dynamic_box(10.0, 5.0);
  spring_def.local_anchor_a = Vec2(10.0, 8.0);
  spring_def.rest_length = 2.0;
  spring_def.stiffness = 200.0;
  spring_def.damping = 2.0;
  ASSERT_TRUE(w.create_spring(spring_def).ok());
  for (int i = 0; i < 40; ++i) {
    ASSERT_TRUE(w.set_motor_joint_targets(motor, Vec2(-3.0 + 0.02 * i, 4.0), 0.01 * i).ok());
    w.step();
  }
  World copy;
  ASSERT_TRUE(copy.restore(w.snapshot()).ok());
  EXPECT_EQ(first_divergence(w, copy, 200), -1);
}

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
  // Boxes on the ground keep their manifolds (ManifoldCache); the ragdolls' capsules do not.
  World pile = build("many_pyramids");
  for (int i = 0; i < 30; ++i) pile.step();
  const WorldSnapshot boxes = pile.snapshot();

  World target = build("many_pyramids");
  const uint64_t before = target.state_hash();
  struct Case {
    const char* expect;  // a piece of the message
    void (*corrupt)(WorldSnapshot&);
    bool of_boxes = false;  // corrupts `boxes` instead of `good`
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
      {"cache.normal",
       [](WorldSnapshot& s) {
         for (size_t i = 0; i < s.contacts.size(); ++i) {
           if (s.contacts[i].alive && s.manifold_caches[i].valid) {
             s.manifold_caches[i].normal.x() = std::nan("");
           }
         }
       },
       true},
      // The narrow phase moves a kept manifold on without reading the shapes again, so only
      // manifolds of flat shapes may be kept.
      {"cache is kept for a sensor or a shape without flat faces",
       [](WorldSnapshot& s) {
         for (size_t i = 0; i < s.contacts.size(); ++i) {
           if (s.contacts[i].alive && s.contacts[i].manifold.count > 0) {
             s.manifold_caches[i].valid = true;
           }
         }
       }},
      {"cache is kept for a manifold without points",
       [](WorldSnapshot& s) {
         for (size_t i = 0; i < s.contacts.size(); ++i) {
           if (s.contacts[i].alive) {
             s.manifold_caches[i].valid = true;
             s.contacts[i].manifold.count = 0;
           }
         }
       }},
      {"joint", [](WorldSnapshot& s) { s.joints[0].body_b = s.joints[0].body_a; }},
      {"settings", [](WorldSnapshot& s) { s.settings.dt = -1.0; }},
      {"awake_bodies", [](WorldSnapshot& s) { s.awake_bodies.push_back(-4); }},
      {"type", [](WorldSnapshot& s) { s.bodies[1].type = static_cast<BodyType>(9); }},
      // Finite but past what any joint definition allows: the snapshot fuzz target's finding
      // (tests/fuzz/findings/snapshot/), whose world went non-finite two ticks after restore.
      {"joint[3].local_b: each coordinate must be at most 1e12 in magnitude",
       [](WorldSnapshot& s) { s.joints[3].local_b.y() = 4.0582731154107935e+143; }},
      {"joint[0].reference_angle: must be at most 1e12",
       [](WorldSnapshot& s) { s.joints[0].reference_angle = -1e13; }},
  };
  for (const Case& c : cases) {
    WorldSnapshot bad = c.of_boxes ? boxes : good;
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
