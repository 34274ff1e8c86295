// Wheel, motor and curve joints, the prismatic joint's spring, and spring force elements:
// physical facts with explained tolerances, break limits, hashing and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "fulcrum/trig.h"
#include "fulcrum/world.h"

namespace fulcrum {
namespace {

constexpr double kDt = 1.0 / 60.0;

BodyId static_body(World& w, const Vec2& p) {
  BodyDef def;
  def.position = p;
  return *w.create_body(def);
}

BodyId dynamic_body(World& w, const Vec2& p, const Geometry& g, double density = 1.0,
                    BodyType type = BodyType::kDynamic) {
  BodyDef def;
  def.type = type;
  def.position = p;
  BodyId id = *w.create_body(def);
  ShapeDef sd;
  sd.geometry = g;
  sd.density = density;
  EXPECT_TRUE(w.create_shape(id, sd).ok());
  return id;
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// Times at which x(t) crosses zero going down, linearly interpolated between ticks.
std::vector<double> down_crossings(const std::vector<double>& x, double dt) {
  std::vector<double> out;
  for (size_t i = 1; i < x.size(); ++i) {
    if (x[i - 1] > 0.0 && x[i] <= 0.0) out.push_back((i - 1 + x[i - 1] / (x[i - 1] - x[i])) * dt);
  }
  return out;
}

// --- Wheel joints ------------------------------------------------------------------------------

struct Car {
  BodyId chassis;
  BodyId wheels[2];
  JointId joints[2];
};

// A 2 m x 0.5 m chassis (density 2: 2 kg) on two 0.4 m wheels (density 1: 0.5 kg each) with a
// 4 Hz suspension, limited to +-0.25 m, over flat ground.
Car make_car(World& w, double x, const WheelJointDef& proto) {
  BodyId ground = static_body(w, Vec2(0.0, -0.5));
  ShapeDef floor;
  floor.geometry = make_box(200.0, 0.5);
  floor.friction = 0.9;
  EXPECT_TRUE(w.create_shape(ground, floor).ok());
  Car car;
  car.chassis = dynamic_body(w, Vec2(x, 1.0), make_box(1.0, 0.25), 2.0);
  for (int i = 0; i < 2; ++i) {
    Vec2 hub(x + (i == 0 ? -0.8 : 0.8), 0.4);
    car.wheels[i] = dynamic_body(w, hub, Circle{Vec2::Zero(), 0.4}, 1.0);
    WheelJointDef def = proto;
    def.body_a = car.chassis;
    def.body_b = car.wheels[i];
    def.local_anchor_a = hub - Vec2(x, 1.0);
    car.joints[i] = *w.create_wheel_joint(def);
  }
  return car;
}

// A car standing on its suspension for 10 s keeps each hub on its suspension line within
// 0.1 mm. The line row is a 60 Hz soft constraint (settings.joint_hertz): its error under a
// sideways acceleration a is a / omega^2, 3e-5 m for a of a few m/s^2 at the touchdown
// (omega = 2 pi 60). At rest each suspension carries half the chassis' weight (10 N) and sags
// by 10 N / k, where the spring's stiffness is k = m_eff (2 pi 4 Hz)^2 on the row's effective
// mass m_eff = 1 / (1 / m_chassis + 1 / m_wheel + a1^2 / I_chassis), a1 = 0.8 m the hub's
// lever arm about the chassis' centre (Box2D's convention: a joint spring's frequency is set
// on the effective mass of its row). Within 1 %: a1 changes by the sag itself.
TEST(JointMoreTest, WheelKeepsTheHubOnItsLineUnderLoad) {
  World w;
  WheelJointDef proto;
  proto.hertz = 4.0;
  proto.damping_ratio = 0.7;
  proto.enable_limit = true;
  proto.lower_translation = -0.25;
  proto.upper_translation = 0.25;
  Car car = make_car(w, 0.0, proto);
  double worst = 0.0;
  for (int i = 0; i < 600; ++i) {
    w.step();
    for (JointId id : car.joints) worst = std::max(worst, w.joint_state(id)->linear_error);
  }
  EXPECT_LT(worst, 1e-4);
  for (JointId id : car.joints) {
    JointState s = *w.joint_state(id);
    EXPECT_EQ(s.type, JointType::kWheel);
    const BodyState chassis = *w.body_state(car.chassis);
    double m_eff = 1.0 / (1.0 / chassis.mass + 1.0 / w.body_state(car.wheels[0])->mass +
                          0.8 * 0.8 / chassis.rotational_inertia);
    double sag = 10.0 / (m_eff * std::pow(2.0 * kPi * 4.0, 2.0));
    EXPECT_NEAR(s.length, sag, 0.01 * sag);  // positive: the chassis sits lower on its hubs
  }
}

// A wheel motor holds its speed exactly while the load torque is below max_motor_torque (the
// motor row is rigid and alone on the wheel's rotation: one pass solves it to rounding), its
// torque then equals the load within 1e-6; above the limit the wheel slips, decelerating at
// (max - load) / I within 0.1 % while the motor torque sits at its cap, never above it.
TEST(JointMoreTest, WheelMotorHoldsSpeedUntilItsTorqueLimitThenSlips) {
  World w(WorldSettings{.gravity = Vec2::Zero()});
  BodyId axle = static_body(w, Vec2::Zero());
  BodyId wheel = dynamic_body(w, Vec2::Zero(), Circle{Vec2::Zero(), 0.5});
  WheelJointDef def;
  def.body_a = axle;
  def.body_b = wheel;
  def.enable_motor = true;
  def.motor_speed = 2.0;
  def.max_motor_torque = 5.0;
  JointId id = *w.create_wheel_joint(def);
  const double inertia = w.body_state(wheel)->rotational_inertia;
  for (int i = 0; i < 120; ++i) {
    ASSERT_TRUE(w.apply_torque(wheel, -3.0).ok());
    w.step();
    if (i < 30) continue;
    EXPECT_NEAR(w.body_state(wheel)->angular_velocity, 2.0, 1e-9) << "tick " << i;
    EXPECT_NEAR(w.joint_state(id)->motor_torque, 3.0, 1e-6) << "tick " << i;
  }
  double w0 = w.body_state(wheel)->angular_velocity;
  for (int i = 0; i < 60; ++i) {
    ASSERT_TRUE(w.apply_torque(wheel, -8.0).ok());
    w.step();
    EXPECT_LE(std::abs(w.joint_state(id)->motor_torque), 5.0 * (1.0 + 1e-12));
    EXPECT_NEAR(w.joint_state(id)->motor_torque, 5.0, 1e-9);
  }
  double decel = (w0 - w.body_state(wheel)->angular_velocity) / 1.0;
  EXPECT_NEAR(decel, 3.0 / inertia, 1e-3 * 3.0 / inertia);
}

// --- Motor joints ------------------------------------------------------------------------------

// A 1 kg box follows a target pose x(t) = sin t, angle(t) = 0.5 sin t set every tick. The
// linear row closes its error at rate beta / h = 0.3 * 240 = 72 /s, a first-order lag whose
// steady error at the target's top speed of 1 m/s is 1 / 72 = 1.4 cm (0.7 cm for the angle);
// 3 cm and 0.02 rad bound that plus the target moving by a tick (1.7 cm) between updates.
// The reaction never exceeds max_force or max_torque. With max_force below what the target's
// 1 m/s^2 acceleration needs (1 N), the force sits at its cap and the lag grows.
TEST(JointMoreTest, MotorJointFollowsAMovingTargetWithinItsForce) {
  World w(WorldSettings{.gravity = Vec2::Zero()});
  BodyId ground = static_body(w, Vec2::Zero());
  BodyId box = dynamic_body(w, Vec2::Zero(), make_box(0.5, 0.5));
  ASSERT_NEAR(w.body_state(box)->mass, 1.0, 1e-12);
  MotorJointDef def;
  def.body_a = ground;
  def.body_b = box;
  def.max_force = 20.0;
  def.max_torque = 5.0;
  JointId id = *w.create_motor_joint(def);
  double worst_x = 0.0, worst_a = 0.0, peak_force = 0.0, peak_torque = 0.0;
  for (int i = 0; i < 600; ++i) {
    double t = (i + 1) * kDt;  // the pose wanted at the end of this tick
    SinCos sc = det_sincos(t);
    ASSERT_TRUE(w.set_motor_joint_targets(id, Vec2(sc.sin, 0.0), 0.5 * sc.sin).ok());
    w.step();
    JointState s = *w.joint_state(id);
    peak_force = std::max(peak_force, length(s.reaction_force));
    peak_torque = std::max(peak_torque, std::abs(s.reaction_torque));
    if (i < 60) continue;
    worst_x = std::max(worst_x, std::abs(w.body_state(box)->center.x() - sc.sin));
    worst_a = std::max(worst_a, s.angular_error);
    EXPECT_NEAR(s.linear_error, std::abs(w.body_state(box)->center.x() - sc.sin), 1e-3);
  }
  EXPECT_LT(worst_x, 0.03);
  EXPECT_LT(worst_a, 0.02);
  EXPECT_LE(peak_force, 20.0 * (1.0 + 1e-12));
  EXPECT_LE(peak_torque, 5.0 * (1.0 + 1e-12));

  ASSERT_TRUE(w.destroy_joint(id).ok());
  def.max_force = 0.5;
  id = *w.create_motor_joint(def);
  double capped = 0.0, lag = 0.0;
  for (int i = 600; i < 1200; ++i) {
    SinCos sc = det_sincos((i + 1) * kDt);
    ASSERT_TRUE(w.set_motor_joint_targets(id, Vec2(sc.sin, 0.0), 0.0).ok());
    w.step();
    double f = length(w.joint_state(id)->reaction_force);
    EXPECT_LE(f, 0.5 * (1.0 + 1e-12)) << "tick " << i;
    capped = std::max(capped, f);
    lag = std::max(lag, std::abs(w.body_state(box)->center.x() - sc.sin));
  }
  EXPECT_NEAR(capped, 0.5, 1e-9);
  EXPECT_GT(lag, 0.1);
}

// --- Prismatic springs -------------------------------------------------------------------------

// A 0.25 kg box on a horizontal prismatic joint with a 1 Hz undamped spring, released 0.5 m
// from its rest translation, oscillates at 1 Hz within 1 % (the soft step's implicit spring
// shifts the frequency by O((omega h)^2) = 7e-4 at h = 1/240 s). With damping it settles at
// target_translation within 1e-6 m (sleep off: a body creeping slower than the sleep
// tolerance would otherwise stop short).
TEST(JointMoreTest, PrismaticSpringOscillatesAtItsFrequency) {
  World w(WorldSettings{.gravity = Vec2::Zero(), .enable_sleep = false});
  BodyId ground = static_body(w, Vec2::Zero());
  BodyId slider = dynamic_body(w, Vec2(0.5, 0.0), make_box(0.25, 0.25));
  PrismaticJointDef def;
  def.body_a = ground;
  def.body_b = slider;
  def.local_anchor_a = Vec2::Zero();
  def.local_anchor_b = Vec2::Zero();
  def.enable_spring = true;
  def.hertz = 1.0;
  def.damping_ratio = 0.0;
  JointId id = *w.create_prismatic_joint(def);
  std::vector<double> x;
  for (int i = 0; i < 600; ++i) {
    w.step();
    x.push_back(w.joint_state(id)->length);
  }
  std::vector<double> down = down_crossings(x, kDt);
  ASSERT_GE(down.size(), 8u);
  double period = (down.back() - down.front()) / (down.size() - 1);
  EXPECT_NEAR(1.0 / period, 1.0, 0.01);
  // The implicit spring loses amplitude (about (omega h)^2 / 2 per pass), never gains it.
  EXPECT_LT(*std::max_element(x.begin() + 60, x.end()), 0.5);

  ASSERT_TRUE(w.destroy_joint(id).ok());
  def.damping_ratio = 0.7;
  def.target_translation = 0.3;
  id = *w.create_prismatic_joint(def);
  for (int i = 0; i < 600; ++i) w.step();
  EXPECT_NEAR(w.joint_state(id)->length, 0.3, 1e-6);
}

// --- Curve joints ------------------------------------------------------------------------------

// A bead released at rest level with the centre of a 1 m vertical circle swings like a
// pendulum for 10 s: it stays on the circle within 1 mm (each substep it moves along the
// tangent and leaves the circle by (v h)^2 / (2 R) = 1.7e-4 m at the bottom's 4.5 m/s; the
// 60 Hz, damping-ratio-2 feedback takes out h omega / (2 zeta + h omega) = 28 % of the error
// per substep, so the error settles near 6e-4 m; measured 7.5e-4) and its energy stays within 2 %
// of m g R of the start (frictionless; the relax pass takes out the feedback's velocity). It
// may gain at most omega h = sqrt(g / R) / 240 = 1.3 % of m g R: symplectic Euler's energy
// oscillates by O(omega h) about a conserved value instead of drifting.
TEST(JointMoreTest, CurveBeadOnACircleStaysOnItAndKeepsItsEnergy) {
  World w;
  BodyId ground = static_body(w, Vec2::Zero());
  BodyId bead =
      dynamic_body(w, Vec2(1.0, 0.0), Circle{Vec2::Zero(), 0.05}, 1.0, BodyType::kParticle);
  CurveJointDef def;
  def.body_a = ground;
  def.body_b = bead;
  def.curve = CurveType::kCircle;
  def.point = Vec2::Zero();
  def.radius = 1.0;
  JointId id = *w.create_curve_joint(def);
  const double m = w.body_state(bead)->mass;
  auto energy = [&] {
    BodyState s = *w.body_state(bead);
    return 0.5 * m * length_squared(s.linear_velocity) + m * 10.0 * s.center.y();
  };
  double off = 0.0, drift = 0.0, gain = 0.0, lowest = 0.0;
  for (int i = 0; i < 600; ++i) {
    w.step();
    double error = w.joint_state(id)->linear_error;
    EXPECT_NEAR(error, std::abs(length(w.body_state(bead)->center) - 1.0), 1e-12);
    off = std::max(off, error);
    drift = std::max(drift, std::abs(energy()) / (m * 10.0));
    gain = std::max(gain, energy() / (m * 10.0));
    lowest = std::min(lowest, w.body_state(bead)->center.y());
  }
  EXPECT_LT(off, 1e-3);
  EXPECT_LT(drift, 0.02);
  EXPECT_LT(gain, std::sqrt(10.0) / 240.0);
  EXPECT_LT(lowest, -0.999);  // it swung through the bottom
}

// A bead on a line inclined at 30 degrees slides with g sin 30 = 5 m/s^2 along it (within
// 0.5 %). A bead on a V-shaped polyline (arms of slope 1/3, a 36.9 degree turn at the vertex)
// slides down one arm, through the vertex and up the other. Off the vertex it stays within
// 1 mm of the polyline; passing the kink it overshoots by at most one substep's travel times
// the sine of the turn, v h sin(36.9) = 3.7 m/s / 240 * 0.6 = 9 mm (as a contact may
// penetrate by one substep's travel), removed by the position feedback within a few substeps.
// It never climbs higher than it started: the kink takes the velocity's normal part, a
// perfectly inelastic impact, and keeps cos(36.9)^2 = 64 % of the kinetic energy.
TEST(JointMoreTest, CurveBeadOnALineAndAPolyline) {
  World w;
  BodyId ground = static_body(w, Vec2::Zero());
  SinCos sc = det_sincos(30.0 * kPi / 180.0);
  BodyId bead = dynamic_body(w, Vec2::Zero(), Circle{Vec2::Zero(), 0.05});
  CurveJointDef line;
  line.body_a = ground;
  line.body_b = bead;
  line.curve = CurveType::kLine;
  line.point = Vec2(0.0, 0.0);
  line.direction = Vec2(sc.cos, sc.sin);
  JointId id = *w.create_curve_joint(line);
  for (int i = 0; i < 60; ++i) w.step();
  Vec2 v = w.body_state(bead)->linear_velocity;
  EXPECT_NEAR(dot(v, Vec2(sc.cos, sc.sin)), -5.0, 0.005 * 5.0);
  EXPECT_LT(w.joint_state(id)->linear_error, 1e-3);

  const double y0 = 10.0 + 2.0 / 3.0;
  BodyId bead2 = dynamic_body(w, Vec2(-2.0, y0), Circle{Vec2::Zero(), 0.05});
  CurveJointDef vee;
  vee.body_a = ground;
  vee.body_b = bead2;
  vee.curve = CurveType::kPolyline;
  vee.points = {Vec2(-3.0, 11.0), Vec2(0.0, 10.0), Vec2(3.0, 11.0)};
  JointId id2 = *w.create_curve_joint(vee);
  double off_arm = 0.0, off_kink = 0.0, highest = -1e9, rightmost = -1e9;
  for (int i = 0; i < 300; ++i) {
    w.step();
    Vec2 p = w.body_state(bead2)->center;
    double error = w.joint_state(id2)->linear_error;
    double& off = std::abs(p.x()) > 0.1 ? off_arm : off_kink;
    off = std::max(off, error);
    highest = std::max(highest, p.y());
    rightmost = std::max(rightmost, p.x());
  }
  EXPECT_LT(off_arm, 1e-3);
  EXPECT_LT(off_kink, 0.01);
  EXPECT_LE(highest, y0 + 1e-9);
  // Through the vertex and up the other arm, to about 64 % of the drop (x = 1.28).
  EXPECT_GT(rightmost, 1.0);
}

// --- Spring force elements ---------------------------------------------------------------------

// A ball hanging from a static point on a spring comes to rest at the static extension
// m g / k (within 1e-9 m: at rest the spring force balances gravity to rounding), with a
// reaction of m g. Two free bodies joined by a spring oscillate at sqrt(k / mu) / (2 pi) with
// mu the reduced mass (within 1 %: symplectic Euler's frequency error is (omega h)^2 / 24) and
// keep their total momentum.
TEST(JointMoreTest, SpringHangsAtItsStaticExtensionAndOscillatesAtItsFrequency) {
  World w(WorldSettings{.enable_sleep = false});
  BodyId top = static_body(w, Vec2(0.0, 5.0));
  BodyId ball = dynamic_body(w, Vec2(0.0, 4.0), Circle{Vec2::Zero(), 0.2});
  const double m = w.body_state(ball)->mass;
  SpringDef def;
  def.body_a = top;
  def.body_b = ball;
  def.rest_length = 1.0;
  def.stiffness = 100.0;
  def.damping = std::sqrt(100.0 * m);  // damping ratio 0.5
  JointId id = *w.create_spring(def);
  for (int i = 0; i < 600; ++i) w.step();
  JointState s = *w.joint_state(id);
  EXPECT_EQ(s.type, JointType::kSpring);
  EXPECT_NEAR(s.length, 1.0 + m * 10.0 / 100.0, 1e-9);
  EXPECT_NEAR(s.reaction_force.y(), m * 10.0, 1e-9);
  EXPECT_EQ(s.linear_error, 0.0);

  World z(WorldSettings{.gravity = Vec2::Zero(), .enable_sleep = false});
  BodyId a = dynamic_body(z, Vec2(0.0, 0.0), Circle{Vec2::Zero(), 0.2});
  BodyId b = dynamic_body(z, Vec2(1.3, 0.0), Circle{Vec2::Zero(), 0.3});
  double ma = z.body_state(a)->mass, mb = z.body_state(b)->mass;
  SpringDef free = def;
  free.body_a = a;
  free.body_b = b;
  free.damping = 0.0;
  free.stiffness = 20.0;
  id = *z.create_spring(free);
  std::vector<double> ext;
  for (int i = 0; i < 600; ++i) {
    z.step();
    ext.push_back(z.joint_state(id)->length - 1.0);
    EXPECT_LT(length(z.metrics().linear_momentum), 1e-12);
  }
  std::vector<double> down = down_crossings(ext, kDt);
  ASSERT_GE(down.size(), 4u);
  double period = (down.back() - down.front()) / (down.size() - 1);
  double mu = ma * mb / (ma + mb);
  EXPECT_NEAR(2.0 * kPi / period, std::sqrt(20.0 / mu), 0.01 * std::sqrt(20.0 / mu));
}

// The explicit spring is stable while h^2 k / m + 2 h c / m < 4 (h: the substep, m: the
// effective mass at the anchors), and create_spring refuses a stiffer or more damped one. A
// ball of m = 0.04 pi kg on a spring to a static point at 4 substeps of 1/60 s: the limit is
// 4 m / h^2 = 28 953 N/m undamped. At 1.05 x the limit, or with 1.01 x 2 m / h of damping, it
// is refused naming the field, and the world is unchanged; anchored at the ball's rim it meets
// a third of the mass (1 / m + r^2 / I = 3 / m for a disc) and is refused at 0.34 x the limit.
// At 0.9 x the limit, stretched 0.1 m in zero gravity, it stays bounded for 10 s at the
// amplitude symplectic Euler predicts, 0.1 / sqrt(1 - h^2 k / (4 m)) = 0.1 / sqrt(0.1) =
// 0.316 m (within 1 %: the ticks sample the orbit), which grows without bound as k nears the
// limit.
TEST(JointMoreTest, SpringsTooStiffForTheSubstepAreRefused) {
  World w(WorldSettings{.gravity = Vec2::Zero(), .enable_sleep = false});
  BodyId top = static_body(w, Vec2(0.0, 0.0));
  BodyId ball = dynamic_body(w, Vec2(0.0, -1.1), Circle{Vec2::Zero(), 0.2});
  const double m = w.body_state(ball)->mass;
  ASSERT_NEAR(m, 0.04 * kPi, 1e-12);
  const double h = kDt / 4.0;
  const double limit = 4.0 * m / (h * h);
  const uint64_t before = w.state_hash();
  SpringDef d;
  d.body_a = top;
  d.body_b = ball;
  d.rest_length = 1.0;
  d.stiffness = 1.05 * limit;
  Result<JointId> refused = w.create_spring(d);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(contains(refused.status().message(), "spring.stiffness: must be < 2.895e+04 N/m"))
      << refused.status().message();
  d.stiffness = 0.0;
  d.damping = 1.01 * 2.0 * m / h;
  refused = w.create_spring(d);
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(contains(refused.status().message(), "spring.damping")) << refused.status().message();
  d.damping = 0.0;
  d.stiffness = 0.34 * limit;  // fine at the centre, not at the rim
  d.local_anchor_b = Vec2(0.2, 0.0);
  EXPECT_FALSE(w.create_spring(d).ok());
  EXPECT_EQ(w.state_hash(), before);

  d.local_anchor_b = Vec2::Zero();
  d.stiffness = 0.9 * limit;
  JointId id = *w.create_spring(d);
  double widest = 0.0;
  for (int i = 0; i < 600; ++i) {
    w.step();
    widest = std::max(widest, std::abs(w.joint_state(id)->length - 1.0));
  }
  EXPECT_NEAR(widest, 0.1 / std::sqrt(0.1), 0.01 * 0.1 / std::sqrt(0.1));
}

// --- Every new joint: break limits, destruction with a body, hashing ---------------------------

// Each new kind, holding a 1 kg box under gravity (10 N), breaks on the first tick with a
// 5 N break_force and is reported; with an infinite limit it holds; destroying its body
// removes it and reports it.
TEST(JointMoreTest, NewJointsBreakAndDieWithTheirBodies) {
  for (int kind = 0; kind < 4; ++kind) {
    World w;
    BodyId ground = static_body(w, Vec2::Zero());
    BodyId box = dynamic_body(w, Vec2(0.0, -1.0), make_box(0.5, 0.5));
    Result<JointId> id = invalid_argument("no joint yet");
    if (kind == 0) {
      WheelJointDef d;
      d.body_a = ground;
      d.body_b = box;
      d.local_anchor_a = Vec2(0.0, -1.0);
      d.local_axis_a = Vec2(1.0, 0.0);  // the load is across the line
      id = w.create_wheel_joint(d);
    } else if (kind == 1) {
      MotorJointDef d;
      d.body_a = ground;
      d.body_b = box;
      d.linear_offset = Vec2(0.0, -1.0);
      d.max_force = 100.0;
      id = w.create_motor_joint(d);
    } else if (kind == 2) {
      CurveJointDef d;
      d.body_a = ground;
      d.body_b = box;
      d.curve = CurveType::kLine;
      d.point = Vec2(0.0, -1.0);
      id = w.create_curve_joint(d);
    } else {
      SpringDef d;
      d.body_a = ground;
      d.body_b = box;
      d.rest_length = 0.9;
      d.stiffness = 100.0;
      id = w.create_spring(d);
    }
    ASSERT_TRUE(id.ok()) << kind << ": " << id.status().to_string();
    for (int i = 0; i < 30; ++i) w.step();
    ASSERT_TRUE(w.is_valid(*id)) << kind;
    double force = length(w.joint_state(*id)->reaction_force);
    EXPECT_GT(force, 5.0) << kind;
    ASSERT_TRUE(w.set_joint_break_limits(*id, 5.0, 1e9).ok());
    w.step();
    ASSERT_EQ(w.events().joints_broken.size(), 1u) << kind;
    EXPECT_EQ(w.events().joints_broken[0], *id);
    EXPECT_FALSE(w.is_valid(*id));
    if (kind == 3) {
      SpringDef d;
      d.body_a = ground;
      d.body_b = box;
      id = w.create_spring(d);
    } else {
      CurveJointDef d;
      d.body_a = ground;
      d.body_b = box;
      id = w.create_curve_joint(d);
    }
    ASSERT_TRUE(id.ok());
    ASSERT_TRUE(w.destroy_body(box).ok());
    EXPECT_FALSE(w.is_valid(*id));
    w.step();
    ASSERT_EQ(w.events().joints_destroyed.size(), 1u);
    EXPECT_EQ(w.events().joints_destroyed[0], *id);
  }
}

// A motor joint's targets are state: setting them changes the hash; setting them back restores
// it; two worlds driven the same way agree bit for bit.
TEST(JointMoreTest, MotorTargetsAreHashedAndRunsRepeat) {
  auto run = [](std::vector<uint64_t>* trace) {
    World w;
    BodyId ground = static_body(w, Vec2::Zero());
    BodyId box = dynamic_body(w, Vec2(0.0, 2.0), make_box(0.5, 0.5));
    BodyId wheel = dynamic_body(w, Vec2(2.0, 2.0), Circle{Vec2::Zero(), 0.3});
    BodyId bead = dynamic_body(w, Vec2(-2.0, 2.0), Circle{Vec2::Zero(), 0.1});
    MotorJointDef m;
    m.body_a = ground;
    m.body_b = box;
    m.max_force = 50.0;
    JointId motor = *w.create_motor_joint(m);
    WheelJointDef wh;
    wh.body_a = box;
    wh.body_b = wheel;
    wh.local_anchor_a = Vec2(2.0, 0.0);
    wh.enable_motor = true;
    wh.motor_speed = 3.0;
    wh.max_motor_torque = 2.0;
    EXPECT_TRUE(w.create_wheel_joint(wh).ok());
    CurveJointDef c;
    c.body_a = ground;
    c.body_b = bead;
    c.curve = CurveType::kPolyline;
    c.points = {Vec2(-4.0, 3.0), Vec2(-2.0, 1.0), Vec2(0.0, 3.0)};
    EXPECT_TRUE(w.create_curve_joint(c).ok());
    SpringDef s;
    s.body_a = box;
    s.body_b = bead;
    s.rest_length = 2.0;
    s.stiffness = 30.0;
    s.damping = 1.0;
    EXPECT_TRUE(w.create_spring(s).ok());
    uint64_t before = w.state_hash();
    EXPECT_TRUE(w.set_motor_joint_targets(motor, Vec2(0.0, 2.5), 0.0).ok());
    EXPECT_NE(w.state_hash(), before);
    EXPECT_TRUE(w.set_motor_joint_targets(motor, Vec2::Zero(), 0.0).ok());
    EXPECT_EQ(w.state_hash(), before);
    for (int i = 0; i < 240; ++i) {
      SinCos sc = det_sincos(i * kDt);
      EXPECT_TRUE(w.set_motor_joint_targets(motor, Vec2(sc.sin, 2.0), sc.cos).ok());
      w.step();
      trace->push_back(w.state_hash());
    }
  };
  std::vector<uint64_t> first, second;
  run(&first);
  run(&second);
  EXPECT_EQ(first, second);
}

// --- Bad input ---------------------------------------------------------------------------------

// Every bad field is refused with a message naming it, and the world does not change.
TEST(JointMoreTest, BadNewJointsAreRefusedAndChangeNothing) {
  World w;
  BodyId ground = static_body(w, Vec2::Zero());
  BodyId b = dynamic_body(w, Vec2(1.0, 0.0), Circle{Vec2::Zero(), 0.2});
  BodyId c = dynamic_body(w, Vec2(3.0, 0.0), Circle{Vec2::Zero(), 0.2});
  const uint64_t before = w.state_hash();
  const double nan = std::nan("");

  auto wheel = [&](auto edit, const char* field) {
    WheelJointDef d;
    d.body_a = ground;
    d.body_b = b;
    edit(d);
    Result<JointId> r = w.create_wheel_joint(d);
    ASSERT_FALSE(r.ok()) << field;
    EXPECT_TRUE(contains(r.status().message(), field)) << r.status().message();
  };
  wheel([&](WheelJointDef& d) { d.local_axis_a = Vec2::Zero(); }, "joint.local_axis_a");
  wheel([&](WheelJointDef& d) { d.local_anchor_b = Vec2(nan, 0.0); }, "joint.local_anchor_b");
  wheel([&](WheelJointDef& d) { d.hertz = -1.0; }, "joint.hertz");
  wheel([&](WheelJointDef& d) { d.damping_ratio = nan; }, "joint.damping_ratio");
  wheel(
      [&](WheelJointDef& d) {
        d.lower_translation = 1.0;
        d.upper_translation = 0.0;
      },
      "joint.lower_translation");
  wheel([&](WheelJointDef& d) { d.max_motor_torque = -2.0; }, "joint.max_motor_torque");
  wheel([&](WheelJointDef& d) { d.motor_speed = INFINITY; }, "joint.motor_speed");
  wheel([&](WheelJointDef& d) { d.body_b = ground; }, "joint.body_b");

  auto motor = [&](auto edit, const char* field) {
    MotorJointDef d;
    d.body_a = ground;
    d.body_b = b;
    edit(d);
    Result<JointId> r = w.create_motor_joint(d);
    ASSERT_FALSE(r.ok()) << field;
    EXPECT_TRUE(contains(r.status().message(), field)) << r.status().message();
  };
  motor([&](MotorJointDef& d) { d.max_force = -1.0; }, "joint.max_force");
  motor([&](MotorJointDef& d) { d.max_torque = nan; }, "joint.max_torque");
  motor([&](MotorJointDef& d) { d.correction_factor = 1.5; }, "joint.correction_factor");
  motor([&](MotorJointDef& d) { d.linear_offset = Vec2(0.0, INFINITY); }, "joint.linear_offset");
  motor([&](MotorJointDef& d) { d.angular_offset = nan; }, "joint.angular_offset");

  auto curve = [&](auto edit, const char* field) {
    CurveJointDef d;
    d.body_a = ground;
    d.body_b = b;
    edit(d);
    Result<JointId> r = w.create_curve_joint(d);
    ASSERT_FALSE(r.ok()) << field;
    EXPECT_TRUE(contains(r.status().message(), field)) << r.status().message();
  };
  curve([&](CurveJointDef& d) { d.direction = Vec2::Zero(); }, "joint.direction");
  curve([&](CurveJointDef& d) { d.point = Vec2(nan, 0.0); }, "joint.point");
  curve(
      [&](CurveJointDef& d) {
        d.curve = CurveType::kCircle;
        d.radius = 0.0;
      },
      "joint.radius");
  curve(
      [&](CurveJointDef& d) {
        d.curve = CurveType::kPolyline;
        d.points = {Vec2::Zero()};
      },
      "joint.points");
  curve(
      [&](CurveJointDef& d) {
        d.curve = CurveType::kPolyline;
        d.points = {Vec2::Zero(), Vec2(1.0, 0.0), Vec2(1.0, 0.0)};
      },
      "joint.points[2]");
  curve(
      [&](CurveJointDef& d) {
        d.curve = CurveType::kPolyline;
        d.points = {Vec2::Zero(), Vec2(nan, 0.0)};
      },
      "joint.points[1]");
  curve([&](CurveJointDef& d) { d.body_a = c; }, "joint.body_a");  // not static
  curve([&](CurveJointDef& d) { d.curve = static_cast<CurveType>(7); }, "joint.curve");

  auto spring = [&](auto edit, const char* field) {
    SpringDef d;
    d.body_a = b;
    d.body_b = c;
    edit(d);
    Result<JointId> r = w.create_spring(d);
    ASSERT_FALSE(r.ok()) << field;
    EXPECT_TRUE(contains(r.status().message(), field)) << r.status().message();
  };
  spring([&](SpringDef& d) { d.stiffness = -1.0; }, "spring.stiffness");
  spring([&](SpringDef& d) { d.damping = nan; }, "spring.damping");
  spring([&](SpringDef& d) { d.rest_length = -0.5; }, "spring.rest_length");
  spring([&](SpringDef& d) { d.local_anchor_a = Vec2(INFINITY, 0.0); }, "spring.local_anchor_a");
  spring([&](SpringDef& d) { d.body_b = BodyId{42, 1}; }, "spring.body_b");

  PrismaticJointDef p;
  p.body_a = ground;
  p.body_b = b;
  p.hertz = -3.0;
  EXPECT_TRUE(contains(w.create_prismatic_joint(p).status().message(), "joint.hertz"));
  p.hertz = 1.0;
  p.target_translation = nan;
  EXPECT_TRUE(contains(w.create_prismatic_joint(p).status().message(), "joint.target_translation"));

  EXPECT_EQ(w.state_hash(), before);

  // Setting targets on the wrong joint or with bad values is refused too.
  SpringDef ok;
  ok.body_a = b;
  ok.body_b = c;
  JointId sid = *w.create_spring(ok);
  EXPECT_FALSE(w.set_motor_joint_targets(sid, Vec2::Zero(), 0.0).ok());
  MotorJointDef m;
  m.body_a = ground;
  m.body_b = b;
  JointId mid = *w.create_motor_joint(m);
  uint64_t now = w.state_hash();
  EXPECT_TRUE(
      contains(w.set_motor_joint_targets(mid, Vec2(nan, 0.0), 0.0).message(), "linear_offset"));
  EXPECT_TRUE(
      contains(w.set_motor_joint_targets(mid, Vec2::Zero(), nan).message(), "angular_offset"));
  EXPECT_EQ(w.state_hash(), now);
}

}  // namespace
}  // namespace fulcrum
