// The sequential-impulse step for contacts (Catto, "Modeling and Solving Constraints", GDC
// 2009; "Iterative Dynamics with Temporal Coherence", 2005; "Solver2D", 2024).
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
//   integrate velocities -> warm start -> solve (with feedback) -> integrate positions
//   -> relax (without feedback),
// then restitution and store impulses. The separation is updated every pass from the bodies'
// motion since the tick began, with the anchors held fixed (no new collision per substep).
#include <algorithm>
#include <cmath>

#include "fulcrum/trig.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

Softness make_softness(double hertz, double zeta, double h) {
  if (hertz == 0.0) return Softness{};
  double omega = 2.0 * kPi * hertz;
  double a1 = 2.0 * zeta + h * omega;
  double a2 = h * omega * a1;
  double a3 = 1.0 / (1.0 + a2);
  return Softness{omega / a1, a2 * a3, a3};
}

inline Vec2 relative_velocity(const SolverBody& a, const SolverBody& b, const ContactPointRow& p) {
  return b.v + cross(b.w, p.rb) - a.v - cross(a.w, p.ra);
}

inline void apply_impulse(SolverBody& a, SolverBody& b, const ContactPointRow& p, const Vec2& P) {
  a.v -= a.inv_mass * P;
  a.w -= a.inv_inertia * cross(p.ra, P);
  b.v += b.inv_mass * P;
  b.w += b.inv_inertia * cross(p.rb, P);
}

// Separation now, from the bodies' motion since the tick began.
inline double current_separation(const SolverBody& a, const SolverBody& b, const ContactPointRow& p,
                                 const Vec2& n) {
  Vec2 d = (b.dp - a.dp) + (b.dq.rotate(p.rb) - a.dq.rotate(p.ra));
  return dot(d, n) + p.base_separation;
}

// Gathers the awake, touching, solid contacts in id order.
void gather_contacts(WorldImpl& w, const std::vector<int>& awake, std::vector<int>* out) {
  out->clear();
  for (int bi : awake) {
    for (int e = w.bodies[bi].contact_list; e != kNullIndex;) {
      int ci = edge_contact(e);
      const Contact& c = w.contacts[ci];
      int other = edge_side(e) == 0 ? c.body_b : c.body_a;
      // Take each contact once: from its lower-indexed awake body.
      bool other_first = w.bodies[other].awake && other < bi;
      if (c.touching && !c.sensor && !other_first) out->push_back(ci);
      e = c.edges[edge_side(e)].next;
    }
  }
  std::sort(out->begin(), out->end());
}

void load_bodies(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s) {
  s.bodies.resize(awake.size() + 1);
  s.bodies[0] = SolverBody{};  // the shared static body: zero velocity, infinite mass
  if (s.body_slot.size() < w.bodies.size()) s.body_slot.resize(w.bodies.size(), 0);
  for (size_t k = 0; k < awake.size(); ++k) {
    const Body& b = w.bodies[awake[k]];
    s.body_slot[awake[k]] = static_cast<int>(k + 1);
    SolverBody& sb = s.bodies[k + 1];
    sb = SolverBody{};
    sb.v = b.v;
    sb.w = b.w;
    sb.inv_mass = b.inv_mass;
    sb.inv_inertia = b.inv_inertia;
  }
}

// Step 1: applied forces into velocities, v2 = v1 + h M^-1 F, then damping as the decay
// factor 1 / (1 + h c), which stays stable for any damping.
void integrate_velocities(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s, double h) {
  const Vec2 g = w.settings.gravity;
  const double max_speed = w.settings.max_linear_speed;
  for (size_t k = 0; k < awake.size(); ++k) {
    const Body& b = w.bodies[awake[k]];
    if (!b.is_dynamic()) continue;
    SolverBody& sb = s.bodies[k + 1];
    Vec2 v = sb.v + h * (b.inv_mass * b.force + b.gravity_scale * g);
    double av = sb.w + h * b.inv_inertia * b.torque;
    if (b.linear_damping != 0.0) v *= 1.0 / (1.0 + h * b.linear_damping);
    if (b.angular_damping != 0.0) av *= 1.0 / (1.0 + h * b.angular_damping);
    double speed2 = length_squared(v);
    if (speed2 > max_speed * max_speed) v *= max_speed / std::sqrt(speed2);
    sb.v = v;
    sb.w = av;
  }
}

void prepare(WorldImpl& w, SolverScratch& s, double h) {
  const WorldSettings& set = w.settings;
  const Softness soft = make_softness(set.contact_hertz, set.contact_damping_ratio, h);
  // Contacts against immovable bodies take the push-out alone: twice as stiff.
  const Softness static_soft = make_softness(2.0 * set.contact_hertz, set.contact_damping_ratio, h);
  const bool rigid = set.contact_hertz == 0.0;
  s.rows.resize(s.contacts.size());
  for (size_t k = 0; k < s.contacts.size(); ++k) {
    const Contact& c = w.contacts[s.contacts[k]];
    const Body& body_a = w.bodies[c.body_a];
    const Body& body_b = w.bodies[c.body_b];
    ContactRow& row = s.rows[k];
    row.contact = s.contacts[k];
    row.ia = body_a.awake ? s.body_slot[c.body_a] : 0;
    row.ib = body_b.awake ? s.body_slot[c.body_b] : 0;
    row.normal = c.manifold.normal;
    row.friction = c.friction;
    row.restitution = c.restitution;
    row.count = c.manifold.count;
    const SolverBody& a = s.bodies[row.ia];
    const SolverBody& b = s.bodies[row.ib];
    row.softness = (a.inv_mass == 0.0 || b.inv_mass == 0.0) ? static_soft : soft;
    const Vec2 n = row.normal;
    const Vec2 t = right_perp(n);
    for (int i = 0; i < row.count; ++i) {
      const ManifoldPoint& mp = c.manifold.points[i];
      ContactPointRow& p = row.points[i];
      p.ra = mp.point - body_a.center;
      p.rb = mp.point - body_b.center;
      p.base_separation = mp.separation - dot(p.rb - p.ra, n);
      double rna = cross(p.ra, n), rnb = cross(p.rb, n);
      double kn = a.inv_mass + b.inv_mass + a.inv_inertia * rna * rna + b.inv_inertia * rnb * rnb;
      p.normal_mass = kn > 0.0 ? 1.0 / kn : 0.0;
      double rta = cross(p.ra, t), rtb = cross(p.rb, t);
      double kt = a.inv_mass + b.inv_mass + a.inv_inertia * rta * rta + b.inv_inertia * rtb * rtb;
      p.tangent_mass = kt > 0.0 ? 1.0 / kt : 0.0;
      p.approach_speed = dot(relative_velocity(a, b, p), n);
      p.normal_impulse = set.warm_starting ? mp.normal_impulse : 0.0;
      p.tangent_impulse = set.warm_starting ? mp.tangent_impulse : 0.0;
      p.pseudo_impulse = 0.0;
      p.max_normal_impulse = 0.0;
    }
    row.block = false;
    if (rigid && row.count == 2 && set.block_solver) {
      const ContactPointRow& p1 = row.points[0];
      const ContactPointRow& p2 = row.points[1];
      double rn1a = cross(p1.ra, n), rn1b = cross(p1.rb, n);
      double rn2a = cross(p2.ra, n), rn2b = cross(p2.rb, n);
      double m = a.inv_mass + b.inv_mass;
      double k11 = m + a.inv_inertia * rn1a * rn1a + b.inv_inertia * rn1b * rn1b;
      double k22 = m + a.inv_inertia * rn2a * rn2a + b.inv_inertia * rn2b * rn2b;
      double k12 = m + a.inv_inertia * rn1a * rn2a + b.inv_inertia * rn1b * rn2b;
      double det = k11 * k22 - k12 * k12;
      // Only when K is well conditioned; otherwise the two rows are solved one by one.
      if (k11 * k11 < 1000.0 * det) {
        row.block = true;
        row.k << k11, k12, k12, k22;
        double inv_det = 1.0 / det;
        row.k_inverse << k22 * inv_det, -k12 * inv_det, -k12 * inv_det, k11 * inv_det;
      }
    }
  }
}

// Restitution needs the speed of approach at impact, not at the start of the tick. Within a
// substep the relative normal acceleration a = (v1 - v0) / h is constant, so a gap s closes
// at speed sqrt(v0^2 - 2 a s) (v^2 = v0^2 + 2 a (gap - s) at gap = 0): the exact impact speed
// of the continuous motion, instead of a speed up to |a| h too slow.
void record_speed_before(SolverScratch& s) {
  for (ContactRow& row : s.rows) {
    if (row.restitution == 0.0) continue;
    const SolverBody& a = s.bodies[row.ia];
    const SolverBody& b = s.bodies[row.ib];
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      p.speed_before = dot(relative_velocity(a, b, p), row.normal);
    }
  }
}

void track_approach(SolverScratch& s, double inv_h) {
  for (ContactRow& row : s.rows) {
    if (row.restitution == 0.0) continue;
    const SolverBody& a = s.bodies[row.ia];
    const SolverBody& b = s.bodies[row.ib];
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      double v0 = p.speed_before;
      double v1 = dot(relative_velocity(a, b, p), row.normal);
      double gap = std::max(current_separation(a, b, p, row.normal), 0.0);
      double accel = (v1 - v0) * inv_h;
      double impact = -std::sqrt(std::max(v0 * v0 - 2.0 * accel * gap, 0.0));
      double speed = v0 < 0.0 || accel < 0.0 ? std::min(v1, impact) : v1;
      p.approach_speed = std::min(p.approach_speed, speed);
    }
  }
}

void warm_start(SolverScratch& s) {
  for (ContactRow& row : s.rows) {
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    const Vec2 t = right_perp(row.normal);
    for (int i = 0; i < row.count; ++i) {
      const ContactPointRow& p = row.points[i];
      apply_impulse(a, b, p, p.normal_impulse * row.normal + p.tangent_impulse * t);
    }
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
    *bias =
        r.split ? 0.0 : std::max(r.baumgarte * r.inv_h * std::min(0.0, s + r.slop), -r.max_speed);
  } else {
    *bias = std::max(soft.bias_rate * s, -r.max_speed);
    *mass_scale = soft.mass_scale;
    *impulse_scale = soft.impulse_scale;
  }
}

// Both normal rows of a two-point manifold as one 2x2 mixed linear complementarity problem,
// solved by enumerating its four cases (Box2D 2.x's block solver): find x >= 0 with
// v = K x + b >= 0 and x_i v_i = 0, where b is the row velocity error at zero impulse.
double solve_block(ContactRow& row, SolverBody& a, SolverBody& b, const BiasRule& rule) {
  ContactPointRow& p1 = row.points[0];
  ContactPointRow& p2 = row.points[1];
  const Vec2 n = row.normal;
  double bias1, bias2, ms, is;
  normal_bias(rule, row.softness, current_separation(a, b, p1, n), &bias1, &ms, &is);
  normal_bias(rule, row.softness, current_separation(a, b, p2, n), &bias2, &ms, &is);
  Vec2 acc(p1.normal_impulse, p2.normal_impulse);
  Vec2 vn(dot(relative_velocity(a, b, p1), n) + bias1, dot(relative_velocity(a, b, p2), n) + bias2);
  Vec2 rhs = vn - row.k * acc;
  Vec2 x;
  for (;;) {
    x = -(row.k_inverse * rhs);  // both rows active
    if (x.x() >= 0.0 && x.y() >= 0.0) break;
    x = Vec2(-p1.normal_mass * rhs.x(), 0.0);  // only row 1 active
    if (x.x() >= 0.0 && row.k(1, 0) * x.x() + rhs.y() >= 0.0) break;
    x = Vec2(0.0, -p2.normal_mass * rhs.y());  // only row 2 active
    if (x.y() >= 0.0 && row.k(0, 1) * x.y() + rhs.x() >= 0.0) break;
    x = Vec2::Zero();  // neither active
    if (rhs.x() >= 0.0 && rhs.y() >= 0.0) break;
    return 0.0;  // no case fits (rounding); leave the impulses as they are
  }
  Vec2 d = x - acc;
  apply_impulse(a, b, p1, d.x() * n);
  apply_impulse(a, b, p2, d.y() * n);
  p1.normal_impulse = x.x();
  p2.normal_impulse = x.y();
  p1.max_normal_impulse = std::max(p1.max_normal_impulse, x.x());
  p2.max_normal_impulse = std::max(p2.max_normal_impulse, x.y());
  return std::max(std::abs(d.x()), std::abs(d.y()));
}

// One pass over all rows; returns the largest corrective impulse.
double solve_contacts(SolverScratch& s, const BiasRule& rule) {
  double largest = 0.0;
  for (ContactRow& row : s.rows) {
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    const Vec2 n = row.normal;
    if (row.block) {
      largest = std::max(largest, solve_block(row, a, b, rule));
    } else {
      for (int i = 0; i < row.count; ++i) {
        ContactPointRow& p = row.points[i];
        double bias, mass_scale, impulse_scale;
        normal_bias(rule, row.softness, current_separation(a, b, p, n), &bias, &mass_scale,
                    &impulse_scale);
        double vn = dot(relative_velocity(a, b, p), n);
        double lambda =
            -p.normal_mass * mass_scale * (vn + bias) - impulse_scale * p.normal_impulse;
        double acc = std::max(p.normal_impulse + lambda, 0.0);
        lambda = acc - p.normal_impulse;
        p.normal_impulse = acc;
        p.max_normal_impulse = std::max(p.max_normal_impulse, acc);
        apply_impulse(a, b, p, lambda * n);
        largest = std::max(largest, std::abs(lambda));
      }
    }
    // Friction, bounded by the normal impulses just found.
    const Vec2 t = right_perp(n);
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      double lambda = -p.tangent_mass * dot(relative_velocity(a, b, p), t);
      double limit = row.friction * p.normal_impulse;
      double acc = std::clamp(p.tangent_impulse + lambda, -limit, limit);
      lambda = acc - p.tangent_impulse;
      p.tangent_impulse = acc;
      apply_impulse(a, b, p, lambda * t);
      largest = std::max(largest, std::abs(lambda));
    }
  }
  return largest;
}

// Split impulses: the rigid position error is removed by impulses on pseudo velocities, which
// move bodies this substep and are then forgotten, so correction adds no momentum.
void solve_pseudo(SolverScratch& s, const BiasRule& rule) {
  for (ContactRow& row : s.rows) {
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    const Vec2 n = row.normal;
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      double sep = current_separation(a, b, p, n);
      double bias =
          std::max(rule.baumgarte * rule.inv_h * std::min(0.0, sep + rule.slop), -rule.max_speed);
      Vec2 dv = b.pv + cross(b.pw, p.rb) - a.pv - cross(a.pw, p.ra);
      double lambda = -p.normal_mass * (dot(dv, n) + bias);
      double acc = std::max(p.pseudo_impulse + lambda, 0.0);
      lambda = acc - p.pseudo_impulse;
      p.pseudo_impulse = acc;
      Vec2 P = lambda * n;
      a.pv -= a.inv_mass * P;
      a.pw -= a.inv_inertia * cross(p.ra, P);
      b.pv += b.inv_mass * P;
      b.pw += b.inv_inertia * cross(p.rb, P);
    }
  }
}

// Symplectic Euler for one substep: x += h (v + v_pseudo); rotation by the exact angle.
void integrate_positions(SolverScratch& s, double h) {
  for (size_t k = 1; k < s.bodies.size(); ++k) {
    SolverBody& sb = s.bodies[k];
    sb.dp += h * (sb.v + sb.pv);
    double turn = h * (sb.w + sb.pw);
    if (turn != 0.0) {
      SinCos sc = det_sincos(turn);
      sb.dq = mul(Rot{sc.cos, sc.sin}, sb.dq).normalized();
    }
    sb.pv = Vec2::Zero();
    sb.pw = 0.0;
  }
}

// Bounce: points that approached faster than the threshold and carried load leave with
// -e times their approach speed.
void apply_restitution(SolverScratch& s, double threshold) {
  for (ContactRow& row : s.rows) {
    if (row.restitution == 0.0) continue;
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      if (p.approach_speed > -threshold || p.max_normal_impulse == 0.0) continue;
      double vn = dot(relative_velocity(a, b, p), row.normal);
      double lambda = -p.normal_mass * (vn + row.restitution * p.approach_speed);
      double acc = std::max(p.normal_impulse + lambda, 0.0);
      lambda = acc - p.normal_impulse;
      p.normal_impulse = acc;
      apply_impulse(a, b, p, lambda * row.normal);
    }
  }
}

void store_impulses(WorldImpl& w, const SolverScratch& s) {
  for (const ContactRow& row : s.rows) {
    Manifold& m = w.contacts[row.contact].manifold;
    for (int i = 0; i < row.count; ++i) {
      m.points[i].normal_impulse = row.points[i].normal_impulse;
      m.points[i].tangent_impulse = row.points[i].tangent_impulse;
    }
  }
}

// Moves the bodies by what the substeps accumulated.
void finalize_bodies(WorldImpl& w, const std::vector<int>& awake, const SolverScratch& s) {
  for (size_t k = 0; k < awake.size(); ++k) {
    Body& b = w.bodies[awake[k]];
    const SolverBody& sb = s.bodies[k + 1];
    b.v = sb.v;
    b.w = sb.w;
    b.center += sb.dp;
    if (sb.dq.s != 0.0 || sb.dq.c != 1.0) b.xf.q = mul(sb.dq, b.xf.q).normalized();
    b.xf.p = b.center - b.xf.q.rotate(b.local_center);
  }
}

}  // namespace

void WorldImpl::solve(const std::vector<int>& awake) {
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

  load_bodies(*this, awake, s);
  gather_contacts(*this, awake, &s.contacts);
  prepare(*this, s, h);
  for (int sub = 0; sub < set.substeps; ++sub) {
    record_speed_before(s);
    integrate_velocities(*this, awake, s, h);
    track_approach(s, 1.0 / h);
    // Later substeps always start from the impulses of the one before.
    if (set.warm_starting || sub > 0) warm_start(s);
    for (int it = 0; it < set.velocity_iterations; ++it) {
      if (solve_contacts(s, rule) < set.early_exit_tolerance) break;
    }
    if (rule.rigid && rule.split) {
      for (int it = 0; it < set.position_iterations; ++it) solve_pseudo(s, rule);
    }
    integrate_positions(s, h);
    for (int it = 0; it < set.relax_iterations; ++it) {
      if (solve_contacts(s, relax) < set.early_exit_tolerance) break;
    }
  }
  apply_restitution(s, set.restitution_threshold);
  store_impulses(*this, s);
  finalize_bodies(*this, awake, s);
}

}  // namespace fulcrum
