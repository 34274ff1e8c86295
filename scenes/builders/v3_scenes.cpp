// Box2D v3's benchmark scenes that Fulcrum had no built-in for: rain, smash and spinner, as
// ../shared/TARGETS.md defines them (dimensions read from v3's benchmark definitions, so that
// the two engines are timed on the same scenes; the code is Fulcrum's own).
#include <array>
#include <limits>
#include <memory>

#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"
#include "v3_scenes.h"

namespace fulcrum::scenes {

namespace {

constexpr double kPi = 3.14159265358979323846;

// One bone of the human: a capsule along y centred on the body, the hinge to its parent.
struct Bone {
  double y;                  // body position above the feet, m
  double low, high, radius;  // capsule core from low to high (body frame, y), m
  double linear_damping;     // 1/s
  double friction_scale;     // of the joint friction torque
  int parent;                // bone index, -1 for the hip
  double pivot_y;            // hinge height above the feet, m
  double lower, upper;       // limits, in turns of pi
  double reference;          // reference angle, in turns of pi
  bool foot;                 // carries a foot plate
};

// hip, torso, head, upper and lower left leg, upper and lower right leg, upper and lower left
// arm, upper and lower right arm: the order bodies are created in.
constexpr std::array<Bone, 11> kBones = {{
    {0.95, -0.02, 0.02, 0.095, 0.0, 1.0, -1, 0.0, 0.0, 0.0, 0.0, false},
    {1.2, -0.135, 0.135, 0.09, 0.0, 0.5, 0, 1.0, -0.25, 0.0, 0.0, false},
    {1.475, -0.038, 0.039, 0.075, 0.1, 0.25, 1, 1.4, -0.3, 0.1, 0.0, false},
    {0.775, -0.125, 0.125, 0.06, 0.0, 1.0, 0, 0.9, -0.05, 0.4, 0.0, false},
    {0.475, -0.155, 0.125, 0.045, 0.0, 0.5, 3, 0.625, -0.5, -0.02, 0.0, true},
    {0.775, -0.125, 0.125, 0.06, 0.0, 1.0, 0, 0.9, -0.05, 0.4, 0.0, false},
    {0.475, -0.155, 0.125, 0.045, 0.0, 0.5, 5, 0.625, -0.5, -0.02, 0.0, true},
    {1.225, -0.125, 0.125, 0.035, 0.0, 0.5, 1, 1.35, -0.1, 0.8, 0.0, false},
    {0.975, -0.125, 0.125, 0.03, 0.1, 0.1, 7, 1.1, -0.2, 0.3, 0.25, false},
    {1.225, -0.125, 0.125, 0.035, 0.0, 0.5, 1, 1.35, -0.1, 0.8, 0.0, false},
    {0.975, -0.125, 0.125, 0.03, 0.1, 0.1, 9, 1.1, -0.2, 0.3, 0.25, false},
}};

Polygon foot_plate(double s) {
  const std::array<Vec2, 4> points = {Vec2(-0.03 * s, -0.185 * s), Vec2(0.11 * s, -0.185 * s),
                                      Vec2(0.11 * s, -0.16 * s), Vec2(-0.03 * s, -0.14 * s)};
  Polygon p;
  std::vector<Vec2> hull;
  if (compute_hull(points, &hull).ok()) make_polygon(hull, 0.015 * s, &p).ok();
  return p;
}

SceneBody static_body() {
  SceneBody b;
  b.def.type = BodyType::kStatic;
  return b;
}

SceneBody dynamic_body(const Vec2& position) {
  SceneBody b;
  b.def.type = BodyType::kDynamic;
  b.def.position = position;
  return b;
}

}  // namespace

int add_human(SceneDef* scene, const HumanOptions& o) {
  const double s = o.scale;
  const int first = static_cast<int>(scene->bodies.size());
  const Polygon foot = foot_plate(s);
  for (const Bone& bone : kBones) {
    SceneBody body = dynamic_body(o.feet + Vec2(0.0, s * bone.y));
    body.def.linear_damping = bone.linear_damping;
    ShapeDef limb;
    limb.geometry = Capsule{Vec2(0.0, s * bone.low), Vec2(0.0, s * bone.high), s * bone.radius};
    limb.friction = 0.2;
    limb.filter.category_bits = 2;
    limb.filter.mask_bits = 1 | 2;
    limb.filter.group_index = o.group;
    body.shapes.push_back(limb);
    if (bone.foot) {
      ShapeDef plate;  // touches only the ground (category 1), never another ragdoll
      plate.geometry = foot;
      plate.friction = 0.05;
      plate.filter.category_bits = 2;
      plate.filter.mask_bits = 1;
      plate.filter.group_index = o.group;
      body.shapes.push_back(plate);
    }
    scene->bodies.push_back(body);
  }
  for (size_t i = 0; i < kBones.size(); ++i) {
    const Bone& bone = kBones[i];
    if (bone.parent < 0) continue;
    const Bone& parent = kBones[bone.parent];
    RevoluteJointDef def;
    def.local_anchor_a = Vec2(0.0, s * (bone.pivot_y - parent.y));
    def.local_anchor_b = Vec2(0.0, s * (bone.pivot_y - bone.y));
    def.reference_angle = bone.reference * kPi;
    def.enable_limit = true;
    def.lower_angle = bone.lower * kPi;
    def.upper_angle = bone.upper * kPi;
    def.enable_motor = true;  // joint friction: a motor at speed 0 with a small torque
    def.max_motor_torque = bone.friction_scale * o.friction_torque * s;
    def.enable_spring = o.hertz > 0.0;
    def.hertz = o.hertz;
    def.damping_ratio = o.damping_ratio;
    scene->joints.push_back(SceneJoint{first + bone.parent, first + static_cast<int>(i), def});
  }
  return first;
}

Result<std::vector<BodyId>> add_to_world(World& world, const SceneDef& part) {
  std::vector<BodyId> ids;
  ids.reserve(part.bodies.size());
  for (const SceneBody& sb : part.bodies) {
    Result<BodyId> body = world.create_body(sb.def);
    if (!body.ok()) return body.status();
    ids.push_back(*body);
    for (const ShapeDef& shape : sb.shapes) {
      Result<ShapeId> created = world.create_shape(*body, shape);
      if (!created.ok()) return created.status();
    }
    for (const ChainDef& chain : sb.chains) {
      auto created = world.create_chain(*body, chain);
      if (!created.ok()) return created.status();
    }
  }
  for (const SceneJoint& joint : part.joints) {
    Result<JointId> created =
        create_scene_joint(world, joint, ids[joint.body_a], ids[joint.body_b]);
    if (!created.ok()) return created.status();
  }
  return ids;
}

// --- rain ------------------------------------------------------------------------------------

SceneDef rain() {
  SceneDef s;
  SceneBody ground = static_body();
  for (int row = 0; row < kRainRows; ++row) {
    for (int j = 0; j <= 500; ++j) {
      ShapeDef tile;
      tile.geometry = make_offset_box(0.25, 0.25, Vec2(-125.0 + 0.5 * j, 45.0 * row), 0.0);
      ground.shapes.push_back(tile);
    }
  }
  s.bodies.push_back(ground);
  return s;
}

SceneDef rain_group(int row, int column) {
  SceneDef s;
  const double x = -125.0 + 6.25 * (column + 0.5);
  for (int i = 0; i < kRainGroupSize; ++i) {
    HumanOptions o;
    o.feet = Vec2(x + 0.5 * i, 40.0 + 45.0 * row);
    o.group = -(i + 1);
    o.friction_torque = 0.05;
    o.hertz = 5.0;
    o.damping_ratio = 0.5;
    add_human(&s, o);
  }
  return s;
}

RainDriver::RainDriver() : groups_(kRainRows * kRainColumns) {}

Status RainDriver::before_step(World& world, int64_t step) {
  if ((step & 7) != 0) return {};
  const int column = columns_ < kRainColumns ? columns_ : next_;
  for (int row = 0; row < kRainRows; ++row) {
    std::vector<BodyId>& group = groups_[row * kRainColumns + column];
    for (BodyId id : group) FULCRUM_RETURN_IF_ERROR(world.destroy_body(id));
    Result<std::vector<BodyId>> created = add_to_world(world, rain_group(row, column));
    if (!created.ok()) return created.status();
    group = std::move(created).value();
  }
  if (columns_ < kRainColumns) {
    ++columns_;
  } else {
    next_ = (next_ + 1) % kRainColumns;
  }
  return {};
}

// --- smash and spinner -----------------------------------------------------------------------

SceneDef smash() {
  SceneDef s;
  s.settings.gravity = Vec2::Zero();
  SceneBody hammer = dynamic_body(Vec2(-20.0, 0.0));
  hammer.def.linear_velocity = Vec2(40.0, 0.0);
  ShapeDef heavy;
  heavy.geometry = make_box(4.0, 4.0);
  heavy.density = 8.0;
  hammer.shapes.push_back(heavy);
  s.bodies.push_back(hammer);
  for (int i = 0; i < 120; ++i) {
    for (int j = 0; j < 80; ++j) {
      SceneBody box = dynamic_body(Vec2(30.0 + 0.4 * i, 0.4 * (j - 40)));
      box.def.awake = false;
      ShapeDef shape;
      shape.geometry = make_box(0.2, 0.2);
      box.shapes.push_back(shape);
      s.bodies.push_back(box);
    }
  }
  return s;
}

SceneDef spinner() {
  SceneDef s;
  SceneBody ground = static_body();
  ChainDef loop;
  loop.loop = true;
  loop.friction = 0.1;
  // 360 points on a circle of radius 40 about (0, 32), clockwise from (40, 32).
  for (int i = 0; i < 360; ++i) {
    SinCos sc = det_sincos(-2.0 * kPi * i / 360.0);
    loop.points.push_back(Vec2(40.0 * sc.cos, 32.0 + 40.0 * sc.sin));
  }
  ground.chains.push_back(loop);
  s.bodies.push_back(ground);

  SceneBody arm = dynamic_body(Vec2(0.0, 12.0));
  arm.def.enable_sleep = false;
  ShapeDef blade;
  Polygon rounded = make_box(0.4, 20.0);
  rounded.radius = 0.2;
  blade.geometry = rounded;
  blade.friction = 0.0;
  arm.shapes.push_back(blade);
  s.bodies.push_back(arm);
  RevoluteJointDef motor;
  motor.local_anchor_a = Vec2(0.0, 12.0);
  motor.enable_motor = true;
  motor.motor_speed = 5.0;
  motor.max_motor_torque = std::numeric_limits<float>::max();  // unlimited, as v3 has it
  s.joints.push_back(SceneJoint{0, 1, motor});

  double x = -23.0, y = 2.0;
  for (int i = 0; i < 6076; ++i) {
    SceneBody body = dynamic_body(Vec2(x, y));
    ShapeDef shape;
    shape.friction = 0.1;
    shape.restitution = 0.1;
    shape.density = 0.25;
    if (i % 3 == 0) {
      shape.geometry = Capsule{Vec2(-0.25, 0.0), Vec2(0.25, 0.0), 0.25};
    } else if (i % 3 == 1) {
      shape.geometry = Circle{Vec2::Zero(), 0.35};
    } else {
      shape.geometry = make_box(0.35, 0.35);
    }
    body.shapes.push_back(shape);
    s.bodies.push_back(body);
    x += 0.5;
    if (x >= 23.0) {
      x = -23.0;
      y += 0.5;
    }
  }
  return s;
}

std::unique_ptr<SceneDriver> builtin_driver(std::string_view name) {
  if (name == "rain") return std::make_unique<RainDriver>();
  return nullptr;
}

}  // namespace fulcrum::scenes
