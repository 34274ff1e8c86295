// The world's state records: every body, shape, contact and joint exactly as the engine keeps
// them between ticks, slots of destroyed objects included. World::snapshot() copies them out
// and World::restore() checks and copies them back, so a restored world continues bit for bit;
// nothing here is a raw memory image (proto/convert writes them field by field). Applications
// use the handles and definitions of world.h; these records are for snapshots, replays and the
// engine itself.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/joints.h"
#include "fulcrum/math.h"
#include "fulcrum/types.h"

namespace fulcrum {

struct ManifoldPoint {
  Vec2 point = Vec2::Zero();  // world position, midway between the two surfaces, m
  double separation =
      0.0;  // signed distance between the surfaces along the normal, m (< 0: overlap)

  // Filled and used by the contact solver, not by the manifold functions.
  double normal_impulse = 0.0;   // accumulated, N s
  double tangent_impulse = 0.0;  // accumulated, N s

  uint32_t id = 0;         // feature id, stable while the same features touch
  bool persisted = false;  // matched a point of the previous step's manifold
};

struct Manifold {
  Vec2 normal = Vec2::Zero();  // world unit normal, pointing from shape A to shape B
  ManifoldPoint points[2];
  int count = 0;  // 0: not touching (no point closer than the speculative distance)
};

// A touching manifold as the shapes last gave it, in A's frame, with the pose of B in A's frame
// it was found at. While B moves little relative to A the narrow phase moves this manifold with
// the bodies instead of colliding the shapes again (WorldSettings::manifold_reuse_distance).
// Only manifolds of flat shapes whose normal is a face normal are kept. Kept beside the contacts,
// one per contact slot, so that the loops over contacts do not carry it.
struct ManifoldCache {
  bool valid = false;
  bool normal_on_b = false;    // the normal is B's face's and turns with B (else A's)
  Transform pose;              // B's body frame in A's when the manifold was found
  Vec2 normal = Vec2::Zero();  // in A's frame then
  Vec2 points[2] = {Vec2::Zero(), Vec2::Zero()};  // in A's frame, manifold.count of them
  double separations[2] = {0.0, 0.0};             // m, as found
};

inline constexpr int kNullIndex = -1;

struct alignas(64) Body {
  BodyType type = BodyType::kStatic;
  uint32_t generation = 0;
  bool alive = false;
  // In the first cache line, beside the type: most walks over contacts and joints ask
  // whether an end is awake and dynamic, and read nothing else of the body.
  bool awake = false;
  bool fixed_rotation = false;
  bool enable_sleep = true;

  Transform xf;                      // body origin
  Vec2 local_center = Vec2::Zero();  // centre of mass in the body frame
  Vec2 center = Vec2::Zero();        // centre of mass, world
  Vec2 v = Vec2::Zero();             // velocity of the centre of mass
  double w = 0.0;
  double mass = 0.0, inv_mass = 0.0;
  double inertia = 0.0, inv_inertia = 0.0;  // about the centre of mass
  Vec2 force = Vec2::Zero();                // applied for the next tick
  double torque = 0.0;
  Vec2 constant_force = Vec2::Zero();  // applied every tick until changed
  double constant_torque = 0.0;

  double linear_damping = 0.0, angular_damping = 0.0, gravity_scale = 1.0;
  double drag = 0.0;  // quadratic drag coefficient, kg/m
  double sleep_time = 0.0;
  uint64_t user_data = 0;

  std::vector<int> shapes;        // shape indices, in creation order
  std::vector<int> joints;        // joint indices, in creation order
  int contact_list = kNullIndex;  // head of this body's contact edge list (edge key)
  int contact_count = 0;          // length of that list
  int awake_slot = kNullIndex;    // position in WorldImpl::awake_bodies, or kNullIndex

  bool is_dynamic() const { return type == BodyType::kDynamic || type == BodyType::kParticle; }
  bool rotates() const { return type != BodyType::kParticle && !fixed_rotation; }
};

// The body and the filter come first, in one cache line before the geometry's several: the
// broad phase's pair test reads them for every pair a moved shape finds, most often the parts
// of one ragdoll that its group keeps apart, and nothing else of the shape.
struct Shape {
  int body = kNullIndex;
  uint32_t generation = 0;
  bool alive = false;
  bool is_sensor = false;
  bool in_move_buffer = false;
  int proxy = kNullIndex;  // broad-phase leaf
  Filter filter;
  Geometry geometry;
  double density = 0.0, friction = 0.0, restitution = 0.0;
  uint64_t user_data = 0;
};

// The fields every tick reads for each awake joint come first, in its first two cache lines
// (the joint grid's 19 800 joints take 7.6 MB): which joint it is, its bodies and anchors, the
// flags that make a revolute joint a plain pin, the break limits and the accumulated impulses.
struct alignas(64) Joint {
  JointType type = JointType::kDistance;
  uint32_t generation = 0;
  bool alive = false;
  bool collide_connected = false;
  // Revolute joints (and the wheel's motor, the prismatic's limit, motor and spring).
  bool enable_limit = false, enable_motor = false, enable_spring = false;
  int body_a = kNullIndex, body_b = kNullIndex;
  double break_force = std::numeric_limits<double>::infinity();
  Vec2 local_a = Vec2::Zero(), local_b = Vec2::Zero();  // anchors in the body frames
  // Accumulated impulses, per substep (warm starting carries them across ticks).
  Vec2 linear_impulse = Vec2::Zero();  // revolute, weld, motor: point rows; prismatic: line
                                       // and angle rows; wheel: line row (x)
  double axial_impulse = 0.0;          // distance: rigid row; weld, motor: angle row;
                                       // curve: the normal row
  double lower_impulse = 0.0, upper_impulse = 0.0;
  double motor_impulse = 0.0;
  double spring_impulse = 0.0;  // springs of joints; spring force elements: the impulse of
                                // the last substep along anchor A -> anchor B
  double break_torque = std::numeric_limits<double>::infinity();
  // Distance joints.
  double length = 1.0, min_length = 1.0, max_length = 1.0;
  // Revolute joints.
  double reference_angle = 0.0;
  double lower_angle = 0.0, upper_angle = 0.0;
  double motor_speed = 0.0, max_motor_torque = 0.0;
  double target_angle = 0.0;
  // Springs (distance, revolute); weld: the linear part's spring.
  double hertz = 0.0, damping_ratio = 0.0;
  // Weld: the angular part's spring.
  double angular_hertz = 0.0, angular_damping_ratio = 0.0;
  // Prismatic and wheel joints: the axis in body A's frame; translation limits are kept in
  // lower_angle / upper_angle, and the spring (hertz, damping_ratio) pulls toward
  // target_translation (wheel: 0). Wheel: the motor turns B (motor_speed, max_motor_torque).
  Vec2 local_axis = Vec2(1.0, 0.0);
  double max_motor_force = 0.0;
  double target_translation = 0.0;
  // Target joints; motor joints: max_force and max_motor_torque cap the linear and angular
  // rows, local_a holds the linear offset (local_b is B's origin) and reference_angle the
  // angular offset, both changed by World::set_motor_joint_targets.
  Vec2 target = Vec2::Zero();
  double max_force = 0.0;
  double correction_factor = 0.0;  // motor joints
  // Curve joints: the curve in world coordinates. Line: curve_points = {point, unit
  // direction}; circle: {centre} and curve_radius; polyline: its vertices.
  CurveType curve_type = CurveType::kLine;
  std::vector<Vec2> curve_points;
  double curve_radius = 0.0;
  // Springs (force elements): rest length in `length`.
  double stiffness = 0.0, damping = 0.0;
};

// A contact sits in two intrusive doubly linked lists, one per body. Edge key = 2 * contact
// index + side (0: body A, 1: body B).
struct ContactEdge {
  int prev = kNullIndex;
  int next = kNullIndex;
};

struct Contact {
  bool alive = false;
  bool touching = false;
  bool sensor = false;
  uint32_t stamp = 0;  // the step that last collected it (dedupe while gathering)
  int shape_a = kNullIndex, shape_b = kNullIndex;  // geometry_type(a) <= geometry_type(b)
  int body_a = kNullIndex, body_b = kNullIndex;
  double friction = 0.0, restitution = 0.0;  // mixed once at creation
  Manifold manifold;
  ContactEdge edges[2];
};

// A whole world: definitions and settings, dynamic state and the solver's warm-start cache
// (the manifolds' and joints' accumulated impulses). Slot vectors are indexed by id; dead slots
// keep their generation so that handles stay unique after a restore.
struct WorldSnapshot {
  WorldSettings settings;
  int64_t tick = 0;
  uint32_t step_stamp = 0;
  std::vector<Body> bodies;
  std::vector<int> free_bodies;  // reused last first
  std::vector<Shape> shapes;     // `proxy` is not kept: the tree is rebuilt from shape_boxes
  std::vector<int> free_shapes;
  std::vector<AABB> shape_boxes;  // broad-phase fat box of each live shape (dead: empty box)
  std::vector<Contact> contacts;
  std::vector<ManifoldCache> manifold_caches;  // one per contact slot
  std::vector<int> free_contacts;
  std::vector<Joint> joints;
  std::vector<int> free_joints;
  std::vector<JointId> pending_joint_events;  // destroyed with a body, reported next step
  std::vector<int> awake_bodies;              // in the world's own order
  std::vector<int> move_buffer;               // shapes whose boxes moved since the last step
  std::vector<AttractorDef> attractors;       // in the world's order
  uint64_t state_hash = 0;                    // World::state_hash() when it was taken
};

}  // namespace fulcrum
