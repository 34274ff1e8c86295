// Hard case 11 (the bridge) in Box2D v3, measured as Fulcrum's sweep measures it: 160 planks of
// 1 m x 0.25 m (density 20) pinned end to end, both ends pinned to the ground 160 m apart, the
// ground's top 20 m below, 600 ticks at 60 Hz. Prints the largest joint separation over every
// tick, how far the middle plank moves in the last second, and the planks lying on the ground.
// usage: v3_bridge [HINGE_FRICTION_N_M] [SUBSTEPS]   (defaults 0 and 4, v3's own)
#include <stdio.h>
#include <stdlib.h>

#include "box2d/box2d.h"

enum { kPlanks = 160, kTicks = 600 };

static b2JointId pin(b2WorldId world, b2BodyId a, b2BodyId b, b2Pos pivot, float friction) {
  b2RevoluteJointDef def = b2DefaultRevoluteJointDef();
  def.base.bodyIdA = a;
  def.base.bodyIdB = b;
  def.base.localFrameA.p = b2Body_GetLocalPoint(a, pivot);
  def.base.localFrameB.p = b2Body_GetLocalPoint(b, pivot);
  def.enableMotor = friction > 0.0f;  // a motor at zero speed: hinge friction
  def.maxMotorTorque = friction;
  return b2CreateRevoluteJoint(world, &def);
}

int main(int argc, char** argv) {
  const float friction = argc > 1 ? (float)atof(argv[1]) : 0.0f;
  const int substeps = argc > 2 ? atoi(argv[2]) : 4;
  b2WorldDef world_def = b2DefaultWorldDef();
  world_def.gravity = (b2Vec2){0.0f, -10.0f};
  b2WorldId world = b2CreateWorld(&world_def);

  b2BodyDef ground_def = b2DefaultBodyDef();
  b2BodyId ground = b2CreateBody(world, &ground_def);
  b2Polygon slab = b2MakeOffsetBox(100.0f, 1.0f, (b2Vec2){0.0f, -21.0f}, b2Rot_identity);
  b2ShapeDef ground_shape = b2DefaultShapeDef();
  b2CreatePolygonShape(ground, &ground_shape, &slab);

  b2BodyId planks[kPlanks];
  b2JointId joints[kPlanks + 1];
  b2Polygon plank = b2MakeBox(0.5f, 0.125f);
  b2ShapeDef plank_shape = b2DefaultShapeDef();
  plank_shape.density = 20.0f;
  const double left = -80.0;
  b2BodyId previous = ground;
  for (int i = 0; i < kPlanks; ++i) {
    b2BodyDef def = b2DefaultBodyDef();
    def.type = b2_dynamicBody;
    def.position = (b2Pos){left + 0.5 + i, 0.0};
    planks[i] = b2CreateBody(world, &def);
    b2CreatePolygonShape(planks[i], &plank_shape, &plank);
    joints[i] = pin(world, previous, planks[i], (b2Pos){left + i, 0.0}, friction);
    previous = planks[i];
  }
  joints[kPlanks] = pin(world, previous, ground, (b2Pos){left + kPlanks, 0.0}, friction);

  double separation = 0.0, low = 1e300, high = -1e300;
  for (int tick = 1; tick <= kTicks; ++tick) {
    b2World_Step(world, 1.0f / 60.0f, substeps);
    for (int j = 0; j <= kPlanks; ++j) {
      const double s = b2Joint_GetLinearSeparation(joints[j]);
      if (s > separation) separation = s;
    }
    if (tick > kTicks - 60) {
      const double y = b2Body_GetPosition(planks[kPlanks / 2 - 1]).y;
      if (y < low) low = y;
      if (y > high) high = y;
    }
  }
  int on_ground = 0;
  for (int i = 0; i < kPlanks; ++i) on_ground += b2Body_GetPosition(planks[i]).y < -19.5;
  printf(
      "v3 bridge (hinge friction %.0f N m, %d substeps): largest joint separation %.4f m, "
      "middle plank moved %.4f m in the last second (y %.3f to %.3f), %d planks on the ground\n",
      friction, substeps, separation, high - low, low, high, on_ground);
  b2DestroyWorld(world);
  return 0;
}
