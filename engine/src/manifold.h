// Contact manifolds: for a pair of shapes, up to two contact points with a shared normal and
// feature ids that stay the same while the same features touch, so that the solver can carry
// accumulated impulses from one step to the next (warm starting).
#pragma once

#include <cstdint>

#include "fulcrum/geometry.h"
#include "fulcrum/math.h"
#include "fulcrum/state.h"

namespace fulcrum {

// Feature id of a contact point: the indices of the two features (vertex or edge) that made it.
inline constexpr uint32_t make_feature_id(int a, int b) {
  return (static_cast<uint32_t>(a & 0xff) << 8) | static_cast<uint32_t>(b & 0xff);
}

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

// What collide returns for shapes of these types when no point comes closer than the speculative
// distance, bit for bit (a pair handled by the swapped function has its zero normal negated).
// Every point collide reports lies between the surfaces with a separation no less than their
// distance, so shapes whose boxes are farther apart than the speculative distance get this
// without calling collide.
Manifold no_points(ShapeType ta, ShapeType tb);

// Whether a shape has sharp flat faces (a polygon without rounding, or a segment): the only
// shapes whose manifolds the narrow phase keeps and moves with the bodies (contact.cpp).
inline bool flat(const Geometry& g) {
  if (const Polygon* p = std::get_if<Polygon>(&g)) return p->radius == 0.0;
  return std::holds_alternative<Segment>(g);
}

}  // namespace fulcrum
