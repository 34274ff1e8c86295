// The reference solver (fulcrum/reference.h): closed forms on small problems, its residual,
// the classic solver converging to it, and its determinism.
#include "fulcrum/reference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "fulcrum/trig.h"
#include "fulcrum/world.h"
#include "scene_fixture.h"

namespace fulcrum {
namespace {

constexpr double kDt = 1.0 / 60.0;
constexpr double kG = 10.0;
constexpr double kTol = 1e-10;  // the reference's residual target, N s

BodyId static_box(World& w, Vec2 center, double angle, double hx, double hy) {
  BodyDef def;
  def.position = center;
  def.angle = angle;
  BodyId id = w.create_body(def).value();
  ShapeDef shape;
  shape.geometry = make_box(hx, hy);
  EXPECT_TRUE(w.create_shape(id, shape).ok());
  return id;
}

BodyId dynamic_box(World& w, Vec2 center, double angle, double half, double friction) {
  BodyDef def;
  def.type = BodyType::kDynamic;
  def.position = center;
  def.angle = angle;
  BodyId id = w.create_body(def).value();
  ShapeDef shape;
  shape.geometry = make_box(half, half);
  shape.friction = friction;
  EXPECT_TRUE(w.create_shape(id, shape).ok());
  return id;
}

double sum_of(const ReferenceSolution& r, ReferenceRowKind kind) {
  double s = 0.0;
  for (const ReferenceImpulse& i : r.impulses) {
    if (i.kind == kind) s += i.impulse;
  }
  return s;
}

// A 1 m box (1 kg) resting on the ground: the two contact points together carry m g dt, the
// box leaves the tick at rest, and friction carries nothing.
TEST(Reference, BoxRestingOnGroundCarriesItsWeight) {
  World w;
  static_box(w, Vec2(0.0, -0.5), 0.0, 10.0, 0.5);
  BodyId box = dynamic_box(w, Vec2(0.0, 0.5), 0.0, 0.5, 0.6);
  auto ref = solve_reference(w);
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_TRUE(ref->converged);
  EXPECT_LE(ref->residual, kTol);
  EXPECT_EQ(ref->normal_rows, 2);
  EXPECT_EQ(ref->friction_rows, 2);
  ASSERT_EQ(ref->bodies.size(), 1u);
  EXPECT_EQ(ref->bodies[0], box);
  const double m = w.body_state(box)->mass;
  // The residual bounds each row's impulse error by 1e-10 N s; 1e-9 covers the sum of two.
  EXPECT_NEAR(sum_of(*ref, ReferenceRowKind::kNormal), m * kG * kDt, 1e-9);
  EXPECT_NEAR(sum_of(*ref, ReferenceRowKind::kFriction), 0.0, 1e-9);
  // Velocities: an impulse error of 1e-10 N s moves a 1 kg box by 1e-10 m/s.
  EXPECT_NEAR(ref->linear_velocity[0].x(), 0.0, 1e-9);
  EXPECT_NEAR(ref->linear_velocity[0].y(), 0.0, 1e-9);
  EXPECT_NEAR(ref->angular_velocity[0], 0.0, 1e-8);
}

// A particle on a 1 m rod from a static pivot, at rest 30 degrees from the vertical: the rod
// row takes the weight's component along the rod, m g dt cos(theta), and the bob leaves along
// the tangent with g dt sin(theta).
TEST(Reference, PendulumRodRowTakesTheWeightAlongTheRod) {
  World w;
  BodyId pivot = w.create_body(BodyDef{}).value();
  const double theta = kPi / 6.0;
  SinCos sc = det_sincos(theta);
  BodyDef bob_def;
  bob_def.type = BodyType::kParticle;
  bob_def.position = Vec2(sc.sin, -sc.cos);
  BodyId bob = w.create_body(bob_def).value();
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), 0.05};
  ASSERT_TRUE(w.create_shape(bob, shape).ok());
  DistanceJointDef rod;
  rod.body_a = pivot;
  rod.body_b = bob;
  ASSERT_TRUE(w.create_distance_joint(rod).ok());
  auto ref = solve_reference(w);
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_EQ(ref->method, "sparse LDLT");
  EXPECT_EQ(ref->equality_rows, 1);
  EXPECT_LE(ref->residual, kTol);
  const double m = w.body_state(bob)->mass;
  ASSERT_EQ(ref->impulses.size(), 1u);
  // One row, solved directly: exact to rounding (1e-12 of an impulse near 0.0013 N s).
  EXPECT_NEAR(std::abs(ref->impulses[0].impulse), m * kG * kDt * sc.cos, 1e-14);
  Vec2 v = ref->linear_velocity[0];
  Vec2 along(sc.sin, -sc.cos), tangent(sc.cos, sc.sin);
  EXPECT_NEAR(dot(v, along), 0.0, 1e-14);
  EXPECT_NEAR(dot(v, tangent), -kG * kDt * sc.sin, 1e-14);
}

// A 1 m box on a slope of angle alpha (static, rotated), touching: with friction mu.
// Sticking (tan alpha < mu): friction carries m g dt sin(alpha), the box stays at rest.
// Slipping (tan alpha > mu): friction = mu x normal = mu m g dt cos(alpha), and the box leaves
// sliding down at g dt (sin(alpha) - mu cos(alpha)).
void slope_case(double alpha, double mu, bool sticks) {
  World w;
  SinCos sc = det_sincos(alpha);
  Vec2 normal(-sc.sin, sc.cos), down_slope(-sc.cos, -sc.sin);
  static_box(w, -0.5 * normal, alpha, 10.0, 0.5);
  BodyId box = dynamic_box(w, 0.5 * normal, alpha, 0.5, mu);
  // The ground box has the default friction 0.6; mixing is sqrt(a b): give the box mu^2 / 0.6.
  ASSERT_TRUE(w.set_shape_material(w.body_shapes(box)->front(), mu * mu / 0.6, 0.0).ok());
  auto ref = solve_reference(w);
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_LE(ref->residual, kTol);
  const double m = w.body_state(box)->mass;
  const double n = sum_of(*ref, ReferenceRowKind::kNormal);
  const double f = std::abs(sum_of(*ref, ReferenceRowKind::kFriction));
  Vec2 v = ref->linear_velocity[0];
  // Impulse sums over two points within 1e-9 N s (residual 1e-10 per row, rounding of the
  // rotated geometry); the contact normal is the slope's to rounding.
  EXPECT_NEAR(n, m * kG * kDt * sc.cos, 1e-9);
  if (sticks) {
    EXPECT_NEAR(f, m * kG * kDt * sc.sin, 1e-9);
    EXPECT_NEAR(length(v), 0.0, 1e-9);
  } else {
    EXPECT_NEAR(f, mu * n, 1e-9);
    EXPECT_NEAR(dot(v, down_slope), kG * kDt * (sc.sin - mu * sc.cos), 1e-9);
    EXPECT_NEAR(dot(v, normal), 0.0, 1e-9);
  }
}

TEST(Reference, BoxOnSlopeSticks) {
  slope_case(20.0 * kPi / 180.0, 0.6, true);  // tan 20 deg = 0.36 < 0.6
}

TEST(Reference, BoxOnSlopeSlipsAtMuTimesNormal) {
  slope_case(30.0 * kPi / 180.0, 0.3, false);  // tan 30 deg = 0.58 > 0.3
}

// The shared vertical stack (20 boxes), settled for 60 ticks at the default setting, with
// sleeping off (a stack at rest falls asleep within a second and then has nothing to solve).
World settled_stack() {
  SceneDef scene = testing::scene("vertical_stack");
  scene.settings.enable_sleep = false;
  World w = testing::build(scene);
  for (int i = 0; i < 60; ++i) w.step();
  return w;
}

TEST(Reference, StackReachesTheResidual) {
  World w = settled_stack();
  auto ref = solve_reference(w);
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_TRUE(ref->converged) << ref->residual;
  EXPECT_LE(ref->residual, kTol);
  EXPECT_GE(ref->normal_rows, 40);  // 20 boxes on two points each
}

// A stack of `n` 1 m boxes on the ground, alternately offset by +-1 cm, settled for 60 ticks
// at the classic step with split impulses (8 passes), sleeping off.
WorldSettings classic_split(int iterations) {
  WorldSettings s;
  s.enable_sleep = false;
  s.substeps = 1;
  s.velocity_iterations = iterations;
  s.relax_iterations = 0;
  s.contact_hertz = 0.0;
  s.split_impulses = true;
  return s;
}

World small_stack(int n) {
  World w(classic_split(8));
  static_box(w, Vec2(0.0, -0.5), 0.0, 10.0, 0.5);
  for (int i = 0; i < n; ++i) dynamic_box(w, Vec2(i % 2 ? 0.01 : -0.01, 0.5 + i), 0.0, 0.5, 0.6);
  for (int i = 0; i < 60; ++i) w.step();
  return w;
}

// The classic step with split impulses (1 substep, rigid contacts, no relax) solves exactly
// the reference's problem in its velocities (the push-out goes to pseudo velocities), so its
// error must fall as its passes rise. Cold started (no warm starting), so that the passes alone
// do the work: Gauss-Seidel on a column of 5 boxes contracts the error by about
// cos^2(pi / 7) = 0.81 per pass in its slowest normal mode, 0.81^62 = 2e-6 from pass 2 to 64;
// the two nearly equal friction rows of each manifold converge more slowly (measured: 290 x
// from 2 to 64 passes, 0.14 m/s to 5e-4 m/s), so 100 x is asserted.
TEST(Reference, ClassicStepConvergesToTheReference) {
  World w = small_stack(5);
  auto at = [&](int iterations) {
    WorldSettings s = classic_split(iterations);
    s.warm_starting = false;
    auto e = setting_velocity_error(w, s);
    EXPECT_TRUE(e.ok()) << e.status().to_string();
    EXPECT_TRUE(e->reference.converged);
    return e->error;
  };
  VelocityError e2 = at(2), e8 = at(8), e64 = at(64);
  EXPECT_EQ(e2.bodies, 5);
  EXPECT_LT(e8.max_linear, e2.max_linear);
  EXPECT_LT(e64.max_linear, e8.max_linear);
  EXPECT_LT(e64.max_linear, 0.01 * e2.max_linear);
  EXPECT_LT(e64.rms_linear, 0.01 * e2.rms_linear);
}

// Same input, same bits: the reference is part of a deterministic engine's tooling.
TEST(Reference, IsDeterministic) {
  World w = settled_stack();
  auto a = solve_reference(w);
  auto b = solve_reference(w);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->iterations, b->iterations);
  ASSERT_EQ(a->linear_velocity.size(), b->linear_velocity.size());
  for (size_t k = 0; k < a->linear_velocity.size(); ++k) {
    EXPECT_EQ(std::memcmp(&a->linear_velocity[k], &b->linear_velocity[k], sizeof(Vec2)), 0);
    EXPECT_EQ(std::memcmp(&a->angular_velocity[k], &b->angular_velocity[k], sizeof(double)), 0);
  }
  for (size_t k = 0; k < a->impulses.size(); ++k) {
    EXPECT_EQ(std::memcmp(&a->impulses[k].impulse, &b->impulses[k].impulse, sizeof(double)), 0);
  }
  // And the world it read is untouched: stepping it matches a world that never was read.
  World fresh = settled_stack();
  w.step();
  fresh.step();
  EXPECT_EQ(w.state_hash(), fresh.state_hash());
}

// A chain of revolute joints without limits: equality rows only, one sparse factorization.
TEST(Reference, JointChainIsSolvedDirectly) {
  World w;
  BodyId prev = w.create_body(BodyDef{}).value();
  for (int i = 0; i < 10; ++i) {
    BodyId link = dynamic_box(w, Vec2(0.5 + i, 0.0), 0.0, 0.25, 0.6);
    RevoluteJointDef j;
    j.body_a = prev;
    j.body_b = link;
    j.local_anchor_a = i == 0 ? Vec2::Zero() : Vec2(0.5, 0.0);
    j.local_anchor_b = Vec2(-0.5, 0.0);
    ASSERT_TRUE(w.create_revolute_joint(j).ok());
    prev = link;
  }
  auto ref = solve_reference(w);
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_EQ(ref->method, "sparse LDLT");
  EXPECT_EQ(ref->equality_rows, 20);
  EXPECT_LE(ref->residual, kTol);
  EXPECT_FALSE(ref->regularized);
}

TEST(Reference, RefusesRowsItDoesNotModel) {
  World w;
  BodyId ground = w.create_body(BodyDef{}).value();
  BodyId wheel = dynamic_box(w, Vec2(0.0, 1.0), 0.0, 0.5, 0.6);
  WheelJointDef j;
  j.body_a = ground;
  j.body_b = wheel;
  JointId id = w.create_wheel_joint(j).value();
  auto ref = solve_reference(w);
  ASSERT_FALSE(ref.ok());
  EXPECT_NE(ref.status().message().find("joint {" + std::to_string(id.index)), std::string::npos)
      << ref.status().message();
  EXPECT_NE(ref.status().message().find("wheel"), std::string::npos);
}

}  // namespace
}  // namespace fulcrum
