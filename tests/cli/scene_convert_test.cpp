// Scene conversion: proto <-> engine definitions and the JSON scene files.
#include "scene_convert.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"

namespace fulcrum {
namespace {

// --- Bitwise comparison of scenes: the first difference, as a path, or "" --------------------

bool same(double a, double b) {
  return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b);
}

std::string diff_double(const std::string& path, double a, double b) {
  if (same(a, b)) return "";
  std::ostringstream s;
  s.precision(17);
  s << path << ": " << a << " vs " << b;
  return s.str();
}

std::string diff_vec(const std::string& path, const Vec2& a, const Vec2& b) {
  std::string d = diff_double(path + ".x", a.x(), b.x());
  return d.empty() ? diff_double(path + ".y", a.y(), b.y()) : d;
}

template <typename T>
std::string diff_value(const std::string& path, const T& a, const T& b) {
  if (a == b) return "";
  return path + ": " + std::to_string(a) + " vs " + std::to_string(b);
}

#define RETURN_IF_DIFF(expr)    \
  do {                          \
    std::string d_ = (expr);    \
    if (!d_.empty()) return d_; \
  } while (false)

std::string diff_filter(const std::string& p, const Filter& a, const Filter& b) {
  RETURN_IF_DIFF(diff_value(p + ".category_bits", a.category_bits, b.category_bits));
  RETURN_IF_DIFF(diff_value(p + ".mask_bits", a.mask_bits, b.mask_bits));
  return diff_value(p + ".group_index", a.group_index, b.group_index);
}

std::string diff_geometry(const std::string& p, const Geometry& a, const Geometry& b) {
  RETURN_IF_DIFF(diff_value(p + ".kind", a.index(), b.index()));
  if (const auto* ca = std::get_if<Circle>(&a)) {
    const auto& cb = std::get<Circle>(b);
    RETURN_IF_DIFF(diff_vec(p + ".center", ca->center, cb.center));
    return diff_double(p + ".radius", ca->radius, cb.radius);
  }
  if (const auto* ca = std::get_if<Capsule>(&a)) {
    const auto& cb = std::get<Capsule>(b);
    RETURN_IF_DIFF(diff_vec(p + ".center1", ca->center1, cb.center1));
    RETURN_IF_DIFF(diff_vec(p + ".center2", ca->center2, cb.center2));
    return diff_double(p + ".radius", ca->radius, cb.radius);
  }
  if (const auto* sa = std::get_if<Segment>(&a)) {
    const auto& sb = std::get<Segment>(b);
    RETURN_IF_DIFF(diff_vec(p + ".point1", sa->point1, sb.point1));
    return diff_vec(p + ".point2", sa->point2, sb.point2);
  }
  const auto& pa = std::get<Polygon>(a);
  const auto& pb = std::get<Polygon>(b);
  RETURN_IF_DIFF(diff_value(p + ".count", pa.count, pb.count));
  for (int i = 0; i < pa.count; ++i) {
    RETURN_IF_DIFF(
        diff_vec(p + ".vertices[" + std::to_string(i) + "]", pa.vertices[i], pb.vertices[i]));
    RETURN_IF_DIFF(
        diff_vec(p + ".normals[" + std::to_string(i) + "]", pa.normals[i], pb.normals[i]));
  }
  RETURN_IF_DIFF(diff_vec(p + ".centroid", pa.centroid, pb.centroid));
  return diff_double(p + ".radius", pa.radius, pb.radius);
}

std::string diff_settings(const WorldSettings& a, const WorldSettings& b) {
  const std::string p = "settings";
  RETURN_IF_DIFF(diff_vec(p + ".gravity", a.gravity, b.gravity));
  RETURN_IF_DIFF(diff_double(p + ".dt", a.dt, b.dt));
  RETURN_IF_DIFF(
      diff_value(p + ".velocity_iterations", a.velocity_iterations, b.velocity_iterations));
  RETURN_IF_DIFF(diff_value(p + ".substeps", a.substeps, b.substeps));
  RETURN_IF_DIFF(diff_value(p + ".relax_iterations", a.relax_iterations, b.relax_iterations));
  RETURN_IF_DIFF(diff_double(p + ".contact_hertz", a.contact_hertz, b.contact_hertz));
  RETURN_IF_DIFF(
      diff_double(p + ".contact_damping_ratio", a.contact_damping_ratio, b.contact_damping_ratio));
  RETURN_IF_DIFF(diff_double(p + ".joint_hertz", a.joint_hertz, b.joint_hertz));
  RETURN_IF_DIFF(
      diff_double(p + ".joint_damping_ratio", a.joint_damping_ratio, b.joint_damping_ratio));
  RETURN_IF_DIFF(diff_value(p + ".max_substeps", a.max_substeps, b.max_substeps));
  RETURN_IF_DIFF(
      diff_double(p + ".joint_give_tolerance", a.joint_give_tolerance, b.joint_give_tolerance));
  RETURN_IF_DIFF(diff_double(p + ".contact_give_tolerance", a.contact_give_tolerance,
                             b.contact_give_tolerance));
  RETURN_IF_DIFF(diff_double(p + ".one_pass_give_tolerance", a.one_pass_give_tolerance,
                             b.one_pass_give_tolerance));
  RETURN_IF_DIFF(
      diff_value(p + ".position_iterations", a.position_iterations, b.position_iterations));
  RETURN_IF_DIFF(diff_value(p + ".split_impulses", a.split_impulses, b.split_impulses));
  RETURN_IF_DIFF(diff_double(p + ".baumgarte", a.baumgarte, b.baumgarte));
  RETURN_IF_DIFF(diff_double(p + ".linear_slop", a.linear_slop, b.linear_slop));
  RETURN_IF_DIFF(
      diff_double(p + ".max_correction_speed", a.max_correction_speed, b.max_correction_speed));
  RETURN_IF_DIFF(
      diff_double(p + ".restitution_threshold", a.restitution_threshold, b.restitution_threshold));
  RETURN_IF_DIFF(
      diff_double(p + ".early_exit_tolerance", a.early_exit_tolerance, b.early_exit_tolerance));
  RETURN_IF_DIFF(diff_value(p + ".warm_starting", a.warm_starting, b.warm_starting));
  RETURN_IF_DIFF(diff_value(p + ".block_solver", a.block_solver, b.block_solver));
  RETURN_IF_DIFF(
      diff_double(p + ".speculative_distance", a.speculative_distance, b.speculative_distance));
  RETURN_IF_DIFF(diff_double(p + ".manifold_reuse_distance", a.manifold_reuse_distance,
                             b.manifold_reuse_distance));
  RETURN_IF_DIFF(diff_double(p + ".aabb_margin", a.aabb_margin, b.aabb_margin));
  RETURN_IF_DIFF(diff_double(p + ".max_linear_speed", a.max_linear_speed, b.max_linear_speed));
  RETURN_IF_DIFF(diff_value(p + ".enable_sleep", a.enable_sleep, b.enable_sleep));
  RETURN_IF_DIFF(diff_double(p + ".time_to_sleep", a.time_to_sleep, b.time_to_sleep));
  RETURN_IF_DIFF(diff_double(p + ".linear_sleep_tolerance", a.linear_sleep_tolerance,
                             b.linear_sleep_tolerance));
  return diff_double(p + ".angular_sleep_tolerance", a.angular_sleep_tolerance,
                     b.angular_sleep_tolerance);
}

std::string diff_body(const std::string& p, const SceneBody& a, const SceneBody& b) {
  const BodyDef& x = a.def;
  const BodyDef& y = b.def;
  RETURN_IF_DIFF(diff_value(p + ".type", static_cast<int>(x.type), static_cast<int>(y.type)));
  RETURN_IF_DIFF(diff_vec(p + ".position", x.position, y.position));
  RETURN_IF_DIFF(diff_double(p + ".angle", x.angle, y.angle));
  RETURN_IF_DIFF(diff_vec(p + ".linear_velocity", x.linear_velocity, y.linear_velocity));
  RETURN_IF_DIFF(diff_double(p + ".angular_velocity", x.angular_velocity, y.angular_velocity));
  RETURN_IF_DIFF(diff_double(p + ".linear_damping", x.linear_damping, y.linear_damping));
  RETURN_IF_DIFF(diff_double(p + ".angular_damping", x.angular_damping, y.angular_damping));
  RETURN_IF_DIFF(diff_double(p + ".gravity_scale", x.gravity_scale, y.gravity_scale));
  RETURN_IF_DIFF(diff_double(p + ".drag", x.drag, y.drag));
  RETURN_IF_DIFF(diff_value(p + ".fixed_rotation", x.fixed_rotation, y.fixed_rotation));
  RETURN_IF_DIFF(diff_value(p + ".awake", x.awake, y.awake));
  RETURN_IF_DIFF(diff_value(p + ".enable_sleep", x.enable_sleep, y.enable_sleep));
  RETURN_IF_DIFF(diff_value(p + ".user_data", x.user_data, y.user_data));
  RETURN_IF_DIFF(diff_vec(p + ".constant_force", x.constant_force, y.constant_force));
  RETURN_IF_DIFF(diff_double(p + ".constant_torque", x.constant_torque, y.constant_torque));
  RETURN_IF_DIFF(diff_value(p + ".shapes.size", a.shapes.size(), b.shapes.size()));
  for (size_t i = 0; i < a.shapes.size(); ++i) {
    const std::string sp = p + ".shapes[" + std::to_string(i) + "]";
    const ShapeDef& s = a.shapes[i];
    const ShapeDef& t = b.shapes[i];
    RETURN_IF_DIFF(diff_geometry(sp + ".geometry", s.geometry, t.geometry));
    RETURN_IF_DIFF(diff_double(sp + ".density", s.density, t.density));
    RETURN_IF_DIFF(diff_double(sp + ".friction", s.friction, t.friction));
    RETURN_IF_DIFF(diff_double(sp + ".restitution", s.restitution, t.restitution));
    RETURN_IF_DIFF(diff_filter(sp + ".filter", s.filter, t.filter));
    RETURN_IF_DIFF(diff_value(sp + ".is_sensor", s.is_sensor, t.is_sensor));
    RETURN_IF_DIFF(diff_value(sp + ".user_data", s.user_data, t.user_data));
  }
  RETURN_IF_DIFF(diff_value(p + ".chains.size", a.chains.size(), b.chains.size()));
  for (size_t i = 0; i < a.chains.size(); ++i) {
    const std::string cp = p + ".chains[" + std::to_string(i) + "]";
    const ChainDef& c = a.chains[i];
    const ChainDef& d = b.chains[i];
    RETURN_IF_DIFF(diff_value(cp + ".points.size", c.points.size(), d.points.size()));
    for (size_t j = 0; j < c.points.size(); ++j) {
      RETURN_IF_DIFF(diff_vec(cp + ".points[" + std::to_string(j) + "]", c.points[j], d.points[j]));
    }
    RETURN_IF_DIFF(diff_value(cp + ".loop", c.loop, d.loop));
    RETURN_IF_DIFF(diff_double(cp + ".friction", c.friction, d.friction));
    RETURN_IF_DIFF(diff_double(cp + ".restitution", c.restitution, d.restitution));
    RETURN_IF_DIFF(diff_filter(cp + ".filter", c.filter, d.filter));
    RETURN_IF_DIFF(diff_value(cp + ".user_data", c.user_data, d.user_data));
  }
  return "";
}

std::string diff_scene(const SceneDef& a, const SceneDef& b) {
  RETURN_IF_DIFF(diff_settings(a.settings, b.settings));
  RETURN_IF_DIFF(diff_value("bodies.size", a.bodies.size(), b.bodies.size()));
  for (size_t i = 0; i < a.bodies.size(); ++i) {
    RETURN_IF_DIFF(diff_body("bodies[" + std::to_string(i) + "]", a.bodies[i], b.bodies[i]));
  }
  RETURN_IF_DIFF(diff_value("attractors.size", a.attractors.size(), b.attractors.size()));
  for (size_t i = 0; i < a.attractors.size(); ++i) {
    const std::string p = "attractors[" + std::to_string(i) + "]";
    const AttractorDef& x = a.attractors[i];
    const AttractorDef& y = b.attractors[i];
    RETURN_IF_DIFF(diff_vec(p + ".point", x.point, y.point));
    RETURN_IF_DIFF(diff_double(p + ".strength", x.strength, y.strength));
    RETURN_IF_DIFF(
        diff_value(p + ".falloff", static_cast<int>(x.falloff), static_cast<int>(y.falloff)));
    RETURN_IF_DIFF(diff_double(p + ".min_distance", x.min_distance, y.min_distance));
    RETURN_IF_DIFF(diff_value(p + ".per_mass", x.per_mass, y.per_mass));
    RETURN_IF_DIFF(diff_value(p + ".mask_bits", x.mask_bits, y.mask_bits));
  }
  return "";
}

#undef RETURN_IF_DIFF

// scene_to_json, then parse_scene_json: must reproduce the scene bit for bit.
void ExpectJsonRoundTrip(const SceneDef& scene) {
  const std::string json = scene_to_json(scene);
  Result<SceneDef> back = parse_scene_json(json);
  ASSERT_TRUE(back.ok()) << back.status().to_string() << "\n" << json.substr(0, 4000);
  EXPECT_EQ(diff_scene(scene, *back), "");
}

ChainDef OpenChain(std::vector<Vec2> points) {
  ChainDef chain;
  chain.points = std::move(points);
  return chain;
}

Polygon MakePolygon(std::vector<Vec2> vertices, double radius = 0.0) {
  Polygon p;
  Status s = make_polygon(vertices, radius, &p);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return p;
}

// A scene that touches every field with values that are hard to print exactly.
SceneDef AwkwardScene() {
  SceneDef scene;
  WorldSettings& s = scene.settings;
  s.gravity = Vec2(0.1, -9.80665);
  s.dt = 1.0 / 240.0;
  s.substeps = 7;
  s.velocity_iterations = 13;
  s.relax_iterations = 0;
  s.contact_hertz = 0.0;
  s.contact_damping_ratio = 0.1;
  s.joint_hertz = 33.0;
  s.joint_damping_ratio = 0.7;
  s.max_substeps = 9;
  s.joint_give_tolerance = 0.1 + 0.2;  // not a short decimal
  s.contact_give_tolerance = 0.7 / 3.0;
  s.one_pass_give_tolerance = 0.0;
  s.position_iterations = 0;
  s.split_impulses = true;
  s.baumgarte = 1.0 / 3.0;
  s.linear_slop = 5e-324;  // the smallest denormal
  s.max_correction_speed = 1.7976931348623157e308;
  s.restitution_threshold = 0.0;
  s.early_exit_tolerance = 1e-300;
  s.warm_starting = false;
  s.block_solver = false;
  s.speculative_distance = 0.030000000000000002;
  s.manifold_reuse_distance = 0.0;
  s.aabb_margin = 0.0;
  s.max_linear_speed = 123.456;
  s.enable_sleep = false;
  s.time_to_sleep = 2.0 / 3.0;
  s.linear_sleep_tolerance = 0.0;
  s.angular_sleep_tolerance = std::nextafter(0.035, 1.0);

  // Static terrain: a box, a segment and two chains.
  SceneBody ground;
  ground.def.position = Vec2(-0.0, -1.0);  // negative zero must survive
  ground.def.user_data = std::numeric_limits<uint64_t>::max();
  ShapeDef box;
  box.geometry = make_box(50.0, 1.0);
  box.friction = 0.7;
  ground.shapes.push_back(box);
  ShapeDef segment;
  segment.geometry = Segment{Vec2(-3.0, 0.1), Vec2(3.0, 0.2)};
  segment.filter = Filter{0x8000000000000000ull, 0x5555, -7};
  ground.shapes.push_back(segment);
  ChainDef open;
  open.points = {Vec2(-10, 0), Vec2(-5, 1e-9), Vec2(0, 0.5)};
  open.restitution = 0.25;
  open.user_data = 42;
  ground.chains.push_back(open);
  ChainDef loop;
  loop.points = {Vec2(20, 0), Vec2(22, 0), Vec2(21, 1.7320508075688772)};
  loop.loop = true;
  loop.friction = 0.0;
  loop.filter.group_index = 3;
  ground.chains.push_back(loop);
  scene.bodies.push_back(ground);

  // A dynamic body with every kind of solid shape.
  SceneBody body;
  body.def.type = BodyType::kDynamic;
  body.def.position = Vec2(1.0 / 3.0, 10.1);
  body.def.angle = -3.141592653589793;
  body.def.linear_velocity = Vec2(1e-17, -2.5);
  body.def.angular_velocity = 0.7;
  body.def.linear_damping = 0.05;
  body.def.angular_damping = 0.5;
  body.def.gravity_scale = -0.5;
  body.def.drag = 0.125;
  body.def.fixed_rotation = true;
  body.def.awake = false;
  body.def.enable_sleep = false;
  ShapeDef circle;
  circle.geometry = Circle{Vec2(0.25, -0.125), 0.3};
  circle.density = 0.0;
  circle.is_sensor = true;
  circle.user_data = 7;
  body.shapes.push_back(circle);
  ShapeDef capsule;
  capsule.geometry = Capsule{Vec2(-0.2, 0.1), Vec2(0.4, 0.3), 0.15};
  capsule.density = 2.5;
  capsule.restitution = 1.0;
  body.shapes.push_back(capsule);
  ShapeDef tri;
  tri.geometry = MakePolygon({Vec2(0, 0), Vec2(1, 0.1), Vec2(0.3, 0.9)}, 0.01);
  body.shapes.push_back(tri);
  ShapeDef offset_box;
  offset_box.geometry = make_offset_box(0.1, 0.2, Vec2(0.3, -0.7), 0.0);
  body.shapes.push_back(offset_box);
  ShapeDef rounded_box;
  Polygon rounded = make_box(0.3, 0.1);
  rounded.radius = 0.05;
  rounded_box.geometry = rounded;
  body.shapes.push_back(rounded_box);
  scene.bodies.push_back(body);

  // A particle and a kinematic body.
  SceneBody particle;
  particle.def.type = BodyType::kParticle;
  particle.def.position = Vec2(2, 3);
  ShapeDef dot;
  dot.geometry = Circle{Vec2::Zero(), 0.1};
  particle.shapes.push_back(dot);
  scene.bodies.push_back(particle);
  SceneBody kinematic;
  kinematic.def.type = BodyType::kKinematic;
  kinematic.def.angular_velocity = 0.4363323129985824;
  ShapeDef plate;
  plate.geometry = make_box(2.0, 0.25);
  kinematic.shapes.push_back(plate);
  scene.bodies.push_back(kinematic);
  scene.bodies[1].def.constant_force = Vec2(-0.0, 1e12);
  scene.bodies[1].def.constant_torque = -3.5;
  AttractorDef pull;
  pull.point = Vec2(1.0 / 3.0, -2.0);
  pull.strength = -7.25;
  pull.falloff = Falloff::kInverseSquare;
  pull.min_distance = 5e-324;
  pull.per_mass = false;
  pull.mask_bits = 0x8000000000000001ull;
  scene.attractors.push_back(pull);
  scene.attractors.push_back(AttractorDef{});
  return scene;
}

// --- Schema guard ----------------------------------------------------------------------------

// scene.proto and scene_convert.cpp must cover every field of the engine's definition structs.
// A size change here means a field was added or removed in engine/include/fulcrum: update
// scene.proto, scene_convert.cpp (both directions) and the comparisons above, then these
// numbers (x86-64 sizes).
TEST(SceneSchema, EngineDefinitionStructsAreCovered) {
  EXPECT_EQ(sizeof(WorldSettings), 224u);
  EXPECT_EQ(sizeof(BodyDef), 160u);
  EXPECT_EQ(sizeof(AttractorDef), 64u);
  EXPECT_EQ(sizeof(ShapeDef), 368u);
  EXPECT_EQ(sizeof(ChainDef), 80u);
  EXPECT_EQ(sizeof(Filter), 24u);
  EXPECT_EQ(sizeof(Circle), 32u);
  EXPECT_EQ(sizeof(Capsule), 48u);
  EXPECT_EQ(sizeof(Segment), 32u);
  EXPECT_EQ(sizeof(Polygon), 288u);
  EXPECT_EQ(std::variant_size_v<Geometry>, 4u);
  // Joints (scene.proto's Joint kinds; TargetJointDef is not scene content).
  EXPECT_EQ(sizeof(DistanceJointDef), 96u);
  EXPECT_EQ(sizeof(RevoluteJointDef), 144u);
  EXPECT_EQ(sizeof(WeldJointDef), 96u);
  EXPECT_EQ(sizeof(PrismaticJointDef), 160u);
  EXPECT_EQ(sizeof(WheelJointDef), 144u);
  EXPECT_EQ(sizeof(MotorJointDef), 80u);
  EXPECT_EQ(std::variant_size_v<decltype(SceneJoint::def)>, 6u);
}

// --- Round trips -----------------------------------------------------------------------------

TEST(SceneJson, RoundTripIsExact) {
  ExpectJsonRoundTrip(AwkwardScene());
}

TEST(SceneJson, RoundTripOfDefaults) {
  SceneDef scene;
  scene.bodies.emplace_back();
  scene.bodies.back().shapes.emplace_back();
  scene.bodies.back().chains.push_back(OpenChain({Vec2(0, 0), Vec2(1, 0)}));
  ExpectJsonRoundTrip(scene);
  ExpectJsonRoundTrip(SceneDef{});
}

TEST(SceneJson, ExportedBoxesStayBoxes) {
  SceneDef scene = AwkwardScene();
  v1::Scene proto = scene_to_proto(scene, "awkward");
  EXPECT_EQ(proto.name(), "awkward");
  EXPECT_EQ(proto.builders_size(), 0);
  EXPECT_TRUE(proto.builtin().empty());
  ASSERT_EQ(proto.bodies_size(), 4);
  EXPECT_TRUE(proto.bodies(0).shapes(0).has_box());
  EXPECT_EQ(proto.bodies(0).shapes(0).box().half_width(), 50.0);
  EXPECT_TRUE(proto.bodies(1).shapes(2).has_polygon());  // the triangle
  EXPECT_TRUE(proto.bodies(1).shapes(3).has_box());      // offset, unturned
  EXPECT_TRUE(proto.bodies(1).shapes(4).has_box());      // rounded
  EXPECT_EQ(proto.bodies(1).shapes(4).box().radius(), 0.05);
  // Every settings field is written out.
  EXPECT_TRUE(proto.settings().has_dt());
  EXPECT_TRUE(proto.settings().has_angular_sleep_tolerance());
}

// Turned boxes are recognised (their angle recovered bit-exactly) and round trip exactly.
TEST(SceneJson, TurnedBoxesStayBoxes) {
  SceneDef scene;
  scene.bodies.emplace_back();
  const double angles[] = {0.3,   -0.3, 1.5707963267948966, -3.141592653589793, 3.141592653589793,
                           1e-10, -2.5, 0.7853981633974483};
  int i = 0;
  for (double angle : angles) {
    for (int k = 0; k < 25; ++k, ++i) {
      ShapeDef shape;
      // Sizes and centres with no short binary form.
      const Vec2 center = k % 5 == 0 ? Vec2::Zero() : Vec2(0.1 * k - 1.3, 0.37 * (k % 7));
      shape.geometry = make_offset_box(0.05 + 0.11 * k, 0.7 / (k + 1), center, angle + 1e-3 * k);
      scene.bodies[0].shapes.push_back(shape);
    }
  }
  v1::Scene proto = scene_to_proto(scene);
  int boxes = 0;
  for (const v1::Shape& shape : proto.bodies(0).shapes()) boxes += shape.has_box() ? 1 : 0;
  EXPECT_EQ(boxes, i);
  ExpectJsonRoundTrip(scene);
}

// Every builtin scene survives export and re-import bit for bit.
TEST(SceneJson, BuiltinsRoundTrip) {
  for (const std::string& name : scenes::builtin_names()) {
    SCOPED_TRACE(name);
    Result<SceneDef> scene = scenes::builtin(name);
    ASSERT_TRUE(scene.ok()) << scene.status().to_string();
    ExpectJsonRoundTrip(*scene);
  }
}

// --- Defaults and assembly order -------------------------------------------------------------

// The JSON spelling of constant forces and attractors (scene.proto), and the world it builds.
TEST(SceneJson, ConstantForcesAndAttractors) {
  Result<SceneDef> scene = parse_scene_json(R"({
    "bodies": [{"type": "BODY_TYPE_DYNAMIC", "constantForce": {"x": 2, "y": 30},
                "constantTorque": 0.5, "shapes": [{"circle": {"radius": 0.5}}]}],
    "attractors": [{"point": {"x": 1, "y": 2}, "strength": 100,
                    "falloff": "FALLOFF_INVERSE_SQUARE", "minDistance": 2, "perMass": false,
                    "maskBits": "6"},
                   {"strength": 3}]
  })");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  EXPECT_EQ(scene->bodies[0].def.constant_force, Vec2(2.0, 30.0));
  EXPECT_EQ(scene->bodies[0].def.constant_torque, 0.5);
  ASSERT_EQ(scene->attractors.size(), 2u);
  const AttractorDef& a = scene->attractors[0];
  EXPECT_EQ(a.point, Vec2(1.0, 2.0));
  EXPECT_EQ(a.strength, 100.0);
  EXPECT_EQ(a.falloff, Falloff::kInverseSquare);
  EXPECT_EQ(a.min_distance, 2.0);
  EXPECT_FALSE(a.per_mass);
  EXPECT_EQ(a.mask_bits, 6u);
  const AttractorDef defaults;  // absent fields: the engine's defaults
  EXPECT_EQ(scene->attractors[1].falloff, Falloff::kConstant);
  EXPECT_EQ(scene->attractors[1].min_distance, defaults.min_distance);
  EXPECT_TRUE(scene->attractors[1].per_mass);
  EXPECT_EQ(scene->attractors[1].mask_bits, ~uint64_t{0});
  Result<World> world = build_world(*scene);
  ASSERT_TRUE(world.ok()) << world.status().to_string();
  EXPECT_EQ(world->attractors().size(), 2u);
  EXPECT_EQ(world->body_state(world->bodies()[0])->constant_force, Vec2(2.0, 30.0));
  // The magnitude bound (kMaxInputMagnitude) is the engine's, checked when the world is built.
  scene->bodies[0].def.constant_torque = 1e13;
  world = build_world(*scene);
  ASSERT_FALSE(world.ok());
  EXPECT_EQ(world.status().message().rfind("bodies[0].constant_torque", 0), 0u)
      << world.status().message();
}

TEST(SceneJson, AbsentFieldsTakeEngineDefaults) {
  Result<SceneDef> scene = parse_scene_json(R"({
    "bodies": [{"shapes": [{"circle": {}}], "chains": [{"points": [{}, {"x": 1}]}]}]
  })");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  SceneDef expected;
  expected.bodies.emplace_back();
  expected.bodies.back().shapes.emplace_back();  // ShapeDef{} holds a default Circle
  expected.bodies.back().chains.push_back(OpenChain({Vec2(0, 0), Vec2(1, 0)}));
  EXPECT_EQ(diff_scene(expected, *scene), "");
}

TEST(SceneJson, BuiltinThenBuildersThenBodies) {
  const std::string name = "vertical_stack";
  Result<SceneDef> builtin = scenes::builtin(name);
  ASSERT_TRUE(builtin.ok()) << builtin.status().to_string();
  Result<SceneDef> scene = parse_scene_json(R"({
    "builtin": "vertical_stack",
    "settings": {"dt": 0.01, "velocityIterations": 4},
    "builders": [{"ground": {"halfWidth": 5, "top": -10}}],
    "bodies": [{"type": "BODY_TYPE_DYNAMIC", "userData": "99",
                "shapes": [{"circle": {"radius": 0.2}}]}]
  })");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  const size_t n = builtin->bodies.size();
  ASSERT_EQ(scene->bodies.size(), n + 2);
  for (size_t i = 0; i < n; ++i) {
    EXPECT_EQ(diff_body("bodies[" + std::to_string(i) + "]", builtin->bodies[i], scene->bodies[i]),
              "");
  }
  SceneDef ground;
  scenes::add_ground(&ground, 5.0, -10.0);
  EXPECT_EQ(diff_body("ground", ground.bodies[0], scene->bodies[n]), "");
  EXPECT_EQ(scene->bodies[n + 1].def.user_data, 99u);
  // Given settings override the builtin's; the rest are the builtin's.
  WorldSettings expected = builtin->settings;
  expected.dt = 0.01;
  expected.velocity_iterations = 4;
  EXPECT_EQ(diff_settings(expected, scene->settings), "");
}

// The JSON spelling of the hand-written-scene builders: a ground placed anywhere, a joint
// chain, a card house; each gives what its builder function gives.
TEST(SceneJson, HandBuildersMatchTheBuilderFunctions) {
  Result<SceneDef> scene = parse_scene_json(R"({"builders": [
    {"ground": {"halfWidth": 30, "center": {"x": 2, "y": -1}, "angle": -0.2, "thickness": 0.5,
                "friction": 0.9}},
    {"ground": {"halfWidth": 10, "top": 3}},
    {"jointChain": {"anchor": {"x": -5, "y": 12}, "links": 8, "linkLength": 0.8,
                    "linkWidth": 0.2, "shape": "LINK_SHAPE_BOX", "joint": "KIND_WELD",
                    "angle": 0.5, "density": 2, "friction": 0.3, "endMass": 100,
                    "endRadius": 0.4}},
    {"jointChain": {}},
    {"cardHouse": {"origin": {"x": 7}, "levels": 4, "cardLength": 0.9, "cardThickness": 0.03,
                   "lean": 0.3, "friction": 0.8, "density": 0.5}}
  ]})");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  SceneDef expected;
  scenes::GroundOptions g;
  g.half_width = 30;
  g.center = Vec2(2, -1);
  g.angle = -0.2;
  g.thickness = 0.5;
  g.friction = 0.9;
  scenes::add_ground(&expected, g);
  scenes::add_ground(&expected, 10.0, 3.0);
  scenes::JointChainOptions c;
  c.anchor = Vec2(-5, 12);
  c.links = 8;
  c.link_length = 0.8;
  c.link_width = 0.2;
  c.shape = scenes::JointChainOptions::LinkShape::kBox;
  c.joint = scenes::JointChainOptions::JointKind::kWeld;
  c.angle = 0.5;
  c.density = 2;
  c.friction = 0.3;
  c.end_mass = 100;
  c.end_radius = 0.4;
  scenes::add_joint_chain(&expected, c);
  scenes::add_joint_chain(&expected, scenes::JointChainOptions{});
  scenes::CardHouseOptions h;
  h.origin = Vec2(7, 0);
  h.levels = 4;
  h.card_length = 0.9;
  h.card_thickness = 0.03;
  h.lean = 0.3;
  h.friction = 0.8;
  h.density = 0.5;
  scenes::add_card_house(&expected, h);
  EXPECT_EQ(diff_scene(expected, *scene), "");
  ASSERT_EQ(scene->joints.size(), expected.joints.size());
  EXPECT_EQ(scene->joints.size(), 9u + 20u);
  for (size_t i = 0; i < expected.joints.size(); ++i) {
    EXPECT_EQ(scene->joints[i].body_a, expected.joints[i].body_a);
    EXPECT_EQ(scene->joints[i].body_b, expected.joints[i].body_b);
    EXPECT_EQ(scene->joints[i].def.index(), expected.joints[i].def.index());
  }
  EXPECT_TRUE(build_world(*scene).ok());
}

TEST(SceneJson, BuildersMatchTheBuilderFunctions) {
  Result<SceneDef> scene = parse_scene_json(R"({"builders": [
    {"pyramid": {"base": 4, "boxSize": 0.5, "spacing": 0.6, "origin": {"x": 1, "y": 2},
                 "density": 3, "friction": 0.4, "topDensity": 30}},
    {"stack": {"count": 3, "boxSize": 2, "offset": -0.1, "density": 0.5, "friction": 0.9}},
    {"pyramid": {}}
  ]})");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  SceneDef expected;
  scenes::PyramidOptions p;
  p.base = 4;
  p.box_size = 0.5;
  p.spacing = 0.6;
  p.origin = Vec2(1, 2);
  p.density = 3;
  p.friction = 0.4;
  p.top_density = 30;
  scenes::add_pyramid(&expected, p);
  scenes::StackOptions s;
  s.count = 3;
  s.box_size = 2;
  s.offset = -0.1;
  s.density = 0.5;
  s.friction = 0.9;
  scenes::add_stack(&expected, s);
  scenes::add_pyramid(&expected, scenes::PyramidOptions{});
  EXPECT_EQ(diff_scene(expected, *scene), "");
}

// The rope, cloth and ragdoll builders of scene files are the builder functions themselves.
TEST(SceneJson, JointBuildersMatchTheBuilderFunctions) {
  Result<SceneDef> scene = parse_scene_json(R"({"builders": [
    {"rope": {"start": {"x": -2, "y": 5}, "end": {"x": 3, "y": 5}, "count": 12, "radius": 0.04,
              "density": 8, "pinStart": false, "collide": false}},
    {"cloth": {"topLeft": {"x": 1, "y": 9}, "columns": 5, "rows": 4, "spacing": 0.3,
               "pinned": [0, 0, 4, 0, 2, 3], "group": -3}},
    {"ragdoll": {"feet": {"x": 6}, "scale": 1.2, "group": -5, "jointFriction": 0.1,
                 "density": 2}}
  ]})");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  SceneDef expected;
  scenes::RopeOptions r;
  r.start = Vec2(-2, 5);
  r.end = Vec2(3, 5);
  r.count = 12;
  r.radius = 0.04;
  r.density = 8;
  r.pin_start = false;
  r.collide = false;
  scenes::add_rope(&expected, r);
  scenes::ClothOptions c;
  c.top_left = Vec2(1, 9);
  c.columns = 5;
  c.rows = 4;
  c.spacing = 0.3;
  c.pinned = {{0, 0}, {4, 0}, {2, 3}};
  c.group = -3;
  scenes::add_cloth(&expected, c);
  scenes::RagdollOptions d;
  d.feet = Vec2(6, 0);
  d.scale = 1.2;
  d.group = -5;
  d.joint_friction = 0.1;
  d.density = 2;
  scenes::add_ragdoll(&expected, d);
  EXPECT_EQ(diff_scene(expected, *scene), "");
  EXPECT_EQ(scene->joints.size(), expected.joints.size());
  Result<World> a = build_world(*scene);
  Result<World> b = build_world(expected);
  ASSERT_TRUE(a.ok() && b.ok());
  for (int i = 0; i < 60; ++i) {
    a->step();
    b->step();
  }
  EXPECT_EQ(a->state_hash(), b->state_hash());
}

// scenes/cloth.json is the builtin cloth scene written with builders: same hash after 120 ticks.
TEST(SceneFiles, ClothFileIsTheBuiltinCloth) {
  Result<SceneDef> file = load_scene_json(std::string(FULCRUM_SCENES_DIR) + "/cloth.json");
  ASSERT_TRUE(file.ok()) << file.status().to_string();
  Result<SceneDef> builtin = scenes::builtin("cloth");
  ASSERT_TRUE(builtin.ok());
  Result<World> a = build_world(*file);
  Result<World> b = build_world(*builtin);
  ASSERT_TRUE(a.ok() && b.ok());
  for (int i = 0; i < 120; ++i) {
    a->step();
    b->step();
  }
  EXPECT_EQ(a->state_hash(), b->state_hash());
}

// --- Example scene files ---------------------------------------------------------------------

TEST(SceneFiles, EveryExampleLoadsAndBuilds) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(FULCRUM_SCENES_DIR)) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    ++count;
    Result<SceneDef> scene = load_scene_json(entry.path().string());
    ASSERT_TRUE(scene.ok()) << scene.status().to_string();
    EXPECT_FALSE(scene->bodies.empty());
    Result<World> world = build_world(*scene);
    ASSERT_TRUE(world.ok()) << world.status().to_string();
    EXPECT_EQ(world->body_count(), static_cast<int>(scene->bodies.size()));
    ExpectJsonRoundTrip(*scene);
  }
  EXPECT_GE(count, 3);
}

TEST(SceneFiles, ExampleContents) {
  const std::string dir = FULCRUM_SCENES_DIR;
  Result<SceneDef> pyramid = load_scene_json(dir + "/pyramid.json");
  ASSERT_TRUE(pyramid.ok()) << pyramid.status().to_string();
  EXPECT_EQ(pyramid->bodies.size(), 1u + 20u * 21u / 2u);
  Result<SceneDef> stack = load_scene_json(dir + "/stack.json");
  ASSERT_TRUE(stack.ok()) << stack.status().to_string();
  EXPECT_EQ(stack->bodies.size(), 11u);
  Result<SceneDef> particles = load_scene_json(dir + "/particles.json");
  ASSERT_TRUE(particles.ok()) << particles.status().to_string();
  int particle_count = 0;
  for (const SceneBody& b : particles->bodies) {
    if (b.def.type != BodyType::kParticle) continue;
    ++particle_count;
    ASSERT_EQ(b.shapes.size(), 1u);
    EXPECT_EQ(geometry_type(b.shapes[0].geometry), ShapeType::kCircle);
  }
  EXPECT_EQ(particle_count, 12);
}

// --- Errors name the field -------------------------------------------------------------------

struct BadInput {
  const char* label;
  const char* json;
  const char* message;  // expected substring of the error message
};

void PrintTo(const BadInput& input, std::ostream* os) {
  *os << input.label;
}

class SceneJsonErrors : public testing::TestWithParam<BadInput> {};

TEST_P(SceneJsonErrors, NameTheField) {
  Result<SceneDef> scene = parse_scene_json(GetParam().json);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(scene.status().message().find(GetParam().message), std::string::npos)
      << "message: " << scene.status().message() << "\nexpected to contain: " << GetParam().message;
}

const BadInput kBadInputs[] = {
    {"ChainLinkTooShort", R"({"builders": [{"jointChain": {"linkLength": 0.2}}]})",
     "builders[0].joint_chain.link_length: must be > link_width (got 0.2 <= 0.25)"},
    {"ChainUnknownShape", R"({"builders": [{"jointChain": {"shape": 5}}]})",
     "builders[0].joint_chain.shape: unknown link shape 5"},
    {"ChainNegativeEndMass", R"({"builders": [{"jointChain": {"endMass": -1}}]})",
     "builders[0].joint_chain.end_mass: must be >= 0 (got -1)"},
    {"CardHouseLean", R"({"builders": [{"cardHouse": {"lean": 0.6}}]})",
     "builders[0].card_house.lean: must be in [0.05, 0.45] (got 0.6)"},
    {"CardHouseThickCards", R"({"builders": [{"cardHouse": {"cardThickness": 0.2}}]})",
     "builders[0].card_house.card_thickness: must be <= card_length / 20 (got 0.2)"},
    {"GroundCenterAndTop", R"({"builders": [{"ground": {"halfWidth": 1, "top": 2,
      "center": {}}}]})",
     "builders[0].ground.top: give center or top, not both"},
    {"NaNConstantForce", R"({"bodies": [{"constantForce": {"y": "NaN"}}]})",
     "bodies[0].constant_force.y: must be finite (got nan)"},
    {"NaNAttractorStrength", R"({"attractors": [{}, {"strength": "NaN"}]})",
     "attractors[1].strength: must be finite (got nan)"},
    {"ZeroAttractorMinDistance", R"({"attractors": [{"minDistance": 0}]})",
     "attractors[0].min_distance: must be > 0 (got 0)"},
    {"UnknownFalloff", R"({"attractors": [{"falloff": 9}]})",
     "attractors[0].falloff: unknown falloff 9"},
    {"UnknownTopLevelField", R"({"bodiess": []})", "bodiess: unknown field"},
    {"UnknownNestedField", R"({"bodies": [{"shapes": [{"circle": {"radius": 1, "centre": {}}}]}]})",
     "bodies[0].shapes[0].circle.centre: unknown field"},
    {"NegativeDensity", R"({"bodies": [{"shapes": [{"circle": {}, "density": -1}]}]})",
     "bodies[0].shapes[0].density: must be >= 0 (got -1)"},
    {"NaNPosition", R"({"bodies": [{"position": {"x": "NaN"}}]})",
     "bodies[0].position.x: must be finite (got nan)"},
    {"NaNDensity", R"({"bodies": [{}, {"shapes": [{"circle": {}, "density": "NaN"}]}]})",
     "bodies[1].shapes[0].density: must be >= 0 (got nan)"},
    {"InfiniteFriction", R"({"bodies": [{"shapes": [{"circle": {}, "friction": "Infinity"}]}]})",
     "bodies[0].shapes[0].friction: must be >= 0 (got inf)"},
    {"NaNDt", R"({"settings": {"dt": "NaN"}})", "settings.dt: must be > 0 (got nan)"},
    {"ZeroDt", R"({"settings": {"dt": 0}})", "settings.dt: must be > 0 (got 0)"},
    {"Baumgarte", R"({"settings": {"baumgarte": 1.5}})",
     "settings.baumgarte: must be in [0, 1] (got 1.5)"},
    {"VelocityIterations", R"({"settings": {"velocityIterations": 0}})",
     "settings.velocity_iterations: must be >= 1 (got 0)"},
    {"GravityNaN", R"({"settings": {"gravity": {"y": "NaN"}}})",
     "settings.gravity.y: must be finite"},
    {"EmptyPolygon", R"({"bodies": [{"shapes": [{"polygon": {}}]}]})",
     "bodies[0].shapes[0].polygon.vertices: need 3 to 8 vertices (got 0)"},
    {"TooManyVertices",
     R"({"bodies": [{"shapes": [{"polygon": {"vertices": [{},{},{},{},{},{},{},{},{}]}}]}]})",
     "bodies[0].shapes[0].polygon.vertices: need 3 to 8 vertices (got 9)"},
    {"PolygonVertexNaN",
     R"({"bodies": [{"shapes": [{"polygon": {"vertices": [{}, {"x": 1}, {"y": "NaN"}]}}]}]})",
     "bodies[0].shapes[0].polygon.vertices[2].y: must be finite"},
    {"ClockwisePolygon",
     R"({"bodies": [{"shapes": [{"polygon": {"vertices": [{}, {"y": 1}, {"x": 1}]}}]}]})",
     "bodies[0].shapes[0].polygon"},
    {"BoxHalfWidth",
     R"({"bodies": [{}, {}, {"shapes": [{"box": {"halfWidth": -1, "halfHeight": 1}}]}]})",
     "bodies[2].shapes[0].box.half_width: must be > 0 (got -1)"},
    {"BoxMissingHalfHeight", R"({"bodies": [{"shapes": [{"box": {"halfWidth": 1}}]}]})",
     "bodies[0].shapes[0].box.half_height: must be > 0 (got 0)"},
    {"CircleRadius", R"({"bodies": [{"shapes": [{"circle": {"radius": 0}}]}]})",
     "bodies[0].shapes[0].circle.radius: must be > 0 (got 0)"},
    {"CapsuleCentres", R"({"bodies": [{"shapes": [{"capsule": {"center1": {}, "center2": {}}}]}]})",
     "bodies[0].shapes[0].capsule: center1 and center2 must be more than"},
    {"SegmentPoints",
     R"({"bodies": [{"shapes": [{"segment": {"point1": {"x": 2}, "point2": {"x": 2}}}]}]})",
     "bodies[0].shapes[0].segment: point1 and point2"},
    {"NoGeometry", R"({"bodies": [{"shapes": [{"density": 2}]}]})",
     "bodies[0].shapes[0]: no geometry"},
    {"TwoGeometries", R"({"bodies": [{"shapes": [{"circle": {}, "box": {}}]}]})",
     "bodies[0].shapes[0]"},
    {"UnknownBodyTypeName", R"({"bodies": [{"type": "BODY_TYPE_GHOST"}]})", "bodies[0].type"},
    {"UnknownBodyTypeNumber", R"({"bodies": [{"type": 7}]})",
     "bodies[0].type: unknown body type 7"},
    {"NegativeDamping", R"({"bodies": [{"linearDamping": -0.1}]})",
     "bodies[0].linear_damping: must be >= 0 (got -0.1)"},
    {"ChainTooShort", R"({"bodies": [{"chains": [{"points": [{}]}]}]})",
     "bodies[0].chains[0].points: need at least 2 points (got 1)"},
    {"LoopTooShort", R"({"bodies": [{"chains": [{"loop": true, "points": [{}, {"x": 1}]}]}]})",
     "bodies[0].chains[0].points: need at least 3 points for a loop (got 2)"},
    {"ChainRepeatedPoint", R"({"bodies": [{"chains": [{"points": [{}, {"x": 1}, {"x": 1}]}]}]})",
     "bodies[0].chains[0].points[2]: equals the previous point"},
    {"UnknownBuiltin", R"({"builtin": "no_such_scene"})",
     "builtin: unknown scene \"no_such_scene\""},
    {"EmptyBuilder", R"({"builders": [{}]})", "builders[0]: no builder"},
    {"PyramidBase", R"({"builders": [{"ground": {"halfWidth": 1}}, {"pyramid": {"base": 0}}]})",
     "builders[1].pyramid.base: must be in [1, 1000] (got 0)"},
    {"PyramidTooBig", R"({"builders": [{"pyramid": {"base": 100000}}]})",
     "builders[0].pyramid.base: must be in [1, 1000]"},
    {"PyramidSpacing", R"({"builders": [{"pyramid": {"boxSize": 2}}]})",
     "builders[0].pyramid.spacing: must be >= box_size 2 (got 1)"},
    {"PyramidTopDensity", R"({"builders": [{"pyramid": {"topDensity": 0}}]})",
     "builders[0].pyramid.top_density"},
    {"TooManyBodies", R"({"builders": [{"pyramid": {"base": 1000}}, {"pyramid": {"base": 1000}}]})",
     "builders[1].pyramid: the scene would have more than 1000000 bodies"},
    {"StackCount", R"({"builders": [{"stack": {"count": -1}}]})",
     "builders[0].stack.count: must be in [1, 10000] (got -1)"},
    {"GroundHalfWidth", R"({"builders": [{"ground": {}}]})",
     "builders[0].ground.half_width: must be > 0 (got 0)"},
    {"WrongType", R"({"bodies": [{"angle": "north"}]})", "bodies[0].angle"},
    {"FractionalInt", R"({"builders": [{"stack": {"count": 2.5}}]})", "builders[0].stack.count"},
    {"SyntaxError", R"({"bodies": [)", ""},
    {"NotAnObject", R"([1, 2])", ""},
    {"Null", "null", "Root element must be a message"},
    {"Empty", " \n ", "empty scene"},
    {"RopeSamePoints", R"({"builders": [{"rope": {"start": {"x": 1}, "end": {"x": 1}}}]})",
     "builders[0].rope.end: must differ from start"},
    {"RopeCount", R"({"builders": [{"rope": {"count": 1}}]})", "builders[0].rope.count"},
    {"ClothOddPins", R"({"builders": [{"cloth": {"pinned": [0, 0, 3]}}]})",
     "builders[0].cloth.pinned: needs (column, row) pairs"},
    {"ClothPinOutside", R"({"builders": [{"cloth": {"columns": 4, "pinned": [4, 0]}}]})",
     "builders[0].cloth.pinned[0]"},
    {"ClothSpacing", R"({"builders": [{"cloth": {"spacing": -0.2}}]})",
     "builders[0].cloth.spacing: must be > 0"},
    {"RagdollScale", R"({"builders": [{"ragdoll": {"scale": 0}}]})",
     "builders[0].ragdoll.scale: must be > 0"},
    {"RagdollFriction", R"({"builders": [{"ragdoll": {"jointFriction": "NaN"}}]})",
     "builders[0].ragdoll.joint_friction"},
};

INSTANTIATE_TEST_SUITE_P(All, SceneJsonErrors, testing::ValuesIn(kBadInputs),
                         [](const testing::TestParamInfo<BadInput>& param_info) {
                           return std::string(param_info.param.label);
                         });

// --- Files -----------------------------------------------------------------------------------

TEST(SceneFiles, MissingFileIsNotFound) {
  const std::string path = testing::TempDir() + "/no_such_scene.json";
  Result<SceneDef> scene = load_scene_json(path);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().code(), StatusCode::kNotFound);
  EXPECT_NE(scene.status().message().find(path + ": cannot open scene file"), std::string::npos)
      << scene.status().message();
}

TEST(SceneFiles, DirectoryIsRefused) {
  Result<SceneDef> scene = load_scene_json(FULCRUM_SCENES_DIR);
  ASSERT_FALSE(scene.ok());
  EXPECT_NE(scene.status().message().find("is a directory"), std::string::npos);
}

TEST(SceneFiles, ErrorsArePrefixedWithThePath) {
  const std::string path = std::string(FULCRUM_TEST_DATA_DIR) + "/bad_density.json";
  Result<SceneDef> scene = load_scene_json(path);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().message(),
            path + ": bodies[0].shapes[0].density: must be >= 0 (got -1)");
}

TEST(SceneFiles, SaveAndLoad) {
  const std::string path = testing::TempDir() + "/scene_convert_test_saved.json";
  const SceneDef scene = AwkwardScene();
  {
    std::ofstream out(path);
    out << scene_to_json(scene, "saved");
  }
  Result<SceneDef> back = load_scene_json(path);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(diff_scene(scene, *back), "");
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace fulcrum

namespace fulcrum {
namespace {

// Joints name bodies by their index in the assembled scene and survive a JSON round trip.
TEST(SceneJoints, ParseBuildAndRoundTrip) {
  const char* json = R"({
    "bodies": [
      {"type": "BODY_TYPE_STATIC"},
      {"type": "BODY_TYPE_DYNAMIC", "position": {"x": 1, "y": 0},
       "shapes": [{"circle": {"radius": 0.1}}]},
      {"type": "BODY_TYPE_DYNAMIC", "position": {"x": 2, "y": 0},
       "shapes": [{"circle": {"radius": 0.1}}]}
    ],
    "joints": [
      {"bodyA": 0, "bodyB": 1, "localAnchorB": {"x": -1, "y": 0},
       "revolute": {"enableLimit": true, "lowerAngle": -0.5, "upperAngle": 0.5}},
      {"bodyA": 1, "bodyB": 2, "distance": {"length": 1, "minLength": 0, "maxLength": 1.5}}
    ]
  })";
  Result<SceneDef> scene = parse_scene_json(json);
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  ASSERT_EQ(scene->joints.size(), 2u);
  const auto& rope = std::get<DistanceJointDef>(scene->joints[1].def);
  EXPECT_EQ(rope.min_length, 0.0);
  EXPECT_EQ(rope.max_length, 1.5);
  Result<World> world = build_world(*scene);
  ASSERT_TRUE(world.ok()) << world.status().to_string();
  // Through JSON and back: the same JSON again.
  std::string once = scene_to_json(*scene);
  Result<SceneDef> again = parse_scene_json(once);
  ASSERT_TRUE(again.ok()) << again.status().to_string();
  EXPECT_EQ(scene_to_json(*again), once);
}

TEST(SceneJoints, BadJointsNameTheField) {
  const char* missing = R"({"bodies": [{}], "joints": [{"bodyA": 0, "bodyB": 3, "distance": {}}]})";
  Result<SceneDef> a = parse_scene_json(missing);
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("joints[0].body_b: no body 3"), std::string::npos)
      << a.status().message();
  const char* limits = R"({"bodies": [{}, {}], "joints": [{"bodyA": 0, "bodyB": 1,
      "revolute": {"lowerAngle": 1, "upperAngle": -1}}]})";
  Result<SceneDef> b = parse_scene_json(limits);
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("joints[0].revolute.lower_angle"), std::string::npos)
      << b.status().message();
  const char* kindless = R"({"bodies": [{}, {}], "joints": [{"bodyA": 0, "bodyB": 1}]})";
  Result<SceneDef> c = parse_scene_json(kindless);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find("joints[0]: needs a kind"), std::string::npos)
      << c.status().message();
}

}  // namespace
}  // namespace fulcrum

namespace fulcrum {
namespace {

bool same_bits(double a, double b) {
  return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b);
}
bool same_bits(const Vec2& a, const Vec2& b) {
  return same_bits(a.x(), b.x()) && same_bits(a.y(), b.y());
}
bool same_bits(bool a, bool b) {
  return a == b;
}

#define SAME(field) EXPECT_TRUE(same_bits(a.field, b.field)) << where << "." #field

void expect_same(const WeldJointDef& a, const WeldJointDef& b, const std::string& where) {
  SAME(local_anchor_a);
  SAME(local_anchor_b);
  SAME(reference_angle);
  SAME(linear_hertz);
  SAME(linear_damping_ratio);
  SAME(angular_hertz);
  SAME(angular_damping_ratio);
  SAME(collide_connected);
}
void expect_same(const PrismaticJointDef& a, const PrismaticJointDef& b, const std::string& where) {
  SAME(local_anchor_a);
  SAME(local_anchor_b);
  SAME(local_axis_a);
  SAME(reference_angle);
  SAME(enable_limit);
  SAME(lower_translation);
  SAME(upper_translation);
  SAME(enable_motor);
  SAME(motor_speed);
  SAME(max_motor_force);
  SAME(enable_spring);
  SAME(hertz);
  SAME(damping_ratio);
  SAME(target_translation);
  SAME(collide_connected);
}
void expect_same(const WheelJointDef& a, const WheelJointDef& b, const std::string& where) {
  SAME(local_anchor_a);
  SAME(local_anchor_b);
  SAME(local_axis_a);
  SAME(enable_spring);
  SAME(hertz);
  SAME(damping_ratio);
  SAME(enable_limit);
  SAME(lower_translation);
  SAME(upper_translation);
  SAME(enable_motor);
  SAME(motor_speed);
  SAME(max_motor_torque);
  SAME(collide_connected);
}
void expect_same(const MotorJointDef& a, const MotorJointDef& b, const std::string& where) {
  SAME(linear_offset);
  SAME(angular_offset);
  SAME(max_force);
  SAME(max_torque);
  SAME(correction_factor);
  SAME(collide_connected);
}
template <typename Def>
void expect_same(const Def&, const Def&, const std::string&) {}  // distance, revolute: above

#undef SAME

// Weld, prismatic, wheel and motor joints with every field off its default go through JSON
// and back bit for bit, and the two scenes simulate to the same state hash.
TEST(SceneJoints, EveryJointKindRoundTrips) {
  SceneDef scene;
  scene.bodies.push_back(SceneBody{});  // static ground
  for (int i = 0; i < 5; ++i) {
    SceneBody body;
    body.def.type = BodyType::kDynamic;
    body.def.position = Vec2(1.0 + i, 2.0);
    ShapeDef shape;
    shape.geometry = make_box(0.2, 0.1);
    body.shapes.push_back(shape);
    scene.bodies.push_back(body);
  }
  WeldJointDef weld;
  weld.local_anchor_a = Vec2(1.0 / 3.0, -0.25);
  weld.local_anchor_b = Vec2(-0.1, 0.7);
  weld.reference_angle = 0.1;
  weld.linear_hertz = 7.0;
  weld.linear_damping_ratio = 0.3;
  weld.angular_hertz = 9.5;
  weld.angular_damping_ratio = 1.1;
  weld.collide_connected = true;
  scene.joints.push_back(SceneJoint{0, 1, weld});
  PrismaticJointDef prismatic;
  prismatic.local_anchor_a = Vec2(2.0, 2.0);
  prismatic.local_axis_a = Vec2(0.6, 0.8);
  prismatic.reference_angle = -0.2;
  prismatic.enable_limit = true;
  prismatic.lower_translation = -0.5;
  prismatic.upper_translation = 0.75;
  prismatic.enable_motor = true;
  prismatic.motor_speed = 0.1;
  prismatic.max_motor_force = 3.0;
  prismatic.enable_spring = true;
  prismatic.hertz = 2.0;
  prismatic.damping_ratio = 0.4;
  prismatic.target_translation = 0.2;
  scene.joints.push_back(SceneJoint{0, 2, prismatic});
  WheelJointDef wheel;
  wheel.local_anchor_a = Vec2(1.0, -0.3);
  wheel.local_axis_a = Vec2(0.0, 2.0);  // normalized by the engine, kept as written here
  wheel.enable_spring = false;
  wheel.hertz = 3.0;
  wheel.damping_ratio = 0.0;
  wheel.enable_limit = true;
  wheel.lower_translation = -0.1;
  wheel.upper_translation = 0.1;
  wheel.enable_motor = true;
  wheel.motor_speed = -4.0;
  wheel.max_motor_torque = 12.0;
  wheel.collide_connected = true;
  scene.joints.push_back(SceneJoint{2, 3, wheel});
  MotorJointDef motor;
  motor.linear_offset = Vec2(4.0, 2.5);
  motor.angular_offset = 0.3;
  motor.max_force = 40.0;
  motor.max_torque = 0.0;
  motor.correction_factor = 1.0;
  scene.joints.push_back(SceneJoint{0, 4, motor});
  WheelJointDef wheel_defaults;  // defaults that differ from proto3's zero defaults
  scene.joints.push_back(SceneJoint{1, 5, wheel_defaults});

  const std::string json = scene_to_json(scene);
  Result<SceneDef> back = parse_scene_json(json);
  ASSERT_TRUE(back.ok()) << back.status().to_string() << "\n" << json;
  ASSERT_EQ(back->joints.size(), scene.joints.size());
  for (size_t i = 0; i < scene.joints.size(); ++i) {
    const SceneJoint& a = scene.joints[i];
    const SceneJoint& b = back->joints[i];
    std::string where = "joints[" + std::to_string(i) + "]";
    EXPECT_EQ(a.body_a, b.body_a) << where;
    EXPECT_EQ(a.body_b, b.body_b) << where;
    ASSERT_EQ(a.def.index(), b.def.index()) << where;
    std::visit(
        [&](const auto& da) {
          expect_same(da, std::get<std::decay_t<decltype(da)>>(b.def), where);
        },
        a.def);
  }
  // Absent optional fields read back as the engine defaults, not proto3's zeros.
  Result<SceneDef> sparse = parse_scene_json(R"({"bodies": [{}, {"type": "BODY_TYPE_DYNAMIC"}],
      "joints": [{"bodyA": 0, "bodyB": 1, "wheel": {}}, {"bodyA": 0, "bodyB": 1, "motor": {}}]})");
  ASSERT_TRUE(sparse.ok()) << sparse.status().to_string();
  const auto& w = std::get<WheelJointDef>(sparse->joints[0].def);
  expect_same(w, WheelJointDef{}, "sparse wheel");
  const auto& m = std::get<MotorJointDef>(sparse->joints[1].def);
  expect_same(m, MotorJointDef{}, "sparse motor");

  Result<World> original = build_world(scene);
  Result<World> again = build_world(*back);
  ASSERT_TRUE(original.ok()) << original.status().to_string();
  ASSERT_TRUE(again.ok()) << again.status().to_string();
  for (int i = 0; i < 60; ++i) {
    original->step();
    again->step();
  }
  EXPECT_EQ(original->state_hash(), again->state_hash());
}

TEST(SceneJoints, BadNewJointsNameTheField) {
  auto error = [](const std::string& joint) {
    std::string json =
        R"({"bodies": [{}, {"type": "BODY_TYPE_DYNAMIC"}], "joints": [)" + joint + "]}";
    Result<SceneDef> s = parse_scene_json(json);
    EXPECT_FALSE(s.ok()) << joint;
    return s.ok() ? std::string() : s.status().message();
  };
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "weld": {"linearHertz": -1}})")
                .find("joints[0].weld.linear_hertz"),
            std::string::npos);
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "prismatic": {"localAxisA": {"x": 0, "y": 0}}})")
                .find("joints[0].prismatic.local_axis_a"),
            std::string::npos);
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "prismatic": {"lowerTranslation": 1,
                "upperTranslation": 0}})")
                .find("joints[0].prismatic.lower_translation"),
            std::string::npos);
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "wheel": {"maxMotorTorque": -2}})")
                .find("joints[0].wheel.max_motor_torque"),
            std::string::npos);
  EXPECT_NE(
      error(R"({"bodyA": 0, "bodyB": 1, "wheel": {"hertz": -2}})").find("joints[0].wheel.hertz"),
      std::string::npos);
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "motor": {"correctionFactor": 2}})")
                .find("joints[0].motor.correction_factor"),
            std::string::npos);
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "motor": {"maxForce": -1}})")
                .find("joints[0].motor.max_force"),
            std::string::npos);
  EXPECT_NE(error(R"({"bodyA": 0, "bodyB": 1, "localAnchorA": {"x": 1}, "motor": {}})")
                .find("joints[0].local_anchor_a: a motor joint has no anchors"),
            std::string::npos);
}

}  // namespace
}  // namespace fulcrum
