// Joints: constraints between two bodies, solved by the same sequential-impulse loop as
// contacts. Each is created from a plain definition; every field states its unit and range.
#pragma once

#include <cstdint>
#include <limits>

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
  kPrismatic = 4
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
  double motor_speed = 0.0;      // m/s along the axis
  double max_motor_force = 0.0;  // N, >= 0
  bool collide_connected = false;
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
  double motor_torque = 0.0;           // revolute: last tick's motor torque, N m (prismatic:
                                       // its motor force, N)
  double length = 0.0;                 // distance between the anchors, m
  double angle = 0.0;                  // revolute: joint angle, rad
  double linear_error = 0.0;           // m: anchor separation (revolute) or how far the
                                       // length is outside [min, max] (distance)
  double angular_error = 0.0;          // rad: how far the angle is outside the limits
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

}  // namespace fulcrum
