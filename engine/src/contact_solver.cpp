// The sequential-impulse step for contacts. Each contact point is two rows of the common form
// in constraint_row.h (an axis row along the normal, bounded to [0, inf), and one along the
// tangent, bounded by +-mu times the normal impulse), written out here on plain doubles
// because this is the hot loop. After Catto: "Modeling and Solving Constraints" (GDC 2009),
// "Iterative Dynamics with Temporal Coherence" (2005) and "Solver2D" (2024).
//
// Normal row of one contact point, with n the normal from A to B and r the point relative to
// each centre of mass:
//   C = separation >= 0,  dC/dt = J v = n . (vB + wB x rB - vA - wA x rA)
//   J = [-n, -(rA x n), n, rB x n],  m_c = 1 / (mA + mB + iA (rA x n)^2 + iB (rB x n)^2)
//   lambda = -m_c (J v + b),  accumulated impulse clamped to >= 0.
// The bias b: while separated by s > 0 it is s / h, so the gap may close within the substep
// and no faster (speculative contact). While overlapping it is the position feedback: soft
// (bias_rate * s with the implicit-spring mass and impulse scales) or rigid Baumgarte
// (beta / h) * min(0, s + slop), the latter optionally on pseudo velocities (split impulses).
// Friction is a velocity motor along the tangent t with target 0, clamped to
// |lambda_t| <= mu * lambda_n. Restitution is applied once after the substeps to points that
// approached faster than the threshold and carried load: they leave at -e times that speed.
//
// One tick = `substeps` substeps of h = dt / substeps, each:
//   integrate velocities (spring forces, gravity) -> warm start -> solve (with feedback)
//   -> integrate positions -> relax (without feedback),
// then restitution and store impulses. The separation is updated every pass from the bodies'
// motion since the tick began, with the anchors held fixed (no new collision per substep).
#include <algorithm>
#include <cmath>

#include "fulcrum/trig.h"
#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

Softness make_softness(double hertz, double zeta, double h) {
  if (hertz == 0.0) return Softness{};
  double omega = 2.0 * kPi * hertz;
  double a1 = 2.0 * zeta + h * omega;
  double a2 = h * omega * a1;
  double a3 = 1.0 / (1.0 + a2);
  return Softness{omega / a1, a2 * a3, a3};
}

namespace {

// The row math below is written on plain doubles: (v + w x r) = (vx - w ry, vy + w rx) and
// r x P = rx Py - ry Px.

// Relative velocity of the contact point, B minus A (of solver bodies or their scalar copies).
template <class Body>
inline void relative_velocity(const Body& a, const Body& b, const ContactPointRow& p, double* dvx,
                              double* dvy) {
  *dvx = (b.vx - b.w * p.rby) - (a.vx - a.w * p.ray);
  *dvy = (b.vy + b.w * p.rbx) - (a.vy + a.w * p.rax);
}

template <class Body>
inline double normal_speed(const Body& a, const Body& b, const ContactPointRow& p, double nx,
                           double ny) {
  double dvx, dvy;
  relative_velocity(a, b, p, &dvx, &dvy);
  return dvx * nx + dvy * ny;
}

// P applied to B at rb and -P to A at ra.
inline void apply_impulse(ScalarBody& a, ScalarBody& b, const ContactPointRow& p, double px,
                          double py) {
  a.vx -= a.inv_mass * px;
  a.vy -= a.inv_mass * py;
  a.w -= a.inv_inertia * (p.rax * py - p.ray * px);
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * (p.rbx * py - p.rby * px);
}

// Separation now, from the bodies' motion since the tick began (anchors turned with them).
template <class Body>
inline double current_separation(const Body& a, const Body& b, const ContactPointRow& p, double nx,
                                 double ny) {
  double ax = a.qc * p.rax - a.qs * p.ray, ay = a.qs * p.rax + a.qc * p.ray;
  double bx = b.qc * p.rbx - b.qs * p.rby, by = b.qs * p.rbx + b.qc * p.rby;
  double dx = (b.dpx - a.dpx) + (bx - ax);
  double dy = (b.dpy - a.dpy) + (by - ay);
  return dx * nx + dy * ny + p.base_separation;
}

// Runs fn(first, end) over [0, n) in runs of `per_chunk`, on the pool's threads if any.
template <class F>
void for_chunks(WorkerPool* pool, size_t n, size_t per_chunk, F fn) {
  const int chunks = static_cast<int>((n + per_chunk - 1) / per_chunk);
  auto chunk = [&](int i) {
    const size_t lo = static_cast<size_t>(i) * per_chunk;
    fn(lo, std::min(lo + per_chunk, n));
  };
  run_chunks(pool, chunks, chunk);
}

// A dynamic body's BodyDrive for substeps of length h (gravity gx, gy).
inline BodyDrive drive_of(const Body& b, double gx, double gy, double h) {
  BodyDrive d;
  // The tick's forces, the constant ones (forces.cpp) and gravity. Constant forces enter
  // only where present, so that bodies without them keep their bits.
  double fx = b.force.x(), fy = b.force.y(), torque = b.torque;
  if (b.constant_force != Vec2::Zero() || b.constant_torque != 0.0) {
    fx += b.constant_force.x();
    fy += b.constant_force.y();
    torque += b.constant_torque;
  }
  d.ax = b.inv_mass * fx + b.gravity_scale * gx;
  d.ay = b.inv_mass * fy + b.gravity_scale * gy;
  d.dw = h * b.inv_inertia * torque;
  d.linear_damped = b.linear_damping != 0.0;
  if (d.linear_damped) d.linear_factor = 1.0 / (1.0 + h * b.linear_damping);
  d.angular_damped = b.angular_damping != 0.0;
  if (d.angular_damped) d.angular_factor = 1.0 / (1.0 + h * b.angular_damping);
  d.dragged = b.drag != 0.0;
  d.drag = h * b.inv_mass * b.drag;
  return d;
}

// kGravityOnly when drive_of would give a body the tick's gravity_drive, bit for bit: no force
// and no torque (+0, as a tick leaves them: -0 would give a -0 term), gravity scale 1, no
// damping and no drag. Then dw is +0 (h inv_inertia +0) and ax, ay are +0 + g.
uint8_t drive_kind(const Body& b) {
  if (!b.is_dynamic()) return kNoDrive;
  const bool plain = b.force.x() == 0.0 && !std::signbit(b.force.x()) && b.force.y() == 0.0 &&
                     !std::signbit(b.force.y()) && b.torque == 0.0 && !std::signbit(b.torque) &&
                     b.constant_force == Vec2::Zero() && b.constant_torque == 0.0 &&
                     b.gravity_scale == 1.0 && b.linear_damping == 0.0 &&
                     b.angular_damping == 0.0 && b.drag == 0.0;
  return plain ? kGravityOnly : kOwnDrive;
}

// `pseudo`: the tick solves split impulses, whose pseudo velocities get an array of their own.
// Each body's drive for substeps of length h is worked out as its record is read (drive_kinds,
// and drives for the bodies with one of their own).
void load_bodies(WorldImpl& w, const std::vector<int>& awake, bool pseudo, double h,
                 SolverScratch& s, WorkerPool* pool) {
  const double gx = w.settings.gravity.x(), gy = w.settings.gravity.y();
  s.drives.resize(awake.size());
  s.drive_kinds.resize(awake.size());
  // What drive_of gives a body of zero force and torque, gravity scale 1 and no damping or drag
  // (inv_mass * +0 is +0 for any finite inverse mass).
  s.gravity_drive = BodyDrive{};
  s.gravity_drive.ax = 0.0 + gx;
  s.gravity_drive.ay = 0.0 + gy;
  s.bodies.resize(awake.size() + 1);
  s.body_extras.resize(awake.size() + 1);
  s.slot_dynamic.resize(awake.size() + 1);
  s.slot_body.resize(awake.size() + 1);
  s.centres.resize(awake.size() + 1);
  s.slot_body[0] = -1;
  s.centres[0] = SlotCentre{};
  s.bodies[0] = SolverBody{};  // the shared static body: zero velocity, infinite mass
  s.body_extras[0] = SolverBodyExtra{};
  s.slot_dynamic[0] = 0;
  if (pseudo) {
    s.pseudo.assign(awake.size() + 1, PseudoVelocity{});
  } else {
    s.pseudo.clear();
  }
  if (s.body_slot.size() < w.bodies.size()) s.body_slot.resize(w.bodies.size(), 0);
  // Each awake body writes its own slot (and body_slot entry: awake holds each body once).
  for_chunks(pool, awake.size(), 1024, [&](size_t lo, size_t hi) {
    for (size_t k = lo; k < hi; ++k) {
      // The records are cold: each is fetched a few bodies ahead, the four lines read here
      // (from the type to the drive's factors).
      if (k + kFetchAhead < hi) {
        const Body& far = w.bodies[awake[k + kFetchAhead]];
        __builtin_prefetch(&far.type);
        __builtin_prefetch(&far.center);
        __builtin_prefetch(&far.inv_inertia);
        __builtin_prefetch(&far.gravity_scale);
      }
      const Body& b = w.bodies[awake[k]];
      s.body_slot[awake[k]] = static_cast<int>(k + 1);
      s.slot_body[k + 1] = awake[k];
      s.centres[k + 1] = SlotCentre{b.center.x(), b.center.y()};
      SolverBody& sb = s.bodies[k + 1];
      sb = SolverBody{};
      sb.vx = b.v.x();
      sb.vy = b.v.y();
      sb.w = b.w;
      sb.inv_mass = b.inv_mass;
      s.slot_dynamic[k + 1] = b.inv_mass > 0.0;
      SolverBodyExtra& x = s.body_extras[k + 1];
      x = SolverBodyExtra{};
      x.inv_inertia = b.inv_inertia;
      const uint8_t kind = drive_kind(b);
      s.drive_kinds[k] = kind;
      if (kind == kOwnDrive) s.drives[k] = drive_of(b, gx, gy, h);
    }
  });
}

// The speed caps: the linear speed at max_linear_speed and the turn at half a turn per substep
// (beyond it a rotation cannot be told from the opposite one). Solved velocities stay far below
// both in any scene that holds together; the caps keep one that flies apart (joints fighting at
// huge mass ratios) finite instead of overflowing to infinity and NaN. Applied before each
// substep moves the bodies.
void cap_speeds(SolverBody& sb, double max_speed, double max_turn_rate) {
  const double speed2 = sb.vx * sb.vx + sb.vy * sb.vy;
  if (speed2 > max_speed * max_speed) {
    const double f = max_speed / std::sqrt(speed2);
    sb.vx *= f;
    sb.vy *= f;
  }
  if (sb.w * sb.w > max_turn_rate * max_turn_rate) {
    sb.w = sb.w > 0.0 ? max_turn_rate : -max_turn_rate;
  }
}

double max_turn_rate(double h) {
  return 3.14159265358979323846 / h;
}

// A slot's gathered warm start (solve_group) added to its velocity, and its row cleared. A row
// no lane wrote is zero and is left alone (adding it would turn a velocity of -0 into +0).
inline void add_warm_row(VelocityBefore& w, SolverBody& b) {
  if (w.vx == 0.0 && w.vy == 0.0 && w.w == 0.0) return;
  b.vx += w.vx;
  b.vy += w.vy;
  b.w += w.w;
  w.vx = w.vy = w.w = 0.0;
}

// Step 1: applied forces into velocities, v2 = v1 + h M^-1 F, then damping as the decay
// factor 1 / (1 + h c), which stays stable for any damping. Speeds are clamped. Attractors
// pull towards where the body is now, so they are the one term worked out every substep.
// With `warm` (not null), each body's gathered warm start is added after its forces, as
// add_gathered_warm would add it next. With `start` (not null), each body's velocity after its
// forces is kept there (SolverScratch::substep_start), and with `add_change` the change of
// velocity since it was kept a substep ago (what the constraints gave the body: solve_group) is
// added after the forces as its warm start.
// kStarts: whether `start` is given (a template argument, so that the loop of a step without it
// is the plain one).
template <bool kStarts>
void integrate_velocities_as(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s,
                             double h, size_t first, size_t end, VelocityBefore* warm,
                             VelocityBefore* start, bool add_change) {
  const double max_speed = w.settings.max_linear_speed;
  const bool attract = !w.attractors.empty();
  for (size_t k = first; k < end; ++k) {
    const uint8_t kind = s.drive_kinds[k];
    SolverBody& sb = s.bodies[k + 1];
    // The change is taken before the forces change the velocity, and added after them.
    VelocityBefore change;
    if (kStarts && add_change) {
      const VelocityBefore& then = start[k + 1];
      change.vx = sb.vx - then.vx;
      change.vy = sb.vy - then.vy;
      change.w = sb.w - then.w;
    }
    auto finish = [&] {
      if (warm != nullptr) add_warm_row(warm[k + 1], sb);
      if constexpr (kStarts) {
        start[k + 1] = VelocityBefore{sb.vx, sb.vy, sb.w, 0.0};
        if (add_change) add_warm_row(change, sb);
      }
    };
    if (kind == kNoDrive) {
      finish();
      continue;
    }
    // A body under gravity alone is not read for its drive (BodyDrive, kGravityOnly): its
    // accelerations are the tick's gravity_drive, its turn and factors none.
    const BodyDrive& d = kind == kGravityOnly ? s.gravity_drive : s.drives[k];
    double ax = d.ax, ay = d.ay;
    if (attract) {
      const Body& b = w.bodies[awake[k]];
      Vec2 pull = w.attraction(b, b.center + Vec2(sb.dpx, sb.dpy));
      ax += pull.x();
      ay += pull.y();
    }
    double vx = sb.vx + h * ax;
    double vy = sb.vy + h * ay;
    double av = sb.w + d.dw;
    if (d.linear_damped) {
      vx *= d.linear_factor;
      vy *= d.linear_factor;
    }
    if (d.angular_damped) av *= d.angular_factor;
    if (d.dragged) {
      // Quadratic drag F = -c v |v|, taken implicitly in |v| (v2 = v1 / (1 + h c |v1| / m)):
      // stable for any c, and exact at terminal velocity, where gravity and drag balance.
      double f = 1.0 / (1.0 + d.drag * std::sqrt(vx * vx + vy * vy));
      vx *= f;
      vy *= f;
    }
    double speed2 = vx * vx + vy * vy;
    if (speed2 > max_speed * max_speed) {
      double f = max_speed / std::sqrt(speed2);
      vx *= f;
      vy *= f;
    }
    sb.vx = vx;
    sb.vy = vy;
    sb.w = av;
    finish();
  }
}

void integrate_velocities(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s, double h,
                          size_t first, size_t end, VelocityBefore* warm = nullptr,
                          VelocityBefore* start = nullptr, bool add_change = false) {
  if (start != nullptr) {
    integrate_velocities_as<true>(w, awake, s, h, first, end, warm, start, add_change);
  } else {
    integrate_velocities_as<false>(w, awake, s, h, first, end, warm, nullptr, false);
  }
}

// What every row of a tick shares: the settings' softnesses and how impulses are carried over.
struct RowRule {
  Softness soft;
  Softness static_soft;  // against immovable bodies: twice as stiff
  bool rigid = false;
  bool block_solver = false;
  bool warm_starting = true;
  // Impulses are kept between ticks per world substep (budget.cpp): an island run with more
  // substeps starts from its share of them.
  bool rescale = false;
  double share = 1.0;
};

RowRule row_rule(const WorldImpl& w, double h) {
  const WorldSettings& set = w.settings;
  RowRule r;
  r.soft = make_softness(set.contact_hertz, set.contact_damping_ratio, h);
  r.static_soft = make_softness(2.0 * set.contact_hertz, set.contact_damping_ratio, h);
  r.rigid = set.contact_hertz == 0.0;
  r.block_solver = set.block_solver;
  r.warm_starting = set.warm_starting;
  r.rescale = set.substeps != w.budget.base_substeps;
  r.share = static_cast<double>(w.budget.base_substeps) / set.substeps;
  return r;
}

// The solver body slots of a contact's bodies (0, the shared static body, for a body the group
// does not solve: static or asleep).
RowBodies row_bodies(const SolverScratch& s, const Contact& c) {
  return RowBodies{solver_slot(s, c.body_a), solver_slot(s, c.body_b)};
}

// Body `body`'s centre of mass at the tick's start, from its solver slot: a row reads a Body
// only for a body in slot 0 (static or asleep), whose centre the slot cannot hold.
Vec2 centre_of(const WorldImpl& w, const SolverScratch& s, int slot, int body) {
  if (slot == 0) return w.bodies[body].center;
  return Vec2(s.centres[slot].x, s.centres[slot].y);
}

// A point's anchors crossed with the normal n = (nx, ny) and the tangent t = (ny, -nx): the
// rows' effective masses are made of them, and the lanes keep them (LanePoint).
struct AnchorCrosses {
  double rna, rnb;  // ra x n, rb x n
  double rta, rtb;  // ra x t, rb x t
};

inline AnchorCrosses anchor_crosses(const ContactPointRow& p, double nx, double ny) {
  const double tx = ny, ty = -nx;
  return {p.rax * ny - p.ray * nx, p.rbx * ny - p.rby * nx, p.rax * ty - p.ray * tx,
          p.rbx * ty - p.rby * tx};
}

// Point mp of a row between bodies a and b (their centres of mass at the tick's start), along
// the unit normal (nx, ny): what the rigid step's rows and the lanes are both prepared from.
inline __attribute__((always_inline)) ContactPointRow prepare_point(
    const RowRule& r, const ManifoldPoint& mp, Vec2 centre_a, Vec2 centre_b, const ScalarBody& a,
    const ScalarBody& b, double nx, double ny) {
  const double m = a.inv_mass + b.inv_mass;
  ContactPointRow p;
  p.rax = mp.point.x() - centre_a.x();
  p.ray = mp.point.y() - centre_a.y();
  p.rbx = mp.point.x() - centre_b.x();
  p.rby = mp.point.y() - centre_b.y();
  p.base_separation = mp.separation - ((p.rbx - p.rax) * nx + (p.rby - p.ray) * ny);
  const AnchorCrosses x = anchor_crosses(p, nx, ny);
  double kn = m + a.inv_inertia * x.rna * x.rna + b.inv_inertia * x.rnb * x.rnb;
  p.normal_mass = kn > 0.0 ? 1.0 / kn : 0.0;
  double kt = m + a.inv_inertia * x.rta * x.rta + b.inv_inertia * x.rtb * x.rtb;
  p.tangent_mass = kt > 0.0 ? 1.0 / kt : 0.0;
  p.normal_impulse = r.warm_starting ? mp.normal_impulse : 0.0;
  p.tangent_impulse = r.warm_starting ? mp.tangent_impulse : 0.0;
  if (r.rescale) {
    p.normal_impulse *= r.share;
    p.tangent_impulse *= r.share;
  }
  p.max_normal_impulse = 0.0;
  return p;
}

// Row k (contact s.contacts[k], its bodies in solver slots `slots`) for the rigid step: depends
// only on its own contact and bodies. The extra's approach speeds only for a contact with
// restitution (nothing else reads them).
void prepare_row(const WorldImpl& w, const SolverScratch& s, const RowRule& r, size_t k,
                 const RowBodies& slots, ContactRow& row, ContactRowExtra& extra) {
  const Contact& c = w.contacts[s.contacts[k]];
  const Vec2 centre_a = centre_of(w, s, slots.ia, c.body_a);
  const Vec2 centre_b = centre_of(w, s, slots.ib, c.body_b);
  extra.contact = s.contacts[k];
  extra.restitution = c.restitution;
  row.ia = slots.ia;
  row.ib = slots.ib;
  row.nx = c.manifold.normal.x();
  row.ny = c.manifold.normal.y();
  row.friction = c.friction;
  row.count = c.manifold.count;
  const ScalarBody a = scalar_body(s, row.ia);
  const ScalarBody b = scalar_body(s, row.ib);
  row.softness = (a.inv_mass == 0.0 || b.inv_mass == 0.0) ? r.static_soft : r.soft;
  const double nx = row.nx, ny = row.ny;
  const double m = a.inv_mass + b.inv_mass;
  for (int i = 0; i < row.count; ++i) {
    ContactPointRow& p = row.points[i];
    p = prepare_point(r, c.manifold.points[i], centre_a, centre_b, a, b, nx, ny);
    if (c.restitution != 0.0) extra.approach_speed[i] = normal_speed(a, b, p, nx, ny);
    extra.pseudo_impulse[i] = 0.0;
  }
  row.linear = a.inv_inertia == 0.0 && a.w == 0.0 && b.inv_inertia == 0.0 && b.w == 0.0;
  row.block = false;
  if (r.rigid && row.count == 2 && r.block_solver && !row.linear) {
    const ContactPointRow& p1 = row.points[0];
    const ContactPointRow& p2 = row.points[1];
    double rn1a = p1.rax * ny - p1.ray * nx, rn1b = p1.rbx * ny - p1.rby * nx;
    double rn2a = p2.rax * ny - p2.ray * nx, rn2b = p2.rbx * ny - p2.rby * nx;
    double k11 = m + a.inv_inertia * rn1a * rn1a + b.inv_inertia * rn1b * rn1b;
    double k22 = m + a.inv_inertia * rn2a * rn2a + b.inv_inertia * rn2b * rn2b;
    double k12 = m + a.inv_inertia * rn1a * rn2a + b.inv_inertia * rn1b * rn2b;
    double det = k11 * k22 - k12 * k12;
    // Only when K is well conditioned; otherwise the two rows are solved one by one.
    if (k11 * k11 < 1000.0 * det) {
      row.block = true;
      double inv_det = 1.0 / det;
      extra.k11 = k11;
      extra.k12 = k12;
      extra.k22 = k22;
      extra.i11 = k22 * inv_det;
      extra.i12 = -k12 * inv_det;
      extra.i22 = k11 * inv_det;
    }
  }
}

// Every row, for the rigid step (solved row by row) and the reference solver.
void prepare(WorldImpl& w, SolverScratch& s, double h, WorkerPool* pool) {
  const size_t n_rows = s.contacts.size();
  s.rows.resize(n_rows);
  s.extras.resize(n_rows);
  const RowRule r = row_rule(w, h);
  for_chunks(pool, n_rows, 256, [&](size_t lo, size_t hi) {
    for (size_t k = lo; k < hi; ++k) {
      const RowBodies slots = row_bodies(s, w.contacts[s.contacts[k]]);
      prepare_row(w, s, r, k, slots, s.rows[k], s.extras[k]);
    }
  });
  s.restitution_rows.clear();
  for (size_t k = 0; k < n_rows; ++k) {
    if (s.extras[k].restitution != 0.0) s.restitution_rows.push_back(static_cast<int>(k));
  }
}

// Row k of the soft step straight into its lane (contact_lanes.h, laid out by colour_contacts):
// the numbers prepare_row works out. The lanes' separations are left to the tick's first pass
// (solve_group), which works them out eight at a time. A lane of a one-point manifold has a
// second point that changes nothing.
void prepare_lane(const WorldImpl& w, SolverScratch& s, const RowRule& r, size_t k,
                  ColouredContacts* cc) {
  const Contact& c = w.contacts[s.contacts[k]];
  const RowBodies slots = s.row_bodies[k];
  s.row_restitution[k] = c.restitution;
  const Vec2 centre_a = centre_of(w, s, slots.ia, c.body_a);
  const Vec2 centre_b = centre_of(w, s, slots.ib, c.body_b);
  const ScalarBody a = scalar_body(s, slots.ia);
  const ScalarBody b = scalar_body(s, slots.ib);
  const int lane = cc->lane_of_row[k];
  ContactBlock& block = cc->blocks[lane / kBlockLanes];
  ContactBlockRest& rest = cc->rests[lane / kBlockLanes];
  const int l = lane % kBlockLanes;
  block.ia[l] = slots.ia;
  block.ib[l] = slots.ib;
  block.write_a[l] = a.inv_mass > 0.0;
  block.write_b[l] = b.inv_mass > 0.0;
  block.inv_inertia_a[l] = a.inv_inertia;
  block.inv_inertia_b[l] = b.inv_inertia;
  const double nx = c.manifold.normal.x(), ny = c.manifold.normal.y();
  block.nx[l] = nx;
  block.ny[l] = ny;
  block.friction[l] = c.friction;
  const int count = c.manifold.count;
  s.row_points[k] = static_cast<uint8_t>(count);
  for (int i = 0; i < 2; ++i) {
    if (i >= count) {
      clear_lane_point(&block, &rest, i, l);
      continue;
    }
    const ContactPointRow p =
        prepare_point(r, c.manifold.points[i], centre_a, centre_b, a, b, nx, ny);
    LanePoint& q = block.points[i];
    const AnchorCrosses x = anchor_crosses(p, nx, ny);
    q.rna[l] = x.rna;
    q.rnb[l] = x.rnb;
    q.rta[l] = x.rta;
    q.rtb[l] = x.rtb;
    rest.base_separation[i][l] = p.base_separation;
    q.normal_mass[l] = p.normal_mass;
    q.tangent_mass[l] = p.tangent_mass;
    q.normal_impulse[l] = p.normal_impulse;
    q.tangent_impulse[l] = p.tangent_impulse;
    rest.max_normal_impulse[i][l] = p.max_normal_impulse;
    rest.approach_speed[i][l] = c.restitution != 0.0 ? normal_speed(a, b, p, nx, ny) : 0.0;
  }
}

// Soft contacts: each row is prepared where it is used, straight into its lane
// (contact_lanes.h), restitution's approach speeds included. Coloured in id order first, from
// the rows' bodies.
void prepare_coloured(WorldImpl& w, SolverScratch& s, const std::vector<ContactBodies>& bodies,
                      double h, ColouredContacts* cc, WorkerPool* pool) {
  const size_t n_rows = s.contacts.size();
  s.row_bodies.resize(n_rows);
  s.row_points.resize(n_rows);
  s.row_restitution.resize(n_rows);
  // The rows' slots from the contacts' bodies as collide listed them: no contact record is read
  // before its row is prepared.
  for_chunks(pool, n_rows, 1024, [&](size_t lo, size_t hi) {
    for (size_t k = lo; k < hi; ++k) {
      s.row_bodies[k] = RowBodies{solver_slot(s, bodies[k].a), solver_slot(s, bodies[k].b)};
    }
  });
  colour_contacts(s.row_bodies, s.slot_dynamic, cc);
  const RowRule r = row_rule(w, h);
  for_chunks(pool, n_rows, 256, [&](size_t lo, size_t hi) {
    for (size_t k = lo; k < hi; ++k) {
      // The touching contacts are a sparse walk through the pool: each is fetched a few rows
      // ahead, the lines from its friction to its manifold's count (at most 48 bytes apart).
      if (k + kFetchAhead < hi) {
        const Contact& far = w.contacts[s.contacts[k + kFetchAhead]];
        __builtin_prefetch(&far.friction);
        __builtin_prefetch(&far.manifold.points[0].normal_impulse);
        __builtin_prefetch(&far.manifold.points[1].normal_impulse);
        __builtin_prefetch(&far.manifold.count);
      }
      prepare_lane(w, s, r, k, cc);
    }
  });
  // Restitution's rows, which prepare_lane noted.
  s.restitution_rows.clear();
  for (size_t k = 0; k < n_rows; ++k) {
    if (s.row_restitution[k] != 0.0) s.restitution_rows.push_back(static_cast<int>(k));
  }
  // The blocks restitution's approach speeds are tracked in, ascending, each once: marked, then
  // listed in block order (a scene of bouncy shapes has most of its rows here, too many to sort
  // each tick).
  cc->bounce_blocks.clear();
  if (!s.restitution_rows.empty()) {
    std::vector<uint8_t>& marks = cc->bounce_marks;
    marks.assign(cc->blocks.size(), 0);
    for (int k : s.restitution_rows) marks[cc->lane_of_row[k] / kBlockLanes] = 1;
    for (size_t b = 0; b < marks.size(); ++b) {
      if (marks[b]) cc->bounce_blocks.push_back(static_cast<int>(b));
    }
  }
}

// Restitution needs the speed of approach at impact, not at the start of the tick. Within a
// substep the relative normal acceleration a = (v1 - v0) / h is constant, so a gap s closes
// at speed sqrt(v0^2 - 2 a s) (v^2 = v0^2 + 2 a (gap - s) at gap = 0): the exact impact speed
// of the continuous motion, instead of a speed up to |a| h too slow. v0 comes from each body's
// velocity before the substep's forces, kept here for all slots at once (one pass in slot
// order), v1 from the velocities after them: the rows are read once per substep.
void record_velocities(SolverScratch& s, size_t first, size_t end) {
  for (size_t k = first; k < end; ++k) {
    const SolverBody& b = s.bodies[k];
    s.velocity_before[k] = VelocityBefore{b.vx, b.vy, b.w, 0.0};
  }
}

// The rigid step's rows (the lanes have track_approach_coloured, the same steps).
void track_approach(SolverScratch& s, double inv_h, size_t first, size_t end) {
  for (size_t r = first; r < end; ++r) {
    const int k = s.restitution_rows[r];
    const ContactRow& row = s.rows[k];
    ContactRowExtra& extra = s.extras[k];
    const SolverBody& a = s.bodies[row.ia];
    const SolverBody& b = s.bodies[row.ib];
    const VelocityBefore& a0 = s.velocity_before[row.ia];
    const VelocityBefore& b0 = s.velocity_before[row.ib];
    for (int i = 0; i < row.count; ++i) {
      const ContactPointRow& p = row.points[i];
      double v0 = normal_speed(a0, b0, p, row.nx, row.ny);
      double v1 = normal_speed(a, b, p, row.nx, row.ny);
      double gap = std::max(current_separation(a, b, p, row.nx, row.ny), 0.0);
      double accel = (v1 - v0) * inv_h;
      double impact = -std::sqrt(std::max(v0 * v0 - 2.0 * accel * gap, 0.0));
      double speed = v0 < 0.0 || accel < 0.0 ? std::min(v1, impact) : v1;
      extra.approach_speed[i] = std::min(extra.approach_speed[i], speed);
    }
  }
}

void warm_start(SolverScratch& s) {
  for (ContactRow& row : s.rows) {
    ScalarBody a = scalar_body(s, row.ia);
    ScalarBody b = scalar_body(s, row.ib);
    for (int i = 0; i < row.count; ++i) {
      const ContactPointRow& p = row.points[i];
      // P = lambda_n n + lambda_t t, with t = (ny, -nx).
      double px = p.normal_impulse * row.nx + p.tangent_impulse * row.ny;
      double py = p.normal_impulse * row.ny - p.tangent_impulse * row.nx;
      apply_impulse(a, b, p, px, py);
    }
    store_velocity(a, s.bodies[row.ia]);
    store_velocity(b, s.bodies[row.ib]);
  }
}

struct BiasRule {
  double inv_h;
  bool use_bias;     // position feedback in this pass
  bool rigid;        // rigid Baumgarte instead of soft
  bool split;        // rigid feedback goes to pseudo velocities instead
  double baumgarte;  // rigid feedback rate
  double slop;
  double max_speed;  // cap on push-out speed
};

// Rigid Baumgarte push-out at separation s: (beta / h) min(0, s + slop), capped.
inline double rigid_push(const BiasRule& r, double s) {
  return std::max(r.baumgarte * r.inv_h * std::min(0.0, s + r.slop), -r.max_speed);
}

// The bias and scales for one normal row at separation s (see the file comment).
inline void normal_bias(const BiasRule& r, const Softness& soft, double s, double* bias,
                        double* mass_scale, double* impulse_scale) {
  *mass_scale = 1.0;
  *impulse_scale = 0.0;
  if (s > 0.0) {
    *bias = s * r.inv_h;
  } else if (!r.use_bias) {
    *bias = 0.0;
  } else if (r.rigid) {
    *bias = r.split ? 0.0 : rigid_push(r, s);
  } else {
    *bias = std::max(soft.bias_rate * s, -r.max_speed);
    *mass_scale = soft.mass_scale;
    *impulse_scale = soft.impulse_scale;
  }
}

// Both normal rows of a two-point manifold as one 2x2 mixed linear complementarity problem,
// solved by enumerating its four cases (Box2D 2.x's block solver): find x >= 0 with
// v = K x + b >= 0 and x_i v_i = 0, where b is the row velocity error at zero impulse.
double solve_block(ContactRow& row, const ContactRowExtra& e, ScalarBody& a, ScalarBody& b,
                   const BiasRule& rule) {
  ContactPointRow& p1 = row.points[0];
  ContactPointRow& p2 = row.points[1];
  const double nx = row.nx, ny = row.ny;
  double bias1, bias2, ms, is;
  normal_bias(rule, row.softness, current_separation(a, b, p1, nx, ny), &bias1, &ms, &is);
  normal_bias(rule, row.softness, current_separation(a, b, p2, nx, ny), &bias2, &ms, &is);
  double a1 = p1.normal_impulse, a2 = p2.normal_impulse;
  double b1 = normal_speed(a, b, p1, nx, ny) + bias1 - (e.k11 * a1 + e.k12 * a2);
  double b2 = normal_speed(a, b, p2, nx, ny) + bias2 - (e.k12 * a1 + e.k22 * a2);
  double x1, x2;
  for (;;) {
    x1 = -(e.i11 * b1 + e.i12 * b2);  // both rows active
    x2 = -(e.i12 * b1 + e.i22 * b2);
    if (x1 >= 0.0 && x2 >= 0.0) break;
    x1 = -p1.normal_mass * b1;  // only row 1 active
    x2 = 0.0;
    if (x1 >= 0.0 && e.k12 * x1 + b2 >= 0.0) break;
    x1 = 0.0;  // only row 2 active
    x2 = -p2.normal_mass * b2;
    if (x2 >= 0.0 && e.k12 * x2 + b1 >= 0.0) break;
    x1 = x2 = 0.0;  // neither active
    if (b1 >= 0.0 && b2 >= 0.0) break;
    return 0.0;  // no case fits (rounding); leave the impulses as they are
  }
  double d1 = x1 - a1, d2 = x2 - a2;
  apply_impulse(a, b, p1, d1 * nx, d1 * ny);
  apply_impulse(a, b, p2, d2 * nx, d2 * ny);
  p1.normal_impulse = x1;
  p2.normal_impulse = x2;
  p1.max_normal_impulse = std::max(p1.max_normal_impulse, x1);
  p2.max_normal_impulse = std::max(p2.max_normal_impulse, x2);
  return std::max(std::abs(d1), std::abs(d2));
}

// A row whose bodies never turn (particles, fixed rotation, the static body): the same math
// as solve_contacts with every angular term, being zero, left out. Rotations by the identity
// are exact, so the results are bit-identical to the general path.
double solve_linear_row(ContactRow& row, ScalarBody& a, ScalarBody& b, const BiasRule& rule) {
  double largest = 0.0;
  const double nx = row.nx, ny = row.ny;
  for (int i = 0; i < row.count; ++i) {
    ContactPointRow& p = row.points[i];
    double sep = ((b.dpx - a.dpx) + (p.rbx - p.rax)) * nx +
                 ((b.dpy - a.dpy) + (p.rby - p.ray)) * ny + p.base_separation;
    double bias, mass_scale, impulse_scale;
    normal_bias(rule, row.softness, sep, &bias, &mass_scale, &impulse_scale);
    double vn = (b.vx - a.vx) * nx + (b.vy - a.vy) * ny;
    double lambda = -p.normal_mass * mass_scale * (vn + bias) - impulse_scale * p.normal_impulse;
    double acc = std::max(p.normal_impulse + lambda, 0.0);
    lambda = acc - p.normal_impulse;
    p.normal_impulse = acc;
    p.max_normal_impulse = std::max(p.max_normal_impulse, acc);
    a.vx -= a.inv_mass * (lambda * nx);
    a.vy -= a.inv_mass * (lambda * ny);
    b.vx += b.inv_mass * (lambda * nx);
    b.vy += b.inv_mass * (lambda * ny);
    largest = std::max(largest, std::abs(lambda));
  }
  const double tx = ny, ty = -nx;
  for (int i = 0; i < row.count; ++i) {
    ContactPointRow& p = row.points[i];
    double lambda = -p.tangent_mass * ((b.vx - a.vx) * tx + (b.vy - a.vy) * ty);
    double limit = row.friction * p.normal_impulse;
    double acc = std::clamp(p.tangent_impulse + lambda, -limit, limit);
    lambda = acc - p.tangent_impulse;
    p.tangent_impulse = acc;
    a.vx -= a.inv_mass * (lambda * tx);
    a.vy -= a.inv_mass * (lambda * ty);
    b.vx += b.inv_mass * (lambda * tx);
    b.vy += b.inv_mass * (lambda * ty);
    largest = std::max(largest, std::abs(lambda));
  }
  return largest;
}

// One row's pass; returns its largest corrective impulse.
double solve_contact_row(ContactRow& row, const ContactRowExtra& e, ScalarBody& a, ScalarBody& b,
                         const BiasRule& rule) {
  if (row.linear) return solve_linear_row(row, a, b, rule);
  double largest = 0.0;
  const double nx = row.nx, ny = row.ny;
  if (row.block) {
    largest = solve_block(row, e, a, b, rule);
  } else {
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      double bias, mass_scale, impulse_scale;
      normal_bias(rule, row.softness, current_separation(a, b, p, nx, ny), &bias, &mass_scale,
                  &impulse_scale);
      double vn = normal_speed(a, b, p, nx, ny);
      double lambda = -p.normal_mass * mass_scale * (vn + bias) - impulse_scale * p.normal_impulse;
      double acc = std::max(p.normal_impulse + lambda, 0.0);
      lambda = acc - p.normal_impulse;
      p.normal_impulse = acc;
      p.max_normal_impulse = std::max(p.max_normal_impulse, acc);
      apply_impulse(a, b, p, lambda * nx, lambda * ny);
      largest = std::max(largest, std::abs(lambda));
    }
  }
  // Friction along t = (ny, -nx), bounded by the normal impulses just found.
  const double tx = ny, ty = -nx;
  for (int i = 0; i < row.count; ++i) {
    ContactPointRow& p = row.points[i];
    double dvx, dvy;
    relative_velocity(a, b, p, &dvx, &dvy);
    double lambda = -p.tangent_mass * (dvx * tx + dvy * ty);
    double limit = row.friction * p.normal_impulse;
    double acc = std::clamp(p.tangent_impulse + lambda, -limit, limit);
    lambda = acc - p.tangent_impulse;
    p.tangent_impulse = acc;
    apply_impulse(a, b, p, lambda * tx, lambda * ty);
    largest = std::max(largest, std::abs(lambda));
  }
  return largest;
}

// One pass over all rows, in id order; returns the largest corrective impulse.
double solve_contacts(SolverScratch& s, const BiasRule& rule) {
  double largest = 0.0;
  const size_t n_rows = s.rows.size();
  for (size_t k = 0; k < n_rows; ++k) {
    ContactRow& row = s.rows[k];
    ScalarBody a = scalar_body(s, row.ia);
    ScalarBody b = scalar_body(s, row.ib);
    largest = std::max(largest, solve_contact_row(row, s.extras[k], a, b, rule));
    store_velocity(a, s.bodies[row.ia]);
    store_velocity(b, s.bodies[row.ib]);
  }
  return largest;
}

// Split impulses: the rigid position error is removed by impulses on pseudo velocities, which
// move bodies this substep and are then forgotten, so correction adds no momentum.
void solve_pseudo(SolverScratch& s, const BiasRule& rule) {
  const size_t n_rows = s.rows.size();
  for (size_t k = 0; k < n_rows; ++k) {
    ContactRow& row = s.rows[k];
    const SolverBody& a = s.bodies[row.ia];
    const SolverBody& b = s.bodies[row.ib];
    const double iia = s.body_extras[row.ia].inv_inertia;
    const double iib = s.body_extras[row.ib].inv_inertia;
    PseudoVelocity& xa = s.pseudo[row.ia];
    PseudoVelocity& xb = s.pseudo[row.ib];
    const double nx = row.nx, ny = row.ny;
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      double bias = rigid_push(rule, current_separation(a, b, p, nx, ny));
      double dvx = (xb.vx - xb.w * p.rby) - (xa.vx - xa.w * p.ray);
      double dvy = (xb.vy + xb.w * p.rbx) - (xa.vy + xa.w * p.rax);
      double& acc_ref = s.extras[k].pseudo_impulse[i];
      double lambda = -p.normal_mass * (dvx * nx + dvy * ny + bias);
      double acc = std::max(acc_ref + lambda, 0.0);
      lambda = acc - acc_ref;
      acc_ref = acc;
      double px = lambda * nx, py = lambda * ny;
      xa.vx -= a.inv_mass * px;
      xa.vy -= a.inv_mass * py;
      xa.w -= iia * (p.rax * py - p.ray * px);
      xb.vx += b.inv_mass * px;
      xb.vy += b.inv_mass * py;
      xb.w += iib * (p.rbx * py - p.rby * px);
    }
  }
}

// Symplectic Euler for one substep: x += h (v + v_pseudo); rotation by the exact angle.
// kAngles: add up the angles turned (SolverBodyExtra::da). kPseudo: take the pseudo
// velocities. Without them the positions get the same bits: v + 0 differs from v only for
// v = -0, whose step h v then moves nothing either way.
template <bool kAngles, bool kPseudo>
void integrate_positions_as(SolverScratch& s, double h, double max_speed, size_t first, size_t end,
                            VelocityBefore* caps) {
  const double max_turn = max_turn_rate(h);
  for (size_t k = first; k < end; ++k) {
    SolverBody& sb = s.bodies[k];
    const double vx0 = sb.vx, vy0 = sb.vy, w0 = sb.w;
    cap_speeds(sb, max_speed, max_turn);
    if (caps != nullptr) note_cap(caps[k], vx0, vy0, w0, sb.vx, sb.vy, sb.w);
    double turn;
    if constexpr (kPseudo) {
      PseudoVelocity& pv = s.pseudo[k];
      sb.dpx += h * (sb.vx + pv.vx);
      sb.dpy += h * (sb.vy + pv.vy);
      turn = h * (sb.w + pv.w);
      pv = PseudoVelocity{};
    } else {
      sb.dpx += h * sb.vx;
      sb.dpy += h * sb.vy;
      turn = h * sb.w;
    }
    if constexpr (kAngles) s.body_extras[k].da += turn;
    if (turn != 0.0) {
      // mul(Rot{cos, sin}, q).normalized(), written out component by component (the same
      // operations in the same order): reading the returned sine and cosine back from memory as
      // one vector stalls on store forwarding, on a loop every body runs every substep.
      const SinCos sc = det_sincos(turn);
      double tc = sc.cos, ts = sc.sin;
#if defined(__x86_64__)
      // Each half in its own register: GCC would otherwise reload both through the stack.
      asm("" : "+x"(tc), "+x"(ts));
#endif
      const double qc = sb.qc, qs = sb.qs;
      const double mc = tc * qc - ts * qs;
      const double ms = ts * qc + tc * qs;
      const double mag = std::sqrt(mc * mc + ms * ms);
      const double inv = mag > 0.0 ? 1.0 / mag : 0.0;
      sb.qc = mc * inv;
      sb.qs = ms * inv;
    }
  }
}

// With `caps` (per slot), what the speed caps change is noted there (note_cap).
void integrate_positions(SolverScratch& s, double h, double max_speed, size_t first, size_t end,
                         VelocityBefore* caps = nullptr) {
  const bool pseudo = !s.pseudo.empty();
  // The 2- and 4-lane paths integrate in lanes, with the same bits (contact_kernel.h); the
  // rigid solver's pseudo velocities and the scalar path take the loop above.
  if (!pseudo) {
    if (const lanes::IntegrateFn integrate = integrate_fn()) {
      const IntegrateRule rule{h, max_speed, max_turn_rate(h), caps};
      integrate(s.bodies.data(), s.track_angles ? s.body_extras.data() : nullptr, rule,
                static_cast<int>(first), static_cast<int>(end));
      return;
    }
  }
  if (s.track_angles) {
    if (pseudo) {
      integrate_positions_as<true, true>(s, h, max_speed, first, end, caps);
    } else {
      integrate_positions_as<true, false>(s, h, max_speed, first, end, caps);
    }
  } else if (pseudo) {
    integrate_positions_as<false, true>(s, h, max_speed, first, end, caps);
  } else {
    integrate_positions_as<false, false>(s, h, max_speed, first, end, caps);
  }
}

// Where point i of row k keeps its accumulated impulses during the tick: in its lane when the
// rows are coloured (null: in the row).
struct PointImpulses {
  double* normal;
  double* tangent;
  double* max_normal;
};

PointImpulses impulses_of(SolverScratch& s, ColouredContacts* lanes, size_t k, int i) {
  if (lanes == nullptr) {
    ContactPointRow& p = s.rows[k].points[i];
    return {&p.normal_impulse, &p.tangent_impulse, &p.max_normal_impulse};
  }
  const int lane = lanes->lane_of_row[k];
  LanePoint& q = lanes->blocks[lane / kBlockLanes].points[i];
  ContactBlockRest& r = lanes->rests[lane / kBlockLanes];
  const int l = lane % kBlockLanes;
  return {&q.normal_impulse[l], &q.tangent_impulse[l], &r.max_normal_impulse[i][l]};
}

// A restitution row as apply_restitution reads it: the rigid step's row, or a soft contact's
// gathered back from its lane (the same numbers).
struct BounceRow {
  ContactRow row;
  double approach_speed[2] = {0.0, 0.0};
  double restitution = 0.0;
};

BounceRow bounce_row(const SolverScratch& s, const ColouredContacts* lanes, int k) {
  BounceRow out;
  if (lanes == nullptr) {
    out.row = s.rows[k];
    out.approach_speed[0] = s.extras[k].approach_speed[0];
    out.approach_speed[1] = s.extras[k].approach_speed[1];
    out.restitution = s.extras[k].restitution;
    return out;
  }
  const int lane = lanes->lane_of_row[k];
  const ContactBlock& b = lanes->blocks[lane / kBlockLanes];
  const ContactBlockRest& rest = lanes->rests[lane / kBlockLanes];
  const int l = lane % kBlockLanes;
  ContactRow& row = out.row;
  row.ia = b.ia[l];
  row.ib = b.ib[l];
  row.count = s.row_points[k];
  row.nx = b.nx[l];
  row.ny = b.ny[l];
  for (int i = 0; i < row.count; ++i) {
    const LanePoint& q = b.points[i];
    ContactPointRow& p = row.points[i];
    // The anchors back from their cross products: r = (r . n) n + (r . t) t, with
    // r . n = -(r x t) and r . t = r x n.
    p.rax = q.rna[l] * row.ny - q.rta[l] * row.nx;
    p.ray = -q.rta[l] * row.ny - q.rna[l] * row.nx;
    p.rbx = q.rnb[l] * row.ny - q.rtb[l] * row.nx;
    p.rby = -q.rtb[l] * row.ny - q.rnb[l] * row.nx;
    p.normal_mass = q.normal_mass[l];
    out.approach_speed[i] = rest.approach_speed[i][l];
  }
  out.restitution = s.row_restitution[k];
  return out;
}

// Bounce: points that approached faster than the threshold and carried load leave with
// -e times their approach speed.
void apply_restitution(SolverScratch& s, ColouredContacts* lanes, double threshold) {
  for (int k : s.restitution_rows) {
    const BounceRow bounce = bounce_row(s, lanes, k);
    const ContactRow& row = bounce.row;
    ScalarBody a = scalar_body(s, row.ia);
    ScalarBody b = scalar_body(s, row.ib);
    for (int i = 0; i < row.count; ++i) {
      const ContactPointRow& p = row.points[i];
      const PointImpulses acc_of = impulses_of(s, lanes, k, i);
      double approach = bounce.approach_speed[i];
      if (approach > -threshold || *acc_of.max_normal == 0.0) continue;
      double vn = normal_speed(a, b, p, row.nx, row.ny);
      double lambda = -p.normal_mass * (vn + bounce.restitution * approach);
      double acc = std::max(*acc_of.normal + lambda, 0.0);
      lambda = acc - *acc_of.normal;
      *acc_of.normal = acc;
      apply_impulse(a, b, p, lambda * row.nx, lambda * row.ny);
    }
    store_velocity(a, s.bodies[row.ia]);
    store_velocity(b, s.bodies[row.ib]);
  }
}

// What the contacts keep of their points' impulses for the next tick: per world substep,
// whatever this group ran (budget.cpp).
struct ImpulseKeep {
  bool rescale;
  double per_base;
  explicit ImpulseKeep(const WorldImpl& w)
      : rescale(w.settings.substeps != w.budget.base_substeps),
        per_base(static_cast<double>(w.settings.substeps) / w.budget.base_substeps) {}
  void operator()(ManifoldPoint& p, double normal, double tangent) const {
    p.normal_impulse = normal;
    p.tangent_impulse = tangent;
    if (rescale) {
      p.normal_impulse *= per_base;
      p.tangent_impulse *= per_base;
    }
  }
};

// The rigid step's rows [first, end), in id order.
void store_impulses(WorldImpl& w, const SolverScratch& s, size_t first, size_t end) {
  const ImpulseKeep keep(w);
  // The contacts are large and cold: each is fetched a few rows ahead of its store.
  for (size_t k = first; k < end; ++k) {
    if (k + kFetchAhead < end) {
      const ManifoldPoint* far = w.contacts[s.contacts[k + kFetchAhead]].manifold.points;
      __builtin_prefetch(&far[0].normal_impulse, 1);
      __builtin_prefetch(&far[1].normal_impulse, 1);
    }
    Manifold& m = w.contacts[s.contacts[k]].manifold;
    for (int i = 0; i < m.count; ++i) {
      keep(m.points[i], s.rows[k].points[i].normal_impulse, s.rows[k].points[i].tangent_impulse);
    }
  }
}

// The coloured lanes' rows, blocks [first, end) in lane order: each lane streams out of its
// block and writes its own contact.
void store_lane_impulses(WorldImpl& w, const SolverScratch& s, const ColouredContacts& cc,
                         size_t first, size_t end) {
  const ImpulseKeep keep(w);
  const int* const row_of_lane = cc.row_of_lane.data();
  const size_t lane_end = end * kBlockLanes;
  // In lane order the contacts are scattered: each is fetched a few lanes ahead of its store.
  for (size_t lane = first * kBlockLanes; lane < lane_end; ++lane) {
    if (lane + kFetchAhead < lane_end && row_of_lane[lane + kFetchAhead] >= 0) {
      const ManifoldPoint* far =
          w.contacts[s.contacts[row_of_lane[lane + kFetchAhead]]].manifold.points;
      __builtin_prefetch(&far[0].normal_impulse, 1);
      __builtin_prefetch(&far[1].normal_impulse, 1);
    }
    const int k = row_of_lane[lane];
    if (k < 0) continue;
    const LanePoint* q = cc.blocks[lane / kBlockLanes].points;
    const size_t l = lane % kBlockLanes;
    Manifold& m = w.contacts[s.contacts[k]].manifold;
    for (int i = 0; i < s.row_points[k]; ++i) {
      keep(m.points[i], q[i].normal_impulse[l], q[i].tangent_impulse[l]);
    }
  }
}

// Moves the bodies by what the substeps accumulated.
// The velocities a tick ends with are capped too (the relax passes and restitution come after
// the last substep's cap), at a full turn per substep: a fast spin after a hard hit keeps its
// speed, and a tick that flew apart cannot feed the next one ever larger velocities.
void finalize_bodies(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s, double h,
                     size_t first, size_t end) {
  const double max_speed = w.settings.max_linear_speed;
  const double max_turn = 2.0 * max_turn_rate(h);
  // The bodies' records are cold (a walk over every awake body's since load_bodies): each is
  // fetched a few bodies ahead of its stores, its first three lines (the transform to the torque).
  for (size_t k = first; k < end; ++k) {
    if (k + kFetchAhead < end) {
      const Body& far = w.bodies[awake[k + kFetchAhead]];
      __builtin_prefetch(&far.xf, 1);
      __builtin_prefetch(&far.center, 1);
      __builtin_prefetch(&far.force, 1);
    }
    Body& b = w.bodies[awake[k]];
    SolverBody& sb = s.bodies[k + 1];
    cap_speeds(sb, max_speed, max_turn);
    b.v = Vec2(sb.vx, sb.vy);
    b.w = sb.w;
    b.center += Vec2(sb.dpx, sb.dpy);
    if (sb.qs != 0.0 || sb.qc != 1.0) b.xf.q = mul(Rot{sb.qc, sb.qs}, b.xf.q).normalized();
    b.xf.p = b.center - b.xf.q.rotate(b.local_center);
    // The applied force lasts one tick; prepare_drives read it.
    b.force = Vec2::Zero();
    b.torque = 0.0;
  }
}

// Slots [first, end): the gathered warm start added to each velocity (add_warm_row).
void add_gathered_warm(SolverScratch& s, size_t first, size_t end) {
  for (size_t i = first; i < end; ++i) add_warm_row(s.warm_next[i], s.bodies[i]);
}

}  // namespace

void WorldImpl::solve_group(const std::vector<int>& awake, const std::vector<int>& contacts_sorted,
                            const std::vector<ContactBodies>& contact_bodies) {
  SolverScratch& s = solver_scratch;
  const WorldSettings& set = settings;
  const double h = set.dt / set.substeps;
  BiasRule rule{1.0 / h,
                true,
                set.contact_hertz == 0.0,
                set.split_impulses,
                set.baumgarte,
                set.linear_slop,
                set.max_correction_speed};
  BiasRule relax = rule;
  relax.use_bias = false;

  // Many bodies to load: shared with the pool's threads (busy for the whole tick, try_step).
  WorkerPool* const loaders = pool != nullptr && awake.size() >= 4096 ? pool : nullptr;
  load_bodies(*this, awake, rule.rigid && rule.split, h, s, loaders);
  s.contacts.assign(contacts_sorted.begin(), contacts_sorted.end());
  // Soft contacts are solved colour by colour in lanes (contact_lanes.h); rigid contacts (the
  // classic settings, with the block solver and split impulses) one by one in id order.
  const bool coloured = !rule.rigid;
  prepare_joints(awake, h);
  // Threads only where a colour has chunks enough to share (see kBlocksPerChunk), or the joints
  // that are not revolute joints have groups enough (kRowsPerJointChunk).
  WorkerPool* workers =
      pool != nullptr &&
              ((coloured && s.contacts.size() >= 256) || coloured_points.points >= 256 ||
               coloured_points.revolutes.joints >= 256 || !coloured_points.chunk_start.empty())
          ? pool
          : nullptr;
  if (coloured) {
    prepare_coloured(*this, s, contact_bodies, h, &coloured_contacts, workers);
  } else {
    prepare(*this, s, h, workers);
  }
  LaneRule lane_solve;
  lane_solve.inv_h = 1.0 / h;
  lane_solve.max_speed = set.max_correction_speed;
  lane_solve.track_max = !s.restitution_rows.empty();
  lane_solve.want_largest = set.early_exit_tolerance > 0.0;
  lane_solve.soft = make_softness(set.contact_hertz, set.contact_damping_ratio, h);
  lane_solve.static_soft = make_softness(2.0 * set.contact_hertz, set.contact_damping_ratio, h);
  LaneRule lane_relax = lane_solve;
  lane_relax.use_bias = false;
  auto contact_pass = [&](const BiasRule& r, const LaneRule& lr) {
    return coloured ? solve_coloured(coloured_contacts, s.bodies.data(), lr, workers)
                    : solve_contacts(s, r);
  };
  if (!s.restitution_rows.empty()) s.velocity_before.resize(s.bodies.size());
  // The lanes' separations at the tick's start: the first pass works them out as it goes, and
  // restitution, which reads them before that pass, has its blocks' worked out here.
  if (coloured && !s.restitution_rows.empty()) {
    bounce_separations(coloured_contacts, s.bodies.data(), workers);
  }
  // The next substep's warm start (the contacts' lanes and the plain pins') is gathered by the
  // last relax pass of a substep, which has every lane's final impulse in hand, into one row per
  // solver slot, and added to the velocities where the warm-start passes came: the same
  // impulses at the same anchors (nothing moves between the two), one pass fewer a substep.
  // Only when that pass is surely the last (no early exit). The rows are zero between uses.
  const bool gather_warm = !rule.rigid && set.relax_iterations > 0 &&
                           !(set.early_exit_tolerance > 0.0) && set.substeps > 1;
  // With contacts alone (no joint, no restitution), the impulses need not be gathered at all: a
  // substep's contacts give each body exactly the change of velocity J^T lambda their final
  // impulses make (the warm start applied the impulses they started from, every pass the change
  // since, all at anchors fixed for the tick), so the next warm start is each body's velocity at
  // the substep's end less its velocity after the substep's forces, less what the speed caps took
  // (integrate_velocities, integrate_positions). Not with joints: their anchors turn with the
  // bodies within the tick, so their impulses act at other anchors before and after a substep's
  // motion. Nor with restitution, which reads the velocities between the forces and the warm
  // start.
  const bool change_warm = gather_warm && s.joints.empty() && s.restitution_rows.empty();
  if (gather_warm && !change_warm && s.warm_next.size() < s.bodies.size()) {
    s.warm_next.resize(s.bodies.size());
  }
  if (change_warm && s.substep_start.size() < s.bodies.size()) {
    s.substep_start.resize(s.bodies.size());
  }
  VelocityBefore* const starts = change_warm ? s.substep_start.data() : nullptr;
  bool gathered_warm = false;
  for (int sub = 0; sub < set.substeps; ++sub) {
    if (!s.restitution_rows.empty()) {
      for_chunks(workers, s.bodies.size(), 1024,
                 [&](size_t lo, size_t hi) { record_velocities(s, lo, hi); });
    }
    // Applied forces, all from the state at the substep's start (explicit), then constraints.
    apply_spring_forces(h);
    // The gathered warm start goes in with the forces, unless restitution reads the velocities
    // between the two (track_approach).
    const bool warm_with_forces = gathered_warm && s.restitution_rows.empty();
    VelocityBefore* const warm_rows =
        warm_with_forces && !change_warm ? s.warm_next.data() : nullptr;
    for_chunks(workers, awake.size(), 256, [&](size_t lo, size_t hi) {
      integrate_velocities(*this, awake, s, h, lo, hi, warm_rows, starts, gathered_warm);
    });
    if (coloured && !s.restitution_rows.empty()) {
      track_approach_coloured(coloured_contacts, s.bodies.data(), s.velocity_before.data(), 1.0 / h,
                              workers);
    } else {
      for_chunks(workers, s.restitution_rows.size(), 256,
                 [&](size_t lo, size_t hi) { track_approach(s, 1.0 / h, lo, hi); });
    }
    // Later substeps always start from the impulses of the one before.
    if (set.warm_starting || sub > 0) {
      if (gathered_warm) {  // the pins' and the contacts' lanes: gathered by the last relax pass
        if (!warm_with_forces) {
          for_chunks(workers, s.bodies.size(), 1024,
                     [&](size_t lo, size_t hi) { add_gathered_warm(s, lo, hi); });
        }
        warm_start_joints(workers, false);
      } else {
        warm_start_joints(workers);
        if (coloured) {
          warm_start_coloured(coloured_contacts, s.bodies.data(), workers);
        } else {
          warm_start(s);
        }
      }
    }
    for (int it = 0; it < set.velocity_iterations; ++it) {
      solve_joints(true, workers, nullptr,
                   PointMassUse::velocity(sub, it, set.velocity_iterations, set.relax_iterations));
      lane_solve.refresh_separation = sub == 0 && it == 0;
      if (contact_pass(rule, lane_solve) < set.early_exit_tolerance) break;
    }
    if (rule.rigid && rule.split) {
      for (int it = 0; it < set.position_iterations; ++it) solve_pseudo(s, rule);
    }
    // Solver slots 1..n hold the awake bodies (0 is the shared static body).
    for_chunks(workers, awake.size(), 256, [&](size_t lo, size_t hi) {
      integrate_positions(s, h, set.max_linear_speed, lo + 1, hi + 1, starts);
    });
    // The bodies moved: the first relax pass refreshes the lanes' separations as it goes.
    if (coloured && set.relax_iterations == 0) {
      update_separations(coloured_contacts, s.bodies.data(), workers);
    }
    gathered_warm = gather_warm && sub + 1 < set.substeps;
    for (int it = 0; it < set.relax_iterations; ++it) {
      VelocityBefore* const warm_next =
          gathered_warm && !change_warm && it + 1 == set.relax_iterations ? s.warm_next.data()
                                                                          : nullptr;
      solve_joints(false, workers, warm_next,
                   PointMassUse::relax(sub, it, set.substeps, set.velocity_iterations,
                                       set.relax_iterations));
      lane_relax.refresh_separation = it == 0;
      lane_relax.warm_next = warm_next;
      if (contact_pass(relax, lane_relax) < set.early_exit_tolerance) break;
    }
  }
  store_joint_impulses(workers);
  ColouredContacts* lanes = coloured ? &coloured_contacts : nullptr;
  apply_restitution(s, lanes, set.restitution_threshold);
  // Each row writes its own contact, each body its own record.
  if (coloured) {
    for_chunks(workers, coloured_contacts.blocks.size(), 32, [&](size_t lo, size_t hi) {
      store_lane_impulses(*this, s, coloured_contacts, lo, hi);
    });
  } else {
    for_chunks(workers, s.contacts.size(), 256,
               [&](size_t lo, size_t hi) { store_impulses(*this, s, lo, hi); });
  }
  for_chunks(workers, awake.size(), 256,
             [&](size_t lo, size_t hi) { finalize_bodies(*this, awake, s, h, lo, hi); });
}

void WorldImpl::prepare_reference_tick() {
  events = StepEvents{};
  ++step_stamp;
  update_pairs();
  collide();
  std::vector<int>& awake = scratch_awake;
  awake.assign(awake_bodies.begin(), awake_bodies.end());
  std::sort(awake.begin(), awake.end());

  SolverScratch& s = solver_scratch;
  const double h = settings.dt;
  budget.base_substeps = settings.substeps;         // impulses as kept, not rescaled
  load_bodies(*this, awake, false, h, s, nullptr);  // the reference solver moves no body
  s.contacts.assign(touching_contacts.begin(), touching_contacts.end());
  prepare(*this, s, h, nullptr);
  prepare_joints(awake, h, true);
  apply_spring_forces(h);
  integrate_velocities(*this, awake, s, h, 0, awake.size());
}

}  // namespace fulcrum
