#include "joint_scenes.h"

#include <cmath>

#include "fulcrum/scenes.h"

namespace fulcrum::scenes {

namespace {

SceneJoint revolute(int a, int b, const Vec2& anchor_a, const Vec2& anchor_b) {
  RevoluteJointDef def;
  def.local_anchor_a = anchor_a;
  def.local_anchor_b = anchor_b;
  return SceneJoint{a, b, def};
}

SceneJoint distance(int a, int b, double length, double min_length, double max_length) {
  DistanceJointDef def;
  def.length = length;
  def.min_length = min_length;
  def.max_length = max_length;
  return SceneJoint{a, b, def};
}

int add_particle(SceneDef* scene, const Vec2& p, double radius, double density,
                 const Filter& filter, BodyType type) {
  SceneBody body;
  body.def.type = type;
  body.def.position = p;
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), radius};
  shape.density = density;
  shape.filter = filter;
  body.shapes.push_back(shape);
  scene->bodies.push_back(body);
  return static_cast<int>(scene->bodies.size()) - 1;
}

}  // namespace

int add_rope(SceneDef* scene, const RopeOptions& o) {
  Filter filter;
  if (!o.collide) filter.mask_bits = 0;
  double segment = fulcrum::distance(o.start, o.end) / (o.count - 1);
  int first = static_cast<int>(scene->bodies.size());
  for (int i = 0; i < o.count; ++i) {
    Vec2 p = lerp(o.start, o.end, static_cast<double>(i) / (o.count - 1));
    BodyType type = i == 0 && o.pin_start ? BodyType::kStatic : BodyType::kParticle;
    int index = add_particle(scene, p, o.radius, o.density, filter, type);
    // Neighbours overlap when the rope bunches up: they never collide (joint default).
    if (i > 0) scene->joints.push_back(distance(index - 1, index, segment, 0.0, segment));
  }
  return first;
}

int add_cloth(SceneDef* scene, const ClothOptions& o) {
  Filter filter;
  filter.group_index = o.group;
  int first = static_cast<int>(scene->bodies.size());
  auto at = [&](int c, int r) { return first + r * o.columns + c; };
  for (int r = 0; r < o.rows; ++r) {
    for (int c = 0; c < o.columns; ++c) {
      bool pinned = false;
      for (auto [pc, pr] : o.pinned) pinned = pinned || (pc == c && pr == r);
      Vec2 p = o.top_left + Vec2(c * o.spacing, -r * o.spacing);
      add_particle(scene, p, o.radius, o.density, filter,
                   pinned ? BodyType::kStatic : BodyType::kParticle);
    }
  }
  const double diagonal = o.spacing * std::sqrt(2.0);
  for (int r = 0; r < o.rows; ++r) {
    for (int c = 0; c < o.columns; ++c) {
      if (c + 1 < o.columns) {
        scene->joints.push_back(distance(at(c, r), at(c + 1, r), o.spacing, o.spacing, o.spacing));
      }
      if (r + 1 < o.rows) {
        scene->joints.push_back(distance(at(c, r), at(c, r + 1), o.spacing, o.spacing, o.spacing));
      }
      if (c + 1 < o.columns && r + 1 < o.rows) {
        scene->joints.push_back(distance(at(c, r), at(c + 1, r + 1), diagonal, diagonal, diagonal));
        scene->joints.push_back(distance(at(c + 1, r), at(c, r + 1), diagonal, diagonal, diagonal));
      }
    }
  }
  return first;
}

// The benchmark table's joint grid: circles of radius 0.4 at (k, -i), never colliding with
// each other; the top row's bodies 47..53 are static; each body is pinned to the one above
// and the one on its left.
SceneDef joint_grid() {
  SceneDef s;
  s.settings.enable_sleep = false;
  const int n = 100;
  Filter filter;
  filter.category_bits = 2;
  filter.mask_bits = ~uint64_t{2};
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < n; ++i) {
      bool fixed = i == 0 && k >= 47 && k <= 53;
      add_particle(&s, Vec2(k, -i), 0.4, 1.0, filter,
                   fixed ? BodyType::kStatic : BodyType::kDynamic);
    }
  }
  auto at = [&](int k, int i) { return k * n + i; };
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < n; ++i) {
      if (i > 0) s.joints.push_back(revolute(at(k, i - 1), at(k, i), Vec2(0, -0.5), Vec2(0, 0.5)));
      if (k > 0) s.joints.push_back(revolute(at(k - 1, i), at(k, i), Vec2(0.5, 0), Vec2(-0.5, 0)));
    }
  }
  return s;
}

int add_bridge(SceneDef* scene, const BridgeOptions& o) {
  const int anchor = static_cast<int>(scene->bodies.size());
  scene->bodies.push_back(SceneBody{});  // static, at the origin: both end pins hang on it
  const int first = anchor + 1;
  const double half_span = 0.5 * o.planks;
  for (int i = 0; i < o.planks; ++i) {
    SceneBody plank;
    plank.def.type = BodyType::kDynamic;
    plank.def.position = Vec2(-half_span + 0.5 + i, 0.0);
    plank.def.linear_damping = o.linear_damping;
    ShapeDef shape;
    shape.geometry = make_box(0.5, 0.125);
    shape.density = 20.0;
    plank.shapes.push_back(shape);
    scene->bodies.push_back(plank);
  }
  scene->joints.push_back(revolute(anchor, first, Vec2(-half_span, 0.0), Vec2(-0.5, 0.0)));
  for (int i = 1; i < o.planks; ++i) {
    scene->joints.push_back(revolute(first + i - 1, first + i, Vec2(0.5, 0.0), Vec2(-0.5, 0.0)));
  }
  scene->joints.push_back(
      revolute(anchor, first + o.planks - 1, Vec2(half_span, 0.0), Vec2(0.5, 0.0)));
  return anchor;
}

// HARD_CASES 11: 160 planks, undamped, 20 m above the ground.
SceneDef bridge() {
  SceneDef s;
  add_ground(&s, 100.0, -20.0);
  add_bridge(&s, BridgeOptions{});
  return s;
}

// HARD_CASES 13: a 30 x 30 cloth of particles 0.2 m apart, pinned at its two top corners.
SceneDef cloth() {
  SceneDef s;
  add_ground(&s, 20.0, -2.0);
  add_cloth(&s, ClothOptions{});
  return s;
}

int add_ragdoll(SceneDef* scene, const RagdollOptions& o) {
  struct Part {
    double y;       // centre height at scale 1, m
    double half;    // half length of the capsule's core, m
    double radius;  // m
  };
  // pelvis, torso, head, upper arm x2, lower arm x2, thigh x2, shin x2
  const Part parts[11] = {{0.95, 0.05, 0.12},  {1.25, 0.12, 0.13}, {1.58, 0.03, 0.10},
                          {1.28, 0.12, 0.05},  {1.28, 0.12, 0.05}, {1.00, 0.12, 0.045},
                          {1.00, 0.12, 0.045}, {0.65, 0.15, 0.07}, {0.65, 0.15, 0.07},
                          {0.26, 0.15, 0.06},  {0.26, 0.15, 0.06}};
  const double s = o.scale;
  const int first = static_cast<int>(scene->bodies.size());
  for (const Part& p : parts) {
    SceneBody body;
    body.def.type = BodyType::kDynamic;
    body.def.position = o.feet + Vec2(0.0, s * p.y);
    ShapeDef shape;
    shape.geometry = Capsule{Vec2(0.0, -s * p.half), Vec2(0.0, s * p.half), s * p.radius};
    shape.density = o.density;
    shape.friction = 0.6;
    shape.filter.group_index = o.group;
    body.shapes.push_back(shape);
    scene->bodies.push_back(body);
  }
  struct Hinge {
    int a, b;      // parts
    double y;      // pivot height at scale 1, m
    double lower;  // rad
    double upper;  // rad
  };
  const Hinge hinges[10] = {
      {0, 1, 1.08, -0.6, 0.3},   // waist
      {1, 2, 1.45, -0.4, 0.4},   // neck
      {1, 3, 1.40, -1.5, 2.5},   // shoulders
      {1, 4, 1.40, -1.5, 2.5},   //
      {3, 5, 1.14, -2.5, 0.0},   // elbows
      {4, 6, 1.14, -2.5, 0.0},   //
      {0, 7, 0.85, -0.4, 1.6},   // hips
      {0, 8, 0.85, -0.4, 1.6},   //
      {7, 9, 0.44, -2.4, 0.0},   // knees
      {8, 10, 0.44, -2.4, 0.0},  //
  };
  for (const Hinge& h : hinges) {
    RevoluteJointDef def;
    def.local_anchor_a = Vec2(0.0, s * (h.y - parts[h.a].y));
    def.local_anchor_b = Vec2(0.0, s * (h.y - parts[h.b].y));
    def.enable_limit = true;
    def.lower_angle = h.lower;
    def.upper_angle = h.upper;
    def.enable_motor = true;  // joint friction: hold still up to a small torque
    def.max_motor_torque = o.joint_friction * s * s;
    scene->joints.push_back(SceneJoint{first + h.a, first + h.b, def});
  }
  return first;
}

// HARD_CASES 12: 50 ragdolls dropped from 10 m (feet height) onto the ground.
SceneDef ragdolls() {
  SceneDef s;
  add_ground(&s, 60.0);
  for (int i = 0; i < 50; ++i) {
    RagdollOptions o;
    o.feet = Vec2(-24.5 + 1.0 * i, 10.0 + 0.5 * (i % 3));
    o.group = -(i + 1);
    add_ragdoll(&s, o);
  }
  return s;
}

// The benchmark table's large joint scene: 1000 ragdolls (11 000 capsules, 10 000 limited
// revolute joints with joint friction) in 25 rows of 40, raining into a 41 m wide container.
SceneDef ragdoll_rain() {
  SceneDef s;
  add_ground(&s, 22.0);
  for (double x : {-21.0, 21.0}) {
    SceneBody wall;
    wall.def.position = Vec2(x, 30.0);
    ShapeDef shape;
    shape.geometry = make_box(0.5, 30.0);
    shape.friction = 0.6;
    wall.shapes.push_back(shape);
    s.bodies.push_back(wall);
  }
  for (int i = 0; i < 1000; ++i) {
    int row = i / 40, col = i % 40;
    RagdollOptions o;
    o.feet = Vec2(-19.75 + 1.0 * col + 0.5 * (row % 2), 1.0 + 2.0 * row);
    o.group = -(i + 1);
    add_ragdoll(&s, o);
  }
  return s;
}

SceneDef rope() {
  SceneDef s;
  add_ground(&s, 30.0);
  for (int i = 0; i < 5; ++i) {
    SceneBody box;
    box.def.type = BodyType::kDynamic;
    box.def.position = Vec2(2.0 + 2.0 * i, 0.5);
    ShapeDef shape;
    shape.geometry = make_box(0.5, 0.5);
    box.shapes.push_back(shape);
    s.bodies.push_back(box);
  }
  RopeOptions o;
  o.start = Vec2(0.0, 8.0);
  o.end = Vec2(12.0, 8.0);
  o.count = 40;
  add_rope(&s, o);
  return s;
}

}  // namespace fulcrum::scenes
