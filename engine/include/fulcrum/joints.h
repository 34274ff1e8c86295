// Joints: constraints between two bodies, solved by the same sequential-impulse loop as
// contacts. Each is created from a plain definition; every field states its unit and range.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "fulcrum/math.h"
#include "fulcrum/types.h"

namespace fulcrum {

struct JointId {
  int32_t index = -1;
  uint32_t generation = 0;
  bool is_null() const { return generation == 0; }
  friend bool operator==(const JointId&, const JointId&) = default;
};

enum class JointType : uint8_t {
  kDistance = 0,
  kRevolute = 1,
  kWeld = 2,
  kTarget = 3,
  kPrismatic = 4,
  kWheel = 5,
  kMotor = 6,
  kCurve = 7,
  kSpring = 8  // a force element, not a constraint (SpringDef)
};
const char* joint_type_name(JointType type);

// Keeps the distance between two anchor points in [min_length, max_length]. A rod has
// min_length = length = max_length (the default); a rope has min_length = 0 (slack below
// max_length, taut at it). With hertz > 0, a spring pulls toward `length` inside the range.
struct DistanceJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_a = Vec2::Zero();  // in body A's frame, m
  Vec2 local_anchor_b = Vec2::Zero();  // in body B's frame, m
  double length = 1.0;                 // rest length, m, > 0
  double min_length = 1.0;             // m, 0 <= min_length <= length
  double max_length = 1.0;             // m, length <= max_length
  double hertz = 0.0;                  // spring frequency, Hz, >= 0 (0: no spring)
  double damping_ratio = 0.0;          // spring damping ratio, >= 0
  bool collide_connected = false;      // whether the two bodies still collide
};

// Pins two bodies together at one point (the talk's point constraint) and lets them turn
// relative to each other, optionally within angle limits, driven by a velocity motor with a
// torque limit, and pulled toward an angle by a spring.
struct RevoluteJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_a = Vec2::Zero();  // in body A's frame, m
  Vec2 local_anchor_b = Vec2::Zero();  // in body B's frame, m
  double reference_angle = 0.0;        // angle_b - angle_a when the joint angle is 0, rad
  bool enable_limit = false;
  double lower_angle = 0.0;  // rad, lower_angle <= upper_angle
  double upper_angle = 0.0;  // rad
  bool enable_motor = false;
  double motor_speed = 0.0;       // target relative angular velocity, rad/s
  double max_motor_torque = 0.0;  // N m, >= 0
  bool enable_spring = false;
  double hertz = 0.0;          // spring frequency, Hz, >= 0
  double damping_ratio = 0.0;  // >= 0
  double target_angle = 0.0;   // spring rest angle, rad (joint angle)
  bool collide_connected = false;
};

// Lets body B slide along an axis fixed in body A, without turning relative to A (the talk's
// line constraint plus an angle row), optionally within translation limits and driven by a
// velocity motor with a force limit.
struct PrismaticJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_a = Vec2::Zero();  // in body A's frame, m
  Vec2 local_anchor_b = Vec2::Zero();  // in body B's frame, m
  Vec2 local_axis_a = Vec2(1.0, 0.0);  // slide direction in body A's frame (normalized), != 0
  double reference_angle = 0.0;        // angle_b - angle_a to hold, rad
  bool enable_limit = false;
  double lower_translation = 0.0;  // m, <= upper_translation
  double upper_translation = 0.0;  // m
  bool enable_motor = false;
  double motor_speed = 0.0;         // m/s along the axis
  double max_motor_force = 0.0;     // N, >= 0
  bool enable_spring = false;       // a spring along the axis toward target_translation
  double hertz = 0.0;               // spring frequency, Hz, >= 0 (0: no spring)
  double damping_ratio = 0.0;       // >= 0
  double target_translation = 0.0;  // spring rest translation, m
  bool collide_connected = false;
};

// A wheel on a suspension: body B's anchor stays on a line through body A's anchor along
// local_axis_a (the talk's line constraint) while B turns freely. Along the axis a spring
// (the suspension) pulls toward translation 0, optionally within translation limits; a
// velocity motor with a torque limit drives B's rotation relative to A.
struct WheelJointDef {
  BodyId body_a;                       // the chassis
  BodyId body_b;                       // the wheel
  Vec2 local_anchor_a = Vec2::Zero();  // in body A's frame, m
  Vec2 local_anchor_b = Vec2::Zero();  // in body B's frame, m (usually its centre)
  Vec2 local_axis_a = Vec2(0.0, 1.0);  // suspension axis in body A's frame, != 0
  bool enable_spring = true;
  double hertz = 1.0;          // suspension frequency, Hz, >= 0 (0: no spring)
  double damping_ratio = 0.7;  // >= 0
  bool enable_limit = false;
  double lower_translation = 0.0;  // m, <= upper_translation
  double upper_translation = 0.0;  // m
  bool enable_motor = false;
  double motor_speed = 0.0;       // target angular velocity of B relative to A, rad/s
  double max_motor_torque = 0.0;  // N m, >= 0
  bool collide_connected = false;
};

// Drives body B's origin and angle toward a pose relative to body A (a position motor on
// three rows: C = relative pose - offset(t)), never with more than max_force and max_torque.
// The offsets may change every tick (World::set_motor_joint_targets): for animated bodies
// that still push and get pushed by the rest of the world.
struct MotorJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 linear_offset = Vec2::Zero();  // B's origin in body A's frame, m
  double angular_offset = 0.0;        // angle_b - angle_a, rad
  double max_force = 1.0;             // N, >= 0
  double max_torque = 1.0;            // N m, >= 0
  double correction_factor = 0.3;     // [0, 1]: fraction of the pose error removed per substep
  bool collide_connected = false;
};

// A curve fixed in the world for a CurveJointDef.
enum class CurveType : uint8_t {
  kLine = 0,     // through `point` along `direction` (unbounded)
  kCircle = 1,   // centre `point`, `radius`
  kPolyline = 2  // through `points` in order (open)
};

// A bead on a wire (the talk's first example): a point of body B stays on a curve fixed in the
// world, free to slide along it and to turn, without friction. One row along the curve normal
// n at the closest point: C = n . (p - closest), J = n^T [I, rb x]. body_a is any static body
// (it takes no reaction).
struct CurveJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_b = Vec2::Zero();  // the bead, in body B's frame, m
  CurveType curve = CurveType::kLine;
  Vec2 point = Vec2::Zero();        // line: a point on it; circle: the centre (world, m)
  Vec2 direction = Vec2(1.0, 0.0);  // line: its direction (normalized), != 0
  double radius = 1.0;              // circle: m, > 0
  std::vector<Vec2> points;         // polyline: >= 2 world points, consecutive ones apart
};

// A spring between two body points, applied as a force (not a constraint) when velocities are
// integrated, before the constraints are solved:
//   F on B = -(stiffness (|d| - rest_length) + damping (d/|d| . relative velocity)) d/|d|,
// and -F on A, with d = anchor B - anchor A. Explicit, so stable only while
// h^2 stiffness / m + 2 h damping / m < 4 for the substep h = dt / substeps and the effective
// mass m at the anchors (1 / m = the bodies' inverse masses plus inv_inertia |r|^2 for each
// anchor arm r); create_spring refuses a spring that breaks this at creation (INVALID_ARGUMENT
// naming spring.stiffness or spring.damping), but does not recheck when settings or masses
// change later, nor for several springs on one body. It joins islands and breaks and is
// destroyed with its bodies like a joint (it has a JointId).
struct SpringDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_a = Vec2::Zero();  // in body A's frame, m
  Vec2 local_anchor_b = Vec2::Zero();  // in body B's frame, m
  double rest_length = 1.0;            // m, >= 0
  double stiffness = 0.0;              // N/m, >= 0
  double damping = 0.0;                // N s/m, >= 0
  bool collide_connected = true;       // a force element does not stop contact
};

// Glues two bodies together: the point constraint plus an angle row (C = angle_b - angle_a -
// reference). Rigid by default (the world's joint feedback); with linear_hertz or
// angular_hertz > 0 that part becomes a spring of that frequency.
struct WeldJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_a = Vec2::Zero();  // in body A's frame, m
  Vec2 local_anchor_b = Vec2::Zero();  // in body B's frame, m
  double reference_angle = 0.0;        // angle_b - angle_a to hold, rad
  double linear_hertz = 0.0;           // Hz, >= 0 (0: rigid)
  double linear_damping_ratio = 0.0;   // >= 0
  double angular_hertz = 0.0;          // Hz, >= 0 (0: rigid)
  double angular_damping_ratio = 0.0;  // >= 0
  bool collide_connected = false;
};

// Pulls a point of body_b toward a world target with a spring, never with more than
// max_force: for dragging things around. body_a is any static body (the frame the target is
// given in; it takes no reaction).
struct TargetJointDef {
  BodyId body_a;
  BodyId body_b;
  Vec2 local_anchor_b = Vec2::Zero();  // the point pulled, in body B's frame, m
  Vec2 target = Vec2::Zero();          // world point, m (World::set_joint_target moves it)
  double max_force = 1000.0;           // N, >= 0
  double hertz = 5.0;                  // spring frequency, Hz, > 0
  double damping_ratio = 0.7;          // >= 0
};

// What a joint reports: its reaction on body B and how far it is from satisfied.
struct JointState {
  JointType type = JointType::kDistance;
  BodyId body_a;
  BodyId body_b;
  Vec2 anchor_a = Vec2::Zero();  // world anchor points, m
  Vec2 anchor_b = Vec2::Zero();
  Vec2 reaction_force = Vec2::Zero();  // on body B over the last tick, N
  double reaction_torque = 0.0;        // on body B over the last tick, N m
  double motor_torque = 0.0;           // revolute, wheel: last tick's motor torque, N m
                                       // (prismatic: its motor force, N)
  double length = 0.0;                 // distance between the anchors, m (prismatic,
                                       // wheel: translation along the axis)
  double angle = 0.0;                  // revolute, wheel: joint angle, rad
  double linear_error = 0.0;           // m: anchor separation (revolute) or how far the
                                       // length is outside [min, max] (distance); wheel:
                                       // off the line; motor: from the target; curve: off
                                       // the curve; spring: 0 (a force, nothing to violate)
  double angular_error = 0.0;          // rad: how far the angle is outside the limits
                                       // (motor: from the target)
};

// Every joint can break: when the force it applies exceeds break_force (N) or the torque
// break_torque (N m) over a tick, it is removed at the end of that tick and reported in
// StepEvents::joints_broken. Both default to infinity (never breaks); set with
// World::set_joint_break_limits.

Status validate_distance_joint_def(const DistanceJointDef& def);
Status validate_weld_joint_def(const WeldJointDef& def);
Status validate_target_joint_def(const TargetJointDef& def);
Status validate_prismatic_joint_def(const PrismaticJointDef& def);
Status validate_revolute_joint_def(const RevoluteJointDef& def);
Status validate_wheel_joint_def(const WheelJointDef& def);
Status validate_motor_joint_def(const MotorJointDef& def);
Status validate_curve_joint_def(const CurveJointDef& def);
Status validate_spring_def(const SpringDef& def);

}  // namespace fulcrum
