// Hard case 9 (the joint grid) in Box2D v3, built as v3's own benchmark builds it: 100 x 100
// circles of radius 0.4 a metre apart, each pinned to its lower and right neighbours at the
// midpoint, the 7 middle circles of the top row static, jointed circles not colliding. Steps
// 500 ticks at 60 Hz and prints the largest joint separation (the gap between a joint's two
// anchors) over every tick, and the tick it came at: case 9 asks for less than 10 cm.
// usage: v3_joint_grid [SUBSTEPS]   (default 4, v3's own)
#include <stdio.h>
#include <stdlib.h>

#include "box2d/box2d.h"

enum { kSide = 100, kTicks = 500 };

int main(int argc, char** argv) {
  const int substeps = argc > 1 ? atoi(argv[1]) : 4;
  b2WorldDef world_def = b2DefaultWorldDef();
  b2WorldId world = b2CreateWorld(&world_def);
  b2World_EnableSleeping(world, false);

  static b2BodyId circles[kSide * kSide];
  static b2JointId joints[2 * kSide * kSide];
  int joint_count = 0;
  b2ShapeDef shape = b2DefaultShapeDef();
  shape.density = 1.0f;
  shape.filter.categoryBits = 2;
  shape.filter.maskBits = ~2u;
  const b2Circle circle = {{0.0f, 0.0f}, 0.4f};
  for (int col = 0; col < kSide; ++col) {
    for (int row = 0; row < kSide; ++row) {
      const int i = col * kSide + row;
      b2BodyDef def = b2DefaultBodyDef();
      const int middle = kSide / 2;
      def.type =
          row == 0 && col >= middle - 3 && col <= middle + 3 ? b2_staticBody : b2_dynamicBody;
      def.position = (b2Pos){(double)col, -(double)row};
      circles[i] = b2CreateBody(world, &def);
      b2CreateCircleShape(circles[i], &shape, &circle);
      b2RevoluteJointDef pin = b2DefaultRevoluteJointDef();
      if (row > 0) {  // to the circle above
        pin.base.bodyIdA = circles[i - 1];
        pin.base.bodyIdB = circles[i];
        pin.base.localFrameA.p = (b2Vec2){0.0f, -0.5f};
        pin.base.localFrameB.p = (b2Vec2){0.0f, 0.5f};
        joints[joint_count++] = b2CreateRevoluteJoint(world, &pin);
      }
      if (col > 0) {  // to the circle on the left
        pin.base.bodyIdA = circles[i - kSide];
        pin.base.bodyIdB = circles[i];
        pin.base.localFrameA.p = (b2Vec2){0.5f, 0.0f};
        pin.base.localFrameB.p = (b2Vec2){-0.5f, 0.0f};
        joints[joint_count++] = b2CreateRevoluteJoint(world, &pin);
      }
    }
  }

  double largest = 0.0, last = 0.0;
  int largest_tick = 0;
  for (int tick = 1; tick <= kTicks; ++tick) {
    b2World_Step(world, 1.0f / 60.0f, substeps);
    last = 0.0;
    for (int j = 0; j < joint_count; ++j) {
      const double gap = b2Joint_GetLinearSeparation(joints[j]);
      if (gap > last) last = gap;
    }
    if (last > largest) {
      largest = last;
      largest_tick = tick;
    }
  }
  printf(
      "v3 joint grid (%d substeps, %d joints): largest joint separation %.3f m (tick %d), "
      "%.3f m at tick %d\n",
      substeps, joint_count, largest, largest_tick, last, kTicks);
  b2DestroyWorld(world);
  return 0;
}
