// The one place tests build worlds from the shared scenes, and the facts they check about
// every world (finite state, how far bodies moved, penetration over time).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/simd.h"
#include "fulcrum/state.h"
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

// A pyramid of `base` unit boxes on a 40 m ground, at the default settings.
inline SceneDef pyramid(int base) {
  SceneDef s;
  scenes::add_ground(&s, 40.0);
  scenes::PyramidOptions p;
  p.base = base;
  scenes::add_pyramid(&s, p);
  return s;
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

// Every instruction path this CPU runs gives the scalar path's state hash at every tick of
// `scene` (at least scalar and the 2-lane baseline are compared).
inline void expect_simd_paths_agree(const SceneDef& scene, int ticks) {
  std::vector<std::vector<uint64_t>> runs;
  for (SimdPath path : supported_simd_paths()) {
    ASSERT_TRUE(set_simd_path(path).ok());
    EXPECT_EQ(active_simd_path(), path);
    World w = build(scene);
    std::vector<uint64_t> hashes;
    for (int i = 0; i < ticks; ++i) {
      w.step();
      hashes.push_back(w.state_hash());
    }
    runs.push_back(hashes);
  }
  ASSERT_TRUE(set_simd_path(SimdPath::kAuto).ok());
  ASSERT_GE(runs.size(), 2u);
  for (size_t p = 1; p < runs.size(); ++p) {
    for (int i = 0; i < ticks; ++i) {
      ASSERT_EQ(runs[p][i], runs[0][i])
          << simd_path_name(supported_simd_paths()[p]) << " differs from scalar at tick " << i + 1;
    }
  }
}

// Each thread count in `counts` (the first is the reference) gives the same state hash at
// every tick of `scene`; `after` (if any) is called on each world after its last tick.
template <class After>
void expect_thread_counts_agree(const SceneDef& scene, int ticks, std::initializer_list<int> counts,
                                After after) {
  std::vector<uint64_t> reference;
  for (int threads : counts) {
    World w = build(scene);
    ASSERT_TRUE(w.set_threads(threads).ok());
    for (int i = 0; i < ticks; ++i) {
      w.step();
      if (reference.size() < static_cast<size_t>(ticks)) {
        reference.push_back(w.state_hash());
      } else {
        ASSERT_EQ(w.state_hash(), reference[i]) << threads << " threads, tick " << i + 1;
      }
    }
    after(w);
  }
}

// Steps two worlds of `scene` for `ticks` ticks, edit(world, tick) applied to both before each
// tick, the second restored from its own snapshot before every tick (a new world: it keeps
// nothing from the tick before, the lanes' layouts included); expects the same state hash after
// every tick, and calls after(first world, tick) after each.
template <class Edit, class After>
void expect_restored_every_tick_agrees(const SceneDef& scene, int ticks, Edit edit, After after) {
  World kept = build(scene);
  World renewed = build(scene);
  for (int tick = 0; tick < ticks; ++tick) {
    edit(kept, tick);
    edit(renewed, tick);
    ASSERT_TRUE(renewed.restore(renewed.snapshot()).ok());
    kept.step();
    renewed.step();
    ASSERT_EQ(kept.state_hash(), renewed.state_hash()) << "tick " << tick;
    after(kept, tick);
  }
}

}  // namespace fulcrum::testing
