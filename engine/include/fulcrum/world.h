// The simulation world: bodies, shapes, contacts, and the fixed-timestep step.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/joints.h"
#include "fulcrum/math.h"
#include "fulcrum/status.h"
#include "fulcrum/types.h"

namespace fulcrum {

// What a body looks like from outside.
struct BodyState {
  BodyType type = BodyType::kStatic;
  Transform transform;                  // body origin and rotation
  Vec2 center = Vec2::Zero();           // world centre of mass, m
  Vec2 linear_velocity = Vec2::Zero();  // of the centre of mass, m/s
  double angular_velocity = 0.0;        // rad/s
  double mass = 0.0;                    // kg (0 for static and kinematic bodies)
  double rotational_inertia = 0.0;      // about the centre of mass, kg m^2
  bool awake = false;
  uint64_t user_data = 0;
  Vec2 constant_force = Vec2::Zero();  // N, every tick until changed (BodyDef)
  double constant_torque = 0.0;        // N m
};

struct ShapeInfo {
  BodyId body;
  ShapeType type = ShapeType::kCircle;
  Geometry geometry;
  double density = 0.0;
  double friction = 0.0;
  double restitution = 0.0;
  Filter filter;
  bool is_sensor = false;
  uint64_t user_data = 0;
};

// Contact and sensor events of the last step, in a deterministic order (by shape ids).
struct ContactEvent {
  ShapeId shape_a;
  ShapeId shape_b;
};
struct SensorEvent {
  ShapeId sensor;
  ShapeId visitor;
};
struct StepEvents {
  // Joints removed since the previous step because a body they held was destroyed.
  std::vector<JointId> joints_destroyed;
  // Joints that broke in the last step (their reaction passed their break limits).
  std::vector<JointId> joints_broken;
  std::vector<ContactEvent> contact_begin;
  std::vector<ContactEvent> contact_end;
  std::vector<SensorEvent> sensor_begin;
  std::vector<SensorEvent> sensor_end;
};

// Accuracy figures any world reports on request, for tests and the speed-against-error report.
struct WorldMetrics {
  int64_t tick = 0;
  int body_count = 0;
  int awake_body_count = 0;
  int contact_count = 0;                // touching, non-sensor manifolds
  double max_penetration = 0.0;         // largest overlap over all contact points, m (>= 0)
  double mean_penetration = 0.0;        // mean overlap over overlapping contact points, m
  double kinetic_energy = 0.0;          // J
  double potential_energy = 0.0;        // J, m g . x summed (relative to the origin)
  Vec2 linear_momentum = Vec2::Zero();  // kg m/s
  double angular_momentum = 0.0;        // about the origin, kg m^2/s
  double max_speed = 0.0;               // largest linear speed of any body, m/s
  double max_joint_error = 0.0;         // largest JointState::linear_error over all joints, m
  // Budgets (WorldSettings::max_substeps): at the last tick, how many islands ran more
  // substeps or relax passes than the world's, the most substeps any island ran, and the most
  // relax passes per substep, and the most velocity passes per substep (1 on a one-pass tick).
  int budget_islands = 0;
  int max_substeps = 0;
  int max_relax_iterations = 0;
  int max_velocity_iterations = 0;
};

struct QueryFilter {
  uint64_t category_bits = 1;
  uint64_t mask_bits = ~uint64_t{0};
};

struct RayHit {
  ShapeId shape;
  Vec2 point = Vec2::Zero();
  Vec2 normal = Vec2::Zero();
  double fraction = 0.0;
};

class WorldImpl;
class WorkerPool;
struct WorldSnapshot;  // fulcrum/state.h

class World {
 public:
  explicit World(const WorldSettings& settings = {});
  ~World();
  World(World&&) noexcept;
  World& operator=(World&&) noexcept;
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // Settings are checked whole; on error nothing changes.
  Status set_settings(const WorldSettings& settings);
  const WorldSettings& settings() const;

  // --- Bodies and shapes (each call either succeeds whole or changes nothing) ---------------
  Result<BodyId> create_body(const BodyDef& def);
  // Destroys the body and its shapes and contacts.
  Status destroy_body(BodyId id);
  Result<ShapeId> create_shape(BodyId body, const ShapeDef& def);
  Result<std::vector<ShapeId>> create_chain(BodyId body, const ChainDef& def);
  Status destroy_shape(ShapeId id);

  bool is_valid(BodyId id) const;
  bool is_valid(ShapeId id) const;
  Result<BodyState> body_state(BodyId id) const;
  Result<ShapeInfo> shape_info(ShapeId id) const;
  Result<std::vector<ShapeId>> body_shapes(BodyId id) const;
  // Live bodies in index order.
  std::vector<BodyId> bodies() const;
  int body_count() const;
  int shape_count() const;                        // live shapes, chain segments included
  Result<int> body_shape_count(BodyId id) const;  // O(1)
  // Work the edits have done since the world was built or restored, in units of roughly equal
  // cost: one per shape or joint created, per broad-phase box a new shape's wake query visited
  // and per sleeping body woken. Overlapping shapes make it grow with the square of their
  // number; servers bound it per batch. Not part of the state.
  uint64_t edit_work() const;

  // Edits wake the body (and its island).
  Status set_transform(BodyId id, const Vec2& position, double angle);
  Status set_linear_velocity(BodyId id, const Vec2& v);
  Status set_angular_velocity(BodyId id, double w);
  // Forces act for the next tick only. `point` is a world point.
  Status apply_force(BodyId id, const Vec2& force, const Vec2& point);
  Status apply_force_to_center(BodyId id, const Vec2& force);
  Status apply_torque(BodyId id, double torque);
  Status apply_linear_impulse(BodyId id, const Vec2& impulse, const Vec2& point);
  Status apply_angular_impulse(BodyId id, double impulse);
  // A force at the centre of mass (N) and a torque (N m) that act every tick from the next on,
  // until set again (zeros: none). Replaces the body's previous constant force and torque;
  // wakes it when either is non-zero. Ignored for static and kinematic bodies, like forces.
  Status set_constant_force(BodyId id, const Vec2& force, double torque);
  // Replaces the world's attractors (AttractorDef), checked whole first. Like gravity they
  // wake nothing: a sleeping body feels them once something wakes it.
  Status set_attractors(const std::vector<AttractorDef>& attractors);
  const std::vector<AttractorDef>& attractors() const;
  Status set_awake(BodyId id, bool awake);
  Status set_shape_material(ShapeId id, double friction, double restitution);
  Status set_shape_filter(ShapeId id, const Filter& filter);

  // --- Joints (joints.h). Destroying a body destroys its joints. ---------------------------
  Result<JointId> create_distance_joint(const DistanceJointDef& def);
  Result<JointId> create_revolute_joint(const RevoluteJointDef& def);
  Result<JointId> create_weld_joint(const WeldJointDef& def);
  Result<JointId> create_target_joint(const TargetJointDef& def);
  Result<JointId> create_prismatic_joint(const PrismaticJointDef& def);
  Result<JointId> create_wheel_joint(const WheelJointDef& def);
  Result<JointId> create_motor_joint(const MotorJointDef& def);
  Result<JointId> create_curve_joint(const CurveJointDef& def);
  // A spring force element (SpringDef); a JointId of type kSpring.
  Result<JointId> create_spring(const SpringDef& def);
  Status set_joint_target(JointId id, const Vec2& target);
  // A motor joint's new offsets (MotorJointDef), from the next tick on.
  Status set_motor_joint_targets(JointId id, const Vec2& linear_offset, double angular_offset);
  // Force (N) and torque (N m) above which the joint breaks; infinity: never. Both >= 0.
  Status set_joint_break_limits(JointId id, double force, double torque);
  Status destroy_joint(JointId id);
  bool is_valid(JointId id) const;
  // Live joints in index order (a scene's joints, as build_world created them, first).
  std::vector<JointId> joints() const;
  Result<JointState> joint_state(JointId id) const;
  // Revolute, prismatic and wheel joints.
  Status set_motor_speed(JointId id, double speed);

  // --- Simulation ----------------------------------------------------------------------------
  // Advances exactly one tick of settings().dt.
  void step();
  // step(), unless the tick would make more contacts than the contact limit allows: then
  // nothing changes (the tick does not run) and the status is RESOURCE_EXHAUSTED with the
  // counts. step() ignores that status, so with a limit set, call this one.
  Status try_step();
  // At most `limit` live contacts (0: no limit, the default). A guard for servers: overlapping
  // shapes make contacts grow with the square of their number, at about 1 KB each. Like the
  // thread count it is not state: snapshots do not carry it and restoring one keeps it.
  Status set_contact_limit(int64_t limit);
  int64_t contact_limit() const { return contact_limit_; }
  // Threads the step may use, the caller's included: 1 (the default) to kMaxThreads. Any
  // count gives the same bits, so this is not part of the world's state: snapshots do not
  // carry it and restoring one keeps it. The step shares out the contact solver's colours when
  // a tick has at least 256 touching contacts.
  static constexpr int kMaxThreads = 64;
  Status set_threads(int threads);
  int threads() const;
  int64_t tick() const;
  // Events produced by the last step.
  const StepEvents& events() const;

  // 64-bit hash of every bit of state that evolves, over bit patterns in id order.
  uint64_t state_hash() const;
  // A state hash as Fulcrum prints it everywhere: 16 lowercase hex digits.
  static std::string hash_text(uint64_t hash);
  WorldMetrics metrics() const;
  // The budgets of the last tick, as in WorldMetrics (cheap: no pass over the world).
  struct Budgets {
    int islands = 0;       // islands that ran more substeps or relax passes than the world's
    int max_substeps = 0;  // the most substeps any island ran
    int max_relax_iterations = 0;  // the most relax passes per substep any island ran
    // The most velocity passes per substep any island ran (1 on a one-pass tick,
    // WorldSettings::one_pass_give_tolerance).
    int max_velocity_iterations = 0;
  };
  Budgets budgets() const;

  // --- Snapshots (fulcrum/state.h) -----------------------------------------------------------
  // The complete world at this tick boundary. A world restored from it continues bit for bit.
  WorldSnapshot snapshot() const;
  // Replaces this world with the snapshot after checking all of it (ranges, links between
  // records, and that the restored state hashes to snapshot.state_hash). On error the world is
  // unchanged and the message names the record and field at fault.
  Status restore(const WorldSnapshot& snapshot);
  // Makes this world a copy of `other` as it stands: the same state, so the two continue bit
  // for bit alike. Unlike restore it checks nothing and rebuilds nothing (the state is already
  // a world's), so it costs only copying the state's arrays: a rollback's fast path. This
  // world keeps its own thread count and contact limit.
  void copy_state(const World& other);

  // --- Queries (results in a deterministic order) --------------------------------------------
  // The nearest hit along origin -> origin + translation (ties broken by shape id).
  std::optional<RayHit> ray_cast_closest(const Vec2& origin, const Vec2& translation,
                                         const QueryFilter& filter = {}) const;
  // Every hit, sorted by fraction then shape id.
  std::vector<RayHit> ray_cast_all(const Vec2& origin, const Vec2& translation,
                                   const QueryFilter& filter = {}) const;
  // Shapes whose bounding box overlaps `box`, by shape id.
  std::vector<ShapeId> overlap_aabb(const AABB& box, const QueryFilter& filter = {}) const;
  // Shapes that contain the point, by shape id (sensors included).
  std::vector<ShapeId> overlap_point(const Vec2& point, const QueryFilter& filter = {}) const;

  // Internal access for tests and the engine's own modules.
  WorldImpl& impl() { return *impl_; }
  const WorldImpl& impl() const { return *impl_; }

 private:
  std::unique_ptr<WorldImpl> impl_;
  std::unique_ptr<WorkerPool> pool_;  // null with one thread
  int64_t contact_limit_ = 0;
};

}  // namespace fulcrum
