// Constant forces and attractors (forces.cpp): physical facts with explained tolerances, and
// their place in the world's state (snapshots, the state hash).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/state.h"
#include "fulcrum/trig.h"
#include "fulcrum/world.h"
#include "scene_fixture.h"

namespace fulcrum {
namespace {

WorldSettings no_gravity() {
  WorldSettings s;
  s.gravity = Vec2::Zero();
  return s;
}

// A 1 m box of density `density` (mass = density kg), or a circle when radius > 0.
BodyId body(World& w, const Vec2& p, double density = 1.0, double radius = 0.0,
            uint64_t category = 1) {
  BodyDef def;
  def.type = BodyType::kDynamic;
  def.position = p;
  def.enable_sleep = false;
  BodyId id = *w.create_body(def);
  ShapeDef sd;
  sd.density = density;
  sd.filter.category_bits = category;
  if (radius > 0.0) {
    sd.geometry = Circle{Vec2::Zero(), radius};
  } else {
    sd.geometry = make_box(0.5, 0.5);
  }
  EXPECT_TRUE(w.create_shape(id, sd).ok());
  return id;
}

// v = F / m t: each of the 4 substeps adds h F / m, so after n ticks the velocity is an exact
// sum of 4 n equal terms; 1e-12 relative covers the rounding of that sum.
TEST(ConstantForce, AcceleratesAtFOverMEveryTick) {
  World w(no_gravity());
  BodyId b = body(w, Vec2::Zero(), 2.0);  // 2 kg
  const Vec2 force(3.0, -4.0);
  ASSERT_TRUE(w.set_constant_force(b, force, 0.0).ok());
  const int ticks = 120;
  for (int i = 0; i < ticks; ++i) w.step();
  const double t = ticks * w.settings().dt;
  BodyState s = *w.body_state(b);
  EXPECT_NEAR(s.linear_velocity.x(), 1.5 * t, 1e-12 * 1.5 * t);
  EXPECT_NEAR(s.linear_velocity.y(), -2.0 * t, 1e-12 * 2.0 * t);
  EXPECT_EQ(s.constant_force, force);
  // Symplectic Euler over n substeps of h: x = a h^2 n (n + 1) / 2 = a t^2 / 2 + a h t / 2.
  const double h = w.settings().dt / w.settings().substeps;
  const double x = 1.5 * t * t / 2.0 + 1.5 * h * t / 2.0;
  EXPECT_NEAR(s.center.x(), x, 1e-9 * x);
}

TEST(ConstantForce, ClearingItStopsTheAcceleration) {
  World w(no_gravity());
  BodyId b = body(w, Vec2::Zero());
  ASSERT_TRUE(w.set_constant_force(b, Vec2(1.0, 0.0), 0.0).ok());
  for (int i = 0; i < 60; ++i) w.step();
  const Vec2 v = w.body_state(b)->linear_velocity;
  EXPECT_NEAR(v.x(), 1.0, 1e-12);  // 1 N on 1 kg for 1 s
  ASSERT_TRUE(w.set_constant_force(b, Vec2::Zero(), 0.0).ok());
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_EQ(w.body_state(b)->linear_velocity, v);  // no force, no damping: not a bit changes
}

// A one-tick apply_force adds to the constant force for that tick only.
TEST(ConstantForce, AddsToOneTickForces) {
  World w(no_gravity());
  BodyId b = body(w, Vec2::Zero());
  ASSERT_TRUE(w.set_constant_force(b, Vec2(1.0, 0.0), 0.0).ok());
  ASSERT_TRUE(w.apply_force_to_center(b, Vec2(6.0, 0.0)).ok());
  w.step();
  w.step();
  // (1 + 6) N for one tick, then 1 N for one tick, on 1 kg: 8 dt.
  EXPECT_NEAR(w.body_state(b)->linear_velocity.x(), 8.0 * w.settings().dt, 1e-14);
}

// w = T / I t, I = m (a^2 + b^2) / 12 = 1/6 kg m^2 for the 1 m box of 1 kg.
TEST(ConstantForce, TorqueSpinsAtTOverI) {
  World w(no_gravity());
  BodyId b = body(w, Vec2::Zero());
  ASSERT_TRUE(w.set_constant_force(b, Vec2::Zero(), 0.5).ok());
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_NEAR(w.body_state(b)->angular_velocity, 0.5 * 6.0 * 1.0, 1e-12 * 3.0);
}

TEST(ConstantForce, WakesASleepingBody) {
  World w(no_gravity());
  BodyDef def;
  def.type = BodyType::kDynamic;
  def.awake = false;
  BodyId b = *w.create_body(def);
  ASSERT_FALSE(w.body_state(b)->awake);
  ASSERT_TRUE(w.set_constant_force(b, Vec2(1.0, 0.0), 0.0).ok());
  EXPECT_TRUE(w.body_state(b)->awake);
}

TEST(ConstantForce, RefusesNonFiniteAndHugeValuesNamingTheField) {
  World w;
  BodyId b = body(w, Vec2::Zero());
  Status s = w.set_constant_force(b, Vec2(std::nan(""), 0.0), 0.0);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message().rfind("force", 0), 0u) << s.message();
  s = w.set_constant_force(b, Vec2::Zero(), 2e12);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message().rfind("torque", 0), 0u) << s.message();
  BodyDef def;
  def.constant_force = Vec2(0.0, INFINITY);
  EXPECT_EQ(w.create_body(def).status().message().rfind("body.constant_force", 0), 0u);
}

// Inverse square with strength G M = 100 m^3/s^2 at the origin; a body at r = 10 m moving at
// sqrt(G M / r) = sqrt(10) m/s across the radius circles with period 2 pi r / v = 19.87 s.
// Symplectic Euler keeps an orbit closed to O((h w)^2) per revolution (h w = 1.3e-3 here):
// over one revolution the radius stays within 0.5 % of 10 m, and the body comes back within
// 1 % of r of its start.
TEST(Attractor, InverseSquareHoldsACircularOrbit) {
  World w(no_gravity());
  BodyId b = body(w, Vec2(10.0, 0.0), 1.0, 0.1);
  ASSERT_TRUE(w.set_linear_velocity(b, Vec2(0.0, std::sqrt(10.0))).ok());
  AttractorDef a;
  a.strength = 100.0;
  a.falloff = Falloff::kInverseSquare;
  ASSERT_TRUE(w.set_attractors({a}).ok());
  const double period = 2.0 * kPi * 10.0 / std::sqrt(10.0);
  const int ticks = static_cast<int>(std::lround(period / w.settings().dt));
  double lo = 10.0, hi = 10.0;
  for (int i = 0; i < ticks; ++i) {
    w.step();
    double r = length(w.body_state(b)->center);
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  EXPECT_GT(lo, 9.95);
  EXPECT_LT(hi, 10.05);
  EXPECT_LT(length(w.body_state(b)->center - Vec2(10.0, 0.0)), 0.1);
}

// Constant falloff, 2 m/s^2 toward the origin from 5 m at rest: the body reaches
// min_distance (0.5 m) after t = sqrt(2 (5 - 0.5) / 2) = 2.121 s (127.3 ticks); within a tick
// of that, since symplectic Euler's position error is a h t / 2 = 0.009 m at that time.
TEST(Attractor, ConstantPullMakesABodyFallIn) {
  World w(no_gravity());
  BodyId b = body(w, Vec2(5.0, 0.0), 1.0, 0.1);
  AttractorDef a;
  a.strength = 2.0;
  ASSERT_TRUE(w.set_attractors({a}).ok());
  int reached = -1;
  for (int i = 1; i <= 200 && reached < 0; ++i) {
    w.step();
    if (w.body_state(b)->center.x() <= 0.5) reached = i;
  }
  EXPECT_GE(reached, 127);
  EXPECT_LE(reached, 129);
}

// per_mass = false: the strength is a force, so a body of 4 kg accelerates a quarter as fast;
// per_mass = true: both alike. A category outside the mask feels nothing.
TEST(Attractor, ForceOrAccelerationAndTheMask) {
  World w(no_gravity());
  BodyId light = body(w, Vec2(0.0, 10.0), 1.0);
  BodyId heavy = body(w, Vec2(0.0, -10.0), 4.0);
  BodyId other = body(w, Vec2(10.0, 0.0), 1.0, 0.0, 2);
  AttractorDef a;
  a.strength = 1.0;
  a.per_mass = false;
  a.mask_bits = 1;
  ASSERT_TRUE(w.set_attractors({a}).ok());
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_NEAR(w.body_state(light)->linear_velocity.y(), -1.0, 1e-12);  // 1 N on 1 kg, 1 s
  EXPECT_NEAR(w.body_state(heavy)->linear_velocity.y(), 0.25, 1e-12);  // 1 N on 4 kg
  EXPECT_EQ(w.body_state(other)->linear_velocity, Vec2::Zero());
}

TEST(Attractor, RefusesBadDefinitionsNamingTheField) {
  World w;
  AttractorDef good, bad;
  bad.strength = std::nan("");
  Status s = w.set_attractors({good, bad});
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message().rfind("attractors[1].strength", 0), 0u) << s.message();
  bad = AttractorDef{};
  bad.min_distance = 0.0;
  s = w.set_attractors({bad});
  EXPECT_EQ(s.message().rfind("attractors[0].min_distance", 0), 0u) << s.message();
  bad = AttractorDef{};
  bad.point = Vec2(1e13, 0.0);
  EXPECT_FALSE(w.set_attractors({bad}).ok());
  EXPECT_TRUE(w.attractors().empty());  // nothing changed
}

// Constant forces and attractors are state: a world restored from a snapshot taken mid-run
// continues bit for bit, and the hash tells worlds with and without them apart.
TEST(ForcesState, SnapshotMidRunContinuesBitForBit) {
  World w;
  BodyId a = body(w, Vec2(0.0, 5.0));
  BodyId b = body(w, Vec2(3.0, 5.0), 1.0, 0.3);
  ASSERT_TRUE(w.set_constant_force(a, Vec2(2.0, 15.0), 0.3).ok());
  AttractorDef pull;
  pull.point = Vec2(1.0, 8.0);
  pull.strength = 30.0;
  pull.falloff = Falloff::kInverseSquare;
  ASSERT_TRUE(w.set_attractors({pull}).ok());
  (void)b;
  for (int i = 0; i < 30; ++i) w.step();
  WorldSnapshot snap = w.snapshot();
  std::vector<uint64_t> expected;
  for (int i = 0; i < 60; ++i) {
    w.step();
    expected.push_back(w.state_hash());
  }
  World copy;
  ASSERT_TRUE(copy.restore(snap).ok());
  EXPECT_EQ(copy.attractors().size(), 1u);
  for (int i = 0; i < 60; ++i) {
    copy.step();
    ASSERT_EQ(copy.state_hash(), expected[i]) << "tick " << copy.tick();
  }
  // The hash covers them: the same world without its attractors or its constant force hashes
  // differently.
  World without;
  ASSERT_TRUE(without.restore(snap).ok());
  ASSERT_TRUE(without.set_attractors({}).ok());
  EXPECT_NE(without.state_hash(), snap.state_hash);
  ASSERT_TRUE(without.restore(snap).ok());
  ASSERT_TRUE(without.set_constant_force(a, Vec2::Zero(), 0.0).ok());
  EXPECT_NE(without.state_hash(), snap.state_hash);
  // A snapshot whose records were changed no longer matches its recorded hash.
  WorldSnapshot forged = snap;
  forged.attractors[0].strength = 31.0;
  EXPECT_FALSE(World().restore(forged).ok());
}

// Attractors and constant forces are summed per body in the world's order, inside the
// step's shared-out integration: any thread count gives one thread's state hash every tick,
// on a pyramid large enough (300 boxes, over 256 touching contacts) that the step shares its
// work out, pulled sideways by an attractor and with a constant force on every fifth box.
TEST(ForcesState, EveryThreadCountGivesOneThreadsBits) {
  SceneDef scene;
  scenes::add_ground(&scene, 60.0);
  scenes::PyramidOptions p;
  p.base = 24;
  scenes::add_pyramid(&scene, p);
  for (size_t i = 1; i < scene.bodies.size(); i += 5) {
    scene.bodies[i].def.constant_force = Vec2(0.5, 2.0);
  }
  AttractorDef pull;
  pull.point = Vec2(40.0, 5.0);
  pull.strength = 400.0;
  pull.falloff = Falloff::kInverseSquare;
  scene.attractors.push_back(pull);
  testing::expect_thread_counts_agree(scene, 60, {1, 2, 4}, [](const World&) {});
}

}  // namespace
}  // namespace fulcrum
