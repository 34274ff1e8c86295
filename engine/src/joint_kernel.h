// The revolute joints of joint_lanes.h over a lane type V (contact_kernel.h's `double`, 2 or 4
// doubles): the rows revolute_joint.cpp states, with joint_frame's and apply_joint_impulse's
// arithmetic. Per lane the same operations in the same order, so every V gives the same bits.
// Included by contact_kernel.cpp and contact_kernel_x4.cpp after contact_kernel.h.
#pragma once

#include <cmath>

#include "joint_lanes.h"

namespace fulcrum {
namespace {

// joint_frame's figures: the anchors turned with the bodies, and how far each body's centre has
// moved since the tick began.
template <class V>
struct PointFrame {
  V rax, ray, rbx, rby, dpax, dpay, dpbx, dpby;
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
  f.dpax = a[0], f.dpay = a[1], f.dpbx = b[0], f.dpby = b[1];
  return f;
}

// Anchor B minus anchor A: the point's error, which only the biased passes read (so the relax
// passes never fetch the centres' lines, fetch_ahead).
template <class V>
FULCRUM_LANE_INLINE void point_error(const PointBlock& k, int l0, const PointFrame<V>& f, V& dx,
                                     V& dy) {
  using L = Lane<V>;
  dx = (L::load(k.dcx + l0) + (f.dpbx - f.dpax)) + (f.rbx - f.rax);
  dy = (L::load(k.dcy + l0) + (f.dpby - f.dpay)) + (f.rby - f.ray);
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

// A revolute joint's point rows, solved together through K, lane by lane, on bodies `v` (loaded,
// not yet stored) with frame `f`: the impulse added to the lanes' accumulated point impulse and
// applied to v. A lane whose K is singular (two immovable bodies, and the padding lanes) changes
// nothing, as the scalar function returns early.
template <class V>
FULCRUM_LANE_INLINE void point_row_lanes(PointBlock& k, int l0, const PointFrame<V>& f,
                                         LaneBodies<V>& v, const PointRule& rule) {
  using L = Lane<V>;
  const V zero = L::splat(0.0);
  const V iia = L::load(k.inv_inertia_a + l0), iib = L::load(k.inv_inertia_b + l0);
  const V cdx = (v.vbx - v.wb * f.rby) - (v.vax - v.wa * f.ray);
  const V cdy = (v.vby + v.wb * f.rbx) - (v.vay + v.wa * f.rax);
  V bias_x = zero, bias_y = zero, ms = L::splat(1.0), is = zero;
  if (rule.use_bias) {
    const V rate = L::splat(rule.rate);
    ms = L::splat(rule.mass_scale);
    is = L::splat(rule.impulse_scale);
    V dx, dy;
    point_error<V>(k, l0, f, dx, dy);
    bias_x = rate * dx;
    bias_y = rate * dy;
  }
  const V m = v.ima_row + v.imb_row;
  const V k11 = m + iia * f.ray * f.ray + iib * f.rby * f.rby;
  const V k12 = -iia * f.rax * f.ray - iib * f.rbx * f.rby;
  const V k22 = m + iia * f.rax * f.rax + iib * f.rbx * f.rbx;
  const V det = k11 * k22 - k12 * k12;
  const auto singular = det == zero;
  V inv_det;
  if (rule.mass.read) {
    inv_det = L::load(k.inv_det + l0);
  } else {
    inv_det = L::splat(1.0) / det;
    if (rule.mass.keep) L::store(k.inv_det + l0, inv_det);
  }
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
      cx = lane_select(over, inv_det * (k22 * dx - k12 * dy), zero);
      cy = lane_select(over, inv_det * (k11 * dy - k12 * dx), zero);
    }
  }
  px = px + cx;
  py = py + cy;
  px = lane_select(singular, zero, px);
  py = lane_select(singular, zero, py);
  L::store(k.ix + l0, lane_select(singular, ox, ox + px));
  L::store(k.iy + l0, lane_select(singular, oy, oy + py));
  v.apply(v.ima_row, iia, v.imb_row, iib, f.rax, f.ray, f.rbx, f.rby, px, py);
}

template <class V>
FULCRUM_LANE_INLINE void solve_point_lanes(PointBlock& k, int l0, SolverBody* bodies,
                                           const PointRule& rule) {
  using L = Lane<V>;
  const PointFrame<V> f = point_frame<V>(k, l0, bodies);
  LaneBodies<V> v(k, l0, bodies);
  point_row_lanes<V>(k, l0, f, v, rule);
  v.store(k, l0, bodies);
  if (rule.warm_next != nullptr) {
    LaneWarmRows<V> w(k, l0, rule.warm_next);
    w.apply(v.ima_row, L::load(k.inv_inertia_a + l0), v.imb_row, L::load(k.inv_inertia_b + l0),
            f.rax, f.ray, f.rbx, f.rby, L::load(k.ix + l0), L::load(k.iy + l0));
    w.store();
  }
}

// --- revolute joints with angle rows (RevoluteBlock) ---

// The angle turned since the tick began of the lanes' bodies in `slots`.
template <class V>
FULCRUM_LANE_INLINE V turned_lanes(const int32_t* slots, int l0, const SolverBodyExtra* extras) {
  using L = Lane<V>;
  alignas(32) double da[L::kCount];
#pragma GCC unroll 16
  for (int l = 0; l < L::kCount; ++l) da[l] = extras[slots[l0 + l]].da;
  return L::load(da);
}

// An angle row's impulse `lambda` on the lanes where `on`: -lambda to A's spin, +lambda to B's
// (revolute_detail::apply_angular); elsewhere the spins stay as they are.
template <class V, class M>
FULCRUM_LANE_INLINE void turn_lanes(M on, V lambda, V iia, V iib, V& wa, V& wb) {
  wa = lane_select(on, wa - iia * lambda, wa);
  wb = lane_select(on, wb + iib * lambda, wb);
}

// The warm start's angle impulse: what the spring, motor and limits have accumulated.
template <class V>
FULCRUM_LANE_INLINE V axial_impulse_lanes(const RevoluteBlock& k, int l0) {
  using L = Lane<V>;
  return L::load(k.spring_impulse + l0) + L::load(k.motor_impulse + l0) +
         L::load(k.lower_impulse + l0) - L::load(k.upper_impulse + l0);
}

// A revolute joint's warm start, lane by lane: the point's impulse at its anchors, then the
// angle rows' about the joint.
template <class V>
FULCRUM_LANE_INLINE void warm_revolute_lanes(RevoluteBlock& k, int l0, SolverBody* bodies) {
  using L = Lane<V>;
  const PointFrame<V> f = point_frame<V>(k, l0, bodies);
  LaneBodies<V> v(k, l0, bodies);
  const V iia = L::load(k.inv_inertia_a + l0), iib = L::load(k.inv_inertia_b + l0);
  v.apply(v.ima_row, iia, v.imb_row, iib, f.rax, f.ray, f.rbx, f.rby, L::load(k.ix + l0),
          L::load(k.iy + l0));
  const V axial = axial_impulse_lanes<V>(k, l0);
  v.wa = v.wa - iia * axial;
  v.wb = v.wb + iib * axial;
  v.store(k, l0, bodies);
}

// A revolute joint's rows, lane by lane: spring, motor, lower and upper limit, then the point.
template <class V>
FULCRUM_LANE_INLINE void solve_revolute_lanes(RevoluteBlock& k, int l0, SolverBody* bodies,
                                              const SolverBodyExtra* extras,
                                              const PointRule& rule) {
  using L = Lane<V>;
  const PointFrame<V> f = point_frame<V>(k, l0, bodies);
  LaneBodies<V> v(k, l0, bodies);
  const V zero = L::splat(0.0);
  const V iia = L::load(k.inv_inertia_a + l0), iib = L::load(k.inv_inertia_b + l0);
  const V theta = L::load(k.angle + l0) +
                  (turned_lanes<V>(k.ib, l0, extras) - turned_lanes<V>(k.ia, l0, extras));
  const V am = L::load(k.axial_mass + l0);

  const auto spring = L::load(k.spring_on + l0) != zero;
  if (any_lane(spring)) {
    const V c = theta - L::load(k.target_angle + l0);
    const V old = L::load(k.spring_impulse + l0);
    const V lambda = -L::load(k.spring_mass_scale + l0) * am *
                         ((v.wb - v.wa) + L::load(k.spring_rate + l0) * c) -
                     L::load(k.spring_impulse_scale + l0) * old;
    L::store(k.spring_impulse + l0, lane_select(spring, old + lambda, old));
    turn_lanes(spring, lambda, iia, iib, v.wa, v.wb);
  }
  const auto motor = L::load(k.motor_on + l0) != zero;
  if (any_lane(motor)) {
    const V lambda = -am * ((v.wb - v.wa) - L::load(k.motor_speed + l0));
    const V limit = L::load(k.max_motor_torque + l0) * L::splat(rule.h);
    const V old = L::load(k.motor_impulse + l0);
    const V acc = lane_min(lane_max(old + lambda, -limit), limit);  // std::clamp's definition
    L::store(k.motor_impulse + l0, lane_select(motor, acc, old));
    turn_lanes(motor, acc - old, iia, iib, v.wa, v.wb);
  }
  const auto limited = L::load(k.limit_on + l0) != zero;
  if (any_lane(limited)) {
    // limit_bias: a speculative row while apart (c > 0), else the joints' feedback.
    const V inv_h = L::splat(rule.inv_h);
    const V rate = L::splat(rule.rate);
    const V fb_ms = L::splat(rule.use_bias ? rule.mass_scale : 1.0);
    const V fb_is = L::splat(rule.use_bias ? rule.impulse_scale : 0.0);
    const V one = L::splat(1.0);
    auto row = [&](V c, V speed, double* impulse) {
      const auto apart = c > zero;
      const V bias = lane_select(apart, c * inv_h, rule.use_bias ? rate * c : zero);
      const V ms = lane_select(apart, one, fb_ms);
      const V is = lane_select(apart, zero, fb_is);
      const V old = L::load(impulse + l0);
      const V lambda = -ms * am * (speed + bias) - is * old;
      const V acc = lane_max(old + lambda, zero);  // std::max's definition
      L::store(impulse + l0, lane_select(limited, acc, old));
      return acc - old;
    };
    const V lower = row(theta - L::load(k.lower_angle + l0), v.wb - v.wa, k.lower_impulse);
    turn_lanes(limited, lower, iia, iib, v.wa, v.wb);
    const V upper = row(L::load(k.upper_angle + l0) - theta, v.wa - v.wb, k.upper_impulse);
    turn_lanes(limited, -upper, iia, iib, v.wa, v.wb);
  }

  point_row_lanes<V>(k, l0, f, v, rule);
  v.store(k, l0, bodies);
  if (rule.warm_next != nullptr) {
    LaneWarmRows<V> w(k, l0, rule.warm_next);
    w.apply(v.ima_row, iia, v.imb_row, iib, f.rax, f.ray, f.rbx, f.rby, L::load(k.ix + l0),
            L::load(k.iy + l0));
    const V axial = axial_impulse_lanes<V>(k, l0);
    w.a[2] = w.a[2] - iia * axial;
    w.b[2] = w.b[2] + iib * axial;
    w.store();
  }
}

// Fetched while block k of [first, end) is solved: the block two on, and the next block's
// bodies. A pass without bias leaves out the centres' lines (point_error).
template <class Block>
FULCRUM_LANE_INLINE void fetch_ahead(const Block* blocks, int k, int end, const SolverBody* bodies,
                                     bool biased) {
  if (k + 2 < end) {
    const char* far = reinterpret_cast<const char*>(&blocks[k + 2]);
    constexpr size_t kCentres = offsetof(PointBlock, dcx);
    constexpr size_t kAfter = offsetof(PointBlock, dcy) + sizeof(PointBlock::dcy);
    static_assert(kCentres % 64 == 0 && kAfter % 64 == 0);
#pragma GCC unroll 32
    for (size_t line = 0; line < sizeof(Block); line += 64) {
      if (biased || line < kCentres || line >= kAfter) __builtin_prefetch(far + line);
    }
  }
  if (k + 1 < end) {
    const Block& next = blocks[k + 1];
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
    fetch_ahead(blocks, k, end, bodies, rule.use_bias);
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      solve_point_lanes<V>(blocks[k], l0, bodies, rule);
    }
  }
}

template <class V>
void warm_point_blocks(PointBlock* blocks, int first, int end, SolverBody* bodies) {
  for (int k = first; k < end; ++k) {
    fetch_ahead(blocks, k, end, bodies, false);
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      warm_point_lanes<V>(blocks[k], l0, bodies);
    }
  }
}

template <class V>
void solve_revolute_blocks(RevoluteBlock* blocks, int first, int end, SolverBody* bodies,
                           const SolverBodyExtra* extras, const PointRule& rule) {
  for (int k = first; k < end; ++k) {
    fetch_ahead(blocks, k, end, bodies, rule.use_bias);
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      solve_revolute_lanes<V>(blocks[k], l0, bodies, extras, rule);
    }
  }
}

template <class V>
void warm_revolute_blocks(RevoluteBlock* blocks, int first, int end, SolverBody* bodies) {
  for (int k = first; k < end; ++k) {
    fetch_ahead(blocks, k, end, bodies, false);
    for (int l0 = 0; l0 < kBlockLanes; l0 += Lane<V>::kCount) {
      warm_revolute_lanes<V>(blocks[k], l0, bodies);
    }
  }
}

}  // namespace
}  // namespace fulcrum
