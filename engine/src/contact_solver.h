// Per-step solver data: compact body states and contact constraint rows, rebuilt each step from
// the awake set. Kept in the world only to reuse allocations. The hot loops read only
// SolverBody and ContactRow, written as plain doubles so that a pass streams little memory;
// what restitution and the rigid block solver need lives apart in ContactRowExtra.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "large_pages.h"

namespace fulcrum {

// What the iterations touch per body, one cache line: the contact and pin lanes load the
// velocity row (vx, vy, w, inv_mass) and the motion row (dpx, dpy, qc, qs) as four doubles each
// (contact_kernel.h), so these two rows stay in this order. The lanes carry the inverse
// inertias themselves; what else a body has in the solver lives apart, in SolverBodyExtra, so
// that a pass over many bodies reads one line per body.
struct alignas(64) SolverBody {
  double vx = 0.0, vy = 0.0, w = 0.0;  // velocity of the centre of mass
  double inv_mass = 0.0;
  double dpx = 0.0, dpy = 0.0;  // displacement of the centre of mass since the tick began
  double qc = 1.0, qs = 0.0;    // rotation since the tick began
};

// The rest of a solver body, read by the rows solved one at a time (joints other than pins,
// rigid contacts, restitution) and by the packing of lanes: four bodies to a cache line.
struct SolverBodyExtra {
  double inv_inertia = 0.0;
  double da = 0.0;  // angle turned since the tick began (sum of h w); kept only while a joint
                    // row reads it (SolverScratch::track_angles)
};

// A solver body's centre of mass at the tick's start, for preparing the rows without reading
// the bodies (slot 0 has none: the static bodies it stands for each have their own).
struct SlotCentre {
  double x = 0.0, y = 0.0;
};

// A solver body's velocity before a substep's forces, kept for restitution's approach speeds;
// four doubles, so that the lanes load it as they load a velocity row.
struct alignas(32) VelocityBefore {
  double vx = 0.0, vy = 0.0, w = 0.0;
  double unused = 0.0;
};

// A speed cap's change of a solver body's velocity (v0 before it, v after it) taken off the
// body's row of `substep_start` (SolverScratch): the warm start worked out from each body's change
// of velocity must leave out what the caps took (solve_group). Only the components a cap
// changed, so that a row is never turned from -0 to +0.
inline void note_cap(VelocityBefore& start, double vx0, double vy0, double w0, double vx, double vy,
                     double w) {
  if (vx != vx0) start.vx += vx - vx0;
  if (vy != vy0) start.vy += vy - vy0;
  if (w != w0) start.w += w - w0;
}

// Rigid contacts with split impulses: the velocity that moves a body out of overlap this
// substep and is then forgotten.
struct PseudoVelocity {
  double vx = 0.0, vy = 0.0, w = 0.0;
};

// One solver body as a row solved one at a time sees it: a copy of its line and of its
// inverse inertia and angle, taken for the row (scalar_body); the row's change of velocity
// goes back with store_velocity. A row's two bodies are two different slots (a joint or
// contact without an awake body has no row), so the two copies never stand for one body.
struct ScalarBody {
  double vx = 0.0, vy = 0.0, w = 0.0;
  double inv_mass = 0.0;
  double dpx = 0.0, dpy = 0.0;
  double qc = 1.0, qs = 0.0;
  double da = 0.0;
  double inv_inertia = 0.0;
};

inline ScalarBody scalar_body(const SolverBody& b, const SolverBodyExtra& x) {
  return ScalarBody{b.vx, b.vy, b.w, b.inv_mass, b.dpx, b.dpy, b.qc, b.qs, x.da, x.inv_inertia};
}

inline void store_velocity(const ScalarBody& from, SolverBody& b) {
  b.vx = from.vx;
  b.vy = from.vy;
  b.w = from.w;
}

// Soft constraint coefficients for one substep (Catto, "Solver2D", 2024): a spring of
// stiffness omega = 2 pi hertz with damping ratio zeta, made implicit. The row impulse becomes
//   lambda = -m_c mass_scale (J v + bias_rate C) - impulse_scale * accumulated.
// Rigid rows have bias_rate 0, mass_scale 1, impulse_scale 0.
struct Softness {
  double bias_rate = 0.0;
  double mass_scale = 1.0;
  double impulse_scale = 0.0;
};
// The implicit spring of frequency `hertz` and damping ratio `zeta` over substep h; rigid (all
// zero feedback) for hertz 0.
Softness make_softness(double hertz, double zeta, double h);

struct ContactPointRow {
  double rax = 0.0, ray = 0.0;  // point relative to body A's centre of mass (tick start)
  double rbx = 0.0, rby = 0.0;
  double base_separation = 0.0;  // separation minus n . (rb - ra): current separation is
                                 // n . (moved anchor B - moved anchor A) + this
  double normal_mass = 0.0;      // 1 / (J M^-1 J^T) for the normal row
  double tangent_mass = 0.0;     // the same for the friction row
  double normal_impulse = 0.0;   // accumulated
  double tangent_impulse = 0.0;  // accumulated
  double max_normal_impulse = 0.0;
};

struct ContactRow {
  int ia = 0, ib = 0;  // solver body slots (0: the shared static body)
  int count = 0;
  bool block = false;   // rigid mode: solve both normal rows together
  bool linear = false;  // neither body turns (particles, fixed rotation, static): no
                        // angular terms, so the row costs about half
  double nx = 0.0, ny = 0.0;
  double friction = 0.0;
  Softness softness;
  ContactPointRow points[2];
};

// The solver body slots of a row's bodies.
struct RowBodies {
  int ia = 0, ib = 0;
  bool operator==(const RowBodies&) const = default;
};

struct ContactRowExtra {
  int contact = -1;
  double restitution = 0.0;
  double approach_speed[2] = {0.0, 0.0};   // normal relative velocity at impact
  double pseudo_impulse[2] = {0.0, 0.0};   // split impulses, accumulated
  double k11 = 0.0, k12 = 0.0, k22 = 0.0;  // block solver: effective-mass matrix K
  double i11 = 0.0, i12 = 0.0, i22 = 0.0;  // and its inverse
};

struct JointRow;

// What integrate_velocities adds to one dynamic awake body every substep, worked out once per
// tick from its Body (which is large and cold) with the very operations the substep would do,
// so that the substeps read one small record and give the same bits.
struct BodyDrive {
  double ax = 0.0, ay = 0.0;                         // inv_mass f + gravity_scale g
  double dw = 0.0;                                   // h inv_inertia torque
  double linear_factor = 1.0, angular_factor = 1.0;  // 1 / (1 + h damping)
  double drag = 0.0;                                 // h inv_mass drag
  bool linear_damped = false, angular_damped = false, dragged = false;
};

// How integrate_velocities finds a body's drive (SolverScratch::drive_kinds): none (not
// dynamic), the tick's gravity_drive (most bodies), or its own in `drives`.
inline constexpr uint8_t kNoDrive = 0, kGravityOnly = 1, kOwnDrive = 2;

struct SolverScratch {
  LargeVector<SolverBody> bodies;
  std::vector<SolverBodyExtra> body_extras;  // beside bodies, slot for slot
  std::vector<uint8_t> slot_dynamic;         // beside bodies: inv_mass > 0 (load_bodies)
  std::vector<PseudoVelocity> pseudo;        // beside bodies with split impulses, else empty
  // Whether this tick's joint rows read the angles turned (SolverBodyExtra::da): the substeps
  // add them up only then.
  bool track_angles = false;
  LargeVector<BodyDrive> drives;     // per awake body (slot k + 1's is drives[k]): kOwnDrive's
  std::vector<uint8_t> drive_kinds;  // per awake body, beside drives: kNoDrive, ...
  BodyDrive gravity_drive;           // a kGravityOnly body's drive this tick
  std::vector<int> body_slot;        // body index -> solver slot (stale for bodies not solved)
  std::vector<int> slot_body;        // solver slot -> body index (-1 for slot 0)
  LargeVector<SlotCentre> centres;   // beside bodies, slot for slot
  // The rigid step's rows (soft contacts' rows live in the coloured lanes, contact_lanes.h).
  LargeVector<ContactRow> rows;
  LargeVector<ContactRowExtra> extras;
  std::vector<RowBodies> row_bodies;  // soft contacts: each row's bodies, for the colouring
  // Soft contacts: each row's manifold points, noted as it is prepared, so that storing the
  // impulses need not read the contact before writing it.
  std::vector<uint8_t> row_points;
  std::vector<double> row_restitution;  // soft contacts: each row's restitution (0: none)
  std::vector<int> contacts;
  std::vector<int> restitution_rows;  // rows with restitution > 0
  // With restitution rows: each slot's velocity before this substep's forces.
  LargeVector<VelocityBefore> velocity_before;
  LargeVector<VelocityBefore> warm_next;  // the lanes' next warm start, per slot (solve_group)
  // Each slot's velocity after the substep's forces, less what the speed caps took since, when
  // the next substep's warm start is each body's change of velocity (solve_group).
  LargeVector<VelocityBefore> substep_start;
  std::vector<int> joints;           // awake joints, by id (after solve: every group's)
  LargeVector<JointRow> joint_rows;  // constraints
  // Each joint row's slots and kind, written beside it: colour_points reads only these, 12
  // bytes a row instead of a cache line of each large row.
  struct RowSlots {
    int ia = 0, ib = 0;
    bool plain_point = false;
    bool revolute = false;  // a revolute joint that is not a plain point
  };
  std::vector<RowSlots> joint_row_slots;
  std::vector<JointRow> spring_rows;  // spring force elements
};

inline ScalarBody scalar_body(const SolverScratch& s, int slot) {
  return scalar_body(s.bodies[slot], s.body_extras[slot]);
}

// The solver slot of body `body` in this group, 0 (the shared static body) when the group does
// not solve it: asleep, static, or another group's. Reads no Body.
inline int solver_slot(const SolverScratch& s, int body) {
  const int k = s.body_slot[body];
  return k > 0 && static_cast<size_t>(k) < s.slot_body.size() && s.slot_body[k] == body ? k : 0;
}

}  // namespace fulcrum
