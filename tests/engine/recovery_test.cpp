// Bounded recovery of stored contact overlap: soft contacts under a heavy load hold overlap
// (the spring's give), and when the load goes that overlap must be released without flinging
// what held it. Joint gaps are covered by joint_correction_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>

#include "fulcrum/geometry.h"
#include "fulcrum/world.h"

namespace fulcrum {
namespace {

struct Released {
  double loaded_overlap = 0.0;  // the largest overlap while loaded, m
  double rest_y = 0.0;          // the light box's centre at the end, unloaded, m
  double highest_y = 0.0;       // its highest centre after the load went, m
  double fastest_up = 0.0;      // its largest upward speed after the load went, m/s
};

// A light 1 m box on the ground under a box `ratio` times denser, settled for 2 s; then the
// heavy box is destroyed and the light one watched for 2 s.
Released release(double ratio) {
  World w;
  BodyDef g;
  g.type = BodyType::kStatic;
  BodyId ground = *w.create_body(g);
  ShapeDef gs;
  gs.geometry = make_box(20.0, 0.5);
  EXPECT_TRUE(w.create_shape(ground, gs).ok());
  BodyDef b;
  b.type = BodyType::kDynamic;
  b.position = Vec2(0.0, 1.0);
  BodyId light = *w.create_body(b);
  ShapeDef s;
  s.geometry = make_box(0.5, 0.5);
  s.density = 1.0;
  EXPECT_TRUE(w.create_shape(light, s).ok());
  b.position = Vec2(0.0, 2.0);
  BodyId heavy = *w.create_body(b);
  s.density = ratio;
  EXPECT_TRUE(w.create_shape(heavy, s).ok());
  Released r;
  for (int i = 0; i < 120; ++i) {
    w.step();
    r.loaded_overlap = std::max(r.loaded_overlap, w.metrics().max_penetration);
  }
  EXPECT_TRUE(w.destroy_body(heavy).ok());
  r.highest_y = w.body_state(light)->center.y();
  for (int i = 0; i < 120; ++i) {
    w.step();
    r.highest_y = std::max(r.highest_y, w.body_state(light)->center.y());
    r.fastest_up = std::max(r.fastest_up, w.body_state(light)->linear_velocity.y());
  }
  r.rest_y = w.body_state(light)->center.y();
  return r;
}

// At 100:1 the heavy box sinks 1.6 cm into the light one (measured 1.62 cm). Released at the
// push-out cap (1.5 m/s) that overlap would throw the light box up by centimetres; instead it
// comes back to rest without rising above where it rests unloaded (rounding: 1 micrometre)
// and never moves up faster than 2 cm/s (measured 1.6 cm/s): the stored overlap leaves as the
// spring relaxes, gaining no energy.
TEST(Recovery, OverlapUnderA100To1LoadIsReleasedWithoutAPop) {
  Released r = release(100.0);
  EXPECT_GT(r.loaded_overlap, 0.01);  // the load did hold centimetres of overlap
  EXPECT_LE(r.highest_y, r.rest_y + 1e-6);
  EXPECT_LT(r.fastest_up, 0.02);
}

}  // namespace
}  // namespace fulcrum
