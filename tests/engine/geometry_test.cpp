// Shape geometry: construction and validation, mass properties against closed forms and
// numerical integration, convex hulls against brute force, ray casts, point tests and bounds.

#include "fulcrum/geometry.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "fulcrum/math.h"
#include "fulcrum/trig.h"

namespace fulcrum {
namespace {

// Mass properties are sums of a handful of products; each carries a relative rounding error of
// ~1e-16, so agreement with an independently written closed form to 1e-12 relative leaves
// four orders of magnitude of slack and still catches any wrong term.
constexpr double kRelTol = 1e-12;

void expect_rel_near(double actual, double expected, double rel, const char* what) {
  EXPECT_NEAR(actual, expected, rel * std::fabs(expected)) << what;
}

void expect_vec_near(const Vec2& a, const Vec2& b, double tol) {
  EXPECT_NEAR(a.x(), b.x(), tol);
  EXPECT_NEAR(a.y(), b.y(), tol);
}

// Deterministic uniform doubles in [lo, hi) from the top 53 bits of a 64-bit generator
// (std::uniform_real_distribution differs between standard libraries).
struct Rng {
  uint64_t state;
  uint64_t next() {
    // splitmix64
    uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(next() >> 11) * 0x1.0p-53);
  }
};

// Mass properties by the midpoint rule on an n x n grid over `box`, using contains_point. An
// independent check of both compute_mass and contains_point for shapes with curved boundaries.
MassData integrate_mass(const Geometry& g, const AABB& box, int n, double density) {
  double hx = (box.upper.x() - box.lower.x()) / n;
  double hy = (box.upper.y() - box.lower.y()) / n;
  double area = 0.0;
  Vec2 first = Vec2::Zero();
  double second = 0.0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      Vec2 p(box.lower.x() + (i + 0.5) * hx, box.lower.y() + (j + 0.5) * hy);
      if (!contains_point(g, p)) continue;
      area += 1.0;
      first += p;
      second += length_squared(p);
    }
  }
  double cell = hx * hy;
  MassData out;
  out.mass = density * area * cell;
  out.center = first / area;
  out.rotational_inertia = density * cell * (second - area * length_squared(out.center));
  return out;
}

// --- Construction -----------------------------------------------------------------------------

TEST(GeometryTest, ShapeTypeNames) {
  EXPECT_STREQ(shape_type_name(ShapeType::kCircle), "circle");
  EXPECT_STREQ(shape_type_name(ShapeType::kCapsule), "capsule");
  EXPECT_STREQ(shape_type_name(ShapeType::kSegment), "segment");
  EXPECT_STREQ(shape_type_name(ShapeType::kPolygon), "polygon");
  EXPECT_EQ(geometry_type(Geometry{Capsule{}}), ShapeType::kCapsule);
}

TEST(GeometryTest, MakeBoxIsCounterClockwiseWithOutwardNormals) {
  Polygon box = make_box(2.0, 0.5);
  ASSERT_EQ(box.count, 4);
  EXPECT_EQ(box.vertices[0], Vec2(-2.0, -0.5));
  EXPECT_EQ(box.vertices[2], Vec2(2.0, 0.5));
  for (int i = 0; i < 4; ++i) {
    Vec2 e = box.vertices[(i + 1) % 4] - box.vertices[i];
    EXPECT_GT(cross(box.vertices[i], box.vertices[(i + 1) % 4]), 0.0);  // CCW about the centre
    EXPECT_EQ(dot(box.normals[i], e), 0.0);                             // normal is perpendicular
    EXPECT_GT(dot(box.normals[i], box.vertices[i]), 0.0);               // and points outward
  }
  EXPECT_EQ(box.centroid, Vec2::Zero());
  EXPECT_TRUE(validate_geometry(box).ok());
}

TEST(GeometryTest, OffsetBoxCentroidAndMass) {
  const Vec2 center(3.0, -2.0);
  Polygon box = make_offset_box(0.5, 0.25, center, 0.7);
  EXPECT_EQ(box.centroid, center);
  // The vertices are the rotated corners: all at the half-diagonal from the centre (rounding of
  // the rotation and the translation by ~3 leaves errors of a few 1e-16).
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(distance(box.vertices[i], center), std::sqrt(0.25 + 0.0625), 1e-15);
    EXPECT_NEAR(length(box.normals[i]), 1.0, 1e-15);
  }
  EXPECT_NEAR(box.normals[1].x(), det_cos(0.7), 1e-15);
  EXPECT_NEAR(box.normals[1].y(), det_sin(0.7), 1e-15);
  ASSERT_TRUE(validate_geometry(box).ok());

  // Mass properties do not depend on placement: centre at the offset, inertia m (w^2 + h^2)/12
  // about it. Vertices near (3, -2) lose a few bits in the fan, hence 1e-12 absolute on centre.
  MassData md = compute_mass(box, 2.0);
  expect_rel_near(md.mass, 2.0 * 1.0 * 0.5, kRelTol, "mass");
  expect_vec_near(md.center, center, 1e-12);
  expect_rel_near(md.rotational_inertia, md.mass * (1.0 + 0.25) / 12.0, kRelTol, "inertia");
}

TEST(GeometryTest, MakePolygonComputesNormalsAndCentroid) {
  const Vec2 pts[] = {Vec2(0.0, 0.0), Vec2(3.0, 0.0), Vec2(0.0, 3.0)};
  Polygon p;
  ASSERT_TRUE(make_polygon(pts, 0.0, &p).ok());
  EXPECT_EQ(p.count, 3);
  // Centroid of a triangle is the mean of its vertices. Exact inputs, few operations: 1e-15.
  expect_vec_near(p.centroid, Vec2(1.0, 1.0), 1e-15);
  expect_vec_near(p.normals[0], Vec2(0.0, -1.0), 1e-15);
  expect_vec_near(p.normals[1], Vec2(std::sqrt(0.5), std::sqrt(0.5)), 1e-15);
  expect_vec_near(p.normals[2], Vec2(-1.0, 0.0), 1e-15);
  EXPECT_EQ(p.radius, 0.0);

  Polygon rounded;
  ASSERT_TRUE(make_polygon(pts, 0.1, &rounded).ok());
  EXPECT_EQ(rounded.radius, 0.1);
}

// Expects a refusal whose message names the field and contains `reason`.
void expect_refused(std::span<const Vec2> pts, double radius, const std::string& reason) {
  Polygon p;
  Status s = make_polygon(pts, radius, &p, "shape.polygon");
  ASSERT_FALSE(s.ok()) << reason;
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("shape.polygon"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find(reason), std::string::npos) << s.message();
}

TEST(GeometryTest, MakePolygonRefusals) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();

  const Vec2 two[] = {Vec2(0, 0), Vec2(1, 0)};
  expect_refused(two, 0.0, "shape.polygon.vertices: a polygon needs 3 to 8 vertices (got 2)");

  std::vector<Vec2> nine;
  for (int i = 0; i < 9; ++i) {
    double a = 2.0 * kPi * i / 9.0;
    nine.emplace_back(det_cos(a), det_sin(a));
  }
  expect_refused(nine, 0.0, "(got 9)");

  const Vec2 with_nan[] = {Vec2(0, 0), Vec2(1, nan), Vec2(0, 1)};
  expect_refused(with_nan, 0.0, "shape.polygon.vertices[1]: must be finite");
  const Vec2 with_inf[] = {Vec2(0, 0), Vec2(1, 0), Vec2(inf, 1)};
  expect_refused(with_inf, 0.0, "vertices[2]: must be finite");

  const Vec2 triangle[] = {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)};
  expect_refused(triangle, -0.5, "shape.polygon.radius: must be finite and >= 0 (got -0.5)");
  expect_refused(triangle, nan, "shape.polygon.radius");
  expect_refused(triangle, inf, "shape.polygon.radius");

  // An edge of 5e-5 m, below kGeometryTolerance.
  const Vec2 short_edge[] = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 0.00005), Vec2(0, 1)};
  expect_refused(short_edge, 0.0, "edge from vertex 1 to vertex 2");
  expect_refused(short_edge, 0.0, "shorter than");

  const Vec2 clockwise[] = {Vec2(0, 0), Vec2(0, 1), Vec2(1, 1), Vec2(1, 0)};
  expect_refused(clockwise, 0.0, "clockwise");

  // An arrowhead: vertex 2 points inward.
  const Vec2 dented[] = {Vec2(0, 0), Vec2(2, 0), Vec2(1, 0.5), Vec2(2, 2), Vec2(0, 2)};
  expect_refused(dented, 0.0, "shape.polygon.vertices: polygon is not convex at vertex 2");

  // Vertex 1 on the segment from 0 to 2, and a vertex only 5e-5 out of line.
  const Vec2 collinear[] = {Vec2(0, 0), Vec2(1, 0), Vec2(2, 0), Vec2(1, 1)};
  expect_refused(collinear, 0.0, "vertex 1 is collinear");
  const Vec2 nearly[] = {Vec2(0, 0), Vec2(1, -0.00005), Vec2(2, 0), Vec2(1, 1)};
  expect_refused(nearly, 0.0, "vertex 1 is collinear");
  const Vec2 all_on_a_line[] = {Vec2(0, 0), Vec2(1, 1), Vec2(2, 2)};
  expect_refused(all_on_a_line, 0.0, "collinear");

  // Coordinates so large that the convexity arithmetic would overflow are refused by the
  // input bound (kMaxInputMagnitude) before any arithmetic, not accepted with a NaN centroid.
  const Vec2 huge[] = {Vec2(-1e308, -1e308), Vec2(1e308, -1e308), Vec2(0, 1e308)};
  expect_refused(huge, 0.0,
                 "vertices[0]: each coordinate must be at most 1e12 in magnitude (got (-1e+308, "
                 "-1e+308))");

  // A pentagram turns left at every vertex but winds twice.
  std::vector<Vec2> star;
  for (int i = 0; i < 5; ++i) {
    double a = 2.0 * kPi * ((2 * i) % 5) / 5.0;
    star.emplace_back(det_cos(a), det_sin(a));
  }
  expect_refused(star, 0.0, "not convex");
}

TEST(GeometryTest, ValidateGeometry) {
  EXPECT_TRUE(validate_geometry(Circle{}).ok());
  EXPECT_TRUE(validate_geometry(Capsule{}).ok());
  EXPECT_TRUE(validate_geometry(Segment{}).ok());
  EXPECT_TRUE(validate_geometry(make_box(1.0, 1.0)).ok());

  Status s = validate_geometry(Circle{Vec2::Zero(), -1.0});
  EXPECT_EQ(s.message(), "shape.circle.radius: must be finite and > 0 (got -1)");
  s = validate_geometry(Circle{Vec2(std::numeric_limits<double>::quiet_NaN(), 0.0), 1.0}, "s");
  EXPECT_NE(s.message().find("s.circle.center: must be finite"), std::string::npos);

  s = validate_geometry(Capsule{Vec2(0, 0), Vec2(0.00005, 0), 0.5});
  EXPECT_NE(s.message().find("shape.capsule: center1 and center2 must be more than"),
            std::string::npos)
      << s.message();
  s = validate_geometry(Capsule{Vec2(0, 0), Vec2(1, 0), 0.0});
  EXPECT_NE(s.message().find("shape.capsule.radius: must be finite and > 0 (got 0)"),
            std::string::npos)
      << s.message();

  s = validate_geometry(Segment{Vec2(1, 1), Vec2(1, 1)});
  EXPECT_NE(s.message().find("shape.segment: point1 and point2"), std::string::npos);
  s = validate_geometry(Segment{Vec2(0, 0), Vec2(std::numeric_limits<double>::infinity(), 0)});
  EXPECT_NE(s.message().find("shape.segment.point2: must be finite"), std::string::npos);

  Polygon p = make_box(1.0, 1.0);
  p.count = 2;
  s = validate_geometry(p);
  EXPECT_EQ(s.message(), "shape.polygon.count: must be in [3, 8] (got 2)");
  p = make_box(1.0, 1.0);
  p.radius = -0.1;
  s = validate_geometry(p);
  EXPECT_NE(s.message().find("shape.polygon.radius"), std::string::npos) << s.message();
  p = make_box(1.0, 1.0);
  p.vertices[3] = Vec2(std::numeric_limits<double>::quiet_NaN(), 1.0);
  s = validate_geometry(p);
  EXPECT_NE(s.message().find("shape.polygon.vertices[3]: must be finite"), std::string::npos)
      << s.message();
  p = make_box(1.0, 1.0);
  p.normals[1] = Vec2(-1.0, 0.0);  // inward
  s = validate_geometry(p);
  EXPECT_NE(s.message().find("shape.polygon.normals[1]: is not the outward unit normal"),
            std::string::npos)
      << s.message();
  // Far from the origin the recomputed normals differ in the last bits; still accepted.
  EXPECT_TRUE(validate_geometry(make_offset_box(0.01, 0.02, Vec2(1e4, -3e4), 0.3)).ok());
  // A degenerate box (zero height) fails the edge length test like make_polygon would.
  s = validate_geometry(make_box(1.0, 0.0));
  EXPECT_NE(s.message().find("shape.polygon.vertices: edge"), std::string::npos) << s.message();
}

// --- Mass -------------------------------------------------------------------------------------

TEST(GeometryTest, BoxMass) {
  const double hx = 0.7;
  const double hy = 1.3;
  const double density = 2.5;
  MassData md = compute_mass(make_box(hx, hy), density);
  const double w = 2 * hx;
  const double h = 2 * hy;
  const double m = density * w * h;
  expect_rel_near(md.mass, m, kRelTol, "mass = density * area");
  expect_rel_near(md.rotational_inertia, m * (w * w + h * h) / 12.0, kRelTol, "m(w^2+h^2)/12");
  // The centre is computed from a fan about a corner; its error is a few ulps of hx.
  expect_vec_near(md.center, Vec2::Zero(), 1e-15);
}

TEST(GeometryTest, CircleMass) {
  MassData md = compute_mass(Circle{Vec2(1.0, -2.0), 0.3}, 4.0);
  const double m = 4.0 * kPi * 0.09;
  expect_rel_near(md.mass, m, kRelTol, "mass");
  expect_rel_near(md.rotational_inertia, 0.5 * m * 0.09, kRelTol, "inertia m r^2 / 2");
  EXPECT_EQ(md.center, Vec2(1.0, -2.0));
}

TEST(GeometryTest, CapsuleMass) {
  const Capsule cap{Vec2(-1.0, 0.5), Vec2(2.0, 4.5), 0.4};  // length 5, turned
  const double density = 3.0;
  MassData md = compute_mass(cap, density);

  // Closed form, built piece by piece: a 5 x 0.8 rectangle plus two half discs.
  const double len = 5.0;
  const double r = 0.4;
  const double m_rect = density * len * 2 * r;
  const double i_rect = m_rect * (len * len + (2 * r) * (2 * r)) / 12.0;
  const double m_half = density * 0.5 * kPi * r * r;
  const double d_half = 4.0 * r / (3.0 * kPi);  // centroid from the flat side
  const double i_half_own = m_half * r * r / 2.0 - m_half * d_half * d_half;  // about its centroid
  const double arm = len / 2 + d_half;  // centroid from the capsule centre
  const double i_total = i_rect + 2.0 * (i_half_own + m_half * arm * arm);

  expect_rel_near(md.mass, m_rect + 2 * m_half, kRelTol, "mass");
  expect_rel_near(md.rotational_inertia, i_total, kRelTol, "inertia");
  expect_vec_near(md.center, Vec2(0.5, 2.5), 1e-15);

  // Independent check by integration: midpoint rule on a 1500^2 grid. Boundary cells cut by the
  // outline make errors of a few 1e-5 relative (measured: below 6e-5 here and for the rounded
  // triangle); 3e-4 leaves 5x slack yet catches a wrong term (misplacing a curved piece's
  // centroid by 25% moves the inertia by 6e-3).
  Geometry g = cap;
  MassData num = integrate_mass(g, compute_aabb(g, Transform{}), 1500, density);
  expect_rel_near(num.mass, md.mass, 3e-4, "integrated mass");
  expect_rel_near(num.rotational_inertia, md.rotational_inertia, 3e-4, "integrated inertia");
  expect_vec_near(num.center, md.center, 3e-4);
}

TEST(GeometryTest, RoundedBoxMass) {
  const double hx = 1.0;
  const double hy = 0.5;
  const double r = 0.2;
  const double density = 1.5;
  Polygon box = make_box(hx, hy);
  box.radius = r;
  MassData md = compute_mass(box, density);

  // Closed form: core + four side rectangles + four quarter discs (one disc in total).
  const double area = 4 * hx * hy + 2 * r * (2 * hx) + 2 * r * (2 * hy) + kPi * r * r;
  expect_rel_near(md.mass, density * area, kRelTol, "mass = density * rounded area");

  double inertia = 0.0;
  // Core 2hx x 2hy.
  double m = density * 4 * hx * hy;
  inertia += m * (4 * hx * hx + 4 * hy * hy) / 12.0;
  // Top and bottom strips 2hx x r, centred at y = +-(hy + r/2).
  m = density * 2 * hx * r;
  inertia += 2 * (m * (4 * hx * hx + r * r) / 12.0 + m * (hy + r / 2) * (hy + r / 2));
  // Left and right strips r x 2hy, centred at x = +-(hx + r/2).
  m = density * 2 * hy * r;
  inertia += 2 * (m * (r * r + 4 * hy * hy) / 12.0 + m * (hx + r / 2) * (hx + r / 2));
  // Quarter discs at the corners: polar moment m r^2/2 about the corner; centroid offset
  // 4r/(3 pi) along both axes, outward.
  m = density * kPi * r * r / 4.0;
  const double k = 4.0 * r / (3.0 * kPi);
  const double own = m * r * r / 2.0 - m * 2.0 * k * k;
  inertia += 4 * (own + m * ((hx + k) * (hx + k) + (hy + k) * (hy + k)));
  expect_rel_near(md.rotational_inertia, inertia, kRelTol, "inertia");
  expect_vec_near(md.center, Vec2::Zero(), 1e-15);
}

TEST(GeometryTest, RoundedTriangleMassMatchesIntegration) {
  // A scalene triangle has sectors of three different angles and an off-centre centre of mass,
  // which the box does not exercise. Grid integration bound as in CapsuleMass.
  const Vec2 pts[] = {Vec2(-1.0, -0.5), Vec2(2.0, 0.0), Vec2(0.0, 1.5)};
  Polygon tri;
  ASSERT_TRUE(make_polygon(pts, 0.3, &tri).ok());
  MassData md = compute_mass(tri, 2.0);
  Geometry g = tri;
  MassData num = integrate_mass(g, compute_aabb(g, Transform{}), 1500, 2.0);
  expect_rel_near(num.mass, md.mass, 3e-4, "integrated mass");
  expect_rel_near(num.rotational_inertia, md.rotational_inertia, 3e-4, "integrated inertia");
  expect_vec_near(num.center, md.center, 3e-4);

  // Rounding adds perimeter * r + pi r^2 of area exactly (Steiner's formula).
  double perimeter = 0.0;
  for (int i = 0; i < 3; ++i) perimeter += distance(pts[i], pts[(i + 1) % 3]);
  const double core = 0.5 * cross(pts[1] - pts[0], pts[2] - pts[0]);
  expect_rel_near(md.mass, 2.0 * (core + perimeter * 0.3 + kPi * 0.09), kRelTol, "Steiner");
}

TEST(GeometryTest, GeometryMassDispatch) {
  MassData seg = compute_mass(Geometry{Segment{Vec2(0, 0), Vec2(2, 0)}}, 5.0);
  EXPECT_EQ(seg.mass, 0.0);
  EXPECT_EQ(seg.rotational_inertia, 0.0);
  MassData circle = compute_mass(Geometry{Circle{Vec2::Zero(), 1.0}}, 1.0);
  EXPECT_EQ(circle.mass, compute_mass(Circle{Vec2::Zero(), 1.0}, 1.0).mass);
}

// --- Hull -------------------------------------------------------------------------------------

// Brute force: p is a hull vertex iff some edge p -> q has every other point strictly left of it.
std::vector<Vec2> brute_force_hull_vertices(const std::vector<Vec2>& pts) {
  std::vector<Vec2> out;
  for (size_t i = 0; i < pts.size(); ++i) {
    for (size_t j = 0; j < pts.size(); ++j) {
      if (i == j) continue;
      bool all_left = true;
      for (size_t k = 0; k < pts.size() && all_left; ++k) {
        if (k == i || k == j) continue;
        if (cross(pts[j] - pts[i], pts[k] - pts[i]) <= 0.0) all_left = false;
      }
      if (all_left) {
        out.push_back(pts[i]);
        break;
      }
    }
  }
  return out;
}

bool lex_less(const Vec2& a, const Vec2& b) {
  return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
}

TEST(GeometryTest, HullOfRandomPointsMatchesBruteForce) {
  Rng rng{12345};
  for (int trial = 0; trial < 500; ++trial) {
    int n = 3 + trial % 6;  // 3..8 points, so the hull never exceeds 8 vertices
    std::vector<Vec2> pts;
    for (int i = 0; i < n; ++i) pts.emplace_back(rng.uniform(-5, 5), rng.uniform(-5, 5));
    std::vector<Vec2> hull;
    Status s = compute_hull(pts, &hull);
    ASSERT_TRUE(s.ok()) << s.message();

    // Same vertex set as brute force (random points are far from the 1e-4 tolerances).
    std::vector<Vec2> expected = brute_force_hull_vertices(pts);
    std::vector<Vec2> got = hull;
    std::sort(expected.begin(), expected.end(), lex_less);
    std::sort(got.begin(), got.end(), lex_less);
    ASSERT_EQ(got, expected) << "trial " << trial;

    // Counter-clockwise and containing every input point: each point is on the inner side of
    // each edge (a cross product of size ~100 rounds by ~1e-14).
    const size_t m = hull.size();
    for (size_t i = 0; i < m; ++i) {
      Vec2 a = hull[i];
      Vec2 e = hull[(i + 1) % m] - a;
      for (const Vec2& p : pts) EXPECT_GE(cross(e, p - a), -1e-12);
    }
    Polygon poly;
    EXPECT_TRUE(make_polygon(hull, 0.0, &poly).ok());

    // Order-independent (no near-duplicates to weld): reversed input, identical output.
    std::vector<Vec2> reversed(pts.rbegin(), pts.rend());
    std::vector<Vec2> hull2;
    ASSERT_TRUE(compute_hull(reversed, &hull2).ok());
    EXPECT_EQ(hull2, hull);
  }
}

TEST(GeometryTest, HullWeldsAndDropsCollinearPoints) {
  // A unit square with edge midpoints, interior points, a duplicate corner and a corner jittered
  // by 1e-5 (welded into the first copy).
  const std::vector<Vec2> pts = {Vec2(0, 0),   Vec2(0.5, 0),   Vec2(1, 0),
                                 Vec2(1, 0.5), Vec2(1, 1),     Vec2(0.5, 1),
                                 Vec2(0, 1),   Vec2(0, 0.5),   Vec2(0.5, 0.5),
                                 Vec2(1, 1),   Vec2(0.3, 0.6), Vec2(1.00001, 1.00001)};
  std::vector<Vec2> hull;
  ASSERT_TRUE(compute_hull(pts, &hull).ok());
  const std::vector<Vec2> expected = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
  EXPECT_EQ(hull, expected);

  // A vertex 5e-5 outside an edge is within tolerance of collinear and is dropped.
  const std::vector<Vec2> bumpy = {Vec2(0, 0), Vec2(1, -0.00005), Vec2(2, 0), Vec2(2, 2),
                                   Vec2(0, 2)};
  ASSERT_TRUE(compute_hull(bumpy, &hull).ok());
  EXPECT_EQ(hull.size(), 4u);
  // One 2e-4 outside is a real vertex.
  const std::vector<Vec2> corner = {Vec2(0, 0), Vec2(1, -0.0002), Vec2(2, 0), Vec2(2, 2),
                                    Vec2(0, 2)};
  ASSERT_TRUE(compute_hull(corner, &hull).ok());
  EXPECT_EQ(hull.size(), 5u);
}

TEST(GeometryTest, HullRefusals) {
  std::vector<Vec2> hull;
  // Three points, two of them within the weld distance.
  Status s = compute_hull(std::vector<Vec2>{Vec2(0, 0), Vec2(1, 0), Vec2(1, 0.00001)}, &hull);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("at least 3 distinct points (got 2"), std::string::npos)
      << s.message();
  EXPECT_TRUE(hull.empty());

  s = compute_hull(std::vector<Vec2>{Vec2(0, 0), Vec2(1, 1), Vec2(2, 2), Vec2(3, 3.00001)}, &hull);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("collinear"), std::string::npos) << s.message();

  std::vector<Vec2> dodecagon;
  for (int i = 0; i < 12; ++i) {
    double a = 2.0 * kPi * i / 12.0;
    dodecagon.emplace_back(det_cos(a), det_sin(a));
  }
  s = compute_hull(dodecagon, &hull);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("12 vertices, more than the maximum of 8"), std::string::npos)
      << s.message();

  s = compute_hull(
      std::vector<Vec2>{Vec2(0, 0), Vec2(1, 0), Vec2(std::numeric_limits<double>::quiet_NaN(), 1)},
      &hull);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("hull.points[2]: must be finite"), std::string::npos);
}

// --- Ray casts --------------------------------------------------------------------------------
// Hits are at hand-computed places. The arithmetic involved (a square root or one division)
// leaves errors of an ulp or two of the O(1) values, so 1e-14 is a comfortable tolerance.
constexpr double kCastTol = 1e-14;

void expect_hit(const CastOutput& out, double fraction, const Vec2& point, const Vec2& normal) {
  ASSERT_TRUE(out.hit);
  EXPECT_NEAR(out.fraction, fraction, kCastTol);
  expect_vec_near(out.point, point, kCastTol);
  expect_vec_near(out.normal, normal, kCastTol);
}

TEST(GeometryTest, RayCastCircle) {
  const Circle c{Vec2(1.0, 0.0), 1.0};
  // Along the x axis from x = -3: enters at x = 0 after 3 of 6 units.
  expect_hit(ray_cast(c, RayCastInput{Vec2(-3, 0), Vec2(6, 0), 1.0}), 0.5, Vec2(0, 0), Vec2(-1, 0));
  // Offset by 0.6: enters at x = 1 - 0.8 = 0.2 (a 3-4-5 triangle), 2 of 4 units along, with
  // normal (-0.8, 0.6).
  expect_hit(ray_cast(c, RayCastInput{Vec2(-1.8, 0.6), Vec2(4, 0), 1.0}), 0.5, Vec2(0.2, 0.6),
             Vec2(-0.8, 0.6));
  // Passing above, too short, starting inside, no translation.
  EXPECT_FALSE(ray_cast(c, RayCastInput{Vec2(-3, 1.5), Vec2(6, 0), 1.0}).hit);
  EXPECT_FALSE(ray_cast(c, RayCastInput{Vec2(-3, 0), Vec2(6, 0), 0.49}).hit);
  EXPECT_FALSE(ray_cast(c, RayCastInput{Vec2(1.5, 0), Vec2(6, 0), 1.0}).hit);
  EXPECT_FALSE(ray_cast(c, RayCastInput{Vec2(-3, 0), Vec2(0, 0), 1.0}).hit);
  // Pointing away.
  EXPECT_FALSE(ray_cast(c, RayCastInput{Vec2(-3, 0), Vec2(-6, 0), 1.0}).hit);
}

TEST(GeometryTest, RayCastCapsule) {
  const Capsule cap{Vec2(-1, 0), Vec2(1, 0), 0.5};
  // Straight down onto the flat top at y = 0.5.
  expect_hit(ray_cast(cap, RayCastInput{Vec2(0.3, 3), Vec2(0, -5), 1.0}), 0.5, Vec2(0.3, 0.5),
             Vec2(0, 1));
  // From below onto the flat bottom.
  expect_hit(ray_cast(cap, RayCastInput{Vec2(-0.2, -2.5), Vec2(0, 4), 1.0}), 0.5, Vec2(-0.2, -0.5),
             Vec2(0, -1));
  // Head-on into the left cap at x = -1.5.
  expect_hit(ray_cast(cap, RayCastInput{Vec2(-4, 0), Vec2(5, 0), 1.0}), 0.5, Vec2(-1.5, 0),
             Vec2(-1, 0));
  // Off-axis into the right cap at height 0.3: x = 1 + 0.4, normal (0.8, 0.6).
  expect_hit(ray_cast(cap, RayCastInput{Vec2(3.4, 0.3), Vec2(-4, 0), 1.0}), 0.5, Vec2(1.4, 0.3),
             Vec2(0.8, 0.6));
  EXPECT_FALSE(ray_cast(cap, RayCastInput{Vec2(-4, 0.6), Vec2(8, 0), 1.0}).hit);
  EXPECT_FALSE(ray_cast(cap, RayCastInput{Vec2(0.9, 0.2), Vec2(0, 5), 1.0}).hit);  // inside
  EXPECT_FALSE(ray_cast(cap, RayCastInput{Vec2(0.3, 3), Vec2(0, -5), 0.49}).hit);  // too short
}

TEST(GeometryTest, RayCastSegmentIsTwoSided) {
  const Segment seg{Vec2(-1, 0), Vec2(1, 0)};
  expect_hit(ray_cast(seg, RayCastInput{Vec2(0.5, 2), Vec2(0, -4), 1.0}), 0.5, Vec2(0.5, 0),
             Vec2(0, 1));
  expect_hit(ray_cast(seg, RayCastInput{Vec2(0.5, -2), Vec2(0, 4), 1.0}), 0.5, Vec2(0.5, 0),
             Vec2(0, -1));
  // Diagonal: from (-1, 1) along (2, -2) it crosses y = 0 at (0, 0), halfway.
  expect_hit(ray_cast(seg, RayCastInput{Vec2(-1, 1), Vec2(2, -2), 1.0}), 0.5, Vec2(0, 0),
             Vec2(0, 1));
  EXPECT_FALSE(ray_cast(seg, RayCastInput{Vec2(1.5, 2), Vec2(0, -4), 1.0}).hit);  // past the end
  EXPECT_FALSE(ray_cast(seg, RayCastInput{Vec2(-2, 0), Vec2(4, 0), 1.0}).hit);    // parallel
  EXPECT_FALSE(ray_cast(seg, RayCastInput{Vec2(0.5, 2), Vec2(0, -4), 0.4}).hit);  // too short
}

TEST(GeometryTest, RayCastPolygon) {
  const Polygon box = make_box(1.0, 0.5);
  expect_hit(ray_cast(box, RayCastInput{Vec2(-3, 0.2), Vec2(4, 0), 1.0}), 0.5, Vec2(-1, 0.2),
             Vec2(-1, 0));
  expect_hit(ray_cast(box, RayCastInput{Vec2(0.25, -2.5), Vec2(0, 4), 1.0}), 0.5, Vec2(0.25, -0.5),
             Vec2(0, -1));
  EXPECT_FALSE(ray_cast(box, RayCastInput{Vec2(-3, 0.6), Vec2(6, 0), 1.0}).hit);   // above
  EXPECT_FALSE(ray_cast(box, RayCastInput{Vec2(0.2, 0.1), Vec2(6, 0), 1.0}).hit);  // inside
  EXPECT_FALSE(ray_cast(box, RayCastInput{Vec2(-3, 0.2), Vec2(4, 0), 0.4}).hit);   // too short
  EXPECT_FALSE(ray_cast(box, RayCastInput{Vec2(-3, 0.2), Vec2(-4, 0), 1.0}).hit);  // away

  // A rotated, offset box: the hit in its frame is the same as for the plain box.
  Polygon turned = make_offset_box(1.0, 0.5, Vec2(2, 1), 0.5 * kPi);
  // Now 1 wide and 2 tall around (2, 1): the bottom face is y = 0, its normal (0, -1).
  expect_hit(ray_cast(turned, RayCastInput{Vec2(2.2, -1), Vec2(0, 2), 1.0}), 0.5, Vec2(2.2, 0),
             Vec2(0, -1));
}

TEST(GeometryTest, RayCastRoundedPolygon) {
  Polygon box = make_box(1.0, 0.5);
  box.radius = 0.25;
  // Onto the offset face x = -1.25.
  expect_hit(ray_cast(box, RayCastInput{Vec2(-3, 0.2), Vec2(3.5, 0), 1.0}), 0.5, Vec2(-1.25, 0.2),
             Vec2(-1, 0));
  // Diagonally onto the corner arc around (-1, -0.5): the first contact is 0.25 from the corner
  // along the diagonal, at distance 2 sqrt(2) - 0.25 from the origin (-3, -2.5).
  const double s = std::sqrt(0.5);
  const double dist = 2.0 * std::sqrt(2.0) - 0.25;
  expect_hit(ray_cast(box, RayCastInput{Vec2(-3, -2.5), Vec2(4, 4), 1.0}),
             dist / (4 * std::sqrt(2.0)), Vec2(-1 - 0.25 * s, -0.5 - 0.25 * s), Vec2(-s, -s));
  // Starting in the rounded band (outside the core, inside the shape): no hit.
  EXPECT_FALSE(ray_cast(box, RayCastInput{Vec2(0, 0.6), Vec2(0, -3), 1.0}).hit);
  // Rays across the top-right corner (1, 0.5) along (1, -1)/sqrt2, passing the corner at 0.3
  // and at 0.2. Both cross the corner square [1, 1.25] x [0.5, 0.75] that the AABB includes,
  // but only the second reaches the arc (radius 0.25): it enters sqrt(0.25^2 - 0.2^2) = 0.15
  // before its closest approach, which lies 2 units along the ray.
  const Vec2 corner(1.0, 0.5);
  const Vec2 u(s, -s);
  const Vec2 out(s, s);
  const Vec2 far_origin = corner + 0.3 * out - 2.0 * u;
  EXPECT_FALSE(ray_cast(box, RayCastInput{far_origin, 4.0 * u, 1.0}).hit);
  const Vec2 near_origin = corner + 0.2 * out - 2.0 * u;
  const Vec2 entry = corner + 0.2 * out - 0.15 * u;
  expect_hit(ray_cast(box, RayCastInput{near_origin, 4.0 * u, 1.0}), 1.85 / 4.0, entry,
             (entry - corner) / 0.25);
}

TEST(GeometryTest, RayCastGeometryDispatch) {
  RayCastInput in{Vec2(-3, 0), Vec2(6, 0), 1.0};
  Circle c{Vec2(0, 0), 1.0};
  CastOutput a = ray_cast(Geometry{c}, in);
  CastOutput b = ray_cast(c, in);
  EXPECT_TRUE(a.hit);
  EXPECT_EQ(a.fraction, b.fraction);
  EXPECT_EQ(a.normal, b.normal);
  EXPECT_TRUE(ray_cast(Geometry{make_box(1, 1)}, in).hit);
  EXPECT_TRUE(ray_cast(Geometry{Capsule{}}, in).hit);
  EXPECT_FALSE(ray_cast(Geometry{Segment{}}, in).hit);  // parallel to the default segment
}

// --- Point tests and bounds -------------------------------------------------------------------

TEST(GeometryTest, ContainsPoint) {
  EXPECT_TRUE(contains_point(Circle{Vec2(1, 1), 0.5}, Vec2(1.3, 1.3)));
  EXPECT_FALSE(contains_point(Circle{Vec2(1, 1), 0.5}, Vec2(1.4, 1.4)));

  const Capsule cap{Vec2(-1, 0), Vec2(1, 0), 0.5};
  EXPECT_TRUE(contains_point(cap, Vec2(0.9, 0.45)));
  EXPECT_TRUE(contains_point(cap, Vec2(-1.4, 0.2)));
  EXPECT_FALSE(contains_point(cap, Vec2(-1.4, 0.4)));  // in the bounding box, outside the cap
  EXPECT_FALSE(contains_point(cap, Vec2(0, 0.6)));

  EXPECT_FALSE(contains_point(Segment{}, Vec2(0, 0)));  // no interior
  Polygon empty = make_box(1.0, 1.0);
  empty.count = 0;
  EXPECT_FALSE(contains_point(empty, Vec2(0, 0)));  // an empty polygon has no interior

  Polygon box = make_box(1.0, 0.5);
  EXPECT_TRUE(contains_point(box, Vec2(0.99, -0.49)));
  EXPECT_FALSE(contains_point(box, Vec2(1.01, 0.0)));
  box.radius = 0.25;
  EXPECT_TRUE(contains_point(box, Vec2(1.2, 0.0)));    // in the side band
  EXPECT_TRUE(contains_point(box, Vec2(1.15, 0.65)));  // 0.21 from the corner
  EXPECT_FALSE(contains_point(box, Vec2(1.2, 0.7)));   // 0.28 from the corner
  EXPECT_FALSE(contains_point(box, Vec2(0.0, 0.76)));
}

TEST(GeometryTest, Aabbs) {
  const Transform shift{Vec2(10, -5), Rot{}};
  AABB a = compute_aabb(Circle{Vec2(1, 2), 0.5}, shift);
  EXPECT_EQ(a.lower, Vec2(10.5, -3.5));
  EXPECT_EQ(a.upper, Vec2(11.5, -2.5));

  a = compute_aabb(Capsule{Vec2(-1, 0), Vec2(1, 2), 0.5}, Transform{});
  EXPECT_EQ(a.lower, Vec2(-1.5, -0.5));
  EXPECT_EQ(a.upper, Vec2(1.5, 2.5));

  a = compute_aabb(Segment{Vec2(2, -1), Vec2(-3, 4)}, shift);
  EXPECT_EQ(a.lower, Vec2(7, -6));
  EXPECT_EQ(a.upper, Vec2(12, -1));

  Polygon box = make_box(2.0, 1.0);
  box.radius = 0.1;
  a = compute_aabb(box, shift);
  EXPECT_EQ(a.lower, Vec2(7.9, -6.1));
  EXPECT_EQ(a.upper, Vec2(12.1, -3.9));

  // Turned by a quarter, half-widths (2, 1) become (1, 2). cos(pi/2) is 6e-17, not 0, so the
  // corners move by ~1e-16.
  a = compute_aabb(make_box(2.0, 1.0), Transform{Vec2::Zero(), Rot::from_angle(0.5 * kPi)});
  expect_vec_near(a.lower, Vec2(-1, -2), 1e-15);
  expect_vec_near(a.upper, Vec2(1, 2), 1e-15);
  // Every vertex of a rotated polygon lies in its box.
  const Transform xf{Vec2(0.3, -0.7), Rot::from_angle(0.9)};
  Polygon tri;
  const Vec2 pts[] = {Vec2(0, 0), Vec2(2, 0.5), Vec2(-0.5, 1.5)};
  ASSERT_TRUE(make_polygon(pts, 0.0, &tri).ok());
  a = compute_aabb(tri, xf);
  for (const Vec2& v : pts) EXPECT_TRUE(a.contains(xf.apply(v)));
}

}  // namespace
}  // namespace fulcrum
