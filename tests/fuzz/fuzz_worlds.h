// The running worlds the edit and snapshot fuzz targets start from: built-in scenes small
// enough for thousands of inputs a second, stepped until contacts, islands, joints and sleeping
// bodies exist. Built once per process; each input restores one (bit-exact, cheap).
#pragma once

#include <string>
#include <vector>

#include "fulcrum/scenes.h"
#include "fulcrum/state.h"
#include "fulcrum/world.h"
#include "fuzz_support.h"

namespace fulcrum::fuzz {

struct BaseWorld {
  std::string name;
  WorldSnapshot snapshot;
};

inline const std::vector<BaseWorld>& base_worlds() {
  static const std::vector<BaseWorld> all = [] {
    std::vector<BaseWorld> out;
    // Joints of every kind the built-ins use (bridge, ragdolls: revolute, weld, distance...),
    // shapes of every kind (mixed), bouncing and resting bodies.
    for (const char* name : {"bridge", "ragdolls", "mixed", "bounce"}) {
      Result<SceneDef> scene = scenes::builtin(name);
      check(scene.ok(), std::string("builtin ") + name);
      Result<World> built = build_world(*scene);
      check(built.ok(), std::string("builtin ") + name + " builds");
      for (int t = 0; t < 40; ++t) built->step();
      out.push_back({name, built->snapshot()});
    }
    return out;
  }();
  return all;
}

// The base world an input's first byte chooses, restored into a fresh world.
inline World base_world(uint8_t choice) {
  const std::vector<BaseWorld>& all = base_worlds();
  World w{WorldSettings{}};
  check(w.restore(all[choice % all.size()].snapshot).ok(), "base world restores");
  return w;
}

}  // namespace fulcrum::fuzz
