// A scene: world settings plus bodies with their shapes, as plain data. Scene files (JSON, see
// proto/fulcrum/v1/scene.proto) and the scene builders (scenes/builders) both produce one, and
// build_world turns it into a World.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
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
  std::vector<SceneJoint> joints;        // created after every body, in order
  std::vector<AttractorDef> attractors;  // World::set_attractors, in order
};

// Bounds on what building a scene or applying edits may do, for servers that take them from
// clients they do not control. Zero means no limit. A refusal is RESOURCE_EXHAUSTED and names
// the limit as the server's flag spells it (max_shapes_per_body).
struct WorkLimits {
  int max_bodies = 0;           // live bodies
  int max_shapes = 0;           // live shapes, chain segments included
  int max_shapes_per_body = 0;  // on one dynamic or kinematic body (static shapes never move)
  uint64_t max_work = 0;        // World::edit_work one scene or one edit batch may add
  // Asked between bodies and between edits; a non-OK status (a cancelled call, a passed
  // deadline, a server shutting down) stops the work, which then builds or changes nothing.
  std::function<Status()> keep_going;
};

// The shape limits for adding `adding` shapes to a body of `type` that has `on_body` already,
// in a world of `in_world` shapes. `field` starts the message.
Status check_new_shapes(const WorkLimits& limits, int64_t in_world, BodyType type, int on_body,
                        size_t adding, const std::string& field);
// The segments a chain makes.
size_t chain_segment_count(const ChainDef& chain);

// Validates the whole scene first (messages name the place: "bodies[3].shapes[0].density"),
// then builds it. Bodies are created in order, so bodies[i] gets index i. Counts are checked
// against `limits` before anything is built, the work after each body.
Result<World> build_world(const SceneDef& scene, const WorkLimits& limits = {});

// Creates the joint's definition between two bodies of a world (its body_a and body_b indices
// are not used).
Result<JointId> create_scene_joint(World& world, const SceneJoint& joint, BodyId body_a,
                                   BodyId body_b);

}  // namespace fulcrum
