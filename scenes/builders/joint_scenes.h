// Scenes built of joints (HARD_CASES 9, 11, 13 and the benchmark table's joint grid).
#pragma once

#include "fulcrum/scene.h"

namespace fulcrum::scenes {

SceneDef joint_grid();    // 100 x 100 circles, revolute joints to the neighbours above and left
SceneDef bridge();        // 160 planks on revolute joints, both ends anchored
SceneDef cloth();         // 30 x 30 particles, structural and shear distance joints
SceneDef rope();          // a 40-particle rope pinned at one end, falling onto boxes
SceneDef ragdolls();      // 50 ragdolls dropped 10 m onto the ground
SceneDef ragdoll_rain();  // 1000 ragdolls in 25 rows raining into a container

}  // namespace fulcrum::scenes
