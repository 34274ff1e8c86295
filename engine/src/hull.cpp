// Convex hull of a point set for building polygons: sort, weld near-duplicates, run Andrew's
// monotone chain, then drop vertices that are collinear within kGeometryTolerance. Every step
// is a pure function of the input values, so the output is deterministic.

#include <algorithm>
#include <charconv>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "fulcrum/geometry.h"

namespace fulcrum {
namespace {

std::string tolerance_text() {
  char buf[32];
  auto result = std::to_chars(buf, buf + sizeof(buf), kGeometryTolerance);
  return std::string(buf, result.ptr);
}

// Distance of b from the line through a and c, positive when a -> b -> c turns left. The same
// expression as make_polygon's convexity test (geometry.cpp), so a hull that survives the
// cleanup below always passes make_polygon.
double bulge(const Vec2& a, const Vec2& b, const Vec2& c) {
  double base = length(c - a);
  if (base == 0.0) return 0.0;
  return cross(b - a, c - b) / base;
}

// Lexicographic order by x, then y.
bool lex_less(const Vec2& a, const Vec2& b) {
  return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
}

}  // namespace

Status compute_hull(std::span<const Vec2> points, std::vector<Vec2>* hull) {
  hull->clear();
  for (size_t i = 0; i < points.size(); ++i) {
    if (!is_finite(points[i])) {
      return invalid_argument("hull.points[" + std::to_string(i) + "]: must be finite");
    }
  }

  // Sort by x, then y. stable_sort keeps equal points (say 0 and -0) in input order, so even
  // their bit patterns come out the same on every standard library.
  std::vector<Vec2> sorted(points.begin(), points.end());
  std::stable_sort(sorted.begin(), sorted.end(), lex_less);

  // Weld: in sorted order, keep a point only if it is at least kGeometryTolerance from every
  // point kept so far. Kept points are sorted by x, so only the trailing ones within
  // kGeometryTolerance in x need checking. Afterwards every hull edge is at least that long,
  // and the result does not depend on the input order.
  const double weld_sq = kGeometryTolerance * kGeometryTolerance;
  std::vector<Vec2> kept;
  kept.reserve(sorted.size());
  for (const Vec2& p : sorted) {
    bool unique = true;
    for (size_t j = kept.size(); j-- > 0 && kept[j].x() > p.x() - kGeometryTolerance;) {
      if (distance_squared(p, kept[j]) < weld_sq) {
        unique = false;
        break;
      }
    }
    if (unique) kept.push_back(p);
  }
  if (kept.size() < 3) {
    return invalid_argument("hull.points: need at least 3 distinct points (got " +
                            std::to_string(kept.size()) + " after welding points closer than " +
                            tolerance_text() + ")");
  }

  // Andrew's monotone chain over the sorted points: build the lower hull left to right and the
  // upper hull right to left, popping while the last two points and the new one fail to turn
  // strictly left (cross <= 0), which also drops exactly collinear points.
  const size_t n = kept.size();
  std::vector<Vec2> chain(2 * n);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    while (k >= 2 && cross(chain[k - 1] - chain[k - 2], kept[i] - chain[k - 2]) <= 0.0) --k;
    chain[k++] = kept[i];
  }
  for (size_t i = n - 1, lower_size = k + 1; i-- > 0;) {
    while (k >= lower_size && cross(chain[k - 1] - chain[k - 2], kept[i] - chain[k - 2]) <= 0.0) {
      --k;
    }
    chain[k++] = kept[i];
  }
  // The last point repeats the first.
  chain.resize(k - 1);

  // Drop nearly collinear vertices: repeatedly remove the vertex closest to the chord of its
  // neighbours while that distance is below kGeometryTolerance (lowest index on ties).
  // Removing a vertex of a convex polygon leaves a convex polygon, so this only shrinks it.
  while (chain.size() >= 3) {
    const size_t m = chain.size();
    size_t worst = 0;
    double worst_bulge = 0.0;
    for (size_t i = 0; i < m; ++i) {
      double b = bulge(chain[(i + m - 1) % m], chain[i], chain[(i + 1) % m]);
      if (i == 0 || b < worst_bulge) {
        worst = i;
        worst_bulge = b;
      }
    }
    if (worst_bulge >= kGeometryTolerance) break;
    if (m == 3) {
      chain.clear();
      break;
    }
    chain.erase(chain.begin() + static_cast<std::ptrdiff_t>(worst));
  }
  if (chain.size() < 3) {
    return invalid_argument("hull.points: the points are collinear (the hull is thinner than " +
                            tolerance_text() + ")");
  }
  if (chain.size() > static_cast<size_t>(kMaxPolygonVertices)) {
    return invalid_argument("hull.points: the hull has " + std::to_string(chain.size()) +
                            " vertices, more than the maximum of " +
                            std::to_string(kMaxPolygonVertices));
  }

  // Belt and braces: the result must be a valid polygon by make_polygon's own rules.
  Polygon check;
  Status s = make_polygon(chain, 0.0, &check, "hull");
  if (!s.ok()) return s;
  *hull = std::move(chain);
  return Status::ok_status();
}

}  // namespace fulcrum
