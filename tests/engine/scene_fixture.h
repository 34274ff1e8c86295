// The one place tests build worlds from the shared scenes, and the facts they check about
// every world (finite state, how far bodies moved, penetration over time).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/world.h"

namespace fulcrum::testing {

inline SceneDef scene(const char* name) {
  auto s = scenes::builtin(name);
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.ok() ? *s : SceneDef{};
}

inline World build(const SceneDef& s) {
  auto world = build_world(s);
  EXPECT_TRUE(world.ok()) << world.status().to_string();
  return world.ok() ? std::move(world).value() : World{};
}

inline World build(const char* name) {
  return build(scene(name));
}

inline std::vector<Vec2> centers(const World& w) {
  std::vector<Vec2> out;
  for (BodyId id : w.bodies()) out.push_back(w.body_state(id)->center);
  return out;
}

// No NaN or infinity in any body's position or velocity.
inline bool all_finite(const World& w) {
  for (BodyId id : w.bodies()) {
    BodyState s = *w.body_state(id);
    if (!is_finite(s.center) || !is_finite(s.linear_velocity) ||
        !std::isfinite(s.angular_velocity)) {
      return false;
    }
  }
  return true;
}

// Steps `ticks` ticks; returns the largest penetration seen after the first second (the
// HARD_CASES sampling).
inline double run(World& w, int ticks) {
  double worst = 0.0;
  for (int i = 0; i < ticks; ++i) {
    w.step();
    if (w.tick() > 60) worst = std::max(worst, w.metrics().max_penetration);
  }
  return worst;
}

}  // namespace fulcrum::testing
