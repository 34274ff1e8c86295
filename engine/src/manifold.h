// Contact manifolds: for a pair of shapes, up to two contact points with a shared normal and
// feature ids that stay the same while the same features touch, so that the solver can carry
// accumulated impulses from one step to the next (warm starting).
#pragma once

#include <cstdint>

#include "fulcrum/geometry.h"
#include "fulcrum/math.h"

namespace fulcrum {

// Feature id of a contact point: the indices of the two features (vertex or edge) that made it.
inline constexpr uint32_t make_feature_id(int a, int b) {
  return (static_cast<uint32_t>(a & 0xff) << 8) | static_cast<uint32_t>(b & 0xff);
}

struct ManifoldPoint {
  Vec2 point = Vec2::Zero();  // world position, midway between the two surfaces, m
  double separation =
      0.0;          // signed distance between the surfaces along the normal, m (< 0: overlap)
  uint32_t id = 0;  // feature id, stable while the same features touch

  // Filled and used by the contact solver, not by the manifold functions.
  Vec2 anchor_a = Vec2::Zero();  // point relative to body A's centre of mass, world frame
  Vec2 anchor_b = Vec2::Zero();  // point relative to body B's centre of mass, world frame
  double normal_impulse = 0.0;   // accumulated, N s
  double tangent_impulse = 0.0;  // accumulated, N s
  bool persisted = false;        // matched a point of the previous step's manifold
};

struct Manifold {
  Vec2 normal = Vec2::Zero();  // world unit normal, pointing from shape A to shape B
  ManifoldPoint points[2];
  int count = 0;  // 0: not touching (no point closer than the speculative distance)
};

// Each function takes shape A with its body transform and shape B with its; it reports points
// whose separation is below `speculative` (m) and leaves count = 0 otherwise.
Manifold collide_circles(const Circle& a, const Transform& xfa, const Circle& b,
                         const Transform& xfb, double speculative);
Manifold collide_capsule_and_circle(const Capsule& a, const Transform& xfa, const Circle& b,
                                    const Transform& xfb, double speculative);
Manifold collide_capsules(const Capsule& a, const Transform& xfa, const Capsule& b,
                          const Transform& xfb, double speculative);
Manifold collide_segment_and_circle(const Segment& a, const Transform& xfa, const Circle& b,
                                    const Transform& xfb, double speculative);
Manifold collide_segment_and_capsule(const Segment& a, const Transform& xfa, const Capsule& b,
                                     const Transform& xfb, double speculative);
Manifold collide_segment_and_polygon(const Segment& a, const Transform& xfa, const Polygon& b,
                                     const Transform& xfb, double speculative);
Manifold collide_polygon_and_circle(const Polygon& a, const Transform& xfa, const Circle& b,
                                    const Transform& xfb, double speculative);
Manifold collide_polygon_and_capsule(const Polygon& a, const Transform& xfa, const Capsule& b,
                                     const Transform& xfb, double speculative);
Manifold collide_polygons(const Polygon& a, const Transform& xfa, const Polygon& b,
                          const Transform& xfb, double speculative);

// Dispatches on the two geometry types. Requires geometry_type(a) <= geometry_type(b) (the
// world orders every pair that way) and that not both are segments (segments have no mass and
// never meet each other).
Manifold collide(const Geometry& a, const Transform& xfa, const Geometry& b, const Transform& xfb,
                 double speculative);

}  // namespace fulcrum
