// Builders for what people write by hand: a ground placed anywhere, a jointed chain with an
// optional end mass, a house of cards (fulcrum/scenes.h). Angles go through Fulcrum's own
// sin/cos (Rot::from_angle), so the scenes are the same bits everywhere.
#include <algorithm>

#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"

namespace fulcrum::scenes {

int add_ground(SceneDef* scene, const GroundOptions& o) {
  const Rot q = Rot::from_angle(o.angle);
  SceneBody body;
  body.def.type = BodyType::kStatic;
  body.def.position = o.center - q.rotate(Vec2(0.0, 0.5 * o.thickness));  // the box's centre
  body.def.angle = o.angle;
  ShapeDef shape;
  shape.geometry = make_box(o.half_width, 0.5 * o.thickness);
  shape.friction = o.friction;
  body.shapes.push_back(shape);
  scene->bodies.push_back(body);
  return static_cast<int>(scene->bodies.size()) - 1;
}

int add_joint_chain(SceneDef* scene, const JointChainOptions& o) {
  const Rot q = Rot::from_angle(o.angle);
  const Vec2 along = q.rotate(Vec2(1.0, 0.0));
  SceneBody anchor;
  anchor.def.type = BodyType::kStatic;
  anchor.def.position = o.anchor;
  scene->bodies.push_back(anchor);
  const int first = static_cast<int>(scene->bodies.size()) - 1;

  const double half = 0.5 * o.link_length, r = 0.5 * o.link_width;
  ShapeDef link_shape;
  if (o.shape == JointChainOptions::LinkShape::kCapsule) {
    link_shape.geometry = Capsule{Vec2(-half + r, 0.0), Vec2(half - r, 0.0), r};
  } else {
    link_shape.geometry = make_box(half, r);
  }
  link_shape.density = o.density;
  link_shape.friction = o.friction;
  auto joint = [&](int a, int b, const Vec2& local_a, const Vec2& local_b) {
    if (o.joint == JointChainOptions::JointKind::kWeld) {
      WeldJointDef def;
      def.local_anchor_a = local_a;
      def.local_anchor_b = local_b;
      scene->joints.push_back(SceneJoint{a, b, def});
    } else {
      RevoluteJointDef def;
      def.local_anchor_a = local_a;
      def.local_anchor_b = local_b;
      scene->joints.push_back(SceneJoint{a, b, def});
    }
  };
  for (int i = 0; i < o.links; ++i) {
    SceneBody link;
    link.def.type = BodyType::kDynamic;
    link.def.position = o.anchor + (o.link_length * (i + 0.5)) * along;
    link.def.angle = o.angle;
    link.shapes.push_back(link_shape);
    scene->bodies.push_back(link);
    const int index = static_cast<int>(scene->bodies.size()) - 1;
    joint(index - 1, index, i == 0 ? Vec2::Zero() : Vec2(half, 0.0), Vec2(-half, 0.0));
  }
  if (o.end_mass > 0.0) {
    // The ball's density makes its mass end_mass link masses (areas: the link's shape's).
    const double link_area = o.shape == JointChainOptions::LinkShape::kCapsule
                                 ? (o.link_length - o.link_width) * o.link_width + kPi * r * r
                                 : o.link_length * o.link_width;
    const double ball_area = kPi * o.end_radius * o.end_radius;
    SceneBody ball;
    ball.def.type = BodyType::kDynamic;
    ball.def.position = o.anchor + (o.link_length * o.links + o.end_radius) * along;
    ShapeDef shape;
    shape.geometry = Circle{Vec2::Zero(), o.end_radius};
    shape.density = o.end_mass * o.density * link_area / ball_area;
    shape.friction = o.friction;
    ball.shapes.push_back(shape);
    scene->bodies.push_back(ball);
    const int index = static_cast<int>(scene->bodies.size()) - 1;
    // In the ball's frame its near point is -end_radius along the chain.
    joint(index - 1, index, Vec2(half, 0.0), q.inv_rotate(-o.end_radius * along));
  }
  return first;
}

int add_card_house(SceneDef* scene, const CardHouseOptions& o) {
  const Rot lean = Rot::from_angle(o.lean);
  const double s = lean.s, k = lean.c;  // sin and cos of the lean
  const double half_l = 0.5 * o.card_length, half_t = 0.5 * o.card_thickness;
  // A leaning card's centre sits so that its lowest corner touches the floor and its inner top
  // corner touches its partner's at x = 0.
  const double centre_y = half_l * k + half_t * s;
  const double centre_x = half_l * s + half_t * k;
  const double apex = 2.0 * centre_y;                            // the outer top corners
  const double foot = o.card_length * s + o.card_thickness * k;  // half the tent's base
  // Tents stand pitch apart: their feet clear by a tenth of a card, and a flat card spans the
  // two apexes it rests on with room to spare.
  const double pitch = std::min(2.0 * foot + 0.1 * o.card_length, 0.9 * o.card_length);
  const int first = static_cast<int>(scene->bodies.size());
  auto card = [&](const Vec2& p, double angle, double hx, double hy) {
    SceneBody b;
    b.def.type = BodyType::kDynamic;
    b.def.position = p;
    b.def.angle = angle;
    ShapeDef shape;
    shape.geometry = make_box(hx, hy);
    shape.density = o.density;
    shape.friction = o.friction;
    b.shapes.push_back(shape);
    scene->bodies.push_back(b);
  };
  double floor = o.origin.y();
  for (int level = 0; level < o.levels; ++level) {
    const int tents = o.levels - level;
    for (int i = 0; i < tents; ++i) {
      const double x = o.origin.x() + (i - 0.5 * (tents - 1)) * pitch;
      card(Vec2(x - centre_x, floor + centre_y), -o.lean, half_t, half_l);  // leans right
      card(Vec2(x + centre_x, floor + centre_y), o.lean, half_t, half_l);   // leans left
    }
    for (int i = 0; i + 1 < tents; ++i) {
      const double x = o.origin.x() + (i + 1 - 0.5 * tents) * pitch;
      card(Vec2(x, floor + apex + half_t), 0.0, half_l, half_t);
    }
    floor += apex + o.card_thickness;
  }
  return first;
}

}  // namespace fulcrum::scenes
