// Box2D v3's rain, smash and spinner benchmark scenes (v3_scenes.cpp); the registry in
// scenes.cpp names them.
#pragma once

#include <vector>

#include "fulcrum/scenes.h"

namespace fulcrum::scenes {

inline constexpr int kRainRows = 5;
inline constexpr int kRainColumns = 40;
inline constexpr int kRainGroupSize = 5;

// The static scene of rain: five rows of 501 ground tiles. Its ragdolls come from RainDriver.
SceneDef rain();
// The five ragdolls of one group (row 0..4, column 0..39).
SceneDef rain_group(int row, int column);
SceneDef smash();
SceneDef spinner();

// Every 8th step, a column of five groups (one per row) is created; once 40 columns exist,
// each new column first destroys the oldest one's groups and takes its place.
class RainDriver : public SceneDriver {
 public:
  RainDriver();
  Status before_step(World& world, int64_t step) override;

 private:
  std::vector<std::vector<BodyId>> groups_;  // [row * kRainColumns + column]
  int columns_ = 0;                          // columns created so far, up to kRainColumns
  int next_ = 0;                             // then: the column replaced next
};

}  // namespace fulcrum::scenes
