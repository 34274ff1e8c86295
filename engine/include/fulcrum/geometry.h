// Shape geometry in a body's local frame: circles, capsules, segments and convex polygons (with
// an optional rounding radius), their mass properties, bounding boxes, ray casts and point tests.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <variant>
#include <vector>

#include "fulcrum/math.h"
#include "fulcrum/status.h"

namespace fulcrum {

inline constexpr int kMaxPolygonVertices = 8;

// Shorter edges or thinner polygons than this are degenerate (metres).
inline constexpr double kGeometryTolerance = 1e-4;

// The largest magnitude of any real number given to the engine: coordinates, sizes, velocities,
// forces, impulses, settings; larger ones are refused. Finite is not enough: a body at 1e308 m
// overflows the first difference the solver takes. With every input within 1e12 (and densities
// within [0, 1e12]) the products a step forms, such as a polygon's inertia (density times a
// length to the fourth, below 1e60) or an impulse times an inverse mass, stay far from
// overflow, while a coordinate of 1e12 m still resolves to 1.2e-4 m in double precision.
inline constexpr double kMaxInputMagnitude = 1e12;

struct Circle {
  Vec2 center = Vec2::Zero();  // local position, m
  double radius = 0.5;         // m, > 0
};

// Two half circles joined by a rectangle: every point within `radius` of the core segment.
struct Capsule {
  Vec2 center1 = Vec2(-0.5, 0.0);  // local, m
  Vec2 center2 = Vec2(0.5, 0.0);   // local, m; |center2 - center1| > kGeometryTolerance
  double radius = 0.25;            // m, > 0
};

// A two-sided line segment with no thickness and no mass (terrain, walls).
struct Segment {
  Vec2 point1 = Vec2(-1.0, 0.0);  // local, m
  Vec2 point2 = Vec2(1.0, 0.0);   // local, m
};

// A convex polygon, counter-clockwise, with outward unit normals: normals[i] belongs to the
// edge from vertices[i] to vertices[(i + 1) % count]. With radius > 0 the polygon is rounded:
// every point within `radius` of the core polygon.
struct Polygon {
  std::array<Vec2, kMaxPolygonVertices> vertices;
  std::array<Vec2, kMaxPolygonVertices> normals;
  Vec2 centroid = Vec2::Zero();
  double radius = 0.0;
  int count = 0;
};

enum class ShapeType : uint8_t { kCircle = 0, kCapsule = 1, kSegment = 2, kPolygon = 3 };
inline constexpr int kShapeTypeCount = 4;
const char* shape_type_name(ShapeType type);

// One shape's geometry, whichever kind it is. The variant index equals ShapeType.
using Geometry = std::variant<Circle, Capsule, Segment, Polygon>;
inline ShapeType geometry_type(const Geometry& g) {
  return static_cast<ShapeType>(g.index());
}

struct MassData {
  double mass = 0.0;                // kg
  Vec2 center = Vec2::Zero();       // centre of mass, local, m
  double rotational_inertia = 0.0;  // about `center`, kg m^2
};

// --- Construction and validation -------------------------------------------------------------

// An axis-aligned box centred on the origin with half-widths hx, hy (m, > 0).
Polygon make_box(double hx, double hy);
// A box with half-widths hx, hy centred at `center` and turned by `angle` (radians).
Polygon make_offset_box(double hx, double hy, const Vec2& center, double angle);
// A convex polygon from counter-clockwise vertices. Refuses, naming the reason: fewer than 3 or
// more than kMaxPolygonVertices points, non-finite values, edges shorter than
// kGeometryTolerance, clockwise or non-convex order (including collinear vertices), a negative
// or non-finite radius. `field` prefixes messages ("shape.polygon").
Status make_polygon(std::span<const Vec2> ccw_vertices, double radius, Polygon* out,
                    const char* field = "polygon");
// The convex hull of an arbitrary point set, counter-clockwise, collinear points removed and
// points closer than kGeometryTolerance welded. Refuses fewer than 3 distinct points, a
// degenerate (collinear) set, and hulls with more than kMaxPolygonVertices vertices.
Status compute_hull(std::span<const Vec2> points, std::vector<Vec2>* hull);

// Checks that every value is finite and every size is in range; names the field on failure.
Status validate_geometry(const Geometry& g, const char* field = "shape");

// --- Mass properties (density in kg/m^2, > 0) ------------------------------------------------

MassData compute_mass(const Circle& c, double density);
MassData compute_mass(const Capsule& c, double density);
MassData compute_mass(const Polygon& p, double density);   // includes the rounding radius
MassData compute_mass(const Geometry& g, double density);  // segments have no mass

// --- Bounds, ray casts and point tests -------------------------------------------------------

AABB compute_aabb(const Geometry& g, const Transform& xf);

// The box around count >= 1 points placed by xf, widened by radius: a circle's (one point), a
// capsule's (two) and a polygon's. compute_aabb and the broad phase's packed outlines share it.
inline AABB box_around(const Vec2* points, int count, double radius, const Transform& xf) {
  Vec2 lower = xf.apply(points[0]);
  Vec2 upper = lower;
  for (int i = 1; i < count; ++i) {
    Vec2 v = xf.apply(points[i]);
    lower = lower.cwiseMin(v);
    upper = upper.cwiseMax(v);
  }
  Vec2 r(radius, radius);
  return AABB{lower - r, upper + r};
}

// A ray from origin to origin + max_fraction * translation.
struct RayCastInput {
  Vec2 origin = Vec2::Zero();
  Vec2 translation = Vec2::Zero();
  double max_fraction = 1.0;
};

struct CastOutput {
  Vec2 normal = Vec2::Zero();  // surface normal at the hit, pointing toward the ray origin side
  Vec2 point = Vec2::Zero();   // hit point
  double fraction = 0.0;       // hit at origin + fraction * translation
  bool hit = false;
};

// The ray is given in the shape's local frame, and so is the output. A ray starting inside a
// solid shape does not hit it. Segments are two-sided.
CastOutput ray_cast(const Circle& shape, const RayCastInput& input);
CastOutput ray_cast(const Capsule& shape, const RayCastInput& input);
CastOutput ray_cast(const Segment& shape, const RayCastInput& input);
CastOutput ray_cast(const Polygon& shape, const RayCastInput& input);
CastOutput ray_cast(const Geometry& g, const RayCastInput& input);

// Whether a local point lies inside the solid shape (segments contain no points).
bool contains_point(const Geometry& g, const Vec2& local_point);

}  // namespace fulcrum
