#include "scene_convert.h"

#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <type_traits>
#include <unordered_set>
#include <utility>
#include <variant>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/joints.h"
#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"
#include "fulcrum/types.h"

namespace fulcrum {
namespace {

// Local to this file (status.h may define its own macro; this one does not depend on it).
#define CONVERT_RETURN_IF_ERROR(expr)  \
  do {                                 \
    Status status_ = (expr);           \
    if (!status_.ok()) return status_; \
  } while (false)

// Builder sizes and the scene as a whole are capped so that a small request cannot ask for an
// unbounded allocation.
constexpr int kMaxPyramidBase = 1000;
constexpr int kMaxStackCount = 10000;
constexpr size_t kMaxSceneBodies = 1000000;

// Shortest text that parses back to the same double ("-1", "0.1", "nan").
std::string fmt(double v) {
  char buf[64];
  auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  return ec == std::errc() ? std::string(buf, end) : std::string("?");
}

std::string join(const std::string& path, std::string_view field) {
  return path.empty() ? std::string(field) : path + "." + std::string(field);
}

std::string indexed(const std::string& path, std::string_view field, int i) {
  return join(path, field) + "[" + std::to_string(i) + "]";
}

Status fail(const std::string& path, const std::string& what) {
  return invalid_argument(path + ": " + what);
}

// --- Range checks ------------------------------------------------------------------------------

enum class Range {
  kFinite,       // any finite value
  kPositive,     // finite and > 0
  kNonNegative,  // finite and >= 0
  kUnit,         // [0, 1]
};

Status check(const std::string& path, double v, Range range) {
  // Written as !(ok) so that NaN fails every test.
  switch (range) {
    case Range::kFinite:
      if (!is_finite(v)) return fail(path, "must be finite (got " + fmt(v) + ")");
      break;
    case Range::kPositive:
      if (!(v > 0.0) || !is_finite(v)) return fail(path, "must be > 0 (got " + fmt(v) + ")");
      break;
    case Range::kNonNegative:
      if (!(v >= 0.0) || !is_finite(v)) return fail(path, "must be >= 0 (got " + fmt(v) + ")");
      break;
    case Range::kUnit:
      if (!(v >= 0.0 && v <= 1.0)) return fail(path, "must be in [0, 1] (got " + fmt(v) + ")");
      break;
  }
  return Status::ok_status();
}

Status check_int(const std::string& path, int64_t v, int64_t lo, int64_t hi) {
  if (v < lo || v > hi) {
    std::string range = hi == INT32_MAX
                            ? ">= " + std::to_string(lo)
                            : "in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return fail(path, "must be " + range + " (got " + std::to_string(v) + ")");
  }
  return Status::ok_status();
}

// Sizes of geometry must also stay clear of the degenerate range.
Status check_size(const std::string& path, double v) {
  CONVERT_RETURN_IF_ERROR(check(path, v, Range::kPositive));
  if (v < kGeometryTolerance) {
    return fail(path, "must be >= " + fmt(kGeometryTolerance) + " m (got " + fmt(v) + ")");
  }
  return Status::ok_status();
}

Vec2 to_vec(const v1::Vec2& v) {
  return Vec2(v.x(), v.y());
}

Status check_vec(const std::string& path, const v1::Vec2& v) {
  CONVERT_RETURN_IF_ERROR(check(path + ".x", v.x(), Range::kFinite));
  return check(path + ".y", v.y(), Range::kFinite);
}

// Reads an optional double field: checked and copied when present, `*out` kept otherwise.
Status read_opt(const std::string& path, bool has, double value, Range range, double* out) {
  if (!has) return Status::ok_status();
  CONVERT_RETURN_IF_ERROR(check(path, value, range));
  *out = value;
  return Status::ok_status();
}

// Reads a present-or-absent Vec2 message field the same way.
Status read_opt_vec(const std::string& path, bool has, const v1::Vec2& value, Vec2* out) {
  if (!has) return Status::ok_status();
  CONVERT_RETURN_IF_ERROR(check_vec(path, value));
  *out = to_vec(value);
  return Status::ok_status();
}

// Refuses to grow the scene past kMaxSceneBodies.
Status check_room(const std::string& path, const SceneDef& scene, int64_t added) {
  if (scene.bodies.size() + static_cast<size_t>(added) > kMaxSceneBodies) {
    return fail(path,
                "the scene would have more than " + std::to_string(kMaxSceneBodies) + " bodies");
  }
  return Status::ok_status();
}

// --- Proto to engine ---------------------------------------------------------------------------

Status settings_from_proto(const v1::WorldSettings& p, const std::string& path, WorldSettings* s) {
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "gravity"), p.has_gravity(), p.gravity(), &s->gravity));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "dt"), p.has_dt(), p.dt(), Range::kPositive, &s->dt));
  if (p.has_substeps()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "substeps"), p.substeps(), 1, INT32_MAX));
    s->substeps = p.substeps();
  }
  if (p.has_velocity_iterations()) {
    CONVERT_RETURN_IF_ERROR(
        check_int(join(path, "velocity_iterations"), p.velocity_iterations(), 1, INT32_MAX));
    s->velocity_iterations = p.velocity_iterations();
  }
  if (p.has_relax_iterations()) {
    CONVERT_RETURN_IF_ERROR(
        check_int(join(path, "relax_iterations"), p.relax_iterations(), 0, INT32_MAX));
    s->relax_iterations = p.relax_iterations();
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "contact_hertz"), p.has_contact_hertz(),
                                   p.contact_hertz(), Range::kNonNegative, &s->contact_hertz));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "joint_hertz"), p.has_joint_hertz(), p.joint_hertz(),
                                   Range::kNonNegative, &s->joint_hertz));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "joint_damping_ratio"), p.has_joint_damping_ratio(),
                                   p.joint_damping_ratio(), Range::kNonNegative,
                                   &s->joint_damping_ratio));
  if (p.has_max_substeps()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "max_substeps"), p.max_substeps(), 1, 1000));
    s->max_substeps = p.max_substeps();
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "joint_give_tolerance"), p.has_joint_give_tolerance(),
                                   p.joint_give_tolerance(), Range::kPositive,
                                   &s->joint_give_tolerance));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "contact_give_tolerance"),
                                   p.has_contact_give_tolerance(), p.contact_give_tolerance(),
                                   Range::kPositive, &s->contact_give_tolerance));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "one_pass_give_tolerance"),
                                   p.has_one_pass_give_tolerance(), p.one_pass_give_tolerance(),
                                   Range::kNonNegative, &s->one_pass_give_tolerance));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "contact_damping_ratio"),
                                   p.has_contact_damping_ratio(), p.contact_damping_ratio(),
                                   Range::kNonNegative, &s->contact_damping_ratio));
  if (p.has_position_iterations()) {
    CONVERT_RETURN_IF_ERROR(
        check_int(join(path, "position_iterations"), p.position_iterations(), 0, INT32_MAX));
    s->position_iterations = p.position_iterations();
  }
  if (p.has_split_impulses()) s->split_impulses = p.split_impulses();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "baumgarte"), p.has_baumgarte(), p.baumgarte(),
                                   Range::kUnit, &s->baumgarte));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "linear_slop"), p.has_linear_slop(), p.linear_slop(),
                                   Range::kNonNegative, &s->linear_slop));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "max_correction_speed"), p.has_max_correction_speed(),
                                   p.max_correction_speed(), Range::kPositive,
                                   &s->max_correction_speed));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "restitution_threshold"),
                                   p.has_restitution_threshold(), p.restitution_threshold(),
                                   Range::kNonNegative, &s->restitution_threshold));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "early_exit_tolerance"), p.has_early_exit_tolerance(),
                                   p.early_exit_tolerance(), Range::kNonNegative,
                                   &s->early_exit_tolerance));
  if (p.has_warm_starting()) s->warm_starting = p.warm_starting();
  if (p.has_block_solver()) s->block_solver = p.block_solver();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "speculative_distance"), p.has_speculative_distance(),
                                   p.speculative_distance(), Range::kNonNegative,
                                   &s->speculative_distance));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "manifold_reuse_distance"),
                                   p.has_manifold_reuse_distance(), p.manifold_reuse_distance(),
                                   Range::kNonNegative, &s->manifold_reuse_distance));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "aabb_margin"), p.has_aabb_margin(), p.aabb_margin(),
                                   Range::kNonNegative, &s->aabb_margin));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "max_linear_speed"), p.has_max_linear_speed(),
                                   p.max_linear_speed(), Range::kPositive, &s->max_linear_speed));
  if (p.has_enable_sleep()) s->enable_sleep = p.enable_sleep();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "time_to_sleep"), p.has_time_to_sleep(),
                                   p.time_to_sleep(), Range::kPositive, &s->time_to_sleep));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "linear_sleep_tolerance"),
                                   p.has_linear_sleep_tolerance(), p.linear_sleep_tolerance(),
                                   Range::kNonNegative, &s->linear_sleep_tolerance));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "angular_sleep_tolerance"),
                                   p.has_angular_sleep_tolerance(), p.angular_sleep_tolerance(),
                                   Range::kNonNegative, &s->angular_sleep_tolerance));
  return Status::ok_status();
}

Filter filter_from_proto(const v1::Filter& p) {
  Filter f;
  if (p.has_category_bits()) f.category_bits = p.category_bits();
  if (p.has_mask_bits()) f.mask_bits = p.mask_bits();
  f.group_index = p.group_index();
  return f;
}

Status circle_from_proto(const v1::Circle& p, const std::string& path, Geometry* out) {
  Circle c;
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "center"), p.has_center(), p.center(), &c.center));
  if (p.has_radius()) {
    CONVERT_RETURN_IF_ERROR(check_size(join(path, "radius"), p.radius()));
    c.radius = p.radius();
  }
  *out = c;
  return Status::ok_status();
}

Status capsule_from_proto(const v1::Capsule& p, const std::string& path, Geometry* out) {
  Capsule c;
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "center1"), p.has_center1(), p.center1(), &c.center1));
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "center2"), p.has_center2(), p.center2(), &c.center2));
  if (p.has_radius()) {
    CONVERT_RETURN_IF_ERROR(check_size(join(path, "radius"), p.radius()));
    c.radius = p.radius();
  }
  if (!(distance(c.center1, c.center2) > kGeometryTolerance)) {
    return fail(path,
                "center1 and center2 must be more than " + fmt(kGeometryTolerance) + " m apart");
  }
  *out = c;
  return Status::ok_status();
}

Status segment_from_proto(const v1::Segment& p, const std::string& path, Geometry* out) {
  Segment s;
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "point1"), p.has_point1(), p.point1(), &s.point1));
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "point2"), p.has_point2(), p.point2(), &s.point2));
  if (!(distance(s.point1, s.point2) > kGeometryTolerance)) {
    return fail(path,
                "point1 and point2 must be more than " + fmt(kGeometryTolerance) + " m apart");
  }
  *out = s;
  return Status::ok_status();
}

Status polygon_from_proto(const v1::Polygon& p, const std::string& path, Geometry* out) {
  const int n = p.vertices_size();
  if (n < 3 || n > kMaxPolygonVertices) {
    return fail(join(path, "vertices"), "need 3 to " + std::to_string(kMaxPolygonVertices) +
                                            " vertices (got " + std::to_string(n) + ")");
  }
  std::vector<Vec2> vertices;
  vertices.reserve(n);
  for (int i = 0; i < n; ++i) {
    CONVERT_RETURN_IF_ERROR(check_vec(indexed(path, "vertices", i), p.vertices(i)));
    vertices.push_back(to_vec(p.vertices(i)));
  }
  CONVERT_RETURN_IF_ERROR(check(join(path, "radius"), p.radius(), Range::kNonNegative));
  // Convexity, winding and edge lengths are the engine's rules; it names the field itself.
  Polygon polygon;
  CONVERT_RETURN_IF_ERROR(make_polygon(vertices, p.radius(), &polygon, path.c_str()));
  *out = polygon;
  return Status::ok_status();
}

// The one way a Box message becomes a polygon, shared with scene_to_proto's box detection.
// The centred, unturned box goes through make_box so that it is bit-identical to the boxes the
// builders make.
Polygon build_box(double hx, double hy, const Vec2& center, double angle, double radius) {
  Polygon box = center == Vec2::Zero() && angle == 0.0 ? make_box(hx, hy)
                                                       : make_offset_box(hx, hy, center, angle);
  box.radius = radius;
  return box;
}

Status box_from_proto(const v1::Box& p, const std::string& path, Geometry* out) {
  CONVERT_RETURN_IF_ERROR(check_size(join(path, "half_width"), p.half_width()));
  CONVERT_RETURN_IF_ERROR(check_size(join(path, "half_height"), p.half_height()));
  if (p.has_center()) CONVERT_RETURN_IF_ERROR(check_vec(join(path, "center"), p.center()));
  CONVERT_RETURN_IF_ERROR(check(join(path, "angle"), p.angle(), Range::kFinite));
  CONVERT_RETURN_IF_ERROR(check(join(path, "radius"), p.radius(), Range::kNonNegative));
  const Vec2 center = p.has_center() ? to_vec(p.center()) : Vec2::Zero();
  *out = build_box(p.half_width(), p.half_height(), center, p.angle(), p.radius());
  return Status::ok_status();
}

Status shape_from_proto(const v1::Shape& p, const std::string& path, ShapeDef* def) {
  switch (p.geometry_case()) {
    case v1::Shape::kCircle:
      CONVERT_RETURN_IF_ERROR(circle_from_proto(p.circle(), join(path, "circle"), &def->geometry));
      break;
    case v1::Shape::kCapsule:
      CONVERT_RETURN_IF_ERROR(
          capsule_from_proto(p.capsule(), join(path, "capsule"), &def->geometry));
      break;
    case v1::Shape::kSegment:
      CONVERT_RETURN_IF_ERROR(
          segment_from_proto(p.segment(), join(path, "segment"), &def->geometry));
      break;
    case v1::Shape::kPolygon:
      CONVERT_RETURN_IF_ERROR(
          polygon_from_proto(p.polygon(), join(path, "polygon"), &def->geometry));
      break;
    case v1::Shape::kBox:
      CONVERT_RETURN_IF_ERROR(box_from_proto(p.box(), join(path, "box"), &def->geometry));
      break;
    case v1::Shape::GEOMETRY_NOT_SET:
      return fail(path, "no geometry (set one of circle, capsule, segment, polygon, box)");
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "density"), p.has_density(), p.density(),
                                   Range::kNonNegative, &def->density));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &def->friction));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "restitution"), p.has_restitution(), p.restitution(),
                                   Range::kNonNegative, &def->restitution));
  def->filter = filter_from_proto(p.filter());
  def->is_sensor = p.is_sensor();
  def->user_data = p.user_data();
  return Status::ok_status();
}

Status chain_from_proto(const v1::Chain& p, const std::string& path, ChainDef* def) {
  const int n = p.points_size();
  const int min_points = p.loop() ? 3 : 2;
  if (n < min_points) {
    return fail(join(path, "points"), "need at least " + std::to_string(min_points) +
                                          (p.loop() ? " points for a loop" : " points") + " (got " +
                                          std::to_string(n) + ")");
  }
  def->points.clear();
  def->points.reserve(n);
  for (int i = 0; i < n; ++i) {
    CONVERT_RETURN_IF_ERROR(check_vec(indexed(path, "points", i), p.points(i)));
    def->points.push_back(to_vec(p.points(i)));
    if (i > 0 && def->points[i] == def->points[i - 1]) {
      return fail(indexed(path, "points", i), "equals the previous point");
    }
  }
  if (p.loop() && def->points.front() == def->points.back()) {
    return fail(indexed(path, "points", n - 1),
                "equals the first point (a loop closes itself; do not repeat it)");
  }
  def->loop = p.loop();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &def->friction));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "restitution"), p.has_restitution(), p.restitution(),
                                   Range::kNonNegative, &def->restitution));
  def->filter = filter_from_proto(p.filter());
  def->user_data = p.user_data();
  return Status::ok_status();
}

Status body_from_proto(const v1::Body& p, const std::string& path, SceneBody* body) {
  BodyDef& def = body->def;
  // Proto3 enums are open: a JSON number outside the enum parses, so it is checked here.
  if (!v1::BodyType_IsValid(p.type())) {
    return fail(join(path, "type"), "unknown body type " + std::to_string(p.type()));
  }
  def.type = static_cast<BodyType>(p.type());
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "position"), p.has_position(), p.position(), &def.position));
  CONVERT_RETURN_IF_ERROR(check(join(path, "angle"), p.angle(), Range::kFinite));
  def.angle = p.angle();
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "linear_velocity"), p.has_linear_velocity(),
                                       p.linear_velocity(), &def.linear_velocity));
  CONVERT_RETURN_IF_ERROR(
      check(join(path, "angular_velocity"), p.angular_velocity(), Range::kFinite));
  def.angular_velocity = p.angular_velocity();
  CONVERT_RETURN_IF_ERROR(
      check(join(path, "linear_damping"), p.linear_damping(), Range::kNonNegative));
  def.linear_damping = p.linear_damping();
  CONVERT_RETURN_IF_ERROR(
      check(join(path, "angular_damping"), p.angular_damping(), Range::kNonNegative));
  def.angular_damping = p.angular_damping();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "gravity_scale"), p.has_gravity_scale(),
                                   p.gravity_scale(), Range::kFinite, &def.gravity_scale));
  CONVERT_RETURN_IF_ERROR(check(join(path, "drag"), p.drag(), Range::kNonNegative));
  def.drag = p.drag();
  def.fixed_rotation = p.fixed_rotation();
  if (p.has_awake()) def.awake = p.awake();
  if (p.has_enable_sleep()) def.enable_sleep = p.enable_sleep();
  def.user_data = p.user_data();
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "constant_force"), p.has_constant_force(),
                                       p.constant_force(), &def.constant_force));
  CONVERT_RETURN_IF_ERROR(
      check(join(path, "constant_torque"), p.constant_torque(), Range::kFinite));
  def.constant_torque = p.constant_torque();

  body->shapes.resize(p.shapes_size());
  for (int i = 0; i < p.shapes_size(); ++i) {
    CONVERT_RETURN_IF_ERROR(
        shape_from_proto(p.shapes(i), indexed(path, "shapes", i), &body->shapes[i]));
  }
  body->chains.resize(p.chains_size());
  for (int i = 0; i < p.chains_size(); ++i) {
    CONVERT_RETURN_IF_ERROR(
        chain_from_proto(p.chains(i), indexed(path, "chains", i), &body->chains[i]));
  }
  return Status::ok_status();
}

Status pyramid_from_proto(const v1::Builder::Pyramid& p, const std::string& path, SceneDef* scene) {
  scenes::PyramidOptions o;
  if (p.has_base()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "base"), p.base(), 1, kMaxPyramidBase));
    o.base = p.base();
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "box_size"), p.has_box_size(), p.box_size(),
                                   Range::kPositive, &o.box_size));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "spacing"), p.has_spacing(), p.spacing(), Range::kFinite, &o.spacing));
  // Checked after both are known: the default spacing may meet an explicit box_size.
  if (!(o.spacing >= o.box_size)) {
    return fail(join(path, "spacing"),
                "must be >= box_size " + fmt(o.box_size) + " (got " + fmt(o.spacing) + ")");
  }
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "origin"), p.has_origin(), p.origin(), &o.origin));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &o.friction));
  if (p.has_top_density()) {
    const double top = p.top_density();
    if (!is_finite(top) || top == 0.0) {
      return fail(join(path, "top_density"),
                  "must be > 0, or < 0 to use density (got " + fmt(top) + ")");
    }
    o.top_density = top;
  }
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, int64_t{o.base} * (o.base + 1) / 2));
  scenes::add_pyramid(scene, o);
  return Status::ok_status();
}

Status stack_from_proto(const v1::Builder::Stack& p, const std::string& path, SceneDef* scene) {
  scenes::StackOptions o;
  if (p.has_count()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "count"), p.count(), 1, kMaxStackCount));
    o.count = p.count();
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "box_size"), p.has_box_size(), p.box_size(),
                                   Range::kPositive, &o.box_size));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "offset"), p.has_offset(), p.offset(), Range::kFinite, &o.offset));
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "origin"), p.has_origin(), p.origin(), &o.origin));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &o.friction));
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, o.count));
  scenes::add_stack(scene, o);
  return Status::ok_status();
}

Status ground_from_proto(const v1::Builder::Ground& p, const std::string& path, SceneDef* scene) {
  scenes::GroundOptions o;
  CONVERT_RETURN_IF_ERROR(check(join(path, "half_width"), p.half_width(), Range::kPositive));
  o.half_width = p.half_width();
  CONVERT_RETURN_IF_ERROR(check(join(path, "top"), p.top(), Range::kFinite));
  o.center = Vec2(0.0, p.top());
  if (p.has_center()) {
    if (p.top() != 0.0) return fail(join(path, "top"), "give center or top, not both");
    CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "center"), true, p.center(), &o.center));
  }
  CONVERT_RETURN_IF_ERROR(check(join(path, "angle"), p.angle(), Range::kFinite));
  o.angle = p.angle();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "thickness"), p.has_thickness(), p.thickness(),
                                   Range::kPositive, &o.thickness));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &o.friction));
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, 1));
  scenes::add_ground(scene, o);
  return Status::ok_status();
}

Status joint_chain_from_proto(const v1::Builder::JointChain& p, const std::string& path,
                              SceneDef* scene) {
  scenes::JointChainOptions o;
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "anchor"), p.has_anchor(), p.anchor(), &o.anchor));
  if (p.has_links()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "links"), p.links(), 1, kMaxStackCount));
    o.links = p.links();
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "link_width"), p.has_link_width(), p.link_width(),
                                   Range::kPositive, &o.link_width));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "link_length"), p.has_link_length(), p.link_length(),
                                   Range::kPositive, &o.link_length));
  if (!(o.link_length > o.link_width)) {
    return fail(join(path, "link_length"), "must be > link_width (got " + fmt(o.link_length) +
                                               " <= " + fmt(o.link_width) + ")");
  }
  if (!v1::Builder_JointChain_LinkShape_IsValid(p.shape())) {
    return fail(join(path, "shape"), "unknown link shape " + std::to_string(p.shape()));
  }
  o.shape = static_cast<scenes::JointChainOptions::LinkShape>(p.shape());
  if (!v1::Builder_JointChain_Kind_IsValid(p.joint())) {
    return fail(join(path, "joint"), "unknown joint kind " + std::to_string(p.joint()));
  }
  o.joint = static_cast<scenes::JointChainOptions::JointKind>(p.joint());
  CONVERT_RETURN_IF_ERROR(check(join(path, "angle"), p.angle(), Range::kFinite));
  o.angle = p.angle();
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &o.friction));
  CONVERT_RETURN_IF_ERROR(check(join(path, "end_mass"), p.end_mass(), Range::kNonNegative));
  o.end_mass = p.end_mass();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "end_radius"), p.has_end_radius(), p.end_radius(),
                                   Range::kPositive, &o.end_radius));
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, o.links + 2));
  scenes::add_joint_chain(scene, o);
  return Status::ok_status();
}

Status card_house_from_proto(const v1::Builder::CardHouse& p, const std::string& path,
                             SceneDef* scene) {
  scenes::CardHouseOptions o;
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "origin"), p.has_origin(), p.origin(), &o.origin));
  if (p.has_levels()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "levels"), p.levels(), 1, 100));
    o.levels = p.levels();
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "card_length"), p.has_card_length(), p.card_length(),
                                   Range::kPositive, &o.card_length));
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "card_thickness"), p.has_card_thickness(),
                                   p.card_thickness(), Range::kPositive, &o.card_thickness));
  if (!(o.card_thickness <= o.card_length / 20.0)) {
    return fail(join(path, "card_thickness"),
                "must be <= card_length / 20 (got " + fmt(o.card_thickness) + ")");
  }
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "lean"), p.has_lean(), p.lean(), Range::kFinite, &o.lean));
  if (!(o.lean >= 0.05 && o.lean <= 0.45)) {
    return fail(join(path, "lean"), "must be in [0.05, 0.45] (got " + fmt(o.lean) + ")");
  }
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "friction"), p.has_friction(), p.friction(),
                                   Range::kNonNegative, &o.friction));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, (3 * o.levels * o.levels + o.levels) / 2));
  scenes::add_card_house(scene, o);
  return Status::ok_status();
}

Status rope_from_proto(const v1::Builder::Rope& p, const std::string& path, SceneDef* scene) {
  scenes::RopeOptions o;
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "start"), p.has_start(), p.start(), &o.start));
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "end"), p.has_end(), p.end(), &o.end));
  if (!(distance(o.start, o.end) > kGeometryTolerance)) {
    return fail(join(path, "end"), "must differ from start");
  }
  if (p.has_count()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "count"), p.count(), 2, kMaxStackCount));
    o.count = p.count();
  }
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "radius"), p.has_radius(), p.radius(), Range::kPositive, &o.radius));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  if (p.has_pin_start()) o.pin_start = p.pin_start();
  if (p.has_collide()) o.collide = p.collide();
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, o.count + 1));
  scenes::add_rope(scene, o);
  return Status::ok_status();
}

Status cloth_from_proto(const v1::Builder::Cloth& p, const std::string& path, SceneDef* scene) {
  scenes::ClothOptions o;
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(path, "top_left"), p.has_top_left(), p.top_left(), &o.top_left));
  if (p.has_columns()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "columns"), p.columns(), 2, 300));
    o.columns = p.columns();
  }
  if (p.has_rows()) {
    CONVERT_RETURN_IF_ERROR(check_int(join(path, "rows"), p.rows(), 2, 300));
    o.rows = p.rows();
  }
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "spacing"), p.has_spacing(), p.spacing(), Range::kPositive, &o.spacing));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "radius"), p.has_radius(), p.radius(), Range::kPositive, &o.radius));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  if (p.pinned_size() % 2 != 0) {
    return fail(join(path, "pinned"), "needs (column, row) pairs: an even count");
  }
  if (p.pinned_size() > 0) {
    o.pinned.clear();
    for (int i = 0; i < p.pinned_size(); i += 2) {
      std::string at = indexed(path, "pinned", i);
      CONVERT_RETURN_IF_ERROR(check_int(at, p.pinned(i), 0, o.columns - 1));
      CONVERT_RETURN_IF_ERROR(
          check_int(indexed(path, "pinned", i + 1), p.pinned(i + 1), 0, o.rows - 1));
      o.pinned.emplace_back(p.pinned(i), p.pinned(i + 1));
    }
  } else {
    o.pinned = {{0, 0}, {o.columns - 1, 0}};
  }
  if (p.has_group()) o.group = p.group();
  CONVERT_RETURN_IF_ERROR(check_room(
      path, *scene, int64_t{o.columns} * o.rows + static_cast<int64_t>(o.pinned.size())));
  scenes::add_cloth(scene, o);
  return Status::ok_status();
}

Status ragdoll_from_proto(const v1::Builder::Ragdoll& p, const std::string& path, SceneDef* scene) {
  scenes::RagdollOptions o;
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "feet"), p.has_feet(), p.feet(), &o.feet));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "scale"), p.has_scale(), p.scale(), Range::kPositive, &o.scale));
  if (p.has_group()) o.group = p.group();
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "joint_friction"), p.has_joint_friction(),
                                   p.joint_friction(), Range::kNonNegative, &o.joint_friction));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(path, "density"), p.has_density(), p.density(), Range::kPositive, &o.density));
  CONVERT_RETURN_IF_ERROR(check_room(path, *scene, 11));
  scenes::add_ragdoll(scene, o);
  return Status::ok_status();
}

Status builder_from_proto(const v1::Builder& p, const std::string& path, SceneDef* scene) {
  switch (p.kind_case()) {
    case v1::Builder::kPyramid:
      return pyramid_from_proto(p.pyramid(), join(path, "pyramid"), scene);
    case v1::Builder::kStack:
      return stack_from_proto(p.stack(), join(path, "stack"), scene);
    case v1::Builder::kGround:
      return ground_from_proto(p.ground(), join(path, "ground"), scene);
    case v1::Builder::kRope:
      return rope_from_proto(p.rope(), join(path, "rope"), scene);
    case v1::Builder::kCloth:
      return cloth_from_proto(p.cloth(), join(path, "cloth"), scene);
    case v1::Builder::kRagdoll:
      return ragdoll_from_proto(p.ragdoll(), join(path, "ragdoll"), scene);
    case v1::Builder::kJointChain:
      return joint_chain_from_proto(p.joint_chain(), join(path, "joint_chain"), scene);
    case v1::Builder::kCardHouse:
      return card_house_from_proto(p.card_house(), join(path, "card_house"), scene);
    case v1::Builder::KIND_NOT_SET:
      break;
  }
  return fail(path,
              "no builder (set one of pyramid, stack, ground, rope, cloth, ragdoll, joint_chain, "
              "card_house)");
}

// --- Engine to proto ---------------------------------------------------------------------------

// Bit equality: -0.0 differs from 0.0 and NaN equals itself, so "same as the default" never
// loses a bit.
bool same(double a, double b) {
  return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b);
}
bool same(const Vec2& a, const Vec2& b) {
  return same(a.x(), b.x()) && same(a.y(), b.y());
}

void vec_to_proto(const Vec2& v, v1::Vec2* out) {
  out->set_x(v.x());
  out->set_y(v.y());
}

bool same_polygon(const Polygon& a, const Polygon& b) {
  if (a.count != b.count || !same(a.radius, b.radius) || !same(a.centroid, b.centroid)) {
    return false;
  }
  for (int i = 0; i < a.count; ++i) {
    if (!same(a.vertices[i], b.vertices[i]) || !same(a.normals[i], b.normals[i])) return false;
  }
  return true;
}

// Distance from |x| to the next larger double.
double ulp(double x) {
  const double a = std::abs(x);
  return std::nextafter(a, std::numeric_limits<double>::infinity()) - a;
}

// Candidates for a value known up to `steps` ulps, nearest first; `seen` (bit patterns) keeps
// `out` free of duplicates.
void add_candidates(double estimate, int steps, std::vector<double>* out,
                    std::unordered_set<uint64_t>* seen) {
  auto add = [&](double v) {
    if (seen->insert(std::bit_cast<uint64_t>(v)).second) out->push_back(v);
  };
  add(estimate);
  double down = estimate, up = estimate;
  for (int j = 0; j < steps; ++j) {
    down = std::nextafter(down, -std::numeric_limits<double>::infinity());
    up = std::nextafter(up, std::numeric_limits<double>::infinity());
    add(down);
    add(up);
  }
}

// The angle whose Rot::from_angle is exactly `q`, if one lies within a few ulps of atan2 (or of
// atan2 +- 2 pi, for angles just outside (-pi, pi]).
std::optional<double> exact_angle(const Rot& q) {
  for (double turn : {0.0, 2.0 * kPi, -2.0 * kPi}) {
    std::vector<double> angles;
    std::unordered_set<uint64_t> seen;
    add_candidates(q.angle() + turn, 3, &angles, &seen);
    for (double a : angles) {
      const Rot r = Rot::from_angle(a);
      if (same(r.c, q.c) && same(r.s, q.s)) return a;
    }
  }
  return std::nullopt;
}

// Writes `p` as a Box when box_from_proto would rebuild exactly the same bits; otherwise
// returns false and `p` is written as a Polygon (whose normals and centroid make_polygon
// recomputes, not always to the same last bit as make_offset_box).
//
// make_box's normals[1] is (1, 0), so a turned box's normals[1] is exactly (cos, sin) of its
// angle. The half sizes are then searched near their estimates from the vertices. Every
// candidate is verified by rebuilding the polygon, so a miss costs compactness and last-bit
// exactness of the normals, never correctness.
bool box_to_proto(const Polygon& p, v1::Box* out) {
  if (p.count != 4 || !(p.radius >= 0.0) || !is_finite(p.centroid)) return false;
  const Rot q{p.normals[1].x(), p.normals[1].y()};
  const std::optional<double> angle = exact_angle(q);
  if (!angle) return false;
  // A box's normals depend only on its angle: this rejects other quadrilaterals cheaply.
  const Polygon unit = build_box(1.0, 1.0, Vec2(1.0, 1.0), *angle, 0.0);
  for (int i = 0; i < 4; ++i) {
    if (!same(unit.normals[i], p.normals[i])) return false;
  }

  // The centre as box_from_proto will see it: written only when non-zero.
  const bool write_center = p.centroid != Vec2::Zero();
  const Vec2 center = write_center ? p.centroid : Vec2::Zero();
  // Vertices carry rounding errors of the largest coordinate involved, so a half size much
  // smaller than that is known only to within many of its own ulps; yet only the exact value
  // (or one an ulp away) rebuilds the same vertices. Hence single-ulp steps over a range that
  // grows with the ratio, nearest first.
  double scale = std::max(std::abs(center.x()), std::abs(center.y()));
  for (int i = 0; i < 4; ++i) {
    scale = std::max({scale, std::abs(p.vertices[i].x()), std::abs(p.vertices[i].y())});
  }
  auto steps_for = [scale](double e) {
    return static_cast<int>(std::min(256.0, 2.0 * ulp(scale) / ulp(e) + 2.0));
  };
  // make_box's vertices are (-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy).
  std::vector<double> hxs, hys;
  std::unordered_set<uint64_t> seen_x, seen_y;
  for (int pass = 0; pass < 2; ++pass) {  // every estimate itself first, then the ranges
    for (int i = 0; i < 4; ++i) {
      const Vec2 local = q.inv_rotate(p.vertices[i] - center);
      const double ex = std::abs(local.x()), ey = std::abs(local.y());
      add_candidates(ex, pass == 0 ? 0 : steps_for(ex), &hxs, &seen_x);
      add_candidates(ey, pass == 0 ? 0 : steps_for(ey), &hys, &seen_y);
    }
  }

  auto try_pair = [&](double hx, double hy) {
    // box_from_proto refuses half sizes below the tolerance.
    if (!(hx >= kGeometryTolerance && hy >= kGeometryTolerance)) return false;
    if (!same_polygon(build_box(hx, hy, center, *angle, p.radius), p)) return false;
    out->set_half_width(hx);
    out->set_half_height(hy);
    if (write_center) vec_to_proto(center, out->mutable_center());
    out->set_angle(*angle);
    out->set_radius(p.radius);
    return true;
  };
  // Pairs in shells of growing max(i, j), so that near candidates come first, within a budget
  // that bounds the cost of a miss.
  const size_t nx = hxs.size(), ny = hys.size();
  int budget = 4096;
  for (size_t d = 0; d < std::max(nx, ny) && budget > 0; ++d) {
    for (size_t j = 0; d < nx && j <= std::min(d, ny - 1); ++j, --budget) {
      if (try_pair(hxs[d], hys[j])) return true;
    }
    for (size_t i = 0; d < ny && i < std::min(d, nx); ++i, --budget) {
      if (try_pair(hxs[i], hys[d])) return true;
    }
  }
  return false;
}

void geometry_to_proto(const Geometry& g, v1::Shape* out) {
  if (const auto* c = std::get_if<Circle>(&g)) {
    v1::Circle* m = out->mutable_circle();
    if (!same(c->center, Circle{}.center)) vec_to_proto(c->center, m->mutable_center());
    m->set_radius(c->radius);
  } else if (const auto* cap = std::get_if<Capsule>(&g)) {
    v1::Capsule* m = out->mutable_capsule();
    vec_to_proto(cap->center1, m->mutable_center1());
    vec_to_proto(cap->center2, m->mutable_center2());
    m->set_radius(cap->radius);
  } else if (const auto* s = std::get_if<Segment>(&g)) {
    v1::Segment* m = out->mutable_segment();
    vec_to_proto(s->point1, m->mutable_point1());
    vec_to_proto(s->point2, m->mutable_point2());
  } else if (const auto* p = std::get_if<Polygon>(&g)) {
    v1::Box box;
    if (box_to_proto(*p, &box)) {
      *out->mutable_box() = std::move(box);
      return;
    }
    v1::Polygon* m = out->mutable_polygon();
    for (int i = 0; i < p->count; ++i) vec_to_proto(p->vertices[i], m->add_vertices());
    m->set_radius(p->radius);
  }
}

// Writes only the fields that differ from the default, keeping exported files short.
void filter_to_proto(const Filter& f, v1::Filter* out) {
  const Filter d;
  if (f.category_bits != d.category_bits) out->set_category_bits(f.category_bits);
  if (f.mask_bits != d.mask_bits) out->set_mask_bits(f.mask_bits);
  out->set_group_index(f.group_index);
}

bool is_default_filter(const Filter& f) {
  const Filter d;
  return f.category_bits == d.category_bits && f.mask_bits == d.mask_bits &&
         f.group_index == d.group_index;
}

void shape_to_proto(const ShapeDef& s, v1::Shape* out) {
  const ShapeDef d;
  geometry_to_proto(s.geometry, out);
  if (!same(s.density, d.density)) out->set_density(s.density);
  if (!same(s.friction, d.friction)) out->set_friction(s.friction);
  if (!same(s.restitution, d.restitution)) out->set_restitution(s.restitution);
  if (!is_default_filter(s.filter)) filter_to_proto(s.filter, out->mutable_filter());
  out->set_is_sensor(s.is_sensor);
  out->set_user_data(s.user_data);
}

void chain_to_proto(const ChainDef& c, v1::Chain* out) {
  const ChainDef d;
  for (const Vec2& p : c.points) vec_to_proto(p, out->add_points());
  out->set_loop(c.loop);
  if (!same(c.friction, d.friction)) out->set_friction(c.friction);
  if (!same(c.restitution, d.restitution)) out->set_restitution(c.restitution);
  if (!is_default_filter(c.filter)) filter_to_proto(c.filter, out->mutable_filter());
  out->set_user_data(c.user_data);
}

void body_to_proto(const SceneBody& b, v1::Body* out) {
  const BodyDef d;
  const BodyDef& def = b.def;
  out->set_type(static_cast<v1::BodyType>(def.type));
  if (!same(def.position, d.position)) vec_to_proto(def.position, out->mutable_position());
  out->set_angle(def.angle);
  if (!same(def.linear_velocity, d.linear_velocity)) {
    vec_to_proto(def.linear_velocity, out->mutable_linear_velocity());
  }
  out->set_angular_velocity(def.angular_velocity);
  out->set_linear_damping(def.linear_damping);
  out->set_angular_damping(def.angular_damping);
  if (!same(def.gravity_scale, d.gravity_scale)) out->set_gravity_scale(def.gravity_scale);
  out->set_drag(def.drag);
  out->set_fixed_rotation(def.fixed_rotation);
  if (def.awake != d.awake) out->set_awake(def.awake);
  if (def.enable_sleep != d.enable_sleep) out->set_enable_sleep(def.enable_sleep);
  out->set_user_data(def.user_data);
  if (!same(def.constant_force, d.constant_force)) {
    vec_to_proto(def.constant_force, out->mutable_constant_force());
  }
  out->set_constant_torque(def.constant_torque);
  for (const ShapeDef& s : b.shapes) shape_to_proto(s, out->add_shapes());
  for (const ChainDef& c : b.chains) chain_to_proto(c, out->add_chains());
}

// Every field written: an exported scene does not depend on today's defaults.
void settings_to_proto(const WorldSettings& s, v1::WorldSettings* out) {
  vec_to_proto(s.gravity, out->mutable_gravity());
  out->set_dt(s.dt);
  out->set_substeps(s.substeps);
  out->set_velocity_iterations(s.velocity_iterations);
  out->set_relax_iterations(s.relax_iterations);
  out->set_contact_hertz(s.contact_hertz);
  out->set_contact_damping_ratio(s.contact_damping_ratio);
  out->set_joint_hertz(s.joint_hertz);
  out->set_joint_damping_ratio(s.joint_damping_ratio);
  out->set_max_substeps(s.max_substeps);
  out->set_joint_give_tolerance(s.joint_give_tolerance);
  out->set_contact_give_tolerance(s.contact_give_tolerance);
  out->set_one_pass_give_tolerance(s.one_pass_give_tolerance);
  out->set_position_iterations(s.position_iterations);
  out->set_split_impulses(s.split_impulses);
  out->set_baumgarte(s.baumgarte);
  out->set_linear_slop(s.linear_slop);
  out->set_max_correction_speed(s.max_correction_speed);
  out->set_restitution_threshold(s.restitution_threshold);
  out->set_early_exit_tolerance(s.early_exit_tolerance);
  out->set_warm_starting(s.warm_starting);
  out->set_block_solver(s.block_solver);
  out->set_speculative_distance(s.speculative_distance);
  out->set_manifold_reuse_distance(s.manifold_reuse_distance);
  out->set_aabb_margin(s.aabb_margin);
  out->set_max_linear_speed(s.max_linear_speed);
  out->set_enable_sleep(s.enable_sleep);
  out->set_time_to_sleep(s.time_to_sleep);
  out->set_linear_sleep_tolerance(s.linear_sleep_tolerance);
  out->set_angular_sleep_tolerance(s.angular_sleep_tolerance);
}

// --- JSON ----------------------------------------------------------------------------------------

// Protobuf's parser says "(bodies[0].position) z: Cannot find field." and
// "(bodies[0].type): invalid value ..."; this turns those into the "path: problem" form used
// everywhere else. Messages of any other shape pass through unchanged.
std::string tidy_json_error(const std::string& message) {
  std::string path;
  std::string rest = message;
  if (rest.rfind(": ", 0) == 0) return rest.substr(2);  // an error at the root: no path
  if (!rest.empty() && rest[0] == '(') {
    size_t close = rest.find(')');
    if (close == std::string::npos) return message;
    path = rest.substr(1, close - 1);
    rest = rest.substr(close + 1);
    if (rest.rfind(": ", 0) == 0) return path + rest;
    if (rest.rfind(" ", 0) == 0) rest = rest.substr(1);
  }
  constexpr std::string_view kUnknown = ": Cannot find field.";
  if (rest.size() > kUnknown.size() &&
      rest.compare(rest.size() - kUnknown.size(), kUnknown.size(), kUnknown) == 0) {
    std::string field = rest.substr(0, rest.size() - kUnknown.size());
    return join(path, field) + ": unknown field";
  }
  return message;
}

// Protobuf prints -0.0 as "-0", which its parser reads back as the integer 0, losing the sign.
// Rewrites every bare -0 number (outside strings) as -0.0, which parses back to -0.0.
std::string keep_negative_zeros(const std::string& json) {
  std::string out;
  out.reserve(json.size());
  bool in_string = false;
  bool escaped = false;
  for (size_t i = 0; i < json.size(); ++i) {
    const char ch = json[i];
    out.push_back(ch);
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (ch == '\\') {
        escaped = true;
      } else if (ch == '"') {
        in_string = false;
      }
      continue;
    }
    if (ch == '"') {
      in_string = true;
    } else if (ch == '-' && i + 1 < json.size() && json[i + 1] == '0') {
      const char next = i + 2 < json.size() ? json[i + 2] : ' ';
      const bool more = std::isdigit(static_cast<unsigned char>(next)) || next == '.' ||
                        next == 'e' || next == 'E';
      if (!more) {
        out += "0.0";
        ++i;  // the '0' is written
      }
    }
  }
  return out;
}

Status joint_from_proto(const v1::Joint& p, const std::string& path, int body_count,
                        SceneJoint* out) {
  if (p.body_a() >= static_cast<uint32_t>(body_count)) {
    return fail(join(path, "body_a"), "no body " + std::to_string(p.body_a()) + " in the scene (" +
                                          std::to_string(body_count) + " bodies)");
  }
  if (p.body_b() >= static_cast<uint32_t>(body_count)) {
    return fail(join(path, "body_b"), "no body " + std::to_string(p.body_b()) + " in the scene (" +
                                          std::to_string(body_count) + " bodies)");
  }
  // build_world refuses it too; here the message can name the file it came from.
  if (p.body_a() == p.body_b()) {
    return fail(join(path, "body_b"),
                "must differ from body_a (both are body " + std::to_string(p.body_a()) + ")");
  }
  out->body_a = static_cast<int>(p.body_a());
  out->body_b = static_cast<int>(p.body_b());
  Vec2 anchor_a = Vec2::Zero(), anchor_b = Vec2::Zero();
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "local_anchor_a"), p.has_local_anchor_a(),
                                       p.local_anchor_a(), &anchor_a));
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "local_anchor_b"), p.has_local_anchor_b(),
                                       p.local_anchor_b(), &anchor_b));
  if (p.has_distance()) {
    const v1::DistanceJoint& d = p.distance();
    const std::string where = join(path, "distance");
    DistanceJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    def.collide_connected = p.collide_connected();
    CONVERT_RETURN_IF_ERROR(
        read_opt(join(where, "length"), d.has_length(), d.length(), Range::kPositive, &def.length));
    def.min_length = def.max_length = def.length;
    CONVERT_RETURN_IF_ERROR(read_opt(join(where, "min_length"), d.has_min_length(), d.min_length(),
                                     Range::kNonNegative, &def.min_length));
    CONVERT_RETURN_IF_ERROR(read_opt(join(where, "max_length"), d.has_max_length(), d.max_length(),
                                     Range::kPositive, &def.max_length));
    CONVERT_RETURN_IF_ERROR(check(join(where, "hertz"), d.hertz(), Range::kNonNegative));
    CONVERT_RETURN_IF_ERROR(
        check(join(where, "damping_ratio"), d.damping_ratio(), Range::kNonNegative));
    def.hertz = d.hertz();
    def.damping_ratio = d.damping_ratio();
    out->def = def;
  } else if (p.has_revolute()) {
    const v1::RevoluteJoint& r = p.revolute();
    const std::string where = join(path, "revolute");
    RevoluteJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    def.collide_connected = p.collide_connected();
    for (auto [name, value] :
         {std::pair<const char*, double>{"reference_angle", r.reference_angle()},
          {"lower_angle", r.lower_angle()},
          {"upper_angle", r.upper_angle()},
          {"motor_speed", r.motor_speed()},
          {"target_angle", r.target_angle()}}) {
      CONVERT_RETURN_IF_ERROR(check(join(where, name), value, Range::kFinite));
    }
    CONVERT_RETURN_IF_ERROR(
        check(join(where, "max_motor_torque"), r.max_motor_torque(), Range::kNonNegative));
    CONVERT_RETURN_IF_ERROR(check(join(where, "hertz"), r.hertz(), Range::kNonNegative));
    CONVERT_RETURN_IF_ERROR(
        check(join(where, "damping_ratio"), r.damping_ratio(), Range::kNonNegative));
    def.reference_angle = r.reference_angle();
    def.enable_limit = r.enable_limit();
    def.lower_angle = r.lower_angle();
    def.upper_angle = r.upper_angle();
    def.enable_motor = r.enable_motor();
    def.motor_speed = r.motor_speed();
    def.max_motor_torque = r.max_motor_torque();
    def.enable_spring = r.enable_spring();
    def.hertz = r.hertz();
    def.damping_ratio = r.damping_ratio();
    def.target_angle = r.target_angle();
    out->def = def;
  } else if (p.has_weld()) {
    const v1::WeldJoint& r = p.weld();
    const std::string where = join(path, "weld");
    WeldJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    def.collide_connected = p.collide_connected();
    CONVERT_RETURN_IF_ERROR(
        check(join(where, "reference_angle"), r.reference_angle(), Range::kFinite));
    for (auto [name, value] : {std::pair<const char*, double>{"linear_hertz", r.linear_hertz()},
                               {"linear_damping_ratio", r.linear_damping_ratio()},
                               {"angular_hertz", r.angular_hertz()},
                               {"angular_damping_ratio", r.angular_damping_ratio()}}) {
      CONVERT_RETURN_IF_ERROR(check(join(where, name), value, Range::kNonNegative));
    }
    def.reference_angle = r.reference_angle();
    def.linear_hertz = r.linear_hertz();
    def.linear_damping_ratio = r.linear_damping_ratio();
    def.angular_hertz = r.angular_hertz();
    def.angular_damping_ratio = r.angular_damping_ratio();
    out->def = def;
  } else if (p.has_prismatic()) {
    const v1::PrismaticJoint& r = p.prismatic();
    const std::string where = join(path, "prismatic");
    PrismaticJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    def.collide_connected = p.collide_connected();
    CONVERT_RETURN_IF_ERROR(read_opt_vec(join(where, "local_axis_a"), r.has_local_axis_a(),
                                         r.local_axis_a(), &def.local_axis_a));
    for (auto [name, value] :
         {std::pair<const char*, double>{"reference_angle", r.reference_angle()},
          {"lower_translation", r.lower_translation()},
          {"upper_translation", r.upper_translation()},
          {"motor_speed", r.motor_speed()},
          {"target_translation", r.target_translation()}}) {
      CONVERT_RETURN_IF_ERROR(check(join(where, name), value, Range::kFinite));
    }
    for (auto [name, value] :
         {std::pair<const char*, double>{"max_motor_force", r.max_motor_force()},
          {"hertz", r.hertz()},
          {"damping_ratio", r.damping_ratio()}}) {
      CONVERT_RETURN_IF_ERROR(check(join(where, name), value, Range::kNonNegative));
    }
    def.reference_angle = r.reference_angle();
    def.enable_limit = r.enable_limit();
    def.lower_translation = r.lower_translation();
    def.upper_translation = r.upper_translation();
    def.enable_motor = r.enable_motor();
    def.motor_speed = r.motor_speed();
    def.max_motor_force = r.max_motor_force();
    def.enable_spring = r.enable_spring();
    def.hertz = r.hertz();
    def.damping_ratio = r.damping_ratio();
    def.target_translation = r.target_translation();
    out->def = def;
  } else if (p.has_wheel()) {
    const v1::WheelJoint& r = p.wheel();
    const std::string where = join(path, "wheel");
    WheelJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    def.collide_connected = p.collide_connected();
    CONVERT_RETURN_IF_ERROR(read_opt_vec(join(where, "local_axis_a"), r.has_local_axis_a(),
                                         r.local_axis_a(), &def.local_axis_a));
    if (r.has_enable_spring()) def.enable_spring = r.enable_spring();
    CONVERT_RETURN_IF_ERROR(
        read_opt(join(where, "hertz"), r.has_hertz(), r.hertz(), Range::kNonNegative, &def.hertz));
    CONVERT_RETURN_IF_ERROR(read_opt(join(where, "damping_ratio"), r.has_damping_ratio(),
                                     r.damping_ratio(), Range::kNonNegative, &def.damping_ratio));
    for (auto [name, value] :
         {std::pair<const char*, double>{"lower_translation", r.lower_translation()},
          {"upper_translation", r.upper_translation()},
          {"motor_speed", r.motor_speed()}}) {
      CONVERT_RETURN_IF_ERROR(check(join(where, name), value, Range::kFinite));
    }
    CONVERT_RETURN_IF_ERROR(
        check(join(where, "max_motor_torque"), r.max_motor_torque(), Range::kNonNegative));
    def.enable_limit = r.enable_limit();
    def.lower_translation = r.lower_translation();
    def.upper_translation = r.upper_translation();
    def.enable_motor = r.enable_motor();
    def.motor_speed = r.motor_speed();
    def.max_motor_torque = r.max_motor_torque();
    out->def = def;
  } else if (p.has_motor()) {
    const v1::MotorJoint& r = p.motor();
    const std::string where = join(path, "motor");
    if (p.has_local_anchor_a() || p.has_local_anchor_b()) {
      return fail(join(path, p.has_local_anchor_a() ? "local_anchor_a" : "local_anchor_b"),
                  "a motor joint has no anchors (use motor.linear_offset)");
    }
    MotorJointDef def;
    def.collide_connected = p.collide_connected();
    CONVERT_RETURN_IF_ERROR(read_opt_vec(join(where, "linear_offset"), r.has_linear_offset(),
                                         r.linear_offset(), &def.linear_offset));
    CONVERT_RETURN_IF_ERROR(
        check(join(where, "angular_offset"), r.angular_offset(), Range::kFinite));
    def.angular_offset = r.angular_offset();
    CONVERT_RETURN_IF_ERROR(read_opt(join(where, "max_force"), r.has_max_force(), r.max_force(),
                                     Range::kNonNegative, &def.max_force));
    CONVERT_RETURN_IF_ERROR(read_opt(join(where, "max_torque"), r.has_max_torque(), r.max_torque(),
                                     Range::kNonNegative, &def.max_torque));
    CONVERT_RETURN_IF_ERROR(read_opt(join(where, "correction_factor"), r.has_correction_factor(),
                                     r.correction_factor(), Range::kUnit, &def.correction_factor));
    out->def = def;
  } else if (p.has_target()) {
    return fail(join(path, "target"),
                "a target joint is created by an edit (CreateJoint), not by a scene");
  } else {
    return fail(path, "needs a kind (distance, revolute, weld, prismatic, wheel or motor)");
  }
  // Cross-field rules (min <= length <= max, lower <= upper) are the engine's to check.
  Status s = std::visit(
      [](const auto& def) {
        using Def = std::decay_t<decltype(def)>;
        if constexpr (std::is_same_v<Def, DistanceJointDef>) {
          return validate_distance_joint_def(def);
        } else if constexpr (std::is_same_v<Def, RevoluteJointDef>) {
          return validate_revolute_joint_def(def);
        } else if constexpr (std::is_same_v<Def, WeldJointDef>) {
          return validate_weld_joint_def(def);
        } else if constexpr (std::is_same_v<Def, PrismaticJointDef>) {
          return validate_prismatic_joint_def(def);
        } else if constexpr (std::is_same_v<Def, WheelJointDef>) {
          return validate_wheel_joint_def(def);
        } else {
          static_assert(std::is_same_v<Def, MotorJointDef>);
          return validate_motor_joint_def(def);
        }
      },
      out->def);
  if (!s.ok()) {
    // The engine names a definition's field ("joint.max_length"); the proto keeps the anchors
    // in Joint and the rest in the kind's message ("joints[0].distance.max_length").
    std::string msg = s.message();
    if (msg.rfind("joint.", 0) == 0) msg = msg.substr(6);
    const std::string head = msg.substr(0, msg.find_first_of(".:[ "));
    const bool in_joint = v1::Joint::descriptor()->FindFieldByName(head) != nullptr;
    const std::string kind = p.GetDescriptor()->FindFieldByNumber(p.kind_case())->name();
    return invalid_argument(path + "." + (in_joint ? "" : kind + ".") + msg);
  }
  return Status::ok_status();
}

void joint_to_proto(const SceneJoint& j, v1::Joint* out) {
  out->set_body_a(static_cast<uint32_t>(j.body_a));
  out->set_body_b(static_cast<uint32_t>(j.body_b));
  auto anchors = [&](const auto& def) {
    out->mutable_local_anchor_a()->set_x(def.local_anchor_a.x());
    out->mutable_local_anchor_a()->set_y(def.local_anchor_a.y());
    out->mutable_local_anchor_b()->set_x(def.local_anchor_b.x());
    out->mutable_local_anchor_b()->set_y(def.local_anchor_b.y());
    out->set_collide_connected(def.collide_connected);
  };
  if (const auto* d = std::get_if<DistanceJointDef>(&j.def)) {
    anchors(*d);
    v1::DistanceJoint* p = out->mutable_distance();
    p->set_length(d->length);
    p->set_min_length(d->min_length);
    p->set_max_length(d->max_length);
    p->set_hertz(d->hertz);
    p->set_damping_ratio(d->damping_ratio);
  } else if (const auto* w = std::get_if<WeldJointDef>(&j.def)) {
    anchors(*w);
    v1::WeldJoint* p = out->mutable_weld();
    p->set_reference_angle(w->reference_angle);
    p->set_linear_hertz(w->linear_hertz);
    p->set_linear_damping_ratio(w->linear_damping_ratio);
    p->set_angular_hertz(w->angular_hertz);
    p->set_angular_damping_ratio(w->angular_damping_ratio);
  } else if (const auto* pr = std::get_if<PrismaticJointDef>(&j.def)) {
    anchors(*pr);
    v1::PrismaticJoint* p = out->mutable_prismatic();
    vec_to_proto(pr->local_axis_a, p->mutable_local_axis_a());
    p->set_reference_angle(pr->reference_angle);
    p->set_enable_limit(pr->enable_limit);
    p->set_lower_translation(pr->lower_translation);
    p->set_upper_translation(pr->upper_translation);
    p->set_enable_motor(pr->enable_motor);
    p->set_motor_speed(pr->motor_speed);
    p->set_max_motor_force(pr->max_motor_force);
    p->set_enable_spring(pr->enable_spring);
    p->set_hertz(pr->hertz);
    p->set_damping_ratio(pr->damping_ratio);
    p->set_target_translation(pr->target_translation);
  } else if (const auto* h = std::get_if<WheelJointDef>(&j.def)) {
    anchors(*h);
    v1::WheelJoint* p = out->mutable_wheel();
    vec_to_proto(h->local_axis_a, p->mutable_local_axis_a());
    p->set_enable_spring(h->enable_spring);
    p->set_hertz(h->hertz);
    p->set_damping_ratio(h->damping_ratio);
    p->set_enable_limit(h->enable_limit);
    p->set_lower_translation(h->lower_translation);
    p->set_upper_translation(h->upper_translation);
    p->set_enable_motor(h->enable_motor);
    p->set_motor_speed(h->motor_speed);
    p->set_max_motor_torque(h->max_motor_torque);
  } else if (const auto* m = std::get_if<MotorJointDef>(&j.def)) {
    out->set_collide_connected(m->collide_connected);
    v1::MotorJoint* p = out->mutable_motor();
    vec_to_proto(m->linear_offset, p->mutable_linear_offset());
    p->set_angular_offset(m->angular_offset);
    p->set_max_force(m->max_force);
    p->set_max_torque(m->max_torque);
    p->set_correction_factor(m->correction_factor);
  } else {
    const auto& r = std::get<RevoluteJointDef>(j.def);
    anchors(r);
    v1::RevoluteJoint* p = out->mutable_revolute();
    p->set_reference_angle(r.reference_angle);
    p->set_enable_limit(r.enable_limit);
    p->set_lower_angle(r.lower_angle);
    p->set_upper_angle(r.upper_angle);
    p->set_enable_motor(r.enable_motor);
    p->set_motor_speed(r.motor_speed);
    p->set_max_motor_torque(r.max_motor_torque);
    p->set_enable_spring(r.enable_spring);
    p->set_hertz(r.hertz);
    p->set_damping_ratio(r.damping_ratio);
    p->set_target_angle(r.target_angle);
  }
}

Status attractor_from_proto(const v1::Attractor& p, const std::string& path, AttractorDef* a) {
  *a = AttractorDef{};
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "point"), p.has_point(), p.point(), &a->point));
  CONVERT_RETURN_IF_ERROR(check(join(path, "strength"), p.strength(), Range::kFinite));
  a->strength = p.strength();
  // Proto3 enums are open: a JSON number outside the enum parses, so it is checked here.
  if (!v1::Falloff_IsValid(p.falloff())) {
    return fail(join(path, "falloff"), "unknown falloff " + std::to_string(p.falloff()));
  }
  a->falloff = static_cast<Falloff>(p.falloff());
  CONVERT_RETURN_IF_ERROR(read_opt(join(path, "min_distance"), p.has_min_distance(),
                                   p.min_distance(), Range::kPositive, &a->min_distance));
  if (p.has_per_mass()) a->per_mass = p.per_mass();
  if (p.has_mask_bits()) a->mask_bits = p.mask_bits();
  // The engine's own check (the magnitude bound), named at this path.
  return validate_attractor(*a, path);
}

// Every field written (snapshots restore them exactly; exported scenes do not depend on
// today's defaults).
void attractor_to_proto(const AttractorDef& a, v1::Attractor* out) {
  vec_to_proto(a.point, out->mutable_point());
  out->set_strength(a.strength);
  out->set_falloff(static_cast<v1::Falloff>(a.falloff));
  out->set_min_distance(a.min_distance);
  out->set_per_mass(a.per_mass);
  out->set_mask_bits(a.mask_bits);
}

}  // namespace

Result<SceneDef> scene_from_proto(const v1::Scene& proto) {
  SceneDef scene;
  if (!proto.builtin().empty()) {
    const std::vector<std::string> names = scenes::builtin_names();
    if (std::find(names.begin(), names.end(), proto.builtin()) == names.end()) {
      std::string known;
      for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
      return fail("builtin", "unknown scene \"" + proto.builtin() + "\" (known: " + known + ")");
    }
    Result<SceneDef> builtin = scenes::builtin(proto.builtin());
    if (!builtin.ok()) return builtin.status().with_prefix("builtin: ");
    scene = std::move(builtin).value();
  }
  if (proto.has_settings()) {
    CONVERT_RETURN_IF_ERROR(settings_from_proto(proto.settings(), "settings", &scene.settings));
  }
  for (int i = 0; i < proto.builders_size(); ++i) {
    CONVERT_RETURN_IF_ERROR(
        builder_from_proto(proto.builders(i), indexed("", "builders", i), &scene));
  }
  CONVERT_RETURN_IF_ERROR(check_room("bodies", scene, proto.bodies_size()));
  scene.bodies.reserve(scene.bodies.size() + proto.bodies_size());
  for (int i = 0; i < proto.bodies_size(); ++i) {
    SceneBody body;
    CONVERT_RETURN_IF_ERROR(body_from_proto(proto.bodies(i), indexed("", "bodies", i), &body));
    scene.bodies.push_back(std::move(body));
  }
  for (int i = 0; i < proto.joints_size(); ++i) {
    SceneJoint joint;
    CONVERT_RETURN_IF_ERROR(joint_from_proto(proto.joints(i), indexed("", "joints", i),
                                             static_cast<int>(scene.bodies.size()), &joint));
    scene.joints.push_back(joint);
  }
  for (int i = 0; i < proto.attractors_size(); ++i) {
    AttractorDef a;
    CONVERT_RETURN_IF_ERROR(
        attractor_from_proto(proto.attractors(i), indexed("", "attractors", i), &a));
    scene.attractors.push_back(a);
  }
  return scene;
}

v1::Scene scene_to_proto(const SceneDef& scene, std::string_view name) {
  v1::Scene out;
  out.set_name(std::string(name));
  settings_to_proto(scene.settings, out.mutable_settings());
  for (const SceneBody& b : scene.bodies) body_to_proto(b, out.add_bodies());
  for (const SceneJoint& j : scene.joints) joint_to_proto(j, out.add_joints());
  for (const AttractorDef& a : scene.attractors) attractor_to_proto(a, out.add_attractors());
  return out;
}

Result<SceneDef> parse_scene_json(std::string_view json) {
  if (json.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    return invalid_argument("empty scene (expected a JSON object)");
  }
  v1::Scene proto;
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;  // a misspelt field must not silently take a default
  auto status = google::protobuf::util::JsonStringToMessage(
      google::protobuf::StringPiece(json.data(), json.size()), &proto, options);
  if (!status.ok()) {
    return invalid_argument(tidy_json_error(std::string(status.message())));
  }
  return scene_from_proto(proto);
}

Result<SceneDef> load_scene_json(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return invalid_argument(path + ": is a directory, not a scene file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno;
    return not_found(path + ": cannot open scene file (" +
                     std::string(err != 0 ? std::strerror(err) : "unknown error") + ")");
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Status(StatusCode::kDataLoss, path + ": read error");
  Result<SceneDef> scene = parse_scene_json(text.str());
  if (!scene.ok()) return scene.status().with_prefix(path + ": ");
  return scene;
}

std::string scene_to_json(const SceneDef& scene, std::string_view name) {
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  std::string out;
  // Printing a message we just built cannot fail.
  (void)google::protobuf::util::MessageToJsonString(scene_to_proto(scene, name), &out, options);
  return keep_negative_zeros(out);
}

// --- Pieces shared with the snapshot and edit conversions ---------------------------------------

void world_settings_to_proto(const WorldSettings& s, v1::WorldSettings* out) {
  settings_to_proto(s, out);
}
Status world_settings_from_proto(const v1::WorldSettings& p, const std::string& path,
                                 WorldSettings* s) {
  return settings_from_proto(p, path, s);
}
Status scene_body_from_proto(const v1::Body& p, const std::string& path, SceneBody* body) {
  return body_from_proto(p, path, body);
}
Status scene_shape_from_proto(const v1::Shape& p, const std::string& path, ShapeDef* def) {
  return shape_from_proto(p, path, def);
}
Filter scene_filter_from_proto(const v1::Filter& p) {
  return filter_from_proto(p);
}
void scene_filter_to_proto(const Filter& f, v1::Filter* out) {
  filter_to_proto(f, out);
}
Status scene_joint_from_proto(const v1::Joint& p, const std::string& path, int body_count,
                              SceneJoint* out) {
  return joint_from_proto(p, path, body_count, out);
}
Status scene_attractor_from_proto(const v1::Attractor& p, const std::string& path,
                                  AttractorDef* out) {
  return attractor_from_proto(p, path, out);
}
void scene_attractor_to_proto(const AttractorDef& a, v1::Attractor* out) {
  attractor_to_proto(a, out);
}

Status target_joint_from_proto(const v1::Joint& p, const std::string& path, TargetJointDef* def) {
  if (p.has_local_anchor_a()) {
    return fail(join(path, "local_anchor_a"),
                "a target joint has no anchor on body A (use target.target)");
  }
  CONVERT_RETURN_IF_ERROR(read_opt_vec(join(path, "local_anchor_b"), p.has_local_anchor_b(),
                                       p.local_anchor_b(), &def->local_anchor_b));
  const v1::TargetJoint& t = p.target();
  const std::string where = join(path, "target");
  CONVERT_RETURN_IF_ERROR(
      read_opt_vec(join(where, "target"), t.has_target(), t.target(), &def->target));
  CONVERT_RETURN_IF_ERROR(read_opt(join(where, "max_force"), t.has_max_force(), t.max_force(),
                                   Range::kNonNegative, &def->max_force));
  CONVERT_RETURN_IF_ERROR(
      read_opt(join(where, "hertz"), t.has_hertz(), t.hertz(), Range::kPositive, &def->hertz));
  CONVERT_RETURN_IF_ERROR(read_opt(join(where, "damping_ratio"), t.has_damping_ratio(),
                                   t.damping_ratio(), Range::kNonNegative, &def->damping_ratio));
  Status s = validate_target_joint_def(*def);
  if (!s.ok()) {
    std::string msg = s.message();
    if (msg.rfind("joint.", 0) == 0) msg = msg.substr(6);
    return invalid_argument(where + "." + msg);
  }
  return Status::ok_status();
}

#undef CONVERT_RETURN_IF_ERROR

}  // namespace fulcrum
