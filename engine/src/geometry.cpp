// Shape construction, validation, mass properties, bounds, ray casts and point tests. All of it
// works in the shape's local frame unless a transform is passed in.

#include "fulcrum/geometry.h"

#include <charconv>
#include <cmath>
#include <string>

#include "fulcrum/trig.h"

namespace fulcrum {
namespace {

// Shortest decimal that round-trips, so messages read "(got -1)" rather than "(got -1.000000)".
std::string format_number(double x) {
  char buf[64];
  auto result = std::to_chars(buf, buf + sizeof(buf), x);
  return std::string(buf, result.ptr);
}

std::string format_vec(const Vec2& v) {
  return "(" + format_number(v.x()) + ", " + format_number(v.y()) + ")";
}

// Distance of b from the line through its neighbours a and c, positive when a -> b -> c turns
// left (b bulges outward of a counter-clockwise polygon). turn = cross(b - a, c - b) is twice
// the triangle's area, and dividing by the base |c - a| leaves the triangle's height.
// compute_hull (hull.cpp) uses the same expression so that its output always passes
// make_polygon.
double bulge(const Vec2& a, const Vec2& b, const Vec2& c) {
  double base = length(c - a);
  if (base == 0.0) return 0.0;
  return cross(b - a, c - b) / base;
}

// --- Mass helpers -----------------------------------------------------------------------------

// Mass properties accumulated about a reference point: area, first moment and second (polar)
// moment, all per unit density.
struct Moments {
  double area = 0.0;
  Vec2 first = Vec2::Zero();  // integral of (p - ref) dA
  double second = 0.0;        // integral of |p - ref|^2 dA
};

// Adds a piece with area a, centroid c (relative to the reference point) and polar moment
// i_c about its own centroid: by the parallel axis theorem its moment about the reference is
// i_c + a |c|^2.
void add_piece(Moments* m, double a, const Vec2& c, double i_c) {
  m->area += a;
  m->first += a * c;
  m->second += i_c + a * length_squared(c);
}

MassData finish_mass(const Moments& m, const Vec2& ref, double density) {
  MassData out;
  if (m.area <= 0.0) {
    out.center = ref;
    return out;
  }
  Vec2 c = m.first / m.area;  // centre of mass relative to ref
  out.mass = density * m.area;
  out.center = ref + c;
  // Back from the reference point to the centre of mass: I_cm = I_ref - m |c|^2.
  out.rotational_inertia = density * (m.second - m.area * length_squared(c));
  return out;
}

// --- Ray cast helpers -------------------------------------------------------------------------

CastOutput no_hit() {
  return CastOutput{};
}

CastOutput make_hit(const RayCastInput& in, double fraction, const Vec2& normal) {
  CastOutput out;
  out.hit = true;
  out.fraction = fraction;
  out.point = in.origin + fraction * in.translation;
  out.normal = normal;
  return out;
}

// The first entry of the ray into the disc |p - center| <= radius. With d the unit ray
// direction and s = origin - center, the closest approach is at distance t = -s.d along the
// ray, at squared distance cc = |s + t d|^2 from the centre; the ray enters the disc at
// t - sqrt(r^2 - cc). A ray starting inside has t - sqrt(...) < 0 and does not hit.
CastOutput ray_cast_disc(const Vec2& center, double radius, const RayCastInput& in) {
  double len = length(in.translation);
  if (len == 0.0 || !(radius > 0.0)) return no_hit();
  Vec2 d = in.translation / len;
  Vec2 s = in.origin - center;
  double t = -dot(s, d);
  Vec2 closest = s + t * d;
  double cc = length_squared(closest);
  double rr = radius * radius;
  if (cc > rr) return no_hit();
  double h = std::sqrt(rr - cc);
  double dist = t - h;
  if (dist < 0.0 || dist > in.max_fraction * len) return no_hit();
  double fraction = dist / len;
  CastOutput out = make_hit(in, fraction, Vec2::Zero());
  out.normal = normalize_or_zero(out.point - center);
  return out;
}

// The ray against the segment a -> b seen only from the side `normal` points to (the outside of
// a solid). The line is dot(normal, p - a) = 0; the ray meets it at
// t = dot(normal, a - origin) / dot(normal, translation), and only while moving against the
// normal, i.e. entering.
CastOutput ray_cast_one_sided(const Vec2& a, const Vec2& b, const Vec2& normal,
                              const RayCastInput& in) {
  double denom = dot(normal, in.translation);
  if (!(denom < 0.0)) return no_hit();
  double t = dot(normal, a - in.origin) / denom;
  if (t < 0.0 || t > in.max_fraction) return no_hit();
  Vec2 p = in.origin + t * in.translation;
  Vec2 e = b - a;
  double ee = length_squared(e);
  if (ee == 0.0) return no_hit();
  double s = dot(p - a, e);
  if (s < 0.0 || s > ee) return no_hit();
  return make_hit(in, t, normal);
}

// Keeps the earlier of two hits.
void keep_first(CastOutput* best, const CastOutput& candidate) {
  if (candidate.hit && (!best->hit || candidate.fraction < best->fraction)) *best = candidate;
}

// Squared distance from p to the segment a -> b.
double distance_squared_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  Vec2 e = b - a;
  double ee = length_squared(e);
  double t = ee > 0.0 ? std::clamp(dot(p - a, e) / ee, 0.0, 1.0) : 0.0;
  return distance_squared(p, a + t * e);
}

bool polygon_contains(const Polygon& poly, const Vec2& p) {
  if (poly.count < 3) return false;
  // Inside the core: on the inner side of every edge's supporting line.
  bool inside_core = true;
  for (int i = 0; i < poly.count; ++i) {
    if (dot(poly.normals[i], p - poly.vertices[i]) > 0.0) {
      inside_core = false;
      break;
    }
  }
  if (inside_core) return true;
  if (!(poly.radius > 0.0)) return false;
  // Rounded: within radius of the core's boundary.
  double rr = poly.radius * poly.radius;
  for (int i = 0; i < poly.count; ++i) {
    const Vec2& a = poly.vertices[i];
    const Vec2& b = poly.vertices[i + 1 < poly.count ? i + 1 : 0];
    if (distance_squared_to_segment(p, a, b) <= rr) return true;
  }
  return false;
}

bool capsule_contains(const Capsule& c, const Vec2& p) {
  return distance_squared_to_segment(p, c.center1, c.center2) <= c.radius * c.radius;
}

std::string magnitude_rule() {
  static_assert(kMaxInputMagnitude == 1e12, "the text below names the bound");
  return "at most 1e12 in magnitude";
}

Status check_finite(const Vec2& v, const std::string& name) {
  if (!is_finite(v)) return invalid_argument(name + ": must be finite (got " + format_vec(v) + ")");
  if (!(std::fabs(v.x()) <= kMaxInputMagnitude && std::fabs(v.y()) <= kMaxInputMagnitude)) {
    return invalid_argument(name + ": each coordinate must be " + magnitude_rule() + " (got " +
                            format_vec(v) + ")");
  }
  return Status::ok_status();
}

Status check_positive(double x, const std::string& name) {
  if (!is_finite(x) || !(x > 0.0)) {
    return invalid_argument(name + ": must be finite and > 0 (got " + format_number(x) + ")");
  }
  if (!(x <= kMaxInputMagnitude)) {
    return invalid_argument(name + ": must be " + magnitude_rule() + " (got " + format_number(x) +
                            ")");
  }
  return Status::ok_status();
}

}  // namespace

const char* shape_type_name(ShapeType type) {
  switch (type) {
    case ShapeType::kCircle:
      return "circle";
    case ShapeType::kCapsule:
      return "capsule";
    case ShapeType::kSegment:
      return "segment";
    case ShapeType::kPolygon:
      return "polygon";
  }
  return "unknown";
}

// --- Construction and validation -------------------------------------------------------------

Polygon make_box(double hx, double hy) {
  Polygon p;
  // Unused slots are zeroed (Eigen leaves them uninitialised) so that copies, hashes and
  // serialised bytes of a polygon never depend on garbage.
  p.vertices.fill(Vec2::Zero());
  p.normals.fill(Vec2::Zero());
  p.count = 4;
  p.vertices[0] = Vec2(-hx, -hy);
  p.vertices[1] = Vec2(hx, -hy);
  p.vertices[2] = Vec2(hx, hy);
  p.vertices[3] = Vec2(-hx, hy);
  p.normals[0] = Vec2(0.0, -1.0);
  p.normals[1] = Vec2(1.0, 0.0);
  p.normals[2] = Vec2(0.0, 1.0);
  p.normals[3] = Vec2(-1.0, 0.0);
  p.centroid = Vec2::Zero();
  p.radius = 0.0;
  return p;
}

Polygon make_offset_box(double hx, double hy, const Vec2& center, double angle) {
  Polygon p = make_box(hx, hy);
  Rot q = Rot::from_angle(angle);
  for (int i = 0; i < p.count; ++i) {
    p.vertices[i] = q.rotate(p.vertices[i]) + center;
    p.normals[i] = q.rotate(p.normals[i]);
  }
  p.centroid = center;
  return p;
}

Status make_polygon(std::span<const Vec2> ccw_vertices, double radius, Polygon* out,
                    const char* field) {
  const std::string f(field);
  const std::string vf = f + ".vertices";
  const int n = static_cast<int>(ccw_vertices.size());
  if (n < 3 || n > kMaxPolygonVertices) {
    return invalid_argument(vf + ": a polygon needs 3 to " + std::to_string(kMaxPolygonVertices) +
                            " vertices (got " + std::to_string(n) + ")");
  }
  for (int i = 0; i < n; ++i) {
    Status s = check_finite(ccw_vertices[i], vf + "[" + std::to_string(i) + "]");
    if (!s.ok()) return s;
  }
  if (!is_finite(radius) || radius < 0.0) {
    return invalid_argument(f + ".radius: must be finite and >= 0 (got " + format_number(radius) +
                            ")");
  }
  if (!(radius <= kMaxInputMagnitude)) {
    return invalid_argument(f + ".radius: must be " + magnitude_rule() + " (got " +
                            format_number(radius) + ")");
  }
  auto at = [&](int i) -> const Vec2& { return ccw_vertices[static_cast<size_t>((i + n) % n)]; };

  for (int i = 0; i < n; ++i) {
    double len = distance(at(i), at(i + 1));
    if (len < kGeometryTolerance) {
      return invalid_argument(vf + ": edge from vertex " + std::to_string(i) + " to vertex " +
                              std::to_string((i + 1) % n) + " has length " + format_number(len) +
                              ", shorter than " + format_number(kGeometryTolerance));
    }
  }

  // Convexity, vertex by vertex: each vertex must stand out of the chord joining its
  // neighbours by at least kGeometryTolerance, to the left when walking counter-clockwise.
  // Clockwise input turns right everywhere: no vertex bulges left and at least one clearly
  // bulges right (a fully collinear set is reported as collinear below instead).
  double bulges[kMaxPolygonVertices];
  bool any_left = false;
  bool any_right = false;
  for (int i = 0; i < n; ++i) {
    bulges[i] = bulge(at(i - 1), at(i), at(i + 1));
    if (bulges[i] >= kGeometryTolerance) any_left = true;
    if (bulges[i] <= -kGeometryTolerance) any_right = true;
  }
  if (any_right && !any_left) {
    return invalid_argument(vf +
                            ": vertices are in clockwise order; counter-clockwise is required");
  }
  for (int i = 0; i < n; ++i) {
    if (bulges[i] >= kGeometryTolerance) continue;
    // A right turn, a hairpin (the neighbours coincide, folding the outline back on itself) or
    // a NaN from coordinates so large that the arithmetic overflows.
    if (!(bulges[i] > -kGeometryTolerance) ||
        !(distance(at(i - 1), at(i + 1)) >= kGeometryTolerance)) {
      return invalid_argument(vf + ": polygon is not convex at vertex " + std::to_string(i));
    }
    return invalid_argument(vf + ": vertex " + std::to_string(i) +
                            " is collinear with its neighbours (within " +
                            format_number(kGeometryTolerance) + ")");
  }
  // Every turn is to the left, yet the outline can still wind around more than once (a
  // pentagram). A convex counter-clockwise polygon has every vertex on the inner side of every
  // edge.
  for (int i = 0; i < n; ++i) {
    Vec2 a = at(i);
    Vec2 e = at(i + 1) - a;
    for (int j = 0; j < n; ++j) {
      if (j == i || j == (i + 1) % n) continue;
      if (!(cross(e, at(j) - a) > 0.0)) {
        return invalid_argument(vf + ": polygon is not convex (it winds more than once; vertex " +
                                std::to_string(j) + " lies outside edge " + std::to_string(i) +
                                ")");
      }
    }
  }

  Polygon p;
  p.vertices.fill(Vec2::Zero());  // unused slots zeroed, as in make_box
  p.normals.fill(Vec2::Zero());
  p.count = n;
  p.radius = radius;
  for (int i = 0; i < n; ++i) p.vertices[i] = at(i);
  // Outward normal of a counter-clockwise edge e: e turned clockwise, (e.y, -e.x).
  for (int i = 0; i < n; ++i) p.normals[i] = normalize_or_zero(right_perp(at(i + 1) - at(i)));

  // Centroid of the core polygon by a triangle fan from vertex 0 (small coordinates, less
  // cancellation): each triangle (v0, v0 + e1, v0 + e2) has area cross(e1, e2) / 2 and centroid
  // v0 + (e1 + e2) / 3.
  double area = 0.0;
  Vec2 moment = Vec2::Zero();
  for (int i = 1; i + 1 < n; ++i) {
    Vec2 e1 = at(i) - at(0);
    Vec2 e2 = at(i + 1) - at(0);
    double a = 0.5 * cross(e1, e2);
    area += a;
    moment += a * (e1 + e2) / 3.0;
  }
  p.centroid = at(0) + moment / area;
  *out = p;
  return Status::ok_status();
}

Status validate_geometry(const Geometry& g, const char* field) {
  const std::string f(field);
  switch (geometry_type(g)) {
    case ShapeType::kCircle: {
      const Circle& c = std::get<Circle>(g);
      Status s = check_finite(c.center, f + ".circle.center");
      if (!s.ok()) return s;
      return check_positive(c.radius, f + ".circle.radius");
    }
    case ShapeType::kCapsule: {
      const Capsule& c = std::get<Capsule>(g);
      Status s = check_finite(c.center1, f + ".capsule.center1");
      if (!s.ok()) return s;
      s = check_finite(c.center2, f + ".capsule.center2");
      if (!s.ok()) return s;
      s = check_positive(c.radius, f + ".capsule.radius");
      if (!s.ok()) return s;
      double len = distance(c.center1, c.center2);
      if (!(len > kGeometryTolerance)) {
        return invalid_argument(f + ".capsule: center1 and center2 must be more than " +
                                format_number(kGeometryTolerance) + " apart (got " +
                                format_number(len) + ")");
      }
      return Status::ok_status();
    }
    case ShapeType::kSegment: {
      const Segment& sg = std::get<Segment>(g);
      Status s = check_finite(sg.point1, f + ".segment.point1");
      if (!s.ok()) return s;
      s = check_finite(sg.point2, f + ".segment.point2");
      if (!s.ok()) return s;
      double len = distance(sg.point1, sg.point2);
      if (!(len > kGeometryTolerance)) {
        return invalid_argument(f + ".segment: point1 and point2 must be more than " +
                                format_number(kGeometryTolerance) + " apart (got " +
                                format_number(len) + ")");
      }
      return Status::ok_status();
    }
    case ShapeType::kPolygon: {
      const Polygon& p = std::get<Polygon>(g);
      const std::string pf = f + ".polygon";
      if (p.count < 3 || p.count > kMaxPolygonVertices) {
        return invalid_argument(pf + ".count: must be in [3, " +
                                std::to_string(kMaxPolygonVertices) + "] (got " +
                                std::to_string(p.count) + ")");
      }
      for (int i = 0; i < p.count; ++i) {
        Status s = check_finite(p.normals[i], pf + ".normals[" + std::to_string(i) + "]");
        if (!s.ok()) return s;
      }
      Status s = check_finite(p.centroid, pf + ".centroid");
      if (!s.ok()) return s;
      // Vertices (finite, edge lengths, convex, counter-clockwise) and radius exactly as
      // make_polygon checks them, so a hand-built polygon gets the same scrutiny.
      Polygon rebuilt;
      s = make_polygon(std::span<const Vec2>(p.vertices.data(), static_cast<size_t>(p.count)),
                       p.radius, &rebuilt, pf.c_str());
      if (!s.ok()) return s;
      // The normals must belong to the edges. Recomputing them from vertex differences loses
      // up to ulp(|v|) / kGeometryTolerance (~2e-8 for coordinates of 1e4), far below 1e-6,
      // while a wrong normal is off by much more.
      for (int i = 0; i < p.count; ++i) {
        if (!(distance(p.normals[i], rebuilt.normals[i]) <= 1e-6)) {
          return invalid_argument(pf + ".normals[" + std::to_string(i) +
                                  "]: is not the outward unit normal of edge " + std::to_string(i) +
                                  " (expected " + format_vec(rebuilt.normals[i]) + ", got " +
                                  format_vec(p.normals[i]) + ")");
        }
      }
      return Status::ok_status();
    }
  }
  return invalid_argument(f + ": unknown shape type");
}

// --- Mass properties -------------------------------------------------------------------------

// A disc of radius r: area pi r^2, polar moment about its centre (pi r^2) r^2 / 2.
MassData compute_mass(const Circle& c, double density) {
  double rr = c.radius * c.radius;
  double mass = density * kPi * rr;
  return MassData{mass, c.center, 0.5 * mass * rr};
}

// A rectangle of length L = |c2 - c1| and width 2r, plus two half discs that make one disc.
//   rectangle: m_b = rho 2 r L, I = m_b (L^2 + 4 r^2) / 12 about the centre;
//   half disc: its centroid lies 4r/(3 pi) from the flat side, i.e. at d = L/2 + 4r/(3 pi) from
//   the capsule centre. Its moment about the flat side's midpoint is (m_c/2) r^2/2, so about the
//   capsule centre it is (m_c/2) (r^2/2 - (4r/(3 pi))^2 + d^2). Both halves together, with
//   m_c = rho pi r^2:  m_c (r^2/2 + L^2/4 + L 4r/(3 pi)).
MassData compute_mass(const Capsule& c, double density) {
  double r = c.radius;
  double rr = r * r;
  double len = distance(c.center1, c.center2);
  double box_mass = density * 2.0 * r * len;
  double disc_mass = density * kPi * rr;
  double lc = 4.0 * r / (3.0 * kPi);
  double box_inertia = box_mass * (len * len + 4.0 * rr) / 12.0;
  double disc_inertia = disc_mass * (0.5 * rr + 0.25 * len * len + len * lc);
  return MassData{box_mass + disc_mass, 0.5 * (c.center1 + c.center2), box_inertia + disc_inertia};
}

// Exact mass of a convex polygon rounded by radius r, i.e. every point within r of the core:
// the core polygon, plus a rectangle of depth r on the outside of each edge, plus a circular
// sector of radius r at each vertex spanning the angle between its two edge normals (these
// angles sum to 2 pi, so the sectors make up one disc). Moments are accumulated about
// vertex 0 to keep coordinates small.
MassData compute_mass(const Polygon& poly, double density) {
  const int n = poly.count;
  if (n < 3) return MassData{};
  const Vec2 ref = poly.vertices[0];
  Moments m;

  // Core, as a fan of triangles (0, e1, e2) relative to ref. For such a triangle with
  // D = cross(e1, e2): area D/2, centroid (e1 + e2)/3, and
  //   integral |p|^2 dA = D/12 (e1.e1 + e1.e2 + e2.e2)   (about ref).
  for (int i = 1; i + 1 < n; ++i) {
    Vec2 e1 = poly.vertices[i] - ref;
    Vec2 e2 = poly.vertices[i + 1] - ref;
    double d = cross(e1, e2);
    m.area += 0.5 * d;
    m.first += (0.5 * d / 3.0) * (e1 + e2);
    m.second += (d / 12.0) * (dot(e1, e1) + dot(e1, e2) + dot(e2, e2));
  }

  double r = poly.radius;
  if (r > 0.0) {
    double rr = r * r;
    for (int i = 0; i < n; ++i) {
      const Vec2& a = poly.vertices[i];
      const Vec2& b = poly.vertices[i + 1 < n ? i + 1 : 0];
      const Vec2& normal = poly.normals[i];
      // Edge rectangle L x r: centroid at the edge midpoint pushed out by r/2, own polar moment
      // A (L^2 + r^2) / 12.
      double len = distance(a, b);
      double area = len * r;
      Vec2 c = 0.5 * (a + b) + (0.5 * r) * normal - ref;
      add_piece(&m, area, c, area * (len * len + rr) / 12.0);

      // Vertex sector between the previous edge's normal n1 and this one's n2, of angle theta:
      // area r^2 theta / 2, centroid on the bisector at 4 r sin(theta/2) / (3 theta) from the
      // vertex, polar moment about the vertex A r^2 / 2. sin(theta/2) = |n2 - n1| / 2.
      const Vec2& n1 = poly.normals[i > 0 ? i - 1 : n - 1];
      const Vec2& n2 = poly.normals[i];
      double theta = det_atan2(cross(n1, n2), dot(n1, n2));
      if (theta > 0.0) {
        double sector_area = 0.5 * rr * theta;
        double dist = 2.0 * r * length(n2 - n1) / (3.0 * theta);
        Vec2 bisector = normalize_or_zero(n1 + n2);
        Vec2 sc = a + dist * bisector - ref;
        // Moment about its centroid from the one about the vertex: A r^2/2 - A dist^2.
        add_piece(&m, sector_area, sc, sector_area * (0.5 * rr - dist * dist));
      }
    }
  }
  return finish_mass(m, ref, density);
}

MassData compute_mass(const Geometry& g, double density) {
  switch (geometry_type(g)) {
    case ShapeType::kCircle:
      return compute_mass(std::get<Circle>(g), density);
    case ShapeType::kCapsule:
      return compute_mass(std::get<Capsule>(g), density);
    case ShapeType::kSegment: {
      const Segment& s = std::get<Segment>(g);
      return MassData{0.0, 0.5 * (s.point1 + s.point2), 0.0};
    }
    case ShapeType::kPolygon:
      return compute_mass(std::get<Polygon>(g), density);
  }
  return MassData{};
}

// --- Bounds, ray casts and point tests -------------------------------------------------------

AABB compute_aabb(const Geometry& g, const Transform& xf) {
  switch (geometry_type(g)) {
    case ShapeType::kCircle: {
      const Circle& c = std::get<Circle>(g);
      return box_around(&c.center, 1, c.radius, xf);
    }
    case ShapeType::kCapsule: {
      const Capsule& c = std::get<Capsule>(g);
      const Vec2 ends[2] = {c.center1, c.center2};
      return box_around(ends, 2, c.radius, xf);
    }
    case ShapeType::kSegment: {
      const Segment& s = std::get<Segment>(g);
      Vec2 a = xf.apply(s.point1);
      Vec2 b = xf.apply(s.point2);
      return AABB{a.cwiseMin(b), a.cwiseMax(b)};
    }
    case ShapeType::kPolygon: {
      const Polygon& p = std::get<Polygon>(g);
      if (p.count <= 0) return AABB{xf.p, xf.p};
      return box_around(p.vertices.data(), p.count, p.radius, xf);
    }
  }
  return AABB{};
}

CastOutput ray_cast(const Circle& shape, const RayCastInput& input) {
  return ray_cast_disc(shape.center, shape.radius, input);
}

// A capsule is the union of two discs and the rectangle between them. From outside, the first
// boundary crossing is on one of the discs or one of the rectangle's two long sides (its short
// sides lie inside the discs), so the earliest of those four hits is the answer.
CastOutput ray_cast(const Capsule& shape, const RayCastInput& input) {
  if (capsule_contains(shape, input.origin)) return no_hit();
  CastOutput best;
  keep_first(&best, ray_cast_disc(shape.center1, shape.radius, input));
  keep_first(&best, ray_cast_disc(shape.center2, shape.radius, input));
  Vec2 axis = normalize_or_zero(shape.center2 - shape.center1);
  if (length_squared(axis) > 0.0) {
    Vec2 n = right_perp(axis);
    Vec2 off = shape.radius * n;
    keep_first(&best, ray_cast_one_sided(shape.center1 + off, shape.center2 + off, n, input));
    keep_first(&best, ray_cast_one_sided(shape.center2 - off, shape.center1 - off, -n, input));
  }
  return best;
}

// origin + t d = p1 + s e with d = translation and e = p2 - p1. Crossing both sides with e and
// with d gives t = cross(p1 - origin, e) / cross(d, e) and s = cross(p1 - origin, d) / cross(d, e).
CastOutput ray_cast(const Segment& shape, const RayCastInput& input) {
  Vec2 e = shape.point2 - shape.point1;
  const Vec2& d = input.translation;
  double denom = cross(d, e);
  if (denom == 0.0) return no_hit();  // parallel (or degenerate): no single crossing
  Vec2 w = shape.point1 - input.origin;
  double t = cross(w, e) / denom;
  double s = cross(w, d) / denom;
  if (t < 0.0 || t > input.max_fraction || s < 0.0 || s > 1.0) return no_hit();
  Vec2 normal = normalize_or_zero(left_perp(e));
  // Two-sided: the normal faces the side the ray comes from.
  if (dot(normal, d) > 0.0) normal = -normal;
  return make_hit(input, t, normal);
}

CastOutput ray_cast(const Polygon& shape, const RayCastInput& input) {
  const int n = shape.count;
  if (n < 3) return no_hit();
  if (shape.radius > 0.0) {
    // The rounded polygon is the union of the core, one rectangle of depth r outside each edge
    // and one disc of radius r at each vertex. From outside, the first crossing is on an offset
    // edge or a vertex disc, so the earliest of those hits is the answer.
    if (polygon_contains(shape, input.origin)) return no_hit();
    CastOutput best;
    for (int i = 0; i < n; ++i) {
      const Vec2& a = shape.vertices[i];
      const Vec2& b = shape.vertices[i + 1 < n ? i + 1 : 0];
      Vec2 off = shape.radius * shape.normals[i];
      keep_first(&best, ray_cast_one_sided(a + off, b + off, shape.normals[i], input));
      keep_first(&best, ray_cast_disc(a, shape.radius, input));
    }
    return best;
  }

  // Clip the ray [0, max_fraction] against each edge's half plane dot(n, p - v) <= 0. Along the
  // ray, dot(n, origin + t d - v) = 0 at t = dot(n, v - origin) / dot(n, d); the ray enters the
  // half plane there when dot(n, d) < 0 and leaves it when dot(n, d) > 0.
  double lower = 0.0;
  double upper = input.max_fraction;
  int index = -1;
  for (int i = 0; i < n; ++i) {
    double numerator = dot(shape.normals[i], shape.vertices[i] - input.origin);
    double denominator = dot(shape.normals[i], input.translation);
    if (denominator == 0.0) {
      if (numerator < 0.0) return no_hit();  // parallel to and outside this edge
      continue;
    }
    double t = numerator / denominator;
    if (denominator < 0.0 && t > lower) {
      lower = t;
      index = i;
    } else if (denominator > 0.0 && t < upper) {
      upper = t;
    }
    if (upper < lower) return no_hit();
  }
  // No entering edge: the origin is inside (or on the boundary) and the ray does not hit.
  if (index < 0) return no_hit();
  return make_hit(input, lower, shape.normals[index]);
}

CastOutput ray_cast(const Geometry& g, const RayCastInput& input) {
  return std::visit([&](const auto& shape) { return ray_cast(shape, input); }, g);
}

bool contains_point(const Geometry& g, const Vec2& local_point) {
  switch (geometry_type(g)) {
    case ShapeType::kCircle: {
      const Circle& c = std::get<Circle>(g);
      return distance_squared(local_point, c.center) <= c.radius * c.radius;
    }
    case ShapeType::kCapsule:
      return capsule_contains(std::get<Capsule>(g), local_point);
    case ShapeType::kSegment:
      return false;
    case ShapeType::kPolygon:
      return polygon_contains(std::get<Polygon>(g), local_point);
  }
  return false;
}

}  // namespace fulcrum
