// The plain revolute points of joint_lanes.h over a lane type V (contact_kernel.h's `double`,
// 2 or 4 doubles), written as joint_frame, solve_revolute_point and apply_joint_impulse are:
// per lane the same operations in the same order, so every V gives the same bits. Included by
// contact_kernel.cpp and contact_kernel_x4.cpp after contact_kernel.h.
#pragma once

#include <cmath>

#include "joint_lanes.h"

namespace fulcrum {
namespace {

// joint_frame's figures: the anchors turned with the bodies, and anchor B minus anchor A.
template <class V>
struct PointFrame {
  V rax, ray, rbx, rby, dx, dy;
};

template <class V>
FULCRUM_LANE_INLINE PointFrame<V> point_frame(const PointBlock& k, int l0,
                                              const SolverBody* bodies) {
  using L = Lane<V>;
  V a[4], b[4];  // dpx, dpy, qc, qs
  load_motion_rows<V>(k, l0, bodies, a, b);
  const V rax = L::load(k.rax + l0), ray = L::load(k.ray + l0);
  const V rbx = L::load(k.rbx + l0), rby = L::load(k.rby + l0);
  PointFrame<V> f;
  f.rax = a[2] * rax - a[3] * ray;
  f.ray = a[3] * rax + a[2] * ray;
  f.rbx = b[2] * rbx - b[3] * rby;
  f.rby = b[3] * rbx + b[2] * rby;
  f.dx = (L::load(k.dcx + l0) + (b[0] - a[0])) + (f.rbx - f.rax);
  f.dy = (L::load(k.dcy + l0) + (b[1] - a[1])) + (f.rby - f.ray);
  return f;
}

// Warm start: the pin's accumulated impulse at its anchors as they are now (a pin has no angle
// row: nothing turns about it).
template <class V>
FULCRUM_LANE_INLINE void warm_point_lanes(PointBlock& k, int l0, SolverBody* bodies) {
  using L = Lane<V>;
  const PointFrame<V> f = point_frame<V>(k, l0, bodies);
  LaneBodies<V> v(k, l0, bodies);
  v.apply(v.ima_row, L::load(k.inv_inertia_a + l0), v.imb_row, L::load(k.inv_inertia_b + l0), f.rax,
          f.ray, f.rbx, f.rby, L::load(k.ix + l0), L::load(k.iy + l0));
  v.store(k, l0, bodies);
}

// solve_revolute_point, lane by lane. A lane whose K is singular (two immovable bodies, and
// the padding lanes) changes nothing, as the scalar function returns early.
template <class V>
FULCRUM_LANE_INLINE void solve_point_lanes(PointBlock& k, int l0, SolverBody* bodies,
                                           const PointRule& rule) {
  using L = Lane<V>;
  const PointFrame<V> f = point_frame<V>(k, l0, bodies);
  LaneBodies<V> v(k, l0, bodies);
  const V zero = L::splat(0.0);
  const V iia = L::load(k.inv_inertia_a + l0), iib = L::load(k.inv_inertia_b + l0);
  const V cdx = (v.vbx - v.wb * f.rby) - (v.vax - v.wa * f.ray);
  const V cdy = (v.vby + v.wb * f.rbx) - (v.vay + v.wa * f.rax);
  V bias_x = zero, bias_y = zero, ms = L::splat(1.0), is = zero;
  if (rule.use_bias) {
    const V rate = L::splat(rule.rate);
    ms = L::splat(rule.mass_scale);
    is = L::splat(rule.impulse_scale);
    bias_x = rate * f.dx;
    bias_y = rate * f.dy;
  }
  const V m = v.ima_row + v.imb_row;
  const V k11 = m + iia * f.ray * f.ray + iib * f.rby * f.rby;
  const V k12 = -iia * f.rax * f.ray - iib * f.rbx * f.rby;
  const V k22 = m + iia * f.rax * f.rax + iib * f.rbx * f.rbx;
  const V det = k11 * k22 - k12 * k12;
  const auto singular = det == zero;
  const V inv_det = L::splat(1.0) / det;
  const V rx = cdx + bias_x, ry = cdy + bias_y;
  const V sx = inv_det * (k22 * rx - k12 * ry);
  const V sy = inv_det * (k11 * ry - k12 * rx);
  const V ox = L::load(k.ix + l0), oy = L::load(k.iy + l0);
  V px = -ms * sx - is * ox;
  V py = -ms * sy - is * oy;
  // capped_point_correction: zero unless the feedback's speed passes the cap.
  V cx = zero, cy = zero;
  if (rule.use_bias) {
    const V tx = ms * bias_x + is * (k11 * ox + k12 * oy);
    const V ty = ms * bias_y + is * (k12 * ox + k22 * oy);
    const V cap = ms * L::splat(rule.max_speed);
    const V t2 = tx * tx + ty * ty;
    const auto over = t2 > cap * cap;
    if (any_lane(over)) {
      alignas(32) double t2s[L::kCount], caps[L::kCount], fs[L::kCount];
      L::store(t2s, t2);
      L::store(caps, cap);
      for (int l = 0; l < L::kCount; ++l) {
        fs[l] = t2s[l] > caps[l] * caps[l] ? 1.0 - caps[l] / std::sqrt(t2s[l]) : 0.0;
      }
      const V fct = L::load(fs);
      const V dx = fct * tx, dy = fct * ty;
      cx = over ? inv_det * (k22 * dx - k12 * dy) : zero;
      cy = over ? inv_det * (k11 * dy - k12 * dx) : zero;
    }
  }
  px = px + cx;
  py = py + cy;
  px = singular ? zero : px;
  py = singular ? zero : py;
  L::store(k.ix + l0, singular ? ox : ox + px);
  L::store(k.iy + l0, singular ? oy : oy + py);
  v.apply(v.ima_row, iia, v.imb_row, iib, f.rax, f.ray, f.rbx, f.rby, px, py);
  v.store(k, l0, bodies);
  if (rule.warm_next != nullptr) {
    LaneWarmRows<V> w(k, l0, rule.warm_next);
    w.apply(v.ima_row, iia, v.imb_row, iib, f.rax, f.ray, f.rbx, f.rby, L::load(k.ix + l0),
            L::load(k.iy + l0));
    w.store();
  }
}

// Fetched while block k of [first, end) is solved: the block two on, and the next block's
// bodies.
FULCRUM_LANE_INLINE void fetch_ahead(const PointBlock* blocks, int k, int end,
                                     const SolverBody* bodies) {
  if (k + 2 < end) {
    const char* far = reinterpret_cast<const char*>(&blocks[k + 2]);
#pragma GCC unroll 32
    for (size_t line = 0; line < sizeof(PointBlock); line += 64) __builtin_prefetch(far + line);
  }
  if (k + 1 < end) {
    const PointBlock& next = blocks[k + 1];
#pragma GCC unroll 8
    for (int l = 0; l < kBlockLanes; ++l) {
      __builtin_prefetch(&bodies[next.ia[l]]);
      __builtin_prefetch(&bodies[next.ib[l]]);
    }
  }
}

template <class V>
void solve_point_blocks(PointBlock* blocks, int first, int end, SolverBody* bodies,
                        const PointRule& rule) {
  for (int k = first; k < end; ++k) {
    fetch_ahead(blocks, k, end, bodies);
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      solve_point_lanes<V>(blocks[k], l0, bodies, rule);
    }
  }
}

template <class V>
void warm_point_blocks(PointBlock* blocks, int first, int end, SolverBody* bodies) {
  for (int k = first; k < end; ++k) {
    fetch_ahead(blocks, k, end, bodies);
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      warm_point_lanes<V>(blocks[k], l0, bodies);
    }
  }
}

}  // namespace
}  // namespace fulcrum
