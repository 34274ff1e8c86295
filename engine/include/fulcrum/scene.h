// A scene: world settings plus bodies with their shapes, as plain data. Scene files (JSON, see
// proto/fulcrum/v1/scene.proto) and the scene builders (scenes/builders) both produce one, and
// build_world turns it into a World.
#pragma once

#include <variant>
#include <vector>

#include "fulcrum/joints.h"
#include "fulcrum/status.h"
#include "fulcrum/types.h"
#include "fulcrum/world.h"

namespace fulcrum {

struct SceneBody {
  BodyDef def;
  std::vector<ShapeDef> shapes;
  std::vector<ChainDef> chains;
};

// A joint between two of the scene's bodies, named by their positions in `bodies` (the
// definition's own body_a and body_b handles are ignored).
struct SceneJoint {
  int body_a = 0;
  int body_b = 0;
  std::variant<DistanceJointDef, RevoluteJointDef, WeldJointDef, PrismaticJointDef, WheelJointDef,
               MotorJointDef>
      def;
};

struct SceneDef {
  WorldSettings settings;
  std::vector<SceneBody> bodies;
  std::vector<SceneJoint> joints;  // created after every body, in order
};

// Validates the whole scene first (messages name the place: "bodies[3].shapes[0].density"),
// then builds it. Bodies are created in order, so bodies[i] gets index i.
Result<World> build_world(const SceneDef& scene);

// Creates the joint's definition between two bodies of a world (its body_a and body_b indices
// are not used).
Result<JointId> create_scene_joint(World& world, const SceneJoint& joint, BodyId body_a,
                                   BodyId body_b);

}  // namespace fulcrum
