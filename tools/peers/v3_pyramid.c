// Box2D v3's large pyramid (its benchmark scene: 100 rows of 1 m boxes, 5050 in all), measured
// as fulcrum_bench measures Fulcrum's: after 500 ticks at 60 Hz, how many boxes lie more than
// 0.5 m from where they were built, and how far the top box has come down.
// usage: v3_pyramid [SUBSTEPS]   (default 4, v3's own)
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "box2d/box2d.h"

enum { kRows = 100, kBoxes = kRows * (kRows + 1) / 2, kTicks = 500 };

int main(int argc, char** argv) {
  const int substeps = argc > 1 ? atoi(argv[1]) : 4;
  b2WorldDef world_def = b2DefaultWorldDef();
  b2WorldId world = b2CreateWorld(&world_def);
  b2World_EnableSleeping(world, false);

  b2BodyDef ground_def = b2DefaultBodyDef();
  ground_def.position = (b2Pos){0.0, -1.0};
  b2BodyId ground = b2CreateBody(world, &ground_def);
  b2Polygon slab = b2MakeBox(100.0f, 1.0f);
  b2ShapeDef ground_shape = b2DefaultShapeDef();
  b2CreatePolygonShape(ground, &ground_shape, &slab);

  static b2BodyId boxes[kBoxes];
  static double built_x[kBoxes], built_y[kBoxes];
  b2Polygon box = b2MakeSquare(0.5f);
  b2ShapeDef box_shape = b2DefaultShapeDef();
  box_shape.density = 1.0f;
  int n = 0;
  for (int row = 0; row < kRows; ++row) {
    const double y = row + 0.5;
    for (int k = row; k < kRows; ++k) {
      const double x = 0.5 * (row + 1) + (k - row) - 0.5 * kRows;
      b2BodyDef def = b2DefaultBodyDef();
      def.type = b2_dynamicBody;
      def.position = (b2Pos){x, y};
      boxes[n] = b2CreateBody(world, &def);
      b2CreatePolygonShape(boxes[n], &box_shape, &box);
      built_x[n] = x;
      built_y[n] = y;
      ++n;
    }
  }
  for (int tick = 0; tick < kTicks; ++tick) b2World_Step(world, 1.0f / 60.0f, substeps);

  int moved = 0;
  for (int i = 0; i < n; ++i) {
    const b2Pos p = b2Body_GetPosition(boxes[i]);
    moved += hypot(p.x - built_x[i], p.y - built_y[i]) > 0.5;
  }
  const b2Pos top = b2Body_GetPosition(boxes[n - 1]);
  printf(
      "v3 large pyramid (%d substeps, %d boxes): %d moved more than 0.5 m, top box %.3f m "
      "lower\n",
      substeps, n, moved, built_y[n - 1] - top.y);
  b2DestroyWorld(world);
  return 0;
}
