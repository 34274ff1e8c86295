// The hand-written-scene builders (scenes/builders/hand_scenes.cpp): counts, placement, and
// whether what they build holds at the default settings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"

namespace fulcrum {
namespace {

World build(const SceneDef& scene) {
  Result<World> world = build_world(scene);
  EXPECT_TRUE(world.ok()) << world.status().to_string();
  return std::move(world).value();
}

// A slope placed anywhere: its top surface passes through `center` at the given angle, so a
// ball dropped onto it comes to rest touching that line; and the old form is unchanged.
TEST(HandScenes, GroundPlacedAnywhere) {
  SceneDef s;
  scenes::GroundOptions g;
  g.center = Vec2(3.0, -2.0);
  g.angle = 0.3;
  g.half_width = 10.0;
  g.thickness = 0.5;
  EXPECT_EQ(scenes::add_ground(&s, g), 0);
  ASSERT_EQ(s.bodies.size(), 1u);
  World w = build(s);
  // The surface's top points: the box's top corners, in world.
  const Rot q = Rot::from_angle(0.3);
  const Vec2 normal = q.rotate(Vec2(0.0, 1.0));
  std::vector<ShapeId> shapes = *w.body_shapes(w.bodies()[0]);
  const Polygon box = std::get<Polygon>(w.shape_info(shapes[0])->geometry);
  const Transform xf = w.body_state(w.bodies()[0])->transform;
  double top = -1e9;
  for (int i = 0; i < box.count; ++i)
    top = std::max(top, dot(xf.apply(box.vertices[i]) - g.center, normal));
  EXPECT_NEAR(top, 0.0, 1e-12);  // the top face lies on the line through center
  EXPECT_NEAR(dot(xf.p - g.center, normal), -0.25, 1e-12);

  SceneDef old_form, new_form;
  scenes::add_ground(&old_form, 20.0, 1.5, 0.7);
  scenes::GroundOptions same;
  same.center = Vec2(0.0, 1.5);
  same.half_width = 20.0;
  same.friction = 0.7;
  scenes::add_ground(&new_form, same);
  EXPECT_EQ(build(old_form).state_hash(), build(new_form).state_hash());
}

int joint_count(const SceneDef& s) {
  return static_cast<int>(s.joints.size());
}

TEST(HandScenes, JointChainCounts) {
  SceneDef s;
  scenes::JointChainOptions o;
  o.links = 12;
  EXPECT_EQ(scenes::add_joint_chain(&s, o), 0);
  EXPECT_EQ(s.bodies.size(), 13u);  // anchor + links
  EXPECT_EQ(joint_count(s), 12);
  o.end_mass = 100.0;
  o.shape = scenes::JointChainOptions::LinkShape::kBox;
  o.joint = scenes::JointChainOptions::JointKind::kWeld;
  EXPECT_EQ(scenes::add_joint_chain(&s, o), 13);
  EXPECT_EQ(s.bodies.size(), 13u + 14u);  // anchor + links + ball
  EXPECT_EQ(joint_count(s), 12 + 13);
  EXPECT_TRUE(std::holds_alternative<WeldJointDef>(s.joints.back().def));
  World w = build(s);
  // The ball weighs end_mass link masses (density scaled by the areas), to rounding.
  std::vector<BodyId> ids = w.bodies();
  const double link = w.body_state(ids[14])->mass, ball = w.body_state(ids.back())->mass;
  EXPECT_NEAR(ball / link, 100.0, 1e-9);
}

double max_joint_error_over(World& w, int ticks) {
  double worst = 0.0;
  for (int i = 0; i < ticks; ++i) {
    w.step();
    worst = std::max(worst, w.metrics().max_joint_error);
  }
  return worst;
}

// At the defaults (4 substeps, joints at 60 Hz) a 20-link capsule chain released horizontally
// swings down with every joint within HARD_CASES' 5 cm over 5 s (measured 2.0 cm, when the
// free end whips through the bottom), and a welded box beam of 10 links, cantilevered from its
// anchor, sags with every joint within 5 cm too (measured 0.8 cm).
TEST(HandScenes, JointChainHoldsAtTheDefaults) {
  SceneDef s;
  scenes::add_ground(&s, 100.0, -30.0);
  scenes::JointChainOptions o;
  scenes::add_joint_chain(&s, o);
  World w = build(s);
  double chain = max_joint_error_over(w, 300);
  SceneDef b;
  o.links = 10;
  o.shape = scenes::JointChainOptions::LinkShape::kBox;
  o.joint = scenes::JointChainOptions::JointKind::kWeld;
  scenes::add_joint_chain(&b, o);
  World beam = build(b);
  double weld = max_joint_error_over(beam, 300);
  EXPECT_LT(chain, 0.05);
  EXPECT_LT(weld, 0.05);
}

// The heavy chain of HARD_CASES 10 built by the builder (40 capsule links, a ball of 100 link
// masses) at the DEFAULT settings holds within the case's 5 cm over 10 s: its island's budget
// runs 7 substeps (without budgets, 8.1 cm when the ball whips through the bottom).
TEST(HandScenes, HeavyChainHoldsAtTheDefaults) {
  SceneDef s;
  scenes::JointChainOptions o;
  o.anchor = Vec2(0.0, 50.0);
  o.links = 40;
  o.end_mass = 100.0;
  scenes::add_joint_chain(&s, o);
  World w = build(s);
  double worst = max_joint_error_over(w, 600);
  EXPECT_LT(worst, 0.05);
  EXPECT_EQ(w.metrics().max_substeps, 7);
}

// (3 n^2 + n) / 2 cards. A house of 3 levels at the defaults (cards 1 m x 5 cm leaning 0.35
// rad, friction 0.6) settles within its first second, the leaning cards sliding up to 5 cm
// into firm contact (measured 4.0 cm: they are created with only their inner top corners
// touching), then stands: from 1 s to 10 s no card's centre moves 1 mm, and the whole house
// is asleep (a card that slips or a storey that folds moves tens of centimetres).
TEST(HandScenes, CardHouseCountsAndStands) {
  for (int levels : {1, 2, 3, 5}) {
    SceneDef s;
    scenes::CardHouseOptions o;
    o.levels = levels;
    scenes::add_card_house(&s, o);
    EXPECT_EQ(static_cast<int>(s.bodies.size()), (3 * levels * levels + levels) / 2);
  }
  SceneDef s;
  scenes::add_ground(&s, 20.0);
  scenes::CardHouseOptions o;
  const int first = scenes::add_card_house(&s, o);
  World w = build(s);
  std::vector<BodyId> ids = w.bodies();
  auto centres = [&] {
    std::vector<Vec2> c;
    for (size_t i = first; i < ids.size(); ++i) c.push_back(w.body_state(ids[i])->center);
    return c;
  };
  auto largest_move = [](const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
    double m = 0.0;
    for (size_t i = 0; i < a.size(); ++i) m = std::max(m, length(a[i] - b[i]));
    return m;
  };
  const std::vector<Vec2> start = centres();
  for (int t = 0; t < 60; ++t) w.step();
  const std::vector<Vec2> settled = centres();
  EXPECT_LT(largest_move(start, settled), 0.05);
  for (int t = 0; t < 540; ++t) w.step();
  EXPECT_LT(largest_move(settled, centres()), 0.001);
  EXPECT_EQ(w.metrics().awake_body_count, 0);
}

}  // namespace
}  // namespace fulcrum
