// Builders of the hard cases that live outside scenes.cpp (HARD_CASES.md cases 7, 8, 10, 17, 19
// and 20).
// Internal to the scenes library: reach them by name through scenes::builtin().
#pragma once

#include "fulcrum/scene.h"

namespace fulcrum::scenes::hard {

// Case 7: 17 voussoirs forming a half ring (inner radius 5 m, outer 6 m) standing on a static
// ground, friction 0.6, no joints, sleep off. bodies[0] is the ground, bodies[1 + i] voussoir i
// counted from the right (angle 0) to the left (angle pi); bodies[9] is the crown.
SceneDef arch();

// Case 8: 625 circles of radius 0.5 on a 25 x 25 grid with spacing 0.72 m (every neighbour
// overlaps by 0.28 m) inside a closed box of four static walls, inner size 21 m x 21 m centred
// on the origin, zero gravity, sleep off. The circles cover 491 m^2 of the 441 m^2 inside,
// so they stay overlapping (about 0.2 m) however they settle. bodies[0..3] are the walls, then the
// circles row by row.
SceneDef confined();

// Case 17: a circle of radius 0.05 flying at 300 m/s toward a static wall 0.1 m thick (its
// faces at x = -0.05 and x = 0.05, 10 m tall, standing on the ground). bodies[0] is the
// ground, bodies[1] the wall, bodies[2] the bullet, starting 10 m left of the wall at 5 m.
// Without continuous collision, whether the wall stops it depends on where it starts relative
// to the tick grid (from this start it is stopped; from most others it is not): see case 17
// in tests/engine/hard_cases_more_test.cpp.
SceneDef bullet();

// Cases 10 and 19: 40 capsule links 1 m long (0.25 m wide) laid out horizontally from a static
// anchor at (0, 50), then a ball of radius 0.5 with `end_mass` times one link's mass (100 for
// case 10, 1000 for case 19), revolute joints at the link ends (scenes::add_joint_chain).
// bodies[0] is the anchor, bodies[1..40] the links, bodies[41] the ball; joint k ties body k to
// body k + 1. Released, the chain swings down and the ball whips through the bottom.
SceneDef heavy_chain(double end_mass);

// Case 20: 10 planks 2 m x 2 mm (density 1, friction 0.6) stacked flat on a static ground,
// each resting exactly on the one below, offset sideways alternately by +1 cm and -1 cm, sleep
// off. bodies[0] is the ground, bodies[1 + i] plank i counted from the bottom; the top plank
// is the last body. A plank is thinner than the default linear slop (2 mm against 5 mm).
SceneDef thin_planks();

}  // namespace fulcrum::scenes::hard
