// Handles and definition structs. Every object is created from a plain definition with
// sensible defaults; every field states its unit and range. Definitions map one to one onto the
// proto messages in proto/fulcrum/v1/.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/math.h"

namespace fulcrum {

// Handles are {index, generation}. A destroyed object's index is reused with a new generation,
// so a stale handle is detected and refused, never dereferenced. Generation 0 is never issued:
// a default-constructed handle is null.
struct BodyId {
  int32_t index = -1;
  uint32_t generation = 0;
  bool is_null() const { return generation == 0; }
  friend bool operator==(const BodyId&, const BodyId&) = default;
};

struct ShapeId {
  int32_t index = -1;
  uint32_t generation = 0;
  bool is_null() const { return generation == 0; }
  friend bool operator==(const ShapeId&, const ShapeId&) = default;
};

enum class BodyType : uint8_t {
  kStatic = 0,     // never moves; infinite mass; never integrated
  kKinematic = 1,  // moves with its set velocity; infinite mass; pushes dynamic bodies
  kDynamic = 2,    // moved by forces and contacts; mass from its shapes
  kParticle = 3,   // dynamic with mass but no rotation (mass matrix m*I); one circle at its origin
};
const char* body_type_name(BodyType type);

struct BodyDef {
  BodyType type = BodyType::kStatic;
  Vec2 position = Vec2::Zero();         // world position of the body origin, m
  double angle = 0.0;                   // radians, any finite value (particles ignore it)
  Vec2 linear_velocity = Vec2::Zero();  // of the body origin, m/s
  double angular_velocity = 0.0;        // rad/s
  double linear_damping = 0.0;          // 1/s, >= 0: dv/dt = -linear_damping * v
  double angular_damping = 0.0;         // 1/s, >= 0
  double gravity_scale = 1.0;           // multiplies world gravity; any finite value
  double drag = 0.0;                    // quadratic drag c, kg/m, >= 0: F = -c v |v|
  bool fixed_rotation = false;          // a dynamic body that never turns
  bool awake = true;                    // created awake or asleep
  bool enable_sleep = true;             // false keeps this body (and its island) awake
  uint64_t user_data = 0;               // carried, never interpreted
  // A force at the centre of mass and a torque that act every tick until changed
  // (World::set_constant_force), unlike World::apply_force, which lasts one tick. Dynamic
  // bodies only; finite, at most kMaxInputMagnitude.
  Vec2 constant_force = Vec2::Zero();  // N
  double constant_torque = 0.0;        // N m
};

// How an attractor's pull changes with the distance d from its point.
enum class Falloff {
  kConstant = 0,       // the same pull at any distance
  kInverseSquare = 1,  // strength / d^2 (strength is the pull at 1 m)
};

// A pull toward a point (a push away for negative strength), felt by every dynamic body with a
// shape whose filter category_bits meet mask_bits, applied where gravity is (every substep,
// at the body's centre of mass, from its position at the substep's start). Inside
// min_distance the pull falls linearly to zero at the point (a uniform ball's gravity), so a
// body passing through the point is not flung out. World::set_attractors.
struct AttractorDef {
  Vec2 point = Vec2::Zero();  // m, world; finite
  double strength = 0.0;      // finite: m/s^2 (per_mass) or N; inverse square: at 1 m
  Falloff falloff = Falloff::kConstant;
  double min_distance = 0.5;          // m, > 0, finite
  bool per_mass = true;               // strength is an acceleration, like gravity (an orbit's
                                      // G M for inverse square); false: a force in N
  uint64_t mask_bits = ~uint64_t{0};  // bodies with a shape whose category_bits & mask_bits != 0
};

// Collision filtering: two shapes collide when (a.category & b.mask) != 0 and
// (b.category & a.mask) != 0, unless they share a non-zero group: a positive group always
// collides, a negative group never does.
struct Filter {
  uint64_t category_bits = 1;
  uint64_t mask_bits = ~uint64_t{0};
  int32_t group_index = 0;
};

struct ShapeDef {
  Geometry geometry = Circle{};
  double density = 1.0;      // kg/m^2, >= 0 (> 0 on the one shape of a particle)
  double friction = 0.6;     // Coulomb coefficient, >= 0; mixed as sqrt(a * b)
  double restitution = 0.0;  // >= 0 (1 = elastic); mixed as max(a, b)
  Filter filter;
  bool is_sensor = false;  // reports overlaps (sensor events), never responds to contact
  uint64_t user_data = 0;
};

// A chain of two-sided segments for static terrain: points[i] to points[i + 1], plus the
// closing segment when `loop` is set. Each segment becomes its own shape.
struct ChainDef {
  std::vector<Vec2> points;  // local, m; at least 2 (3 with loop); consecutive points distinct
  bool loop = false;
  double friction = 0.6;
  double restitution = 0.0;
  Filter filter;
  uint64_t user_data = 0;
};

// World settings. All can be changed between ticks with World::set_settings.
struct WorldSettings {
  Vec2 gravity = Vec2(0.0, -10.0);  // m/s^2
  double dt = 1.0 / 60.0;           // s, > 0: the length of one tick

  // Solver. Each tick is split into `substeps` substeps; each substep integrates velocities,
  // warm starts, runs `velocity_iterations` passes with position feedback, integrates
  // positions, then runs `relax_iterations` passes without it (removing the feedback's
  // velocity). Position feedback is soft (a spring of contact_hertz with
  // contact_damping_ratio, Catto's soft step) or, with contact_hertz = 0, rigid Baumgarte with
  // slop, optionally on pseudo velocities (split impulses). The talk's classic sequential
  // impulses are substeps = 1, velocity_iterations = 8, relax_iterations = 0,
  // contact_hertz = 0.
  int substeps = 4;                     // >= 1
  int velocity_iterations = 2;          // >= 1: passes over all rows per substep
  int relax_iterations = 1;             // >= 0: passes without position feedback per substep
  double contact_hertz = 50.0;          // Hz, >= 0: stiffness of soft contacts (0: rigid)
  double contact_damping_ratio = 10.0;  // >= 0: damping of soft contacts
  int position_iterations = 3;          // >= 0: pseudo-velocity passes (split impulses only)
  bool split_impulses = false;          // rigid mode: position error fixed on pseudo velocities
  double baumgarte = 0.2;               // [0, 1]: rigid mode: error fraction fixed per substep
  double linear_slop = 0.005;           // m, >= 0: rigid mode: overlap tolerated before
                                        // correcting; soft contacts correct all overlap
  double max_correction_speed = 1.5;    // m/s, > 0: cap on the position-correction speed
  double restitution_threshold = 1.0;   // m/s, >= 0: slower approaches do not bounce
  double early_exit_tolerance = 0.0;    // N s, >= 0: stop a substep's passes when every
                                        // corrective impulse is below this (0: run them all)
  double joint_hertz = 60.0;            // Hz, >= 0: stiffness of joint position feedback
                                        // (0: rigid Baumgarte with `baumgarte`, no slop)
  double joint_damping_ratio = 2.0;     // >= 0
  // Budgets (budget.cpp): an island whose soft joints would give more than
  // joint_give_tolerance under the weight they carry, or whose soft contacts would be pressed
  // in by more than contact_give_tolerance of the thinner shape's thickness under the loads
  // they carried last tick, runs more substeps, with its joints and contacts stiffer in
  // proportion, up to max_substeps (<= substeps: never).
  int max_substeps = 14;                // >= 1
  double joint_give_tolerance = 0.008;  // m, > 0
  double contact_give_tolerance = 0.5;  // fraction of the thinner shape's thickness, > 0
  // An island whose resting contacts would all be pressed in by at most
  // one_pass_give_tolerance of the thinner shape's thickness runs one velocity pass per
  // substep instead of velocity_iterations, unless it holds a joint, a new contact or a body
  // faster than rest, recovers or touches a kinematic body (budgets and gravity must be on;
  // 0: never; budget.cpp).
  double one_pass_give_tolerance = 0.002;  // fraction of the thinner shape's thickness, >= 0
  bool warm_starting = true;               // start each substep from the last one's impulses
  bool block_solver = true;                // rigid mode: two-point normal rows solved together

  // Collision.
  double speculative_distance = 0.02;  // m, >= 0: contact points kept up to this separation
  // m, >= 0: most a broad-phase box is fattened past its shape's reach (the speculative
  // distance); a shape gets an eighth of its half-diagonal up to this, a static shape none, and
  // a shape travelling more than half its margin a tick none.
  double aabb_margin = 0.1;
  double max_linear_speed = 400.0;  // m/s, > 0: speeds above are clamped
  // A touching manifold between flat shapes (polygons without rounding, segments) is moved
  // with the bodies instead of found again while B has moved at most this far relative to A
  // since it was found, at each point and at the shapes' ends through turning (0: never).
  double manifold_reuse_distance = 0.001;  // m, >= 0

  // Sleeping.
  bool enable_sleep = true;
  double time_to_sleep = 0.5;              // s, > 0: resting this long puts an island to sleep
  double linear_sleep_tolerance = 0.05;    // m/s, >= 0
  double angular_sleep_tolerance = 0.035;  // rad/s, >= 0 (2 degrees/s)
};

// Checks every field against its range; the message names the field.
Status validate_settings(const WorldSettings& s);
Status validate_body_def(const BodyDef& def);
Status validate_shape_def(const ShapeDef& def);
Status validate_chain_def(const ChainDef& def);
// `field` starts the message ("attractors[2]" gives "attractors[2].strength: ...").
Status validate_attractor(const AttractorDef& def, const std::string& field);

}  // namespace fulcrum
