#include "hard_scenes.h"

#include <array>

#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"

namespace fulcrum::scenes::hard {

namespace {

void add_static_box(SceneDef* scene, const Vec2& center, double hx, double hy) {
  SceneBody body;
  body.def.type = BodyType::kStatic;
  body.def.position = center;
  ShapeDef shape;
  shape.geometry = make_box(hx, hy);
  body.shapes.push_back(shape);
  scene->bodies.push_back(body);
}

SceneBody dynamic_circle(const Vec2& center, double radius) {
  SceneBody body;
  body.def.type = BodyType::kDynamic;
  body.def.position = center;
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), radius};
  body.shapes.push_back(shape);
  return body;
}

}  // namespace

SceneDef arch() {
  constexpr int kCount = 17;
  constexpr double kInner = 5.0, kOuter = 6.0;
  SceneDef s;
  // Kept awake so that the test sees any creep over the whole 10 s (an island asleep cannot
  // sag), as in the other cases judged on standing still.
  s.settings.enable_sleep = false;
  add_ground(&s, 20.0);
  for (int i = 0; i < kCount; ++i) {
    // Joint faces are radial, at angles i pi / 17 and (i + 1) pi / 17. The end faces of the
    // first and last voussoir lie on y = 0 (sin 0 = 0 exactly; for the last one the corner
    // heights are rounded to 0 so that it rests flat on the ground).
    SinCos a0 = det_sincos(kPi * i / kCount);
    SinCos a1 = det_sincos(kPi * (i + 1) / kCount);
    double s0 = i == 0 ? 0.0 : a0.sin;
    double s1 = i + 1 == kCount ? 0.0 : a1.sin;
    double c1 = i + 1 == kCount ? -1.0 : a1.cos;
    // Counter-clockwise: inner and outer corner of the right face, then outer and inner
    // corner of the left face.
    std::array<Vec2, 4> corners = {Vec2(kInner * a0.cos, kInner * s0),
                                   Vec2(kOuter * a0.cos, kOuter * s0),
                                   Vec2(kOuter * c1, kOuter * s1), Vec2(kInner * c1, kInner * s1)};
    Vec2 center = 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
    for (Vec2& c : corners) c -= center;
    SceneBody body;
    body.def.type = BodyType::kDynamic;
    body.def.position = center;
    ShapeDef shape;
    Polygon polygon;
    // The corners are a convex quadrilateral by construction, so this cannot fail.
    (void)make_polygon(corners, 0.0, &polygon);
    shape.geometry = polygon;
    shape.friction = 0.6;
    body.shapes.push_back(shape);
    s.bodies.push_back(body);
  }
  return s;
}

SceneDef confined() {
  constexpr int kGrid = 25;
  constexpr double kSpacing = 0.72, kRadius = 0.5;
  constexpr double kInnerHalf = 10.5, kWallHalf = 0.5;
  SceneDef s;
  s.settings.gravity = Vec2::Zero();
  // Kept awake: asleep, the circles would have no kinetic energy to gain and the case would
  // test nothing (with sleep on they all fall asleep within 2 s).
  s.settings.enable_sleep = false;
  const double mid = kInnerHalf + kWallHalf, reach = kInnerHalf + 2.0 * kWallHalf;
  add_static_box(&s, Vec2(-mid, 0.0), kWallHalf, reach);
  add_static_box(&s, Vec2(mid, 0.0), kWallHalf, reach);
  add_static_box(&s, Vec2(0.0, -mid), reach, kWallHalf);
  add_static_box(&s, Vec2(0.0, mid), reach, kWallHalf);
  const double first = -0.5 * (kGrid - 1) * kSpacing;
  for (int j = 0; j < kGrid; ++j) {
    for (int i = 0; i < kGrid; ++i) {
      s.bodies.push_back(dynamic_circle(Vec2(first + kSpacing * i, first + kSpacing * j), kRadius));
    }
  }
  return s;
}

SceneDef bullet() {
  SceneDef s;
  add_ground(&s, 20.0);
  add_static_box(&s, Vec2(0.0, 5.0), 0.05, 5.0);
  SceneBody ball = dynamic_circle(Vec2(-10.0, 5.0), 0.05);
  ball.def.linear_velocity = Vec2(300.0, 0.0);
  s.bodies.push_back(ball);
  return s;
}

SceneDef heavy_chain(double end_mass) {
  SceneDef s;
  JointChainOptions o;
  o.anchor = Vec2(0.0, 50.0);
  o.links = 40;
  o.end_mass = end_mass;
  add_joint_chain(&s, o);
  return s;
}

SceneDef thin_planks() {
  constexpr int kCount = 10;
  constexpr double kHalfLength = 1.0, kHalfThickness = 0.001, kOffset = 0.01;
  SceneDef s;
  // Kept awake, as the arch: the test judges the whole 10 s, and a stack asleep cannot creep.
  s.settings.enable_sleep = false;
  add_ground(&s, 20.0);
  for (int i = 0; i < kCount; ++i) {
    SceneBody plank;
    plank.def.type = BodyType::kDynamic;
    plank.def.position = Vec2(i % 2 == 0 ? kOffset : -kOffset, kHalfThickness * (2 * i + 1));
    ShapeDef shape;
    shape.geometry = make_box(kHalfLength, kHalfThickness);
    shape.density = 1.0;
    shape.friction = 0.6;
    plank.shapes.push_back(shape);
    s.bodies.push_back(plank);
  }
  return s;
}

}  // namespace fulcrum::scenes::hard
