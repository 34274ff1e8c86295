// The soft contact rows of contact_solver.cpp, written once over a lane type V: `double` (one
// contact at a time) or a GCC/Clang vector of 2 or 4 doubles (that many contacts per
// instruction). Each lane performs exactly the operations of the scalar path, in the same
// order: +, -, * and comparisons only, selections written as comparisons (max(a, b) is
// a < b ? b : a for every V), never a fused multiply-add (the engine builds with
// -ffp-contract=off, and no file here enables FMA). So every V gives the same bits.
//
// Included by contact_kernel.cpp (scalar and 2 lanes, the target's baseline: SSE2 or NEON)
// and contact_kernel_x4.cpp (4 lanes, built for AVX2 on x86-64). Everything here has internal
// linkage, so that the two files' copies, built for different instruction sets, never merge.
//
// Loops of a fixed count (lanes, rows, points, lines fetched ahead) carry `#pragma GCC unroll`
// (clang takes it too): GCC 12 at -O2 keeps them as loops, and with them their arrays of row
// pointers and rows on the stack instead of in registers (docs/performance.md, "Lanes").
#pragma once

#include <cmath>
#include <cstddef>
#include <cstring>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "contact_lanes.h"
#include "fulcrum/trig.h"
#include "trig_kernel.h"

#define FULCRUM_LANE_INLINE inline __attribute__((always_inline))

namespace fulcrum {
namespace {

typedef double F64x2 __attribute__((vector_size(16)));
#ifdef FULCRUM_CONTACT_LANES4
typedef double F64x4 __attribute__((vector_size(32)));
#endif

// Lane<V>: loads, stores, and the transposed access to body rows. load_rows reads four
// doubles at rows[l] for each lane l and returns them as four vectors (element j of every
// lane); store_rows does the reverse, skipping lanes whose row pointer is null.
template <class V>
struct Lane;

template <>
struct Lane<double> {
  static constexpr int kCount = 1;
  static FULCRUM_LANE_INLINE double splat(double x) { return x; }
  static FULCRUM_LANE_INLINE double load(const double* p) { return *p; }
  static FULCRUM_LANE_INLINE void store(double* p, double v) { *p = v; }
  static FULCRUM_LANE_INLINE double get(double v, int) { return v; }
  static FULCRUM_LANE_INLINE double sqrt(double v) { return std::sqrt(v); }
  static FULCRUM_LANE_INLINE void load_rows(const double* const* rows, double out[4]) {
    std::memcpy(out, rows[0], 4 * sizeof(double));
  }
  static FULCRUM_LANE_INLINE void store_rows(const double in[4], double* const* rows) {
    std::memcpy(rows[0], in, 4 * sizeof(double));
  }
};

template <>
struct Lane<F64x2> {
  static constexpr int kCount = 2;
  static FULCRUM_LANE_INLINE F64x2 splat(double x) { return F64x2{x, x}; }
  static FULCRUM_LANE_INLINE F64x2 load(const double* p) {
    F64x2 v;
    std::memcpy(&v, p, sizeof v);
    return v;
  }
  static FULCRUM_LANE_INLINE void store(double* p, F64x2 v) { std::memcpy(p, &v, sizeof v); }
  // Square roots are correctly rounded in every instruction set: one instruction where there
  // is one, lane by lane elsewhere.
  static FULCRUM_LANE_INLINE F64x2 sqrt(F64x2 v) {
#if defined(__SSE2__)
    return _mm_sqrt_pd(v);
#else
    return F64x2{std::sqrt(v[0]), std::sqrt(v[1])};
#endif
  }
  static FULCRUM_LANE_INLINE double get(F64x2 v, int l) {
    return v[l];
  }
  static FULCRUM_LANE_INLINE void load_rows(const double* const* rows, F64x2 out[4]) {
    F64x2 a01 = load(rows[0]), a23 = load(rows[0] + 2);
    F64x2 b01 = load(rows[1]), b23 = load(rows[1] + 2);
    out[0] = __builtin_shufflevector(a01, b01, 0, 2);
    out[1] = __builtin_shufflevector(a01, b01, 1, 3);
    out[2] = __builtin_shufflevector(a23, b23, 0, 2);
    out[3] = __builtin_shufflevector(a23, b23, 1, 3);
  }
  static FULCRUM_LANE_INLINE void store_rows(const F64x2 in[4], double* const* rows) {
    F64x2 r0 = __builtin_shufflevector(in[0], in[1], 0, 2);  // lane 0: elements 0, 1
    F64x2 r1 = __builtin_shufflevector(in[2], in[3], 0, 2);  // lane 0: elements 2, 3
    F64x2 s0 = __builtin_shufflevector(in[0], in[1], 1, 3);  // lane 1
    F64x2 s1 = __builtin_shufflevector(in[2], in[3], 1, 3);
    store(rows[0], r0);
    store(rows[0] + 2, r1);
    store(rows[1], s0);
    store(rows[1] + 2, s1);
  }
};

#ifdef FULCRUM_CONTACT_LANES4  // only in contact_kernel_x4.cpp: wide vectors change the ABI
// Four rows of four doubles, transposed (an involution).
FULCRUM_LANE_INLINE void transpose4(F64x4 r0, F64x4 r1, F64x4 r2, F64x4 r3, F64x4 out[4]) {
  F64x4 t0 = __builtin_shufflevector(r0, r1, 0, 4, 2, 6);
  F64x4 t1 = __builtin_shufflevector(r0, r1, 1, 5, 3, 7);
  F64x4 t2 = __builtin_shufflevector(r2, r3, 0, 4, 2, 6);
  F64x4 t3 = __builtin_shufflevector(r2, r3, 1, 5, 3, 7);
  out[0] = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
  out[1] = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
  out[2] = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
  out[3] = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
}

FULCRUM_LANE_INLINE F64x4 load4(const double* p) {
  F64x4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

template <>
struct Lane<F64x4> {
  static constexpr int kCount = 4;
  static FULCRUM_LANE_INLINE F64x4 splat(double x) { return F64x4{x, x, x, x}; }
  static FULCRUM_LANE_INLINE F64x4 load(const double* p) { return load4(p); }
  static FULCRUM_LANE_INLINE void store(double* p, F64x4 v) { std::memcpy(p, &v, sizeof v); }
  static FULCRUM_LANE_INLINE F64x4 sqrt(F64x4 v) {
#if defined(__AVX__)
    return _mm256_sqrt_pd(v);
#else
    return F64x4{std::sqrt(v[0]), std::sqrt(v[1]), std::sqrt(v[2]), std::sqrt(v[3])};
#endif
  }
  static FULCRUM_LANE_INLINE double get(F64x4 v, int l) {
    return v[l];
  }
  static FULCRUM_LANE_INLINE void load_rows(const double* const* rows, F64x4 out[4]) {
    transpose4(load4(rows[0]), load4(rows[1]), load4(rows[2]), load4(rows[3]), out);
  }
  static FULCRUM_LANE_INLINE void store_rows(const F64x4 in[4], double* const* rows) {
    F64x4 out[4];
    transpose4(in[0], in[1], in[2], in[3], out);
#pragma GCC unroll 4
    for (int l = 0; l < 4; ++l) store(rows[l], out[l]);
  }
};

#endif

// Two groups of lanes as one: every operation is done on both halves, whose dependency chains
// are independent, so the processor runs them side by side (a pass is bound by the latency of
// each lane's chain of rows, not by arithmetic). Each lane's operations are unchanged. A vector
// type twice as wide would do the same on paper, but GCC 12 lowers its selections to scalar code.
template <class H>
struct LanePair {
  H lo, hi;
};
template <class M>
struct MaskPair {
  M lo, hi;
};
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator+(LanePair<H> a, LanePair<H> b) {
  return {a.lo + b.lo, a.hi + b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator-(LanePair<H> a, LanePair<H> b) {
  return {a.lo - b.lo, a.hi - b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator*(LanePair<H> a, LanePair<H> b) {
  return {a.lo * b.lo, a.hi * b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator/(LanePair<H> a, LanePair<H> b) {
  return {a.lo / b.lo, a.hi / b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator-(LanePair<H> a) {
  return {-a.lo, -a.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H>& operator+=(LanePair<H>& a, LanePair<H> b) {
  return a = a + b;
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H>& operator-=(LanePair<H>& a, LanePair<H> b) {
  return a = a - b;
}
template <class H>
FULCRUM_LANE_INLINE auto operator<(LanePair<H> a, LanePair<H> b) {
  return MaskPair<decltype(a.lo < b.lo)>{a.lo < b.lo, a.hi < b.hi};
}
template <class H>
FULCRUM_LANE_INLINE auto operator>(LanePair<H> a, LanePair<H> b) {
  return MaskPair<decltype(a.lo > b.lo)>{a.lo > b.lo, a.hi > b.hi};
}
template <class H>
FULCRUM_LANE_INLINE auto operator==(LanePair<H> a, LanePair<H> b) {
  return MaskPair<decltype(a.lo == b.lo)>{a.lo == b.lo, a.hi == b.hi};
}
template <class H>
FULCRUM_LANE_INLINE auto operator!=(LanePair<H> a, LanePair<H> b) {
  return MaskPair<decltype(a.lo != b.lo)>{a.lo != b.lo, a.hi != b.hi};
}
// A number with each lane, as the vector types take it (trig_kernel.h's polynomials).
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator+(double a, LanePair<H> b) {
  return {a + b.lo, a + b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator-(double a, LanePair<H> b) {
  return {a - b.lo, a - b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator*(double a, LanePair<H> b) {
  return {a * b.lo, a * b.hi};
}
template <class H>
FULCRUM_LANE_INLINE LanePair<H> operator*(LanePair<H> a, double b) {
  return {a.lo * b, a.hi * b};
}
template <class M>
FULCRUM_LANE_INLINE MaskPair<M> operator|(MaskPair<M> a, MaskPair<M> b) {
  return {a.lo | b.lo, a.hi | b.hi};
}
template <class M, class H>
FULCRUM_LANE_INLINE LanePair<H> lane_select(MaskPair<M> m, LanePair<H> a, LanePair<H> b) {
  return {m.lo ? a.lo : b.lo, m.hi ? a.hi : b.hi};
}

template <class H>
struct Lane<LanePair<H>> {
  using V = LanePair<H>;
  using Half = Lane<H>;
  static constexpr int kCount = 2 * Half::kCount;
  static FULCRUM_LANE_INLINE V splat(double x) { return {Half::splat(x), Half::splat(x)}; }
  static FULCRUM_LANE_INLINE V load(const double* p) {
    return {Half::load(p), Half::load(p + Half::kCount)};
  }
  static FULCRUM_LANE_INLINE void store(double* p, V v) {
    Half::store(p, v.lo);
    Half::store(p + Half::kCount, v.hi);
  }
  static FULCRUM_LANE_INLINE double get(V v, int l) {
    return l < Half::kCount ? Half::get(v.lo, l) : Half::get(v.hi, l - Half::kCount);
  }
  static FULCRUM_LANE_INLINE V sqrt(V v) { return {Half::sqrt(v.lo), Half::sqrt(v.hi)}; }
  static FULCRUM_LANE_INLINE void load_rows(const double* const* rows, V out[4]) {
    H lo[4], hi[4];
    Half::load_rows(rows, lo);
    Half::load_rows(rows + Half::kCount, hi);
#pragma GCC unroll 4
    for (int j = 0; j < 4; ++j) out[j] = {lo[j], hi[j]};
  }
  static FULCRUM_LANE_INLINE void store_rows(const V in[4], double* const* rows) {
    const H lo[4] = {in[0].lo, in[1].lo, in[2].lo, in[3].lo};
    const H hi[4] = {in[0].hi, in[1].hi, in[2].hi, in[3].hi};
    Half::store_rows(lo, rows);
    Half::store_rows(hi, rows + Half::kCount);
  }
};

// Whether any lane of a comparison's result is true.
FULCRUM_LANE_INLINE bool any_lane(bool m) {
  return m;
}
template <class M>
FULCRUM_LANE_INLINE bool any_lane(M m) {
  auto any = m[0];
#pragma GCC unroll 8
  for (int l = 1; l < static_cast<int>(sizeof(M) / sizeof(m[0])); ++l) any |= m[l];
  return any != 0;
}
template <class M>
FULCRUM_LANE_INLINE bool any_lane(MaskPair<M> m) {
  return any_lane(m.lo) || any_lane(m.hi);
}

// m ? a : b, and std::max's and std::clamp's definitions, lane by lane.
template <class M, class V>
FULCRUM_LANE_INLINE V lane_select(M m, V a, V b) {
  return m ? a : b;
}
template <class V>
FULCRUM_LANE_INLINE V lane_max(V a, V b) {
  return lane_select(a < b, b, a);
}
template <class V>
FULCRUM_LANE_INLINE V lane_min(V a, V b) {
  return lane_select(b < a, b, a);
}
template <class V>
FULCRUM_LANE_INLINE V lane_clamp(V x, V lo, V hi) {
  return lane_select(x < lo, lo, lane_select(hi < x, hi, x));
}

// Where a lane's body rows start: the velocity row (vx, vy, w, inv_mass) and, four doubles
// on, the motion row (dpx, dpy, qc, qs).
static_assert(offsetof(SolverBody, vy) == offsetof(SolverBody, vx) + 8 &&
              offsetof(SolverBody, w) == offsetof(SolverBody, vx) + 16 &&
              offsetof(SolverBody, inv_mass) == offsetof(SolverBody, vx) + 24);
static_assert(offsetof(SolverBody, dpx) == offsetof(SolverBody, vx) + 32 &&
              offsetof(SolverBody, dpy) == offsetof(SolverBody, vx) + 40 &&
              offsetof(SolverBody, qc) == offsetof(SolverBody, vx) + 48 &&
              offsetof(SolverBody, qs) == offsetof(SolverBody, vx) + 56);

FULCRUM_LANE_INLINE const double* velocity_row(const SolverBody& b) {
  return &b.vx;
}
FULCRUM_LANE_INLINE double* velocity_row(SolverBody& b) {
  return &b.vx;
}
FULCRUM_LANE_INLINE const double* motion_row(const SolverBody& b) {
  return &b.vx + 4;
}

// The impulse (px, py) applied to B and its opposite to A, with the moments it has about each
// body's centre given: ma = ra x P and mb = rb x P.
template <class V>
FULCRUM_LANE_INLINE void apply_lane_moments(V& vax, V& vay, V& wa, V& vbx, V& vby, V& wb, V ima,
                                            V iia, V imb, V iib, V px, V py, V ma, V mb) {
  vax -= ima * px;
  vay -= ima * py;
  wa -= iia * ma;
  vbx += imb * px;
  vby += imb * py;
  wb += iib * mb;
}

// P applied to body B at rb and -P to body A at ra: velocities (va, wa), (vb, wb) of a group of
// lanes, whatever rows they come from (LaneBodies, LaneWarmRows).
template <class V>
FULCRUM_LANE_INLINE void apply_lane_impulse(V& vax, V& vay, V& wa, V& vbx, V& vby, V& wb, V ima,
                                            V iia, V imb, V iib, V rax, V ray, V rbx, V rby, V px,
                                            V py) {
  apply_lane_moments(vax, vay, wa, vbx, vby, wb, ima, iia, imb, iib, px, py, rax * py - ray * px,
                     rbx * py - rby * px);
}

// The velocities of a group of lanes' bodies, loaded from and stored to the solver bodies.
// Block is a ContactBlock or a PointBlock (joint_kernel.h): anything with ia, ib, write_a and
// write_b per lane.
template <class V>
struct LaneBodies {
  using L = Lane<V>;
  static constexpr int kCount = L::kCount;
  V vax, vay, wa, ima_row;
  V vbx, vby, wb, imb_row;

  template <class Block>
  FULCRUM_LANE_INLINE LaneBodies(const Block& k, int l0, const SolverBody* bodies) {
    const double* ra[kCount];
    const double* rb[kCount];
#pragma GCC unroll 16
    for (int l = 0; l < kCount; ++l) {
      ra[l] = velocity_row(bodies[k.ia[l0 + l]]);
      rb[l] = velocity_row(bodies[k.ib[l0 + l]]);
    }
    V a[4], b[4];
    L::load_rows(ra, a);
    L::load_rows(rb, b);
    vax = a[0], vay = a[1], wa = a[2], ima_row = a[3];
    vbx = b[0], vby = b[1], wb = b[2], imb_row = b[3];
  }

  // Only dynamic bodies are written: lanes of one colour share no dynamic body. The row's
  // fourth element (the inverse mass) is written back as it was read.
  template <class Block>
  FULCRUM_LANE_INLINE void store(const Block& k, int l0, SolverBody* bodies) const {
    double* ra[kCount];
    double* rb[kCount];
    alignas(32) double sink[2 * kCount][4];
#pragma GCC unroll 16
    for (int l = 0; l < kCount; ++l) {
      ra[l] = k.write_a[l0 + l] ? velocity_row(bodies[k.ia[l0 + l]]) : sink[2 * l];
      rb[l] = k.write_b[l0 + l] ? velocity_row(bodies[k.ib[l0 + l]]) : sink[2 * l + 1];
    }
    const V a[4] = {vax, vay, wa, ima_row};
    const V b[4] = {vbx, vby, wb, imb_row};
    L::store_rows(a, ra);
    L::store_rows(b, rb);
  }

  // P applied to B at rb and -P to A at ra.
  FULCRUM_LANE_INLINE void apply(V ima, V iia, V imb, V iib, V rax, V ray, V rbx, V rby, V px,
                                 V py) {
    apply_lane_impulse(vax, vay, wa, vbx, vby, wb, ima, iia, imb, iib, rax, ray, rbx, rby, px, py);
  }

  // P applied to B and -P to A, with its moments ma = ra x P and mb = rb x P.
  FULCRUM_LANE_INLINE void apply_moments(V ima, V iia, V imb, V iib, V px, V py, V ma, V mb) {
    apply_lane_moments(vax, vay, wa, vbx, vby, wb, ima, iia, imb, iib, px, py, ma, mb);
  }

  // An impulse lambda along the unit axis d applied to B and -lambda d to A, with rda = ra x d
  // and rdb = rb x d: each velocity takes lambda times a factor that does not depend on lambda,
  // so a row's result reaches the velocities in one product and one sum.
  FULCRUM_LANE_INLINE void apply_along(V lambda, V ima, V iia, V imb, V iib, V dx, V dy, V rda,
                                       V rdb) {
    vax -= lambda * (ima * dx);
    vay -= lambda * (ima * dy);
    wa -= lambda * (iia * rda);
    vbx += lambda * (imb * dx);
    vby += lambda * (imb * dy);
    wb += lambda * (iib * rdb);
  }

  // The relative speed along the unit axis d at the points ra, rb (rda = ra x d, rdb = rb x d):
  // (vb - va) . d + wb rdb - wa rda, a difference, a product and two sums from the velocities.
  FULCRUM_LANE_INLINE V speed_along(V dx, V dy, V rda, V rdb) const {
    return ((vbx - vax) * dx + (vby - vay) * dy) + (wb * rdb - wa * rda);
  }
};

// A group of lanes' rows in an array with one VelocityBefore per solver slot (the next
// substep's warm start, LaneRule::warm_next), read and written as LaneBodies does the
// velocities: only the bodies the solver writes; the others read a zero row and write a sink.
inline constexpr VelocityBefore kZeroWarmRow{};

template <class V>
struct LaneWarmRows {
  using L = Lane<V>;
  static constexpr int kCount = L::kCount;
  double* out_a[kCount];
  double* out_b[kCount];
  alignas(32) double sink[2 * kCount][4];
  V a[4], b[4];

  template <class Block>
  FULCRUM_LANE_INLINE LaneWarmRows(const Block& k, int l0, VelocityBefore* rows) {
    const double* in_a[kCount];
    const double* in_b[kCount];
#pragma GCC unroll 16
    for (int l = 0; l < kCount; ++l) {
      const bool wa = k.write_a[l0 + l], wb = k.write_b[l0 + l];
      in_a[l] = wa ? &rows[k.ia[l0 + l]].vx : &kZeroWarmRow.vx;
      in_b[l] = wb ? &rows[k.ib[l0 + l]].vx : &kZeroWarmRow.vx;
      out_a[l] = wa ? &rows[k.ia[l0 + l]].vx : sink[2 * l];
      out_b[l] = wb ? &rows[k.ib[l0 + l]].vx : sink[2 * l + 1];
    }
    L::load_rows(in_a, a);
    L::load_rows(in_b, b);
  }

  // P added to B at rb and -P to A at ra, as LaneBodies::apply adds it to the velocities.
  FULCRUM_LANE_INLINE void apply(V ima, V iia, V imb, V iib, V rax, V ray, V rbx, V rby, V px,
                                 V py) {
    apply_lane_impulse(a[0], a[1], a[2], b[0], b[1], b[2], ima, iia, imb, iib, rax, ray, rbx, rby,
                       px, py);
  }

  // As LaneBodies::apply_moments.
  FULCRUM_LANE_INLINE void apply_moments(V ima, V iia, V imb, V iib, V px, V py, V ma, V mb) {
    apply_lane_moments(a[0], a[1], a[2], b[0], b[1], b[2], ima, iia, imb, iib, px, py, ma, mb);
  }

  FULCRUM_LANE_INLINE void store() {
    L::store_rows(a, out_a);
    L::store_rows(b, out_b);
  }
};

// The accumulated impulses P = lambda_n n + lambda_t t, t = (ny, -nx), of a group of lanes'
// points, applied to `to` (LaneBodies: a warm start; LaneWarmRows: the next one, gathered).
template <class V, class To>
FULCRUM_LANE_INLINE void apply_warm_points(const ContactBlock& k, int l0, To& to, V ima, V iia,
                                           V imb, V iib, V nx, V ny) {
  using L = Lane<V>;
#pragma GCC unroll 2
  for (const LanePoint& p : k.points) {
    const V ni = L::load(p.normal_impulse + l0), ti = L::load(p.tangent_impulse + l0);
    const V px = ni * nx + ti * ny;
    const V py = ni * ny - ti * nx;
    const V ma = ni * L::load(p.rna + l0) + ti * L::load(p.rta + l0);
    const V mb = ni * L::load(p.rnb + l0) + ti * L::load(p.rtb + l0);
    to.apply_moments(ima, iia, imb, iib, px, py, ma, mb);
  }
}

// Warm start: the accumulated impulses applied to the bodies.
template <class V>
FULCRUM_LANE_INLINE void warm_lanes(ContactBlock& k, int l0, SolverBody* bodies) {
  using L = Lane<V>;
  LaneBodies<V> v(k, l0, bodies);
  apply_warm_points<V>(k, l0, v, v.ima_row, L::load(k.inv_inertia_a + l0), v.imb_row,
                       L::load(k.inv_inertia_b + l0), L::load(k.nx + l0), L::load(k.ny + l0));
  v.store(k, l0, bodies);
}

// The lanes' accumulated impulses, as warm_lanes applies them, added to rows (one per solver
// slot, like the velocities) instead: the next substep's warm start, gathered while the last
// relax pass has the block in hand (LaneRule::warm_next).
template <class V>
FULCRUM_LANE_INLINE void gather_warm_lanes(const ContactBlock& k, int l0, VelocityBefore* rows,
                                           V ima, V iia, V imb, V iib, V nx, V ny) {
  LaneWarmRows<V> w(k, l0, rows);
  apply_warm_points<V>(k, l0, w, ima, iia, imb, iib, nx, ny);
  w.store();
}

// The motion rows (dpx, dpy, qc, qs) of a group of lanes' bodies A and B, element j of every
// lane in a[j] and b[j]. Block as for LaneBodies.
template <class V, class Block>
FULCRUM_LANE_INLINE void load_motion_rows(const Block& k, int l0, const SolverBody* bodies, V a[4],
                                          V b[4]) {
  using L = Lane<V>;
  const double* ra[L::kCount];
  const double* rb[L::kCount];
#pragma GCC unroll 16
  for (int l = 0; l < L::kCount; ++l) {
    ra[l] = motion_row(bodies[k.ia[l0 + l]]);
    rb[l] = motion_row(bodies[k.ib[l0 + l]]);
  }
  L::load_rows(ra, a);
  L::load_rows(rb, b);
}

// Separation now, from the bodies' motion since the tick began (anchors turned with them).
template <class V>
FULCRUM_LANE_INLINE void separation_lanes(ContactBlock& k, const ContactBlockRest& rest, int l0,
                                          const SolverBody* bodies) {
  using L = Lane<V>;
  V a[4], b[4];
  load_motion_rows<V>(k, l0, bodies, a, b);
  // The centres' motion along n, and each anchor turned by q = (qc, qs) along n:
  // n . (q r) = qs (r x n) - qc (r x t).
  const V nx = L::load(k.nx + l0), ny = L::load(k.ny + l0);
  const V dn = (b[0] - a[0]) * nx + (b[1] - a[1]) * ny;
  const V qca = a[2], qsa = a[3], qcb = b[2], qsb = b[3];
#pragma GCC unroll 2
  for (int i = 0; i < 2; ++i) {
    LanePoint& p = k.points[i];
    const V na = qsa * L::load(p.rna + l0) - qca * L::load(p.rta + l0);
    const V nb = qsb * L::load(p.rnb + l0) - qcb * L::load(p.rtb + l0);
    L::store(p.separation + l0, (dn + (nb - na)) + L::load(rest.base_separation[i] + l0));
  }
}

// Restitution's speed of approach (contact_solver.cpp, track_approach, states the steps): each
// point's normal speed before the substep's forces (v0) and after them (v1), and the gap now,
// give its speed at impact; the least so far is kept in the rest.
template <class V>
FULCRUM_LANE_INLINE void approach_lanes(const ContactBlock& k, ContactBlockRest& rest, int l0,
                                        const SolverBody* bodies, const VelocityBefore* before,
                                        V inv_h) {
  using L = Lane<V>;
  const LaneBodies<V> v(k, l0, bodies);
  const double* ra[L::kCount];
  const double* rb[L::kCount];
#pragma GCC unroll 16
  for (int l = 0; l < L::kCount; ++l) {
    ra[l] = &before[k.ia[l0 + l]].vx;
    rb[l] = &before[k.ib[l0 + l]].vx;
  }
  V a0[4], b0[4];
  L::load_rows(ra, a0);
  L::load_rows(rb, b0);
  const V zero = L::splat(0.0), two = L::splat(2.0);
  const V nx = L::load(k.nx + l0), ny = L::load(k.ny + l0);
#pragma GCC unroll 2
  for (int i = 0; i < 2; ++i) {
    const LanePoint& p = k.points[i];
    const V rna = L::load(p.rna + l0), rnb = L::load(p.rnb + l0);
    const V v0 = ((b0[0] - a0[0]) * nx + (b0[1] - a0[1]) * ny) + (b0[2] * rnb - a0[2] * rna);
    const V v1 = v.speed_along(nx, ny, rna, rnb);
    const V gap = lane_max(L::load(p.separation + l0), zero);
    const V accel = (v1 - v0) * inv_h;
    const V impact = -L::sqrt(lane_max(v0 * v0 - two * accel * gap, zero));
    const V speed = lane_select((v0 < zero) | (accel < zero), lane_min(v1, impact), v1);
    double* approach = rest.approach_speed[i] + l0;
    L::store(approach, lane_min(L::load(approach), speed));
  }
}

// One pass over a group of lanes: both normal rows, then both friction rows (contact_solver.cpp
// states the rows). Returns the largest corrective impulse of the lanes.
//
// A pass is bound by each lane's chain of rows: every row reads the velocities the row before
// wrote. So each row is written with as few operations as possible between the velocities it
// reads and those it writes; what does not depend on them (the mass and its softness scale
// times the bias, the impulse scale times the old impulse) is worked out beside the chain:
// lambda = k vn + (k bias - s old) with k = -m_c * mass scale. The anchors come crossed with n
// and t (LanePoint), as the rows use them.
template <class V, bool kRefresh>
FULCRUM_LANE_INLINE V solve_lanes(ContactBlock& k, ContactBlockRest& rest, int l0,
                                  SolverBody* bodies, const LaneRule& rule) {
  using L = Lane<V>;
  if constexpr (kRefresh) separation_lanes<V>(k, rest, l0, bodies);
  LaneBodies<V> v(k, l0, bodies);
  const V zero = L::splat(0.0), one = L::splat(1.0);
  const V inv_h = L::splat(rule.inv_h), neg_max_speed = L::splat(-rule.max_speed);
  const V ima = v.ima_row, iia = L::load(k.inv_inertia_a + l0);
  const V imb = v.imb_row, iib = L::load(k.inv_inertia_b + l0);
  const V nx = L::load(k.nx + l0), ny = L::load(k.ny + l0);
  // Contacts with a body of infinite mass take the stiffer softness (as prepare() chose it).
  const auto fixed = (ima == zero) | (imb == zero);
  const V bias_rate =
      lane_select(fixed, L::splat(rule.static_soft.bias_rate), L::splat(rule.soft.bias_rate));
  const V soft_mass_scale =
      lane_select(fixed, L::splat(rule.static_soft.mass_scale), L::splat(rule.soft.mass_scale));
  const V soft_impulse_scale = lane_select(fixed, L::splat(rule.static_soft.impulse_scale),
                                           L::splat(rule.soft.impulse_scale));
  V largest = zero;
#pragma GCC unroll 2
  for (int i = 0; i < 2; ++i) {
    LanePoint& p = k.points[i];
    const V rna = L::load(p.rna + l0), rnb = L::load(p.rnb + l0);
    const V sep = L::load(p.separation + l0);
    // Bias: speculative while apart; soft push-out (capped) while overlapping, if this pass
    // has feedback.
    V bias, mass_scale, impulse_scale;
    if (rule.use_bias) {
      auto apart = sep > zero;
      bias = lane_select(apart, sep * inv_h, lane_max(bias_rate * sep, neg_max_speed));
      mass_scale = lane_select(apart, one, soft_mass_scale);
      impulse_scale = lane_select(apart, zero, soft_impulse_scale);
    } else {
      bias = lane_select(sep > zero, sep * inv_h, zero);
      mass_scale = one;
      impulse_scale = zero;
    }
    V vn = v.speed_along(nx, ny, rna, rnb);
    V old = L::load(p.normal_impulse + l0);
    const V kn = -L::load(p.normal_mass + l0) * mass_scale;
    V lambda = kn * vn + (kn * bias - impulse_scale * old);
    V acc = lane_max(old + lambda, zero);
    lambda = acc - old;
    L::store(p.normal_impulse + l0, acc);
    if (rule.track_max) {
      double* max_normal = rest.max_normal_impulse[i] + l0;
      L::store(max_normal, lane_max(L::load(max_normal), acc));
    }
    v.apply_along(lambda, ima, iia, imb, iib, nx, ny, rna, rnb);
    if (rule.want_largest) largest = lane_max(largest, lane_max(lambda, -lambda));
  }
  // Friction along t = (ny, -nx), bounded by the normal impulses just found.
  const V tx = ny, ty = -nx;
  const V friction = L::load(k.friction + l0);
#pragma GCC unroll 2
  for (LanePoint& p : k.points) {
    const V rta = L::load(p.rta + l0), rtb = L::load(p.rtb + l0);
    V vt = v.speed_along(tx, ty, rta, rtb);
    V old = L::load(p.tangent_impulse + l0);
    V lambda = -L::load(p.tangent_mass + l0) * vt;
    V limit = friction * L::load(p.normal_impulse + l0);
    V acc = lane_clamp(old + lambda, -limit, limit);
    lambda = acc - old;
    L::store(p.tangent_impulse + l0, acc);
    v.apply_along(lambda, ima, iia, imb, iib, tx, ty, rta, rtb);
    if (rule.want_largest) largest = lane_max(largest, lane_max(lambda, -lambda));
  }
  v.store(k, l0, bodies);
  if (rule.warm_next != nullptr)
    gather_warm_lanes<V>(k, l0, rule.warm_next, ima, iia, imb, iib, nx, ny);
  return largest;
}

// One substep's position update of kCount consecutive solver bodies, each lane with the
// operations of contact_solver.cpp's integrate_positions (which states them) in their order:
// speeds capped, dp += h v, and the rotation turned by h w and normalized. The turn's sine and
// cosine come from det_sincos' own kernels in lanes (trig_kernel.h) when every lane's turn is
// within pi/4, which det_sincos would pass to them unreduced; otherwise from det_sincos, lane by
// lane. `extras` (null unless joint rows read the angles turned) adds up each turn.
template <class V>
FULCRUM_LANE_INLINE void integrate_lanes(SolverBody* bodies, SolverBodyExtra* extras,
                                         VelocityBefore* caps, const IntegrateRule& rule) {
  using L = Lane<V>;
  double* rows[L::kCount];
  double* motion[L::kCount];
#pragma GCC unroll 16
  for (int l = 0; l < L::kCount; ++l) {
    rows[l] = velocity_row(bodies[l]);
    motion[l] = rows[l] + 4;
  }
  V v[4], m[4];
  L::load_rows(rows, v);
  L::load_rows(motion, m);
  // cap_speeds; its square root and division (the lanes' longest chain after the rotation's)
  // only when a lane is that fast.
  const V speed2 = v[0] * v[0] + v[1] * v[1];
  const auto fast = speed2 > L::splat(rule.max_speed * rule.max_speed);
  const V v0[3] = {v[0], v[1], v[2]};
  const bool any_fast = any_lane(fast);
  if (any_fast) {
    const V f = L::splat(rule.max_speed) / L::sqrt(speed2);
    v[0] = lane_select(fast, v[0] * f, v[0]);
    v[1] = lane_select(fast, v[1] * f, v[1]);
  }
  const V max_turn = L::splat(rule.max_turn);
  const auto turning_fast = v[2] * v[2] > max_turn * max_turn;
  v[2] = lane_select(turning_fast, lane_select(v[2] > L::splat(0.0), max_turn, -max_turn), v[2]);
  if (caps != nullptr && (any_fast || any_lane(turning_fast))) {
#pragma GCC unroll 16
    for (int l = 0; l < L::kCount; ++l) {
      note_cap(caps[l], L::get(v0[0], l), L::get(v0[1], l), L::get(v0[2], l), L::get(v[0], l),
               L::get(v[1], l), L::get(v[2], l));
    }
  }
  const V h = L::splat(rule.h);
  m[0] += h * v[0];
  m[1] += h * v[1];
  const V turn = h * v[2];
  bool in_kernel = true;
#pragma GCC unroll 16
  for (int l = 0; l < L::kCount; ++l) {
    if (extras != nullptr) extras[l].da += L::get(turn, l);
    in_kernel = in_kernel && std::fabs(L::get(turn, l)) <= kPio4;
  }
  V tc, ts;
  if (in_kernel) {
    ts = kernel_sin(turn, L::splat(0.0));
    tc = kernel_cos(turn, L::splat(0.0));
  } else {
    double sines[L::kCount], cosines[L::kCount];
    for (int l = 0; l < L::kCount; ++l) {
      const SinCos sc = det_sincos(L::get(turn, l));
      sines[l] = sc.sin;
      cosines[l] = sc.cos;
    }
    ts = L::load(sines);
    tc = L::load(cosines);
  }
  // mul(Rot{cos, sin}, q).normalized(); an unturned body keeps its rotation as it is.
  const V mc = tc * m[2] - ts * m[3];
  const V ms = ts * m[2] + tc * m[3];
  const V mag = L::sqrt(mc * mc + ms * ms);
  const V inv = lane_select(mag > L::splat(0.0), L::splat(1.0) / mag, L::splat(0.0));
  const auto turned = turn != L::splat(0.0);
  m[2] = lane_select(turned, mc * inv, m[2]);
  m[3] = lane_select(turned, ms * inv, m[3]);
  L::store_rows(v, rows);
  L::store_rows(m, motion);
}

// Solver bodies [first, end), kCount at a time and the rest one by one.
template <class V>
void integrate_bodies(SolverBody* bodies, SolverBodyExtra* extras, const IntegrateRule& rule,
                      int first, int end) {
  constexpr int kCount = Lane<V>::kCount;
  int k = first;
  for (; k + kCount <= end; k += kCount) {
    integrate_lanes<V>(bodies + k, extras != nullptr ? extras + k : nullptr,
                       rule.caps != nullptr ? rule.caps + k : nullptr, rule);
  }
  for (; k < end; ++k) {
    integrate_lanes<double>(bodies + k, extras != nullptr ? extras + k : nullptr,
                            rule.caps != nullptr ? rule.caps + k : nullptr, rule);
  }
}

// Blocks [first, end) of one colour (or, for the scalar path, any blocks in order).
template <class V, bool kRefresh>
double solve_blocks_as(ContactBlock* blocks, int first, int end, SolverBody* bodies,
                       const LaneRule& rule) {
  using L = Lane<V>;
  V largest = L::splat(0.0);
  for (int k = first; k < end; ++k) {
    // Fetch ahead while this block is solved: the block three on (a pass streams more
    // blocks than the cache holds) with its rest where this pass reads it, and the next
    // block's bodies' velocity rows.
    if (k + 3 < end) {
      const char* far = reinterpret_cast<const char*>(&blocks[k + 3]);
#pragma GCC unroll 32
      for (size_t line = 0; line < sizeof(ContactBlock); line += 64) {
        __builtin_prefetch(far + line);
      }
      if (rule.track_max) {
        const char* rest = reinterpret_cast<const char*>(&rule.rests[k + 3]);
#pragma GCC unroll 32
        for (size_t line = 0; line < sizeof(ContactBlockRest); line += 64) {
          __builtin_prefetch(rest + line);
        }
      }
    }
    // A refreshing pass without restitution reads two lines of each rest, a stream of its own
    // beside the blocks': fetched three blocks on they still came late (a sixth of the pass's
    // time waited on them in the many pyramids), so sixteen on, across the colour's end (the
    // next colour's blocks follow in memory and in time).
    if (!rule.track_max && kRefresh && k + 16 < rule.block_count) {
      const char* rest = reinterpret_cast<const char*>(rule.rests[k + 16].base_separation);
      __builtin_prefetch(rest);
      __builtin_prefetch(rest + 64);
    }
    if (k + 1 < end) {
      const ContactBlock& next = blocks[k + 1];
#pragma GCC unroll 8
      for (int l = 0; l < kBlockLanes; ++l) {
        __builtin_prefetch(&bodies[next.ia[l]]);
        __builtin_prefetch(&bodies[next.ib[l]]);
      }
    }
    for (int l0 = 0; l0 < kBlockLanes; l0 += L::kCount) {
      largest =
          lane_max(largest, solve_lanes<V, kRefresh>(blocks[k], rule.rests[k], l0, bodies, rule));
    }
  }
  double out = L::get(largest, 0);
  for (int l = 1; l < L::kCount; ++l) out = lane_max(out, L::get(largest, l));
  return out;
}

// The lanes' separations are refreshed first when the rule says the bodies have moved since
// they were last computed: the same numbers update_separations gives, without a pass of its own.
template <class V>
double solve_blocks(ContactBlock* blocks, int first, int end, SolverBody* bodies,
                    const LaneRule& rule) {
  return rule.refresh_separation ? solve_blocks_as<V, true>(blocks, first, end, bodies, rule)
                                 : solve_blocks_as<V, false>(blocks, first, end, bodies, rule);
}

template <class V>
void separation_blocks(ContactBlock* blocks, const ContactBlockRest* rests, int first, int end,
                       const SolverBody* bodies) {
  for (int k = first; k < end; ++k) {
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      separation_lanes<V>(blocks[k], rests[k], l0, bodies);
    }
  }
}

template <class V>
void approach_blocks(const ContactBlock* blocks, ContactBlockRest* rests, const int* which,
                     int first, int end, const SolverBody* bodies, const VelocityBefore* before,
                     double inv_h) {
  const V rate = Lane<V>::splat(inv_h);
  for (int j = first; j < end; ++j) {
    const int k = which[j];
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      approach_lanes<V>(blocks[k], rests[k], l0, bodies, before, rate);
    }
  }
}

template <class V>
void warm_blocks(ContactBlock* blocks, int first, int end, SolverBody* bodies) {
  for (int k = first; k < end; ++k) {
    if (k + 3 < end) {
      const char* far = reinterpret_cast<const char*>(&blocks[k + 3]);
#pragma GCC unroll 32
      for (size_t line = 0; line < offsetof(ContactBlock, points); line += 64) {
        __builtin_prefetch(far + line);
      }
#pragma GCC unroll 2
      for (const LanePoint& p : blocks[k + 3].points) {
        __builtin_prefetch(p.rna);
        __builtin_prefetch(p.rnb);
        __builtin_prefetch(p.rta);
        __builtin_prefetch(p.rtb);
        __builtin_prefetch(p.normal_impulse);
        __builtin_prefetch(p.tangent_impulse);
      }
    }
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) warm_lanes<V>(blocks[k], l0, bodies);
  }
}

}  // namespace
}  // namespace fulcrum
