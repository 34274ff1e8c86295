#include "fulcrum/scenes.h"

#include <cmath>
#include <functional>
#include <map>

#include "fulcrum/trig.h"
#include "hard_scenes.h"
#include "joint_scenes.h"
#include "v3_scenes.h"

namespace fulcrum::scenes {

namespace {

SceneBody dynamic_box(const Vec2& center, double half, double density, double friction) {
  SceneBody body;
  body.def.type = BodyType::kDynamic;
  body.def.position = center;
  ShapeDef shape;
  shape.geometry = make_box(half, half);
  shape.density = density;
  shape.friction = friction;
  body.shapes.push_back(shape);
  return body;
}

void add_static_box(SceneDef* scene, const Vec2& center, double hx, double hy, double friction) {
  SceneBody body;
  body.def.type = BodyType::kStatic;
  body.def.position = center;
  ShapeDef shape;
  shape.geometry = make_box(hx, hy);
  shape.friction = friction;
  body.shapes.push_back(shape);
  scene->bodies.push_back(body);
}

// HARD_CASES case 1: 20 boxes, offset alternately by +-1 cm.
SceneDef vertical_stack() {
  SceneDef s;
  add_ground(&s, 20.0);
  add_stack(&s, StackOptions{});
  return s;
}

// Case 2: base 100, 5050 boxes of 1 m touching exactly.
SceneDef large_pyramid() {
  SceneDef s;
  s.settings.enable_sleep = false;
  add_ground(&s, 100.0);
  PyramidOptions p;
  p.base = 100;
  add_pyramid(&s, p);
  return s;
}

// Case 3: 20 pyramids of base 10 side by side.
SceneDef many_pyramids() {
  SceneDef s;
  s.settings.enable_sleep = false;
  add_ground(&s, 140.0);
  for (int i = 0; i < 20; ++i) {
    PyramidOptions p;
    p.base = 10;
    p.origin = Vec2(-123.5 + 13.0 * i, 0.0);
    add_pyramid(&s, p);
  }
  return s;
}

// The benchmark table's many_pyramids: a 20 x 20 grid of base-10 pyramids (22000 boxes of
// 1 m), each row of 20 on its own ground shelf 15 m above the last.
SceneDef many_pyramids_grid() {
  SceneDef s;
  s.settings.enable_sleep = false;
  for (int row = 0; row < 20; ++row) {
    double y = 15.0 * row;
    add_ground(&s, 140.0, y);
    for (int col = 0; col < 20; ++col) {
      PyramidOptions p;
      p.base = 10;
      p.origin = Vec2(-123.5 + 13.0 * col, y);
      add_pyramid(&s, p);
    }
  }
  return s;
}

// Case 4: pyramid of base 10 with 2 m boxes, the top box 100 times denser.
SceneDef mass_ratio_100() {
  SceneDef s;
  add_ground(&s, 40.0);
  PyramidOptions p;
  p.base = 10;
  p.box_size = 2.0;
  p.spacing = 2.0;
  p.top_density = 100.0;
  add_pyramid(&s, p);
  return s;
}

// Case 5: a 20 m box dropped from 1 m onto two 1 m boxes 10 m apart (mass ratio 400:1).
SceneDef mass_ratio_400() {
  SceneDef s;
  add_ground(&s, 40.0);
  s.bodies.push_back(dynamic_box(Vec2(-5.0, 0.5), 0.5, 1.0, 0.6));
  s.bodies.push_back(dynamic_box(Vec2(5.0, 0.5), 0.5, 1.0, 0.6));
  s.bodies.push_back(dynamic_box(Vec2(0.0, 1.0 + 1.0 + 10.0), 10.0, 1.0, 0.6));
  return s;
}

// Case 6: pyramid of base 4 whose boxes overlap their neighbours by 25 %.
SceneDef overlap_recovery() {
  SceneDef s;
  add_ground(&s, 20.0);
  PyramidOptions p;
  p.base = 4;
  p.spacing = 0.75;
  // Rows also overlap by 25 %: place them by hand.
  for (int row = 0; row < p.base; ++row) {
    int n = p.base - row;
    for (int i = 0; i < n; ++i) {
      double x = (i - 0.5 * (n - 1)) * 0.75;
      double y = 0.5 + 0.75 * row;
      s.bodies.push_back(dynamic_box(Vec2(x, y), 0.5, 1.0, 0.6));
    }
  }
  return s;
}

// Case 14: a ball of radius 0.5 dropped from 10 m (centre height), restitution 0.5.
SceneDef bounce() {
  SceneDef s;
  add_ground(&s, 20.0);
  SceneBody ball;
  ball.def.type = BodyType::kDynamic;
  ball.def.position = Vec2(0.0, 10.0);
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), 0.5};
  shape.restitution = 0.5;
  ball.shapes.push_back(shape);
  s.bodies.push_back(ball);
  return s;
}

// Case 15: a 1 m box sliding at 5 m/s on flat ground, friction 0.5 on both.
SceneDef slide() {
  SceneDef s;
  add_ground(&s, 50.0, 0.0, 0.5);
  SceneBody box = dynamic_box(Vec2(-10.0, 0.5), 0.5, 1.0, 0.5);
  box.def.linear_velocity = Vec2(5.0, 0.0);
  s.bodies.push_back(box);
  return s;
}

// A mixed scene: particles, circles, capsules and polygons falling onto chain terrain.
SceneDef mixed() {
  SceneDef s;
  SceneBody terrain;
  ChainDef chain;
  for (int i = 0; i <= 40; ++i) {
    double x = -20.0 + i;
    chain.points.push_back(Vec2(x, 0.5 * det_sin(0.4 * x)));
  }
  terrain.chains.push_back(chain);
  s.bodies.push_back(terrain);
  for (int i = 0; i < 40; ++i) {
    SceneBody b;
    b.def.type = i % 4 == 0 ? BodyType::kParticle : BodyType::kDynamic;
    b.def.position = Vec2(-15.0 + 0.75 * i, 4.0 + (i % 3));
    ShapeDef sh;
    switch (i % 4) {
      case 0:
        sh.geometry = Circle{Vec2::Zero(), 0.2};
        break;
      case 1:
        sh.geometry = Circle{Vec2::Zero(), 0.3};
        break;
      case 2:
        sh.geometry = Capsule{Vec2(-0.3, 0.0), Vec2(0.3, 0.0), 0.2};
        break;
      default:
        sh.geometry = make_offset_box(0.3, 0.2, Vec2::Zero(), 0.3);
        break;
    }
    b.shapes.push_back(sh);
    s.bodies.push_back(b);
  }
  return s;
}

// Case 18 and the benchmark table's tumbler: 2025 boxes of 0.25 m in a 20 m hollow box
// (density 50) turning at 25 deg/s on a motorized revolute joint.
SceneDef tumbler() {
  SceneDef s;
  s.bodies.push_back(SceneBody{});  // the static ground the drum turns on
  SceneBody frame;
  frame.def.type = BodyType::kDynamic;
  frame.def.position = Vec2(0.0, 10.0);
  for (auto [hx, hy, cx, cy] :
       {std::array<double, 4>{0.5, 10.0, 10.0, 0.0}, std::array<double, 4>{0.5, 10.0, -10.0, 0.0},
        std::array<double, 4>{10.0, 0.5, 0.0, 10.0},
        std::array<double, 4>{10.0, 0.5, 0.0, -10.0}}) {
    ShapeDef sh;
    sh.geometry = make_offset_box(hx, hy, Vec2(cx, cy), 0.0);
    sh.density = 50.0;
    frame.shapes.push_back(sh);
  }
  s.bodies.push_back(frame);
  // The drum turns on a revolute joint at its centre, driven by a motor at 25 deg/s.
  RevoluteJointDef motor;
  motor.local_anchor_a = Vec2(0.0, 10.0);
  motor.enable_motor = true;
  motor.motor_speed = 25.0 * kPi / 180.0;
  motor.max_motor_torque = 1e8;
  s.joints.push_back(SceneJoint{0, 1, motor});
  for (int i = 0; i < 45; ++i) {
    for (int j = 0; j < 45; ++j) {
      s.bodies.push_back(dynamic_box(Vec2(-9.0 + 0.4 * i, 1.0 + 0.4 * j), 0.125, 1.0, 0.6));
    }
  }
  return s;
}

// 2000 balls of radius 0.25 poured into a 20 m wide bin, as particles (no rotation) or as
// rigid circles: the same scene twice, to show what modelling only translation saves.
SceneDef pile(BodyType type) {
  SceneDef s;
  add_ground(&s, 10.5);
  add_static_box(&s, Vec2(-10.5, 15.0), 0.5, 15.0, 0.6);
  add_static_box(&s, Vec2(10.5, 15.0), 0.5, 15.0, 0.6);
  for (int j = 0; j < 50; ++j) {
    for (int i = 0; i < 40; ++i) {
      SceneBody b;
      b.def.type = type;
      // Odd rows shift by a quarter radius so the pile does not stand in perfect columns.
      b.def.position = Vec2(-9.75 + 0.5 * i + (j % 2 == 0 ? 0.0 : 0.0625), 0.25 + 0.5 * j);
      ShapeDef sh;
      sh.geometry = Circle{Vec2::Zero(), 0.24};
      b.shapes.push_back(sh);
      s.bodies.push_back(b);
    }
  }
  return s;
}

const std::map<std::string, std::function<SceneDef()>, std::less<>>& registry() {
  static const std::map<std::string, std::function<SceneDef()>, std::less<>> scenes = {
      {"vertical_stack", vertical_stack},
      {"large_pyramid", large_pyramid},
      {"many_pyramids", many_pyramids},
      {"many_pyramids_grid", many_pyramids_grid},
      {"mass_ratio_100", mass_ratio_100},
      {"mass_ratio_400", mass_ratio_400},
      {"overlap_recovery", overlap_recovery},
      {"bounce", bounce},
      {"slide", slide},
      {"arch", hard::arch},
      {"confined", hard::confined},
      {"bullet", hard::bullet},
      {"heavy_chain", [] { return hard::heavy_chain(100.0); }},
      {"very_heavy_chain", [] { return hard::heavy_chain(1000.0); }},
      {"thin_planks", hard::thin_planks},
      {"joint_grid", joint_grid},
      {"bridge", bridge},
      {"cloth", cloth},
      {"rope", rope},
      {"ragdolls", ragdolls},
      {"ragdoll_rain", ragdoll_rain},
      {"mixed", mixed},
      {"tumbler", tumbler},
      {"rain", rain},
      {"smash", smash},
      {"spinner", spinner},
      {"particle_pile", [] { return pile(BodyType::kParticle); }},
      {"circle_pile", [] { return pile(BodyType::kDynamic); }},
  };
  return scenes;
}

}  // namespace

void add_ground(SceneDef* scene, double half_width, double top, double friction) {
  add_static_box(scene, Vec2(0.0, top - 1.0), half_width, 1.0, friction);
}

void add_pyramid(SceneDef* scene, const PyramidOptions& o) {
  double half = 0.5 * o.box_size;
  for (int row = 0; row < o.base; ++row) {
    int n = o.base - row;
    for (int i = 0; i < n; ++i) {
      Vec2 c(o.origin.x() + (i - 0.5 * (n - 1)) * o.spacing,
             o.origin.y() + half + o.box_size * row);
      bool top = row == o.base - 1;
      double density = top && o.top_density >= 0.0 ? o.top_density : o.density;
      scene->bodies.push_back(dynamic_box(c, half, density, o.friction));
    }
  }
}

void add_stack(SceneDef* scene, const StackOptions& o) {
  double half = 0.5 * o.box_size;
  for (int i = 0; i < o.count; ++i) {
    double dx = i % 2 == 0 ? o.offset : -o.offset;
    Vec2 c(o.origin.x() + dx, o.origin.y() + half + o.box_size * i);
    scene->bodies.push_back(dynamic_box(c, half, o.density, o.friction));
  }
}

std::vector<std::string> builtin_names() {
  std::vector<std::string> names;
  for (const auto& [name, fn] : registry()) names.push_back(name);
  return names;
}

Result<SceneDef> builtin(std::string_view name) {
  auto it = registry().find(name);
  if (it == registry().end()) {
    std::string known;
    for (const auto& n : builtin_names()) known += (known.empty() ? "" : ", ") + n;
    return not_found("scene '" + std::string(name) + "': no such builtin scene (known: " + known +
                     ")");
  }
  return it->second();
}

}  // namespace fulcrum::scenes
