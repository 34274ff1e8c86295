// The reference solver (fulcrum/reference.h): one tick's rows, built from the same contact
// manifolds and joint anchors as the step (WorldImpl::prepare_reference_tick), solved to a
// residual of 1e-10 N s.
//
// Rows. Every row is in the common form of constraint_row.h: a Jacobian J over two bodies,
// a bias, bounds, and for friction the normal row whose impulse bounds it. A = J M^-1 J^T is
// symmetric positive semidefinite (singular when rows are redundant, e.g. two contact points
// and two friction rows on a box's three degrees of freedom).
//
// Method.
// - Equality rows only (joints without limits or motors): A lambda = -(J v0 + bias), one
//   sparse LDLT factorization (Eigen SimplicialLDLT, AMD ordering).
// - With bounds (contacts, friction, limits, motors): projected Gauss-Seidel on the same rows
//   (the talk's iteration, cold started, in the engine's row order), which for fixed friction
//   bounds is coordinate descent on the convex quadratic 1/2 lambda^T A lambda + b^T lambda
//   over a box and converges for any positive semidefinite A (Luo and Tseng 1992); the
//   friction bounds +-mu lambda_n follow the normal impulses as a fixed-point iteration, as in
//   the step. Every 20 sweeps (at doubling intervals while it fails) an active-set polish:
//   the rows are split into free, held at a bound and slipping (friction at +-mu lambda_n,
//   coupled to its normal row) as the iterate presses them, the free rows are solved exactly
//   (sparse LDLT, or sparse LU when slipping rows make the system unsymmetric), and the set is
//   corrected up to 8 times (block principal pivoting), keeping the best projected result.
//   Once the active set is found this lands on the solution to rounding, where plain
//   Gauss-Seidel would need a number of sweeps growing with the square of the stack height.
// - Singular systems: when a factorization meets a pivot below 1e-12 of the largest, the
//   system is solved by iterated regularization (proximal point): x += (A + eps I)^-1 (rhs -
//   A x) with eps = 1e-8 of A's largest diagonal entry, which converges to an exact solution
//   of the unregularized, consistent system (eps only picks which of the many impulse
//   distributions is returned; the velocities are the same for all). ReferenceSolution says so.
//
// The residual is measured on velocities recomputed from the impulses from scratch
// (v = v0 + M^-1 J^T lambda), never on the incrementally updated ones.
#include "fulcrum/reference.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "constraint_row.h"
#include "fulcrum/state.h"
#include "joint_solver.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct RefRow {
  int a = 0, b = 0;  // solver body slots
  RowJacobian j;
  double bias = 0.0;
  double lo = -kInf, hi = kInf;
  int normal = -1;  // friction: the row of the normal impulse that bounds it
  double mu = 0.0;
  double mass = 0.0;  // 1 / (J M^-1 J^T)
  ReferenceRowKind kind = ReferenceRowKind::kEquality;
};

struct Problem {
  std::vector<ScalarBody> v0;  // velocities after the applied forces, masses
  std::vector<RefRow> rows;
  bool bounded = false;  // any row with finite bounds
};

Status unsupported(const WorldImpl& w, int ji, const std::string& what) {
  JointId id = w.joint_id(ji);
  return Status(StatusCode::kFailedPrecondition,
                "joint {" + std::to_string(id.index) + ", " + std::to_string(id.generation) +
                    "}: the reference solver does not model " + what);
}

class RowBuilder {
 public:
  RowBuilder(Problem* p, double dt) : p_(p), inv_dt_(1.0 / dt) {}

  // Adds a row unless it cannot move anything; returns its index or -1.
  int add(int a, int b, const RowJacobian& j, double bias, double lo, double hi) {
    double m = effective_mass(j, p_->v0[a], p_->v0[b]);
    if (m == 0.0) return -1;
    RefRow r;
    r.a = a;
    r.b = b;
    r.j = j;
    r.bias = bias;
    r.lo = lo;
    r.hi = hi;
    r.mass = m;
    r.kind = std::isfinite(lo) || std::isfinite(hi) ? ReferenceRowKind::kBounded
                                                    : ReferenceRowKind::kEquality;
    p_->rows.push_back(r);
    if (std::isfinite(lo) || std::isfinite(hi)) p_->bounded = true;
    return static_cast<int>(p_->rows.size()) - 1;
  }
  // An equality row: J v = 0 whatever the drift (no position feedback).
  int equality(int a, int b, const RowJacobian& j) { return add(a, b, j, 0.0, -kInf, kInf); }
  // An inequality C >= 0 along j: speculative (gap / dt) while C > 0, J v >= 0 once reached.
  int limit(int a, int b, const RowJacobian& j, double c) {
    return add(a, b, j, c > 0.0 ? c * inv_dt_ : 0.0, 0.0, kInf);
  }

 private:
  Problem* p_;
  double inv_dt_;
};

RowJacobian negated(const RowJacobian& j) {
  return RowJacobian{-j.linear_a, -j.angular_a, -j.linear_b, -j.angular_b};
}

Status build_joint_rows(const WorldImpl& w, const JointRow& r, RowBuilder& rb,
                        ReferenceSolution* out, const Problem& p) {
  const Joint& j = w.joints[r.joint];
  const double dt = w.settings.dt;
  const ScalarBody& a = p.v0[r.ia];
  const ScalarBody& b = p.v0[r.ib];
  const bool turns = a.inv_inertia + b.inv_inertia > 0.0;
  const Vec2 ra(r.rax, r.ray), rbv(r.rbx, r.rby);
  const Vec2 d = Vec2(r.dcx, r.dcy) + rbv - ra;  // anchor B minus anchor A, tick start
  const Vec2 ex(1.0, 0.0), ey(0.0, 1.0);
  auto count = [](int row, int* counter) {
    if (row >= 0) ++*counter;
  };
  auto point_rows = [&] {
    count(rb.equality(r.ia, r.ib, axis_jacobian(ex, ra, rbv)), &out->equality_rows);
    count(rb.equality(r.ia, r.ib, axis_jacobian(ey, ra, rbv)), &out->equality_rows);
  };
  switch (j.type) {
    case JointType::kRevolute: {
      if (j.enable_spring) return unsupported(w, r.joint, "revolute joint springs");
      if (j.enable_motor && turns) {
        double limit = j.max_motor_torque * dt;
        count(rb.add(r.ia, r.ib, angle_jacobian(), -j.motor_speed, -limit, limit),
              &out->bounded_rows);
      }
      if (j.enable_limit && turns) {
        count(rb.limit(r.ia, r.ib, angle_jacobian(), r.angle - j.lower_angle), &out->bounded_rows);
        count(rb.limit(r.ia, r.ib, negated(angle_jacobian()), j.upper_angle - r.angle),
              &out->bounded_rows);
      }
      point_rows();
      return {};
    }
    case JointType::kWeld: {
      if (j.hertz > 0.0 || j.angular_hertz > 0.0) return unsupported(w, r.joint, "weld springs");
      if (turns) count(rb.equality(r.ia, r.ib, angle_jacobian()), &out->equality_rows);
      point_rows();
      return {};
    }
    case JointType::kDistance: {
      double len = length(d);
      Vec2 u = len < 1e-12 ? ex : Vec2(d / len);
      RowJacobian ju = axis_jacobian(u, ra, rbv);
      if (j.min_length == j.max_length) {
        count(rb.equality(r.ia, r.ib, ju), &out->equality_rows);
        return {};
      }
      if (j.hertz > 0.0) return unsupported(w, r.joint, "distance joint springs");
      if (j.min_length > 0.0)
        count(rb.limit(r.ia, r.ib, ju, len - j.min_length), &out->bounded_rows);
      count(rb.limit(r.ia, r.ib, negated(ju), j.max_length - len), &out->bounded_rows);
      return {};
    }
    case JointType::kPrismatic: {
      if (j.enable_spring && j.hertz > 0.0) return unsupported(w, r.joint, "prismatic springs");
      const Vec2 u(r.axis_x, r.axis_y), perp(-r.axis_y, r.axis_x);
      const Vec2 da = d + ra;
      RowJacobian axial{-u, -cross(da, u), u, cross(rbv, u)};
      RowJacobian line{-perp, -cross(da, perp), perp, cross(rbv, perp)};
      const double t = dot(u, d);
      if (j.enable_motor) {
        double limit = j.max_motor_force * dt;
        count(rb.add(r.ia, r.ib, axial, -j.motor_speed, -limit, limit), &out->bounded_rows);
      }
      if (j.enable_limit) {
        count(rb.limit(r.ia, r.ib, axial, t - j.lower_angle), &out->bounded_rows);
        count(rb.limit(r.ia, r.ib, negated(axial), j.upper_angle - t), &out->bounded_rows);
      }
      count(rb.equality(r.ia, r.ib, line), &out->equality_rows);
      if (turns) count(rb.equality(r.ia, r.ib, angle_jacobian()), &out->equality_rows);
      return {};
    }
    case JointType::kWheel:
      return unsupported(w, r.joint, "wheel joints");
    case JointType::kMotor:
      return unsupported(w, r.joint, "motor joints");
    case JointType::kTarget:
      return unsupported(w, r.joint, "target joints");
    case JointType::kCurve:
      return unsupported(w, r.joint, "curve joints");
    case JointType::kSpring:
      return {};  // a force, already in v0
  }
  return {};
}

// Rows of the tick prepared in `w` (after prepare_reference_tick), in the engine's order:
// joints, then per contact its normal rows and its friction rows.
Status build_problem(const WorldImpl& w, Problem* p, ReferenceSolution* out) {
  const SolverScratch& s = w.solver_scratch;
  const WorldSettings& set = w.settings;
  const double dt = set.dt, inv_dt = 1.0 / dt;
  p->v0.resize(s.bodies.size());
  for (size_t k = 0; k < s.bodies.size(); ++k)
    p->v0[k] = scalar_body(s.bodies[k], s.body_extras[k]);
  RowBuilder rb(p, dt);
  for (const JointRow& r : s.joint_rows) {
    FULCRUM_RETURN_IF_ERROR(build_joint_rows(w, r, rb, out, *p));
  }
  for (const ContactRow& row : s.rows) {
    const Vec2 n(row.nx, row.ny), t(row.ny, -row.nx);
    int normal[2] = {-1, -1};
    for (int i = 0; i < row.count; ++i) {
      const ContactPointRow& pt = row.points[i];
      const Vec2 ra(pt.rax, pt.ray), rbv(pt.rbx, pt.rby);
      const double sep = dot(rbv - ra, n) + pt.base_separation;
      const double bias = sep > 0.0 ? sep * inv_dt : 0.0;
      normal[i] = rb.add(row.ia, row.ib, axis_jacobian(n, ra, rbv), bias, 0.0, kInf);
      if (normal[i] < 0) continue;
      p->rows[normal[i]].kind = ReferenceRowKind::kNormal;
      ++out->normal_rows;
    }
    for (int i = 0; i < row.count; ++i) {
      if (normal[i] < 0 || row.friction == 0.0) continue;
      const ContactPointRow& pt = row.points[i];
      int k = rb.add(row.ia, row.ib, axis_jacobian(t, Vec2(pt.rax, pt.ray), Vec2(pt.rbx, pt.rby)),
                     0.0, 0.0, 0.0);
      if (k < 0) continue;
      p->rows[k].normal = normal[i];
      p->rows[k].mu = row.friction;
      p->rows[k].kind = ReferenceRowKind::kFriction;
      ++out->friction_rows;
    }
  }
  return {};
}

// --- The solver --------------------------------------------------------------------------------

class Solver {
 public:
  Solver(const Problem& p, double tolerance)
      : p_(p), tolerance_(tolerance), lambda_(p.rows.size(), 0.0), v_(p.v0) {}

  const std::vector<ScalarBody>& velocities() const { return v_; }
  const std::vector<double>& impulses() const { return lambda_; }
  int sweeps = 0;
  int direct_solves = 0;
  bool regularized = false;

  void bounds(size_t i, const std::vector<double>& lam, double* lo, double* hi) const {
    const RefRow& r = p_.rows[i];
    if (r.normal >= 0) {
      *hi = r.mu * std::max(lam[r.normal], 0.0);
      *lo = -*hi;
    } else {
      *lo = r.lo;
      *hi = r.hi;
    }
  }

  // One projected Gauss-Seidel sweep over all rows.
  void sweep() {
    for (size_t i = 0; i < p_.rows.size(); ++i) {
      const RefRow& r = p_.rows[i];
      double lo, hi;
      bounds(i, lambda_, &lo, &hi);
      double w = row_velocity(r.j, v_[r.a], v_[r.b]) + r.bias;
      double next = std::clamp(lambda_[i] - r.mass * w, lo, hi);
      apply_row_impulse(r.j, next - lambda_[i], v_[r.a], v_[r.b]);
      lambda_[i] = next;
    }
    ++sweeps;
  }

  // v = v0 + M^-1 J^T lambda from scratch, then the residual (reference.h).
  double refresh() { return refresh(lambda_, &v_); }

  double refresh(const std::vector<double>& lam, std::vector<ScalarBody>* v) const {
    *v = p_.v0;
    for (size_t i = 0; i < p_.rows.size(); ++i) {
      const RefRow& r = p_.rows[i];
      if (lam[i] != 0.0) apply_row_impulse(r.j, lam[i], (*v)[r.a], (*v)[r.b]);
    }
    double worst = 0.0;
    for (size_t i = 0; i < p_.rows.size(); ++i) {
      const RefRow& r = p_.rows[i];
      double lo, hi;
      bounds(i, lam, &lo, &hi);
      double w = row_velocity(r.j, (*v)[r.a], (*v)[r.b]) + r.bias;
      worst = std::max(worst, std::abs(lam[i] - std::clamp(lam[i] - r.mass * w, lo, hi)));
    }
    return worst;
  }

  // Active-set polishing. Each row is free (its equation J v + bias = 0 holds), held at a
  // bound, or, for friction at its bound, slipping (lambda_t = +-mu lambda_n, following its
  // normal row). Starting from the set the iterate presses, the free rows are solved exactly
  // given the others; rows whose solution leaves its bounds are then held at the bound they
  // crossed, held rows the velocities would pull inside are freed, and the solve repeats until
  // the set stops changing (block principal pivoting, Judice and Pires 1994), at most
  // kPivots times. The result is projected onto the bounds. Returns its residual; keeps it if
  // `keep_if_better` is false or it beats `current`.
  double polish(double current, bool keep_if_better) {
    constexpr int kPivots = 8;
    const size_t n = p_.rows.size();
    std::vector<double> lam = lambda_;
    std::vector<ScalarBody> v = v_;
    std::vector<int> state(n, kFree);  // kFree, kHeld or kSlip
    std::vector<double> held(n, 0.0), slip(n, 0.0);
    // The set the iterate presses.
    for (size_t i = 0; i < n; ++i) classify(i, lam, v, &state, &held, &slip);
    // The projected result of each pivot; the best one is kept.
    std::vector<double> best_lam;
    std::vector<ScalarBody> best_v;
    double best = std::numeric_limits<double>::infinity();
    for (int pivot = 0; pivot < kPivots; ++pivot) {
      solve_set(state, held, slip, &lam);
      refresh(lam, &v);
      ++direct_solves;
      std::vector<double> projected = lam;
      for (int pass = 0; pass < 2; ++pass) {  // bounded rows, then friction against them
        for (size_t i = 0; i < n; ++i) {
          if ((p_.rows[i].normal >= 0) != (pass == 1)) continue;
          double lo, hi;
          bounds(i, projected, &lo, &hi);
          projected[i] = std::clamp(projected[i], lo, hi);
        }
      }
      std::vector<ScalarBody> pv;
      double res = refresh(projected, &pv);
      if (res < best) {
        best = res;
        best_lam = std::move(projected);
        best_v = std::move(pv);
      }
      bool changed = false;
      for (size_t i = 0; i < n; ++i) {
        const RefRow& r = p_.rows[i];
        double lo, hi;
        bounds(i, lam, &lo, &hi);
        if (state[i] == kFree) {
          // Friction bounds move with the normal impulse: compare with the bounds of the
          // solution itself.
          if (lam[i] < lo || lam[i] > hi) {
            if (r.normal >= 0 && hi > 0.0) {
              state[i] = kSlip;
              slip[i] = lam[i] < lo ? -1.0 : 1.0;
            } else {
              state[i] = kHeld;
              held[i] = lam[i] < lo ? lo : hi;
            }
            changed = true;
          }
        } else {
          double w = row_velocity(r.j, v[r.a], v[r.b]) + r.bias;
          double trial = lam[i] - r.mass * w;
          if (trial > lo && trial < hi) {
            state[i] = kFree;
            changed = true;
          }
        }
      }
      if (!changed || best <= tolerance_) break;
    }
    double res = best;
    lam = std::move(best_lam);
    v = std::move(best_v);
    if (!keep_if_better || res < current) {
      lambda_ = std::move(lam);
      v_ = std::move(v);
      return res;
    }
    return current;
  }

 private:
  enum { kFree = 0, kHeld = 1, kSlip = 2 };

  // Row i's state from the impulses and velocities: free when the unclamped update lands
  // strictly inside its bounds, else held at (friction: slipping along) the bound it presses.
  void classify(size_t i, const std::vector<double>& lam, const std::vector<ScalarBody>& v,
                std::vector<int>* state, std::vector<double>* held,
                std::vector<double>* slip) const {
    const RefRow& r = p_.rows[i];
    double lo, hi;
    bounds(i, lam, &lo, &hi);
    double w = row_velocity(r.j, v[r.a], v[r.b]) + r.bias;
    double trial = lam[i] - r.mass * w;
    if (trial > lo && trial < hi) {
      (*state)[i] = kFree;
    } else if (r.normal >= 0 && hi > 0.0) {
      (*state)[i] = kSlip;
      (*slip)[i] = trial <= lo ? -1.0 : 1.0;
    } else {
      (*state)[i] = kHeld;
      (*held)[i] = trial <= lo ? lo : hi;
    }
  }

  // The impulses of one active set: held rows at their values, the free rows solved, slipping
  // rows at +-mu times their normal row (held at 0 when that row is not free).
  void solve_set(const std::vector<int>& state, const std::vector<double>& held,
                 const std::vector<double>& slip_in, std::vector<double>* lam) {
    const size_t n = p_.rows.size();
    std::vector<int> free_index(n, -1);
    std::vector<int> free_rows;
    std::vector<double> slip(n, 0.0);
    for (size_t i = 0; i < n; ++i) {
      if (state[i] == kFree) {
        free_index[i] = static_cast<int>(free_rows.size());
        free_rows.push_back(static_cast<int>(i));
      }
    }
    for (size_t i = 0; i < n; ++i) {
      (*lam)[i] = 0.0;
      if (state[i] == kHeld) (*lam)[i] = held[i];
      if (state[i] == kSlip && free_index[p_.rows[i].normal] >= 0) slip[i] = slip_in[i];
    }
    if (free_rows.empty()) return;
    std::vector<ScalarBody> v;
    refresh(*lam, &v);
    const int m = static_cast<int>(free_rows.size());
    Eigen::VectorXd rhs(m);
    for (int k = 0; k < m; ++k) {
      const RefRow& r = p_.rows[free_rows[k]];
      rhs[k] = -(row_velocity(r.j, v[r.a], v[r.b]) + r.bias);
    }
    Eigen::VectorXd x = solve_free(free_index, free_rows, slip, rhs);
    for (int k = 0; k < m; ++k) (*lam)[free_rows[k]] = x[k];
    for (size_t i = 0; i < n; ++i) {
      if (slip[i] != 0.0) (*lam)[i] = slip[i] * p_.rows[i].mu * (*lam)[p_.rows[i].normal];
    }
  }

  // K x = rhs over the free rows: equation i, unknown k, K_ik = A_ik (A_ij = J_i M^-1 J_j^T
  // summed over the bodies they share), plus s mu A_it for each slipping friction row t bound
  // to normal row k. Symmetric (LDLT) without slipping rows, else LU.
  Eigen::VectorXd solve_free(const std::vector<int>& free_index, const std::vector<int>& free_rows,
                             const std::vector<double>& slip, const Eigen::VectorXd& rhs) {
    const int m = static_cast<int>(free_rows.size());
    // Rows by body (slot 0, the static body, has no mass and couples nothing): the free rows
    // and the slipping ones.
    std::vector<std::vector<int>> by_body(p_.v0.size());
    bool coupled = false;
    for (size_t i = 0; i < p_.rows.size(); ++i) {
      if (free_index[i] < 0 && slip[i] == 0.0) continue;
      coupled = coupled || slip[i] != 0.0;
      const RefRow& r = p_.rows[i];
      if (r.a != 0) by_body[r.a].push_back(static_cast<int>(i));
      if (r.b != 0 && r.b != r.a) by_body[r.b].push_back(static_cast<int>(i));
    }
    auto part = [](const RefRow& r, size_t body, Vec2* l, double* w) {
      const bool on_a = r.a == static_cast<int>(body);
      *l = on_a ? r.j.linear_a : r.j.linear_b;
      *w = on_a ? r.j.angular_a : r.j.angular_b;
    };
    std::vector<Eigen::Triplet<double>> triplets;
    for (size_t body = 1; body < by_body.size(); ++body) {
      const ScalarBody& sb = p_.v0[body];
      for (int i1 : by_body[body]) {
        if (free_index[i1] < 0) continue;  // slipping rows are no equations
        const RefRow& r1 = p_.rows[i1];
        Vec2 l1;
        double w1;
        part(r1, body, &l1, &w1);
        for (int i2 : by_body[body]) {
          const RefRow& r2 = p_.rows[i2];
          Vec2 l2;
          double w2;
          part(r2, body, &l2, &w2);
          double aij = sb.inv_mass * dot(l1, l2) + sb.inv_inertia * w1 * w2;
          if (free_index[i2] >= 0) {
            triplets.emplace_back(free_index[i1], free_index[i2], aij);
          } else {
            triplets.emplace_back(free_index[i1], free_index[r2.normal], slip[i2] * r2.mu * aij);
          }
        }
      }
    }
    Eigen::SparseMatrix<double> k(m, m);
    k.setFromTriplets(triplets.begin(), triplets.end());
    double max_diag = 0.0;
    for (int i = 0; i < m; ++i) max_diag = std::max(max_diag, std::abs(k.coeff(i, i)));

    if (!coupled) {
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(k);
      if (ldlt.info() == Eigen::Success) {
        const Eigen::VectorXd& dvec = ldlt.vectorD();
        double dmax = dvec.cwiseAbs().maxCoeff();
        if (dvec.minCoeff() > 1e-12 * dmax) {
          Eigen::VectorXd x = ldlt.solve(rhs);
          x += ldlt.solve(rhs - k * x);  // one step of iterative refinement
          return x;
        }
      }
    } else {
      k.makeCompressed();
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(k);
      if (lu.info() == Eigen::Success) {
        Eigen::VectorXd x = lu.solve(rhs);
        if (lu.info() == Eigen::Success && x.allFinite()) {
          x += lu.solve(rhs - k * x);
          if (x.allFinite() && (rhs - k * x).cwiseAbs().maxCoeff() <=
                                   1e-12 * std::max(1.0, rhs.cwiseAbs().maxCoeff())) {
            return x;
          }
        }
      }
    }
    // Singular (redundant rows): iterated regularization, see the file comment.
    regularized = true;
    Eigen::SparseMatrix<double> shifted = k;
    const double eps = 1e-8 * max_diag;
    for (int i = 0; i < m; ++i) shifted.coeffRef(i, i) += eps;
    shifted.makeCompressed();
    Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
    auto iterate = [&](auto& factor) {
      if (factor.info() != Eigen::Success) return;
      for (int it = 0; it < 60; ++it) {
        Eigen::VectorXd r = rhs - k * x;
        if (r.cwiseAbs().maxCoeff() <= 1e-15 * std::max(1.0, rhs.cwiseAbs().maxCoeff())) break;
        x += factor.solve(r);
      }
    };
    if (!coupled) {
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> reg(shifted);
      iterate(reg);
    } else {
      Eigen::SparseLU<Eigen::SparseMatrix<double>> reg(shifted);
      iterate(reg);
    }
    if (!x.allFinite()) x.setZero();
    return x;
  }

  const Problem& p_;
  double tolerance_;
  std::vector<double> lambda_;
  std::vector<ScalarBody> v_;
};

Result<ReferenceSolution> solve_prepared(World& copy, const ReferenceOptions& opt) {
  if (!(opt.tolerance > 0.0)) return invalid_argument("options.tolerance: must be > 0");
  if (opt.max_iterations < 1) return invalid_argument("options.max_iterations: must be >= 1");
  WorldImpl& w = copy.impl();
  w.prepare_reference_tick();
  ReferenceSolution out;
  Problem p;
  FULCRUM_RETURN_IF_ERROR(build_problem(w, &p, &out));

  Solver solver(p, opt.tolerance);
  double res = solver.refresh();
  if (!p.bounded) {
    out.method = "sparse LDLT";
    for (int k = 0; k < 3 && res > opt.tolerance; ++k) res = solver.polish(res, false);
  } else {
    out.method = "projected Gauss-Seidel + active-set LDLT";
    // Sweeps between checks; the polishing is tried at each check and, while it fails to
    // halve the residual, at checks ever further apart (its factorizations cost far more than
    // a sweep).
    constexpr int kCheckEvery = 20;
    int polish_every = 1, checks = 0;
    while (res > opt.tolerance && solver.sweeps < opt.max_iterations) {
      for (int k = 0; k < kCheckEvery && solver.sweeps < opt.max_iterations; ++k) solver.sweep();
      res = solver.refresh();
      if (++checks % polish_every != 0) continue;
      double before = res;
      res = solver.polish(res, true);
      polish_every = res < 0.5 * before ? 1 : std::min(2 * polish_every, 1024);
    }
  }
  out.residual = res;
  out.converged = res <= opt.tolerance;
  out.iterations = solver.sweeps;
  out.direct_solves = solver.direct_solves;
  out.regularized = solver.regularized;
  const std::vector<ScalarBody>& v = solver.velocities();
  const std::vector<int>& awake = w.scratch_awake;
  auto body_at = [&](int slot) { return slot == 0 ? BodyId{} : w.body_id(awake[slot - 1]); };
  for (size_t i = 0; i < p.rows.size(); ++i) {
    const RefRow& r = p.rows[i];
    out.impulses.push_back(
        ReferenceImpulse{r.kind, body_at(r.a), body_at(r.b), solver.impulses()[i]});
  }
  for (size_t k = 0; k < awake.size(); ++k) {
    out.bodies.push_back(w.body_id(awake[k]));
    out.linear_velocity.emplace_back(v[k + 1].vx, v[k + 1].vy);
    out.angular_velocity.push_back(v[k + 1].w);
  }
  return out;
}

Result<World> copy_of(const World& world) {
  World copy(world.settings());
  FULCRUM_RETURN_IF_ERROR(copy.restore(world.snapshot()));
  return copy;
}

}  // namespace

Result<ReferenceSolution> solve_reference(const World& world, const ReferenceOptions& options) {
  Result<World> copy = copy_of(world);
  if (!copy.ok()) return copy.status();
  return solve_prepared(*copy, options);
}

Result<VelocityError> velocity_error(const ReferenceSolution& reference, const World& stepped) {
  VelocityError e;
  double sum_v = 0.0, sum_w = 0.0;
  for (size_t k = 0; k < reference.bodies.size(); ++k) {
    Result<BodyState> s = stepped.body_state(reference.bodies[k]);
    if (!s.ok()) return s.status().with_prefix("stepped: ");
    double dv = length(s->linear_velocity - reference.linear_velocity[k]);
    double dw = std::abs(s->angular_velocity - reference.angular_velocity[k]);
    e.max_linear = std::max(e.max_linear, dv);
    e.max_angular = std::max(e.max_angular, dw);
    sum_v += dv * dv;
    sum_w += dw * dw;
    ++e.bodies;
  }
  if (e.bodies > 0) {
    e.rms_linear = std::sqrt(sum_v / e.bodies);
    e.rms_angular = std::sqrt(sum_w / e.bodies);
  }
  return e;
}

Result<SettingError> setting_velocity_error(const World& world, const WorldSettings& settings,
                                            const ReferenceOptions& options) {
  WorldSettings s = settings;
  s.enable_sleep = false;
  FULCRUM_RETURN_IF_ERROR(validate_settings(s).with_prefix("settings: "));
  Result<World> stepped = copy_of(world);
  if (!stepped.ok()) return stepped.status();
  FULCRUM_RETURN_IF_ERROR(stepped->set_settings(s));
  Result<World> ref_world = copy_of(*stepped);
  if (!ref_world.ok()) return ref_world.status();
  Result<ReferenceSolution> ref = solve_prepared(*ref_world, options);
  if (!ref.ok()) return ref.status();
  stepped->step();
  Result<VelocityError> e = velocity_error(*ref, *stepped);
  if (!e.ok()) return e.status();
  return SettingError{std::move(ref).value(), *e};
}

}  // namespace fulcrum
