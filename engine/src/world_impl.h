// The world's internal state. Bodies, shapes and contacts live in pools indexed by id; the
// solver copies what it touches into compact per-step arrays (contact_solver.h) so that the hot
// loops read little memory.
#pragma once

#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "contact_solver.h"
#include "dynamic_tree.h"
#include "fulcrum/world.h"
#include "joint_solver.h"
#include "manifold.h"

namespace fulcrum {

inline constexpr int kNullIndex = -1;

struct Body {
  BodyType type = BodyType::kStatic;
  uint32_t generation = 0;
  bool alive = false;

  Transform xf;                      // body origin
  Vec2 local_center = Vec2::Zero();  // centre of mass in the body frame
  Vec2 center = Vec2::Zero();        // centre of mass, world
  Vec2 v = Vec2::Zero();             // velocity of the centre of mass
  double w = 0.0;
  Vec2 force = Vec2::Zero();  // applied for the next tick
  double torque = 0.0;

  double mass = 0.0, inv_mass = 0.0;
  double inertia = 0.0, inv_inertia = 0.0;  // about the centre of mass
  double linear_damping = 0.0, angular_damping = 0.0, gravity_scale = 1.0;
  double drag = 0.0;  // quadratic drag coefficient, kg/m
  bool fixed_rotation = false;
  bool awake = false;
  bool enable_sleep = true;
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

struct Shape {
  int body = kNullIndex;
  uint32_t generation = 0;
  bool alive = false;
  Geometry geometry;
  double density = 0.0, friction = 0.0, restitution = 0.0;
  Filter filter;
  bool is_sensor = false;
  uint64_t user_data = 0;
  int proxy = kNullIndex;  // broad-phase leaf
  bool in_move_buffer = false;
};

struct Joint {
  JointType type = JointType::kDistance;
  uint32_t generation = 0;
  bool alive = false;
  int body_a = kNullIndex, body_b = kNullIndex;
  bool collide_connected = false;
  Vec2 local_a = Vec2::Zero(), local_b = Vec2::Zero();  // anchors in the body frames
  // Distance joints.
  double length = 1.0, min_length = 1.0, max_length = 1.0;
  // Revolute joints.
  double reference_angle = 0.0;
  bool enable_limit = false, enable_motor = false, enable_spring = false;
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
  double break_force = std::numeric_limits<double>::infinity();
  double break_torque = std::numeric_limits<double>::infinity();
  // Accumulated impulses, per substep (warm starting carries them across ticks).
  Vec2 linear_impulse = Vec2::Zero();  // revolute, weld, motor: point rows; prismatic: line
                                       // and angle rows; wheel: line row (x)
  double axial_impulse = 0.0;          // distance: rigid row; weld, motor: angle row;
                                       // curve: the normal row
  double lower_impulse = 0.0, upper_impulse = 0.0;
  double motor_impulse = 0.0;
  double spring_impulse = 0.0;  // springs of joints; spring force elements: the impulse of
                                // the last substep along anchor A -> anchor B
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
  int shape_a = kNullIndex, shape_b = kNullIndex;  // geometry_type(a) <= geometry_type(b)
  int body_a = kNullIndex, body_b = kNullIndex;
  double friction = 0.0, restitution = 0.0;  // mixed once at creation
  Manifold manifold;
  ContactEdge edges[2];
  uint32_t stamp = 0;  // the step that last collected it (dedupe while gathering)
};

class WorldImpl {
 public:
  explicit WorldImpl(const WorldSettings& s) : settings(s) {}

  WorldSettings settings;
  int64_t tick = 0;
  uint32_t step_stamp = 0;

  std::vector<Body> bodies;
  std::vector<int> free_bodies;  // reused last-freed first
  std::vector<Shape> shapes;
  std::vector<int> free_shapes;
  std::vector<Contact> contacts;
  std::vector<int> free_contacts;
  std::vector<Joint> joints;
  std::vector<int> free_joints;
  std::vector<JointId> pending_joint_events;  // destroyed with a body, reported next step
  std::vector<int> awake_bodies;  // unordered set (swap-remove); sorted when a step uses it
  int body_count = 0;

  DynamicTree tree;
  std::vector<int> move_buffer;  // shape indices whose proxies moved or were created

  StepEvents events;

  // --- lookups (return kNullIndex for stale or unknown handles) ---
  int body_index(BodyId id) const;
  int shape_index(ShapeId id) const;
  BodyId body_id(int index) const { return BodyId{index, bodies[index].generation}; }
  ShapeId shape_id(int index) const { return ShapeId{index, shapes[index].generation}; }
  int joint_index(JointId id) const;
  JointId joint_id(int index) const { return JointId{index, joints[index].generation}; }

  // --- joints (joint.cpp and one file per type) ---
  // A new joint of `type` between two live, distinct bodies (its type-specific fields at
  // their defaults); wakes both and drops their contacts unless collide_connected.
  Result<int> add_joint(JointType type, BodyId body_a, BodyId body_b, bool collide_connected);
  void destroy_joint_at(int joint);
  // Whether a joint between the two bodies forbids their contact.
  bool joint_blocks_contact(int body_a, int body_b) const;
  void prepare_joints(const std::vector<int>& awake, double h);
  void warm_start_joints();
  void solve_joints(bool use_bias);
  // Spring force elements: one substep's forces into the solver bodies' velocities.
  void apply_spring_forces(double h);
  // Removes joints whose last tick's reaction passed their break limits.
  void break_joints();

  // --- bodies (world.cpp) ---
  void update_mass(int body);
  void set_awake_flag(int body, bool awake);
  // Wakes a sleeping dynamic body and everything resting on it (its former island).
  void wake_island(int body);
  // Wakes sleeping bodies whose shapes' boxes overlap `box`.
  void wake_in_box(const AABB& box);

  // --- broad phase (broad_phase.cpp) ---
  void create_proxy(int shape);
  void destroy_proxy(int shape);
  void synchronize_shapes(int body);
  void update_pairs();
  bool should_collide(int shape_a, int shape_b) const;

  // --- contacts (contact.cpp) ---
  void create_contact(int shape_a, int shape_b);
  void destroy_contact(int contact, bool report_end);
  bool has_contact(int shape_a, int shape_b) const;
  // Refreshes the manifolds of contacts with an awake body; destroys contacts whose boxes
  // stopped overlapping; reports begin/end events; wakes bodies touched by awake ones.
  void collide();
  void collide_round(size_t first, size_t end);  // awake_bodies[first, end)
  void destroy_body_contacts(int body);

  // --- islands and sleep (island.cpp) ---
  void update_sleep(const std::vector<int>& awake_sorted);

  // --- solver (contact_solver.cpp) ---
  void solve(const std::vector<int>& awake_sorted);

  // Scratch reused every step (never part of the state).
  std::vector<int> scratch_contacts;
  std::vector<int> scratch_awake;
  SolverScratch solver_scratch;
  std::vector<std::pair<int, int>> scratch_pairs;  // broad phase
  std::vector<int> scratch_parent;                 // islands
  std::vector<double> scratch_rest, scratch_root_rest;
};

inline int edge_contact(int edge_key) {
  return edge_key >> 1;
}
inline int edge_side(int edge_key) {
  return edge_key & 1;
}

}  // namespace fulcrum
