// Box2D v3's rain, smash and spinner benchmark scenes as built-ins (scenes/builders/v3_scenes):
// they build, rain's driver follows v3's schedule, and each does what its scene is for.
#include <gtest/gtest.h>

#include <cmath>

#include "scene_fixture.h"

namespace fulcrum::testing {
namespace {

// Rain: a column of 5 groups of 5 ragdolls (11 bodies each) every 8th step; after 40 columns
// each new column replaces the oldest. The driver's edits alone, without stepping.
TEST(V3Scenes, RainSpawnsAColumnEvery8StepsAndKeepsAtMost40) {
  World w = build("rain");
  ASSERT_EQ(w.body_count(), 1);  // the ground: 5 rows of 501 tiles on one static body
  EXPECT_EQ(w.body_shapes(w.bodies()[0])->size(), 5u * 501u);
  std::unique_ptr<scenes::SceneDriver> driver = scenes::builtin_driver("rain");
  ASSERT_NE(driver, nullptr);
  EXPECT_EQ(scenes::builtin_driver("smash"), nullptr);
  const int column = 5 * 5 * 11;
  std::vector<BodyId> first_column;
  for (int step = 0; step < 8 * 45; ++step) {
    ASSERT_TRUE(driver->before_step(w, step).ok());
    const int columns = std::min(step / 8 + 1, 40);
    ASSERT_EQ(w.body_count(), 1 + columns * column) << "step " << step;
    if (step == 0) first_column = w.bodies();
  }
  // The first column was replaced at step 320: its bodies are gone.
  ASSERT_EQ(first_column.size(), 1u + column);
  EXPECT_FALSE(w.is_valid(first_column[1]));
  EXPECT_TRUE(w.is_valid(first_column[0]));  // the ground stays
}

// A ragdoll falls and lands on the tiles in one piece.
TEST(V3Scenes, RainRagdollsLandWhole) {
  World w = build("rain");
  std::unique_ptr<scenes::SceneDriver> driver = scenes::builtin_driver("rain");
  for (int step = 0; step < 240; ++step) {
    ASSERT_TRUE(driver->before_step(w, step).ok());
    w.step();
  }
  EXPECT_TRUE(all_finite(w));
  // Dropped from 40 m above a row, the first column has landed by 4 s (free fall: 2.9 s).
  // Joints hold within a few centimetres (the limits and springs of v3's ragdoll).
  EXPECT_LT(w.metrics().max_joint_error, 0.05);
  EXPECT_LT(w.metrics().max_penetration, 0.1);
}

// Smash: 9600 sleeping boxes, no gravity; the 512 kg box at 40 m/s reaches them after 1.15 s.
// Contact impulses are equal and opposite, so momentum stays 20480 kg m/s (rounding only), and
// the heavy box has given some of it to the blocks.
TEST(V3Scenes, SmashConservesMomentum) {
  World w = build("smash");
  const std::vector<BodyId> ids = w.bodies();
  ASSERT_EQ(ids.size(), 9601u);
  EXPECT_TRUE(w.body_state(ids[0])->awake);
  for (size_t i = 1; i < ids.size(); ++i) ASSERT_FALSE(w.body_state(ids[i])->awake);
  const double p0 = 512.0 * 40.0;
  EXPECT_NEAR(w.metrics().linear_momentum.x(), p0, 1e-9 * p0);
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_EQ(w.metrics().awake_body_count, 1);  // still in flight: the blocks sleep, free
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_NEAR(w.metrics().linear_momentum.x(), p0, 1e-6 * p0);
  EXPECT_NEAR(w.metrics().linear_momentum.y(), 0.0, 1e-6 * p0);
  EXPECT_LT(w.body_state(ids[0])->linear_velocity.x(), 39.0);
  EXPECT_GT(w.metrics().awake_body_count, 100);
}

// Spinner: the motor (unlimited torque) turns the 40 m blade at 5 rad/s through 6076 bodies.
TEST(V3Scenes, SpinnerTurnsAtItsMotorSpeed) {
  World w = build("spinner");
  ASSERT_EQ(w.body_count(), 6078);
  for (int i = 0; i < 90; ++i) w.step();
  EXPECT_TRUE(all_finite(w));
  const BodyId blade = w.bodies()[1];
  EXPECT_NEAR(w.body_state(blade)->angular_velocity, 5.0, 0.25);
}

}  // namespace
}  // namespace fulcrum::testing
