// fulcrum query: ray casts, AABB overlaps and point queries against a world on the server.
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

namespace {

// A finite decimal number, whole word; nullopt (and *error) otherwise.
std::optional<double> parse_double(const std::string& text, std::string* error) {
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE ||
      !std::isfinite(value)) {
    *error = "expected a finite number, got '" + text + "'";
    return std::nullopt;
  }
  return value;
}

std::optional<uint64_t> parse_bits(const std::string& text, std::string* error) {
  errno = 0;
  char* end = nullptr;
  const unsigned long long value = std::strtoull(text.c_str(), &end, 0);
  if (text.empty() || text[0] == '-' || end != text.c_str() + text.size() || errno == ERANGE) {
    *error = "expected a 64-bit mask (decimal or 0x hex), got '" + text + "'";
    return std::nullopt;
  }
  return static_cast<uint64_t>(value);
}

std::string point(const Vec2& p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "(%.6g, %.6g)", p.x(), p.y());
  return buf;
}

std::string handle(int32_t index, uint32_t generation) {
  return std::to_string(index) + ":" + std::to_string(generation);
}

}  // namespace

int run_query(const Invocation& inv) {
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 0, &exit_code);
  if (!world) return exit_code;
  const auto& pos = inv.args.positional();
  if (pos.size() < 2) return inv.usage_error("missing the query kind: ray, aabb or point");
  const std::string& kind = pos[1];
  const size_t want = kind == "point" ? 2 : (kind == "ray" || kind == "aabb") ? 4 : 0;
  if (want == 0) return inv.usage_error("unknown query '" + kind + "' (ray, aabb or point)");
  if (pos.size() != 2 + want) {
    return inv.usage_error(kind + ": expected " + std::to_string(want) + " numbers (got " +
                           std::to_string(pos.size() - 2) + ")");
  }
  std::vector<double> v;
  for (size_t i = 2; i < pos.size(); ++i) {
    std::string error;
    std::optional<double> x = parse_double(pos[i], &error);
    if (!x) return inv.usage_error(kind + ": " + error);
    v.push_back(*x);
  }
  QueryFilter filter;
  for (const char* name : {"category", "mask"}) {
    if (auto text = inv.args.value(name)) {
      std::string error;
      std::optional<uint64_t> bits = parse_bits(*text, &error);
      if (!bits) return inv.usage_error("--" + std::string(name) + ": " + error);
      (std::string(name) == "category" ? filter.category_bits : filter.mask_bits) = *bits;
    }
  }
  if (inv.args.has("all") && kind != "ray") return inv.usage_error("--all is for ray queries");
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;

  if (kind == "ray") {
    const Vec2 from(v[0], v[1]), to(v[2], v[3]);
    std::vector<client::RayCastHit> hits;
    if (inv.args.has("all")) {
      auto r = client->ray_cast_all(*world, from, to - from, filter);
      if (!r.ok()) return inv.fail(r.status().message());
      hits = std::move(r).value();
    } else {
      auto r = client->ray_cast_closest(*world, from, to - from, filter);
      if (!r.ok()) return inv.fail(r.status().message());
      if (r->has_value()) {
        client::RayCastHit h;
        h.shape = (*r)->shape;
        h.point = (*r)->point;
        h.normal = (*r)->normal;
        h.fraction = (*r)->fraction;
        hits.push_back(h);
      }
    }
    inv.out << hits.size() << (hits.size() == 1 ? " hit" : " hits") << "\n";
    for (const client::RayCastHit& h : hits) {
      char fraction[32];
      std::snprintf(fraction, sizeof fraction, "%.6f", h.fraction);
      inv.out << "shape " << handle(h.shape.index, h.shape.generation);
      if (inv.args.has("all")) inv.out << " body " << handle(h.body.index, h.body.generation);
      inv.out << " at " << point(h.point) << " normal " << point(h.normal) << " fraction "
              << fraction << "\n";
    }
    return kExitOk;
  }
  Result<std::vector<client::ShapeHit>> r =
      kind == "aabb"
          ? client->overlap_aabb(*world, AABB{Vec2(v[0], v[1]), Vec2(v[2], v[3])}, filter)
          : client->overlap_point(*world, Vec2(v[0], v[1]), filter);
  if (!r.ok()) return inv.fail(r.status().message());
  inv.out << r->size() << (r->size() == 1 ? " shape" : " shapes") << "\n";
  for (const client::ShapeHit& h : *r) {
    inv.out << "shape " << handle(h.shape.index, h.shape.generation) << " body "
            << handle(h.body.index, h.body.generation) << "\n";
  }
  return kExitOk;
}

}  // namespace fulcrum::cli
