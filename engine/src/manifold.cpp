// Contact manifolds for every pair of shape types.
//
// Everything is computed in the frame of shape A (B is brought over with inv_mul) and moved to
// world coordinates at the end. Capsules and segments are treated as two-vertex polygons with a
// radius (0 for a segment) wherever a polygon is involved, so one polygon routine serves
// polygon-polygon, polygon-capsule and segment-polygon. Circles, and capsule/segment pairs,
// have their own closest-point routines.
//
// Conventions for every point: the normal n points from A to B; with cA the closest point on
// A's surface and cB the one on B's surface, `separation` = (cB - cA) . n and `point` is the
// midpoint (cA + cB) / 2.
#include "manifold.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cstdint>
#include <variant>

namespace fulcrum {
namespace {

// The manifold functions do not receive the world's linear slop; this copy of its default only
// tunes two heuristics (when to prefer a closest-feature normal over face clipping, and how much
// better B's face must be before it replaces A's as the reference face), so a constant is fine.
constexpr double kLinearSlop = 0.005;

// Below this length (m) a direction is treated as undefined.
constexpr double kTinyLength = 1e-12;

// Two capsule cores whose directions differ by less than asin(0.05) ~ 2.9 degrees are treated as
// parallel and get two points. The separation along A's normal then overestimates the true
// distance by at most h (1 - cos angle) < 0.0013 h, well below the slop for usual radii.
constexpr double kParallelSine = 0.05;

// The starting value of every result. Copying it is cheaper than default construction, which GCC
// compiles to two `rep stos` (slow to start for ~200 bytes) on the box-box hot path.
inline const Manifold& empty_manifold() {
  static const Manifold kEmpty;
  return kEmpty;
}

// Appends a point unless it lies at or beyond the speculative distance (also drops NaN).
inline void add_point(Manifold& m, const Vec2& point, double separation, uint32_t id,
                      double speculative) {
  if (!(separation < speculative)) return;
  ManifoldPoint& mp = m.points[m.count];
  mp.point = point;
  mp.separation = separation;
  mp.id = id;
  m.count += 1;
}

// From A's frame to world, in place. The routines below fill a default-constructed manifold
// that the public function returns (NRVO), so it is zeroed only once per call; an empty one
// gets its default zero normal back.
inline void to_world(Manifold& m, const Transform& xfa) {
  if (m.count == 0) {
    m.normal = Vec2::Zero();
    return;
  }
  m.normal = xfa.q.rotate(m.normal);
  for (int i = 0; i < m.count; ++i) m.points[i].point = xfa.apply(m.points[i].point);
}

// The same contact seen from the other shape: the normal reverses, points and separations stay,
// and the two feature indices in each id swap places so that the first is still A's.
inline Manifold flipped(Manifold m) {
  m.normal = -m.normal;
  for (int i = 0; i < m.count; ++i) {
    uint32_t id = m.points[i].id;
    m.points[i].id = ((id & 0xffu) << 8) | ((id >> 8) & 0xffu);
  }
  return m;
}

// Two round features: a disc of radius ra about pa and one of radius rb about pb (a vertex or a
// closest point on a core, with the shape's radius). n = (pb - pa) / |pb - pa|, or `fallback`
// when the centres coincide; separation = (pb - pa) . n - ra - rb.
void collide_discs(const Vec2& pa, double ra, const Vec2& pb, double rb, const Vec2& fallback,
                   uint32_t id, double speculative, Manifold& m) {
  const Vec2 d = pb - pa;
  const double dist_sq = length_squared(d);
  const double max_dist = ra + rb + speculative;
  if (dist_sq > max_dist * max_dist) return;
  const double dist = std::sqrt(dist_sq);
  const Vec2 n = dist > kTinyLength ? Vec2(d / dist) : fallback;
  const Vec2 ca = pa + ra * n;
  const Vec2 cb = pb - rb * n;
  m.normal = n;
  add_point(m, 0.5 * (ca + cb), dot(cb - ca, n), id, speculative);
}

// Capsule core p1-p2 with radius ra against a disc about c with radius rb, all in A's frame.
// The closest core point is p1 + t (p2 - p1) with t = clamp((c - p1) . d / (d . d), 0, 1).
void collide_core_and_disc(const Vec2& p1, const Vec2& p2, double ra, const Vec2& c, double rb,
                           double speculative, Manifold& m) {
  const Vec2 d = p2 - p1;
  const double dd = length_squared(d);
  double t = 0.0;
  if (dd > 0.0) t = std::clamp(dot(c - p1, d) / dd, 0.0, 1.0);
  const Vec2 closest = p1 + t * d;
  // A centre on the core has no direction; any side will do, pick the core's left side.
  Vec2 fallback = normalize_or_zero(left_perp(d));
  if (fallback.isZero()) fallback = Vec2(0.0, 1.0);
  collide_discs(closest, ra, c, rb, fallback, 0, speculative, m);
}

// Closest points between segments p1 + f1 (q1 - p1) and p2 + f2 (q2 - p2), f1, f2 in [0, 1].
struct SegmentDistance {
  Vec2 closest1;
  Vec2 closest2;
  double fraction1;
  double fraction2;
  double distance_squared;
};

// Minimises |r + f1 d1 - f2 d2|^2 with r = p1 - p2: the unconstrained minimum solves
//   [d1.d1  -d1.d2] [f1]   [-d1.r]
//   [d1.d2  -d2.d2] [f2] = [-d2.r];
// f1 is clamped first, f2 follows from f1, and when f2 had to be clamped f1 is recomputed
// against the clamped end (Ericson, Real-Time Collision Detection, 5.1.9).
SegmentDistance segment_distance(const Vec2& p1, const Vec2& q1, const Vec2& p2, const Vec2& q2) {
  const Vec2 d1 = q1 - p1;
  const Vec2 d2 = q2 - p2;
  const Vec2 r = p1 - p2;
  const double dd1 = length_squared(d1);
  const double dd2 = length_squared(d2);
  const double rd1 = dot(r, d1);
  const double rd2 = dot(r, d2);
  constexpr double kEpsSq = kTinyLength * kTinyLength;

  double f1 = 0.0;
  double f2 = 0.0;
  if (dd1 < kEpsSq || dd2 < kEpsSq) {
    // A degenerate segment is a point; project it onto the other one.
    if (dd1 >= kEpsSq) f1 = std::clamp(-rd1 / dd1, 0.0, 1.0);
    if (dd2 >= kEpsSq) f2 = std::clamp(rd2 / dd2, 0.0, 1.0);
  } else {
    const double d12 = dot(d1, d2);
    const double denom = dd1 * dd2 - d12 * d12;  // |d1|^2 |d2|^2 sin^2(angle)
    // Parallel segments have a whole range of closest pairs; start from p1's end.
    if (denom > 1e-12 * dd1 * dd2) f1 = std::clamp((d12 * rd2 - rd1 * dd2) / denom, 0.0, 1.0);
    f2 = (d12 * f1 + rd2) / dd2;
    if (f2 < 0.0) {
      f2 = 0.0;
      f1 = std::clamp(-rd1 / dd1, 0.0, 1.0);
    } else if (f2 > 1.0) {
      f2 = 1.0;
      f1 = std::clamp((d12 - rd1) / dd1, 0.0, 1.0);
    }
  }
  SegmentDistance out;
  out.closest1 = p1 + f1 * d1;
  out.closest2 = p2 + f2 * d2;
  out.fraction1 = f1;
  out.fraction2 = f2;
  out.distance_squared = distance_squared(out.closest1, out.closest2);
  return out;
}

// Capsule cores p1-p2 (radius ra) and q1-q2 (radius rb) in A's frame; segments have radius 0.
void collide_cores(const Vec2& p1, const Vec2& p2, double ra, const Vec2& q1, const Vec2& q2,
                   double rb, double speculative, Manifold& m) {
  const double total = ra + rb;
  const double max_dist = total + speculative;
  const SegmentDistance sd = segment_distance(p1, p2, q1, q2);
  if (sd.distance_squared > max_dist * max_dist) return;

  const Vec2 d1 = p2 - p1;
  const Vec2 d2 = q2 - q1;
  const double len1 = length(d1);
  const double len2 = length(d2);
  const Vec2 u1 = len1 > kTinyLength ? Vec2(d1 / len1) : Vec2(1.0, 0.0);

  if (len1 > kTinyLength && len2 > kTinyLength && std::abs(cross(u1, d2 / len2)) < kParallelSine) {
    // Nearly parallel: clip B's core to A's extent along u1 and measure both ends of the
    // clipped piece along A's normal. t is the coordinate along u1 from p1.
    const double t1 = dot(q1 - p1, u1);
    const double t2 = dot(q2 - p1, u1);
    const bool reversed = t2 < t1;
    const Vec2& q_lo = reversed ? q2 : q1;
    const Vec2& q_hi = reversed ? q1 : q2;
    const double t_lo = reversed ? t2 : t1;
    const double t_hi = reversed ? t1 : t2;
    const double lower = std::max(t_lo, 0.0);
    const double upper = std::min(t_hi, len1);
    // Require an overlap longer than the slop so that the two points are distinct.
    if (upper - lower > kLinearSlop) {
      // t_hi - t_lo = len2 |cos angle| > 0.99 len2, so the division is safe.
      const double inv_span = 1.0 / (t_hi - t_lo);
      const Vec2 b_lo = lerp(q_lo, q_hi, (lower - t_lo) * inv_span);
      const Vec2 b_hi = lerp(q_lo, q_hi, (upper - t_lo) * inv_span);
      const Vec2 n_left = left_perp(u1);
      const double h_lo = dot(b_lo - p1, n_left);
      const double h_hi = dot(b_hi - p1, n_left);
      // Both ends on the same side of A's core; crossing cores fall through to one point.
      if ((h_lo > 0.0 && h_hi > 0.0) || (h_lo < 0.0 && h_hi < 0.0)) {
        const double side = h_lo > 0.0 ? 1.0 : -1.0;
        const Vec2 n = side * n_left;
        m.normal = n;
        // b projects onto A's core at height h, so cA = b - h n + ra n and cB = b - rb n.
        const double s_lo = side * h_lo;
        const double s_hi = side * h_hi;
        // Ids pair the ends: A's p1 side with B's lower end, A's p2 side with B's upper end.
        const int b_lo_index = reversed ? 1 : 0;
        add_point(m, b_lo + 0.5 * (ra - rb - s_lo) * n, s_lo - total,
                  make_feature_id(0, b_lo_index), speculative);
        add_point(m, b_hi + 0.5 * (ra - rb - s_hi) * n, s_hi - total,
                  make_feature_id(1, 1 - b_lo_index), speculative);
        return;
      }
    }
  }

  // One point between the closest core points. Crossing cores have no closest direction: use
  // A's core normal on the side of B's centre.
  Vec2 fallback = left_perp(u1);
  if (dot(fallback, 0.5 * (q1 + q2) - 0.5 * (p1 + p2)) < 0.0) fallback = -fallback;
  collide_discs(sd.closest1, ra, sd.closest2, rb, fallback, 0, speculative, m);
}

// A convex polygon (or a two-vertex capsule core) already expressed in A's frame.
struct PolygonView {
  const Vec2* vertices;
  const Vec2* normals;
  int count;
  double radius;
};

// Separating-axis test over p1's face normals. For face i the separation of the cores is
//   s_i = min_j n_i . (w_j - v_i)   (w_j: p2's vertices, v_i: the face's first vertex).
// Returns max_i s_i and its face. The cores are disjoint iff this (or the other polygon's) value
// is positive, and then it is a lower bound on their distance.
// Once a face separates the polygons by more than `limit` the caller has its answer (some value
// above the limit: no points), so the other faces are not looked at.
// kVertices: p2's vertex count known at compile time (the loop over them unrolled), or 0.
template <int kVertices>
double max_separation_as(const PolygonView& p1, const PolygonView& p2, double limit, int* face) {
  const int count = kVertices > 0 ? kVertices : p2.count;
  int best_face = 0;
  double best = -DBL_MAX;
  for (int i = 0; i < p1.count; ++i) {
    // Scalar arithmetic on purpose: B's vertices were just written component by component, and
    // packed 16-byte loads of them would stall on store forwarding.
    const double nx = p1.normals[i].x();
    const double ny = p1.normals[i].y();
    const double vx = p1.vertices[i].x();
    const double vy = p1.vertices[i].y();
    double s = DBL_MAX;
#pragma GCC unroll 8
    for (int j = 0; j < count; ++j) {
      s = std::min(s, nx * (p2.vertices[j].x() - vx) + ny * (p2.vertices[j].y() - vy));
    }
    if (s > best) {
      best = s;
      best_face = i;
      if (best > limit) break;
    }
  }
  *face = best_face;
  return best;
}

// Boxes, the common case, take the unrolled loop: the same operations in the same order.
double max_separation(const PolygonView& p1, const PolygonView& p2, double limit, int* face) {
  return p2.count == 4 ? max_separation_as<4>(p1, p2, limit, face)
                       : max_separation_as<0>(p1, p2, limit, face);
}

// The general routine: the core separation from SAT picks a reference face (and the most
// anti-parallel incident face); then either one point between the closest features of the two
// faces (separated cores meeting corner to corner), or the incident face clipped to the
// reference face, which gives up to two points.
void collide_polygon_views(const PolygonView& pa, const PolygonView& pb, double speculative,
                           Manifold& m) {
  const double total = pa.radius + pb.radius;
  const double limit = total + speculative;
  int face_a = 0;
  const double sep_a = max_separation(pa, pb, limit, &face_a);
  if (sep_a > limit) return;
  int face_b = 0;
  const double sep_b = max_separation(pb, pa, limit, &face_b);
  if (sep_b > limit) return;

  // B's face becomes the reference only when clearly better, so that near ties (a box resting
  // on an equal box) do not switch faces from step to step.
  const bool flip = sep_b > sep_a + 0.1 * kLinearSlop;
  const PolygonView& ref = flip ? pb : pa;
  const PolygonView& inc = flip ? pa : pb;
  const int i11 = flip ? face_b : face_a;
  const int i12 = i11 + 1 < ref.count ? i11 + 1 : 0;
  const Vec2 n = ref.normals[i11];

  // Incident face: the one whose normal is most anti-parallel to the reference normal. The
  // incident vertex deepest along -n is one of its ends.
  int i21 = 0;
  double min_dot = DBL_MAX;
  for (int j = 0; j < inc.count; ++j) {
    const double d = dot(n, inc.normals[j]);
    if (d < min_dot) {
      min_dot = d;
      i21 = j;
    }
  }
  const int i22 = i21 + 1 < inc.count ? i21 + 1 : 0;

  const Vec2 v11 = ref.vertices[i11];
  const Vec2 v12 = ref.vertices[i12];
  const Vec2 v21 = inc.vertices[i21];
  const Vec2 v22 = inc.vertices[i22];

  // Coordinates along the reference face, t = left_perp(n) (the CCW edge direction), from v11.
  // The reference face spans [0, upper1]; the incident face runs backwards, v22 at lower2 and
  // v21 at upper2, and upper2 - lower2 = -|e2| (n . n_inc) >= 0.
  const Vec2 t = left_perp(n);
  const double upper1 = dot(v12 - v11, t);
  const double lower2 = dot(v22 - v11, t);
  const double upper2 = dot(v21 - v11, t);
  const double overlap = std::min(upper1, upper2) - std::max(0.0, lower2);

  const double r1 = ref.radius;
  const double r2 = inc.radius;
  const double separation = std::max(sep_a, sep_b);
  if (separation > 0.1 * kLinearSlop) {
    // Separated cores. Clipping is exact for incident points inside the reference face's slab
    // 0 <= t <= upper1 (their height is their distance), but it discards an incident vertex
    // beyond a side plane, which is the closest point when two corners face each other. So take
    // the closest points of the two faces instead when the faces do not overlap along t, or when
    // they are vertex to vertex with the incident vertex clearly outside the slab. The tolerance
    // keeps exactly stacked equal boxes, whose closest pair may land on two vertices by
    // rounding, on the two-point path. The direction between the closest points is the proper
    // normal, which matters for rounded corners; the distance is >= separation > 0.
    const SegmentDistance sd = segment_distance(v11, v12, v21, v22);
    const bool vertex_vertex = (sd.fraction1 == 0.0 || sd.fraction1 == 1.0) &&
                               (sd.fraction2 == 0.0 || sd.fraction2 == 1.0);
    const double t_closest = dot(sd.closest2 - v11, t);
    const double slab_tolerance = 0.1 * kLinearSlop;
    if (overlap <= 0.0 ||
        (vertex_vertex && (t_closest < -slab_tolerance || t_closest > upper1 + slab_tolerance))) {
      const double dist = std::sqrt(sd.distance_squared);
      const Vec2 n12 = (sd.closest2 - sd.closest1) / dist;
      const Vec2 c1 = sd.closest1 + r1 * n12;
      const Vec2 c2 = sd.closest2 - r2 * n12;
      const int ref_vertex = sd.fraction1 < 0.5 ? i11 : i12;
      const int inc_vertex = sd.fraction2 < 0.5 ? i21 : i22;
      m.normal = flip ? Vec2(-n12) : n12;
      add_point(
          m, 0.5 * (c1 + c2), dist - total,
          flip ? make_feature_id(inc_vertex, ref_vertex) : make_feature_id(ref_vertex, inc_vertex),
          speculative);
      return;
    }
  }

  // Clip the incident face to the reference face's side planes t = 0 and t = upper1. The clip
  // fractions are clamped so that an incident face that misses the reference face entirely (only
  // possible in odd deep overlaps) collapses onto its nearest end instead of extrapolating.
  Vec2 v_lower = v22;
  Vec2 v_upper = v21;
  const double span = upper2 - lower2;
  if (span > kTinyLength) {
    if (lower2 < 0.0) v_lower = lerp(v22, v21, std::min(-lower2 / span, 1.0));
    if (upper2 > upper1) v_upper = lerp(v22, v21, std::max((upper1 - lower2) / span, 0.0));
  }
  // Heights of the incident core above the reference face line.
  const double h_lower = dot(v_lower - v11, n);
  const double h_upper = dot(v_upper - v11, n);

  m.normal = flip ? Vec2(-n) : n;
  // Ids pair the reference face's ends with the incident face's nearby ends. They depend only on
  // the two faces, not on which of them was clipped, and a flip gives the same (A, B) pairs.
  const uint32_t id_lower = flip ? make_feature_id(i22, i11) : make_feature_id(i11, i22);
  const uint32_t id_upper = flip ? make_feature_id(i21, i12) : make_feature_id(i12, i21);
  // The midpoint between the surfaces: the reference surface is at height r1, the incident one
  // at h - r2, so point = v + ((r1 + h - r2) / 2 - h) n.
  add_point(m, v_lower + 0.5 * (r1 - r2 - h_lower) * n, h_lower - total, id_lower, speculative);
  if (overlap >= 0.0 || span <= kTinyLength) {
    add_point(m, v_upper + 0.5 * (r1 - r2 - h_upper) * n, h_upper - total, id_upper, speculative);
  }
}

// B's polygon in A's frame, written into caller-provided arrays (no allocation).
inline PolygonView transform_polygon(const Polygon& p, const Transform& xf,
                                     std::array<Vec2, kMaxPolygonVertices>& vertices,
                                     std::array<Vec2, kMaxPolygonVertices>& normals) {
  // Component by component, in the same operation order as Transform::apply and Rot::rotate
  // (so bit-identical): building a Vec2 from two scalars and then using it as a packed vector
  // makes GCC store two halves and reload them whole, a store-forwarding stall on this hot path.
  const double c = xf.q.c;
  const double s = xf.q.s;
  const double px = xf.p.x();
  const double py = xf.p.y();
  for (int i = 0; i < p.count; ++i) {
    const double vx = p.vertices[i].x();
    const double vy = p.vertices[i].y();
    const double nx = p.normals[i].x();
    const double ny = p.normals[i].y();
    vertices[i].x() = (c * vx - s * vy) + px;
    vertices[i].y() = (s * vx + c * vy) + py;
    normals[i].x() = c * nx - s * ny;
    normals[i].y() = s * nx + c * ny;
  }
  return PolygonView{vertices.data(), normals.data(), p.count, p.radius};
}

// A capsule core (or segment) p1-p2 as a two-vertex polygon: face 0 runs p1 -> p2 with normal
// right_perp(p2 - p1) / |p2 - p1| (outward for a CCW order), face 1 runs back with the opposite
// normal.
inline PolygonView core_polygon(const Vec2& p1, const Vec2& p2, double radius,
                                std::array<Vec2, 2>& vertices, std::array<Vec2, 2>& normals) {
  vertices[0] = p1;
  vertices[1] = p2;
  normals[0] = normalize_or_zero(right_perp(p2 - p1));
  normals[1] = -normals[0];
  return PolygonView{vertices.data(), normals.data(), 2, radius};
}

}  // namespace

Manifold collide_circles(const Circle& a, const Transform& xfa, const Circle& b,
                         const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  Manifold m = empty_manifold();
  // Concentric circles have no direction; A's local y axis is as good as any.
  collide_discs(a.center, a.radius, xf.apply(b.center), b.radius, Vec2(0.0, 1.0), 0, speculative,
                m);
  to_world(m, xfa);
  return m;
}

Manifold collide_capsule_and_circle(const Capsule& a, const Transform& xfa, const Circle& b,
                                    const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  Manifold m = empty_manifold();
  collide_core_and_disc(a.center1, a.center2, a.radius, xf.apply(b.center), b.radius, speculative,
                        m);
  to_world(m, xfa);
  return m;
}

Manifold collide_capsules(const Capsule& a, const Transform& xfa, const Capsule& b,
                          const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  Manifold m = empty_manifold();
  collide_cores(a.center1, a.center2, a.radius, xf.apply(b.center1), xf.apply(b.center2), b.radius,
                speculative, m);
  to_world(m, xfa);
  return m;
}

Manifold collide_segment_and_circle(const Segment& a, const Transform& xfa, const Circle& b,
                                    const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  Manifold m = empty_manifold();
  collide_core_and_disc(a.point1, a.point2, 0.0, xf.apply(b.center), b.radius, speculative, m);
  to_world(m, xfa);
  return m;
}

Manifold collide_segment_and_capsule(const Segment& a, const Transform& xfa, const Capsule& b,
                                     const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  Manifold m = empty_manifold();
  collide_cores(a.point1, a.point2, 0.0, xf.apply(b.center1), xf.apply(b.center2), b.radius,
                speculative, m);
  to_world(m, xfa);
  return m;
}

Manifold collide_segment_and_polygon(const Segment& a, const Transform& xfa, const Polygon& b,
                                     const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  std::array<Vec2, 2> av, an;
  std::array<Vec2, kMaxPolygonVertices> bv, bn;
  const PolygonView pa = core_polygon(a.point1, a.point2, 0.0, av, an);
  const PolygonView pb = transform_polygon(b, xf, bv, bn);
  Manifold m = empty_manifold();
  collide_polygon_views(pa, pb, speculative, m);
  to_world(m, xfa);
  return m;
}

Manifold collide_polygon_and_circle(const Polygon& a, const Transform& xfa, const Circle& b,
                                    const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  const Vec2 c = xf.apply(b.center);
  const double ra = a.radius;
  const double rb = b.radius;
  const double total = ra + rb;
  Manifold m = empty_manifold();

  // Face of largest separation s_i = n_i . (c - v_i). Inside the core this is the nearest face;
  // outside, the closest core feature is this face or one of its two vertices (the faces whose
  // normals bracket the direction from the closest vertex to c separate the most).
  int face = 0;
  double s = -DBL_MAX;
  for (int i = 0; i < a.count; ++i) {
    const double si = dot(a.normals[i], c - a.vertices[i]);
    if (si > s) {
      s = si;
      face = i;
    }
  }
  if (s > total + speculative) return m;

  const Vec2 v1 = a.vertices[face];
  const Vec2 v2 = a.vertices[face + 1 < a.count ? face + 1 : 0];
  const Vec2 n_face = a.normals[face];
  // Beyond an end of the face (projection outside the edge) and outside the core: the closest
  // feature is that vertex, and the normal runs from it to the centre.
  if (s > kTinyLength && dot(c - v1, v2 - v1) < 0.0) {
    collide_discs(v1, ra, c, rb, n_face, 0, speculative, m);
  } else if (s > kTinyLength && dot(c - v2, v1 - v2) < 0.0) {
    collide_discs(v2, ra, c, rb, n_face, 0, speculative, m);
  } else {
    // Face region (also any centre inside the core: pushed out of the nearest face). A's
    // surface point is c projected on the face line, plus ra along n.
    const Vec2 ca = c + (ra - s) * n_face;
    const Vec2 cb = c - rb * n_face;
    m.normal = n_face;
    add_point(m, 0.5 * (ca + cb), s - total, 0, speculative);
  }
  to_world(m, xfa);
  return m;
}

Manifold collide_polygon_and_capsule(const Polygon& a, const Transform& xfa, const Capsule& b,
                                     const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  std::array<Vec2, 2> bv, bn;
  const PolygonView pa{a.vertices.data(), a.normals.data(), a.count, a.radius};
  const PolygonView pb = core_polygon(xf.apply(b.center1), xf.apply(b.center2), b.radius, bv, bn);
  Manifold m = empty_manifold();
  collide_polygon_views(pa, pb, speculative, m);
  to_world(m, xfa);
  return m;
}

Manifold collide_polygons(const Polygon& a, const Transform& xfa, const Polygon& b,
                          const Transform& xfb, double speculative) {
  const Transform xf = inv_mul(xfa, xfb);
  std::array<Vec2, kMaxPolygonVertices> bv, bn;
  const PolygonView pa{a.vertices.data(), a.normals.data(), a.count, a.radius};
  const PolygonView pb = transform_polygon(b, xf, bv, bn);
  Manifold m = empty_manifold();
  collide_polygon_views(pa, pb, speculative, m);
  to_world(m, xfa);
  return m;
}

Manifold collide(const Geometry& a, const Transform& xfa, const Geometry& b, const Transform& xfb,
                 double speculative) {
  const ShapeType ta = geometry_type(a);
  const ShapeType tb = geometry_type(b);
  // The world orders pairs so that ta <= tb; tolerate the other order by symmetry.
  if (ta > tb) return flipped(collide(b, xfb, a, xfa, speculative));

  // Pairs without a function of their own use the swapped one: f(B, A) gives the same contact
  // with the normal pointing from B to A, hence the flip.
  switch (ta) {
    case ShapeType::kCircle: {
      const Circle& ca = std::get<Circle>(a);
      switch (tb) {
        case ShapeType::kCircle:
          return collide_circles(ca, xfa, std::get<Circle>(b), xfb, speculative);
        case ShapeType::kCapsule:
          return flipped(
              collide_capsule_and_circle(std::get<Capsule>(b), xfb, ca, xfa, speculative));
        case ShapeType::kSegment:
          return flipped(
              collide_segment_and_circle(std::get<Segment>(b), xfb, ca, xfa, speculative));
        case ShapeType::kPolygon:
          return flipped(
              collide_polygon_and_circle(std::get<Polygon>(b), xfb, ca, xfa, speculative));
      }
      break;
    }
    case ShapeType::kCapsule: {
      const Capsule& ca = std::get<Capsule>(a);
      switch (tb) {
        case ShapeType::kCapsule:
          return collide_capsules(ca, xfa, std::get<Capsule>(b), xfb, speculative);
        case ShapeType::kSegment:
          return flipped(
              collide_segment_and_capsule(std::get<Segment>(b), xfb, ca, xfa, speculative));
        case ShapeType::kPolygon:
          return flipped(
              collide_polygon_and_capsule(std::get<Polygon>(b), xfb, ca, xfa, speculative));
        default:
          break;
      }
      break;
    }
    case ShapeType::kSegment:
      // Segments never meet segments (both are static terrain without mass).
      if (tb == ShapeType::kPolygon) {
        return collide_segment_and_polygon(std::get<Segment>(a), xfa, std::get<Polygon>(b), xfb,
                                           speculative);
      }
      break;
    case ShapeType::kPolygon:
      return collide_polygons(std::get<Polygon>(a), xfa, std::get<Polygon>(b), xfb, speculative);
  }
  return Manifold{};
}

Manifold no_points(ShapeType ta, ShapeType tb) {
  if (ta > tb) return flipped(no_points(tb, ta));
  // The pairs collide hands to the swapped function, as its switch does.
  const bool swapped = ta < tb && !(ta == ShapeType::kSegment && tb == ShapeType::kPolygon);
  return swapped ? flipped(empty_manifold()) : empty_manifold();
}

}  // namespace fulcrum
