// 2D math on Eigen: vectors, rotations stored as unit complex numbers, rigid transforms and
// axis-aligned boxes. Everything here is inline and uses only +, -, *, / and sqrt, which IEEE 754
// rounds exactly, so results are bit-identical across compilers given the engine's build flags.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace fulcrum {

using Vec2 = Eigen::Vector2d;
using Mat22 = Eigen::Matrix2d;

// 2D cross product of two vectors: the z component of (a, 0) x (b, 0).
inline double cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}
// a x (0, 0, s): the vector a turned clockwise and scaled by s.
inline Vec2 cross(const Vec2& a, double s) {
  return Vec2(s * a.y(), -s * a.x());
}
// (0, 0, s) x a: the vector a turned counter-clockwise and scaled by s (w x r for a spin w).
inline Vec2 cross(double s, const Vec2& a) {
  return Vec2(-s * a.y(), s * a.x());
}
inline Vec2 left_perp(const Vec2& v) {
  return Vec2(-v.y(), v.x());
}
inline Vec2 right_perp(const Vec2& v) {
  return Vec2(v.y(), -v.x());
}
inline double dot(const Vec2& a, const Vec2& b) {
  return a.x() * b.x() + a.y() * b.y();
}
inline double length_squared(const Vec2& v) {
  return v.x() * v.x() + v.y() * v.y();
}
inline double length(const Vec2& v) {
  return std::sqrt(length_squared(v));
}
inline double distance(const Vec2& a, const Vec2& b) {
  return length(b - a);
}
inline double distance_squared(const Vec2& a, const Vec2& b) {
  return length_squared(b - a);
}
inline Vec2 lerp(const Vec2& a, const Vec2& b, double t) {
  return a + t * (b - a);
}

// Unit vector along v, or zero when v is (nearly) zero.
inline Vec2 normalize_or_zero(const Vec2& v) {
  double len = length(v);
  if (len < 1e-300) return Vec2::Zero();
  return v / len;
}

inline bool is_finite(double x) {
  return std::isfinite(x);
}
inline bool is_finite(const Vec2& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y());
}

// A rotation as the unit complex number (c, s) = (cos angle, sin angle).
struct Rot {
  double c = 1.0;
  double s = 0.0;

  // Built with Fulcrum's deterministic sin/cos (trig.h), never libm.
  static Rot from_angle(double radians);
  // The angle in (-pi, pi], from Fulcrum's deterministic atan2.
  double angle() const;

  Vec2 rotate(const Vec2& v) const { return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y()); }
  Vec2 inv_rotate(const Vec2& v) const {
    return Vec2(c * v.x() + s * v.y(), -s * v.x() + c * v.y());
  }
  Vec2 x_axis() const { return Vec2(c, s); }
  Vec2 y_axis() const { return Vec2(-s, c); }

  // Back onto the unit circle; used after integration so rounding never accumulates.
  Rot normalized() const {
    double mag = std::sqrt(c * c + s * s);
    double inv = mag > 0.0 ? 1.0 / mag : 0.0;
    return Rot{c * inv, s * inv};
  }
};

// q * r: rotate by r, then by q.
inline Rot mul(const Rot& q, const Rot& r) {
  return Rot{q.c * r.c - q.s * r.s, q.s * r.c + q.c * r.s};
}
// q^-1 * r: the rotation that takes q to r.
inline Rot inv_mul(const Rot& q, const Rot& r) {
  return Rot{q.c * r.c + q.s * r.s, q.c * r.s - q.s * r.c};
}

// A rigid transform: rotate by q, then translate by p.
struct Transform {
  Vec2 p = Vec2::Zero();
  Rot q;

  Vec2 apply(const Vec2& v) const { return q.rotate(v) + p; }
  Vec2 inv_apply(const Vec2& v) const { return q.inv_rotate(v - p); }
};

// a * b: apply b, then a.
inline Transform mul(const Transform& a, const Transform& b) {
  return Transform{a.q.rotate(b.p) + a.p, mul(a.q, b.q)};
}
// a^-1 * b: b expressed in the frame of a.
inline Transform inv_mul(const Transform& a, const Transform& b) {
  return Transform{a.q.inv_rotate(b.p - a.p), inv_mul(a.q, b.q)};
}

// Axis-aligned bounding box.
struct AABB {
  Vec2 lower = Vec2::Zero();
  Vec2 upper = Vec2::Zero();

  bool overlaps(const AABB& o) const {
    return !(o.lower.x() > upper.x() || o.lower.y() > upper.y() || lower.x() > o.upper.x() ||
             lower.y() > o.upper.y());
  }
  bool contains(const AABB& o) const {
    return lower.x() <= o.lower.x() && lower.y() <= o.lower.y() && o.upper.x() <= upper.x() &&
           o.upper.y() <= upper.y();
  }
  bool contains(const Vec2& p) const {
    return lower.x() <= p.x() && lower.y() <= p.y() && p.x() <= upper.x() && p.y() <= upper.y();
  }
  double perimeter() const { return 2.0 * ((upper.x() - lower.x()) + (upper.y() - lower.y())); }
  Vec2 center() const { return 0.5 * (lower + upper); }
  AABB fattened(double margin) const {
    return AABB{lower - Vec2(margin, margin), upper + Vec2(margin, margin)};
  }
};

inline AABB union_of(const AABB& a, const AABB& b) {
  return AABB{Vec2(std::min(a.lower.x(), b.lower.x()), std::min(a.lower.y(), b.lower.y())),
              Vec2(std::max(a.upper.x(), b.upper.x()), std::max(a.upper.y(), b.upper.y()))};
}

}  // namespace fulcrum
