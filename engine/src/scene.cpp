#include "fulcrum/scene.h"

#include <string>
#include <variant>

#include "world_impl.h"

namespace fulcrum {

namespace {

// "shape.density: ..." under "bodies[2].shapes[0]" reads "bodies[2].shapes[0].density: ...".
Status at(const Status& s, const std::string& where, const char* kind) {
  if (s.ok()) return s;
  std::string msg = s.message();
  std::string head = std::string(kind) + ".";
  if (msg.rfind(head, 0) == 0)
    msg = msg.substr(head.size());
  else if (msg.rfind(kind, 0) == 0)
    msg = msg.substr(std::string(kind).size());
  return Status(s.code(), where + (msg.rfind(":", 0) == 0 ? "" : ".") + msg);
}

Status validate(const DistanceJointDef& d) {
  return validate_distance_joint_def(d);
}
Status validate(const RevoluteJointDef& d) {
  return validate_revolute_joint_def(d);
}
Status validate(const WeldJointDef& d) {
  return validate_weld_joint_def(d);
}
Status validate(const PrismaticJointDef& d) {
  return validate_prismatic_joint_def(d);
}
Status validate(const WheelJointDef& d) {
  return validate_wheel_joint_def(d);
}
Status validate(const MotorJointDef& d) {
  return validate_motor_joint_def(d);
}

Result<JointId> create(World& w, const DistanceJointDef& d) {
  return w.create_distance_joint(d);
}
Result<JointId> create(World& w, const RevoluteJointDef& d) {
  return w.create_revolute_joint(d);
}
Result<JointId> create(World& w, const WeldJointDef& d) {
  return w.create_weld_joint(d);
}
Result<JointId> create(World& w, const PrismaticJointDef& d) {
  return w.create_prismatic_joint(d);
}
Result<JointId> create(World& w, const WheelJointDef& d) {
  return w.create_wheel_joint(d);
}
Result<JointId> create(World& w, const MotorJointDef& d) {
  return w.create_motor_joint(d);
}

}  // namespace

namespace {

Status exhausted(std::string message) {
  return Status(StatusCode::kResourceExhausted, std::move(message));
}

}  // namespace

size_t chain_segment_count(const ChainDef& chain) {
  const size_t n = chain.points.size();
  return chain.loop ? n : (n > 0 ? n - 1 : 0);
}

Status check_new_shapes(const WorkLimits& limits, int64_t in_world, BodyType type, int on_body,
                        size_t adding, const std::string& field) {
  const int64_t world_after = in_world + static_cast<int64_t>(adding);
  if (limits.max_shapes > 0 && world_after > limits.max_shapes) {
    return exhausted(field + ": would make " + std::to_string(world_after) +
                     " shapes in the world; this server allows " +
                     std::to_string(limits.max_shapes) + " (max_shapes)");
  }
  const int64_t body_after = static_cast<int64_t>(on_body) + static_cast<int64_t>(adding);
  if (limits.max_shapes_per_body > 0 && type != BodyType::kStatic &&
      body_after > limits.max_shapes_per_body) {
    return exhausted(field + ": would put " + std::to_string(body_after) +
                     " shapes on one moving body; this server allows " +
                     std::to_string(limits.max_shapes_per_body) +
                     " per dynamic or kinematic body (max_shapes_per_body; static bodies are "
                     "bound only by max_shapes)");
  }
  return {};
}

Result<World> build_world(const SceneDef& scene, const WorkLimits& limits) {
  FULCRUM_RETURN_IF_ERROR(validate_settings(scene.settings));
  if (limits.max_bodies > 0 && scene.bodies.size() > static_cast<size_t>(limits.max_bodies)) {
    return exhausted("bodies: " + std::to_string(scene.bodies.size()) +
                     " bodies; this server allows " + std::to_string(limits.max_bodies) +
                     " per world (max_bodies)");
  }
  int64_t shapes_so_far = 0;
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneBody& sb = scene.bodies[i];
    size_t adding = sb.shapes.size();
    for (const ChainDef& c : sb.chains) adding += chain_segment_count(c);
    FULCRUM_RETURN_IF_ERROR(check_new_shapes(limits, shapes_so_far, sb.def.type, 0, adding,
                                             "bodies[" + std::to_string(i) + "].shapes"));
    shapes_so_far += static_cast<int64_t>(adding);
  }
  // Validate everything before creating anything: a bad scene builds nothing.
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneBody& sb = scene.bodies[i];
    std::string where = "bodies[" + std::to_string(i) + "]";
    FULCRUM_RETURN_IF_ERROR(at(validate_body_def(sb.def), where, "body"));
    for (size_t j = 0; j < sb.shapes.size(); ++j) {
      FULCRUM_RETURN_IF_ERROR(at(validate_shape_def(sb.shapes[j]),
                                 where + ".shapes[" + std::to_string(j) + "]", "shape"));
    }
    for (size_t j = 0; j < sb.chains.size(); ++j) {
      FULCRUM_RETURN_IF_ERROR(at(validate_chain_def(sb.chains[j]),
                                 where + ".chains[" + std::to_string(j) + "]", "chain"));
    }
  }
  const int body_count = static_cast<int>(scene.bodies.size());
  for (size_t i = 0; i < scene.joints.size(); ++i) {
    const SceneJoint& sj = scene.joints[i];
    std::string where = "joints[" + std::to_string(i) + "]";
    if (sj.body_a < 0 || sj.body_a >= body_count) {
      return invalid_argument(where + ".body_a: no body " + std::to_string(sj.body_a) +
                              " in the scene (" + std::to_string(body_count) + " bodies)");
    }
    if (sj.body_b < 0 || sj.body_b >= body_count) {
      return invalid_argument(where + ".body_b: no body " + std::to_string(sj.body_b) +
                              " in the scene (" + std::to_string(body_count) + " bodies)");
    }
    if (sj.body_a == sj.body_b) return invalid_argument(where + ".body_b: must differ from body_a");
    Status s = std::visit([](const auto& def) { return validate(def); }, sj.def);
    FULCRUM_RETURN_IF_ERROR(at(s, where, "joint"));
  }
  for (size_t i = 0; i < scene.attractors.size(); ++i) {
    FULCRUM_RETURN_IF_ERROR(
        validate_attractor(scene.attractors[i], "attractors[" + std::to_string(i) + "]"));
  }
  World world(scene.settings);
  FULCRUM_RETURN_IF_ERROR(world.set_attractors(scene.attractors));
  std::vector<BodyId> ids;
  ids.reserve(scene.bodies.size());
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneBody& sb = scene.bodies[i];
    std::string where = "bodies[" + std::to_string(i) + "]";
    if (limits.keep_going) FULCRUM_RETURN_IF_ERROR(limits.keep_going().with_prefix(where + ": "));
    Result<BodyId> body = world.create_body(sb.def);
    if (!body.ok()) return at(body.status(), where, "body");
    ids.push_back(*body);
    for (size_t j = 0; j < sb.shapes.size(); ++j) {
      Result<ShapeId> shape = world.create_shape(*body, sb.shapes[j]);
      if (!shape.ok()) {
        return at(shape.status(), where + ".shapes[" + std::to_string(j) + "]", "shape");
      }
    }
    for (size_t j = 0; j < sb.chains.size(); ++j) {
      auto chain = world.create_chain(*body, sb.chains[j]);
      if (!chain.ok()) {
        return at(chain.status(), where + ".chains[" + std::to_string(j) + "]", "chain");
      }
    }
    if (limits.max_work > 0 && world.edit_work() > limits.max_work) {
      return exhausted(where + ": building the scene up to this body did " +
                       std::to_string(world.edit_work()) +
                       " units of work (shapes created, broad-phase boxes their wake queries "
                       "visited); this server allows " +
                       std::to_string(limits.max_work) +
                       " (max_batch_work). Shapes that overlap many others cost the most.");
    }
  }
  // Each new shape wakes the sleeping bodies it touches (the rule for edits), so a block of
  // bodies declared asleep would wake itself while it is built. Declared asleep, they stay
  // asleep, with the velocities they were given; joints below may still wake them.
  WorldImpl& impl = world.impl();
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const BodyDef& def = scene.bodies[i].def;
    Body& b = impl.bodies[ids[i].index];
    if (def.awake || def.type == BodyType::kStatic || !b.awake) continue;
    const Vec2 v = b.v;
    const double w = b.w;
    impl.set_awake_flag(ids[i].index, false);
    b.v = v;
    b.w = w;
  }
  for (size_t i = 0; i < scene.joints.size(); ++i) {
    const SceneJoint& sj = scene.joints[i];
    Result<JointId> joint = create_scene_joint(world, sj, ids[sj.body_a], ids[sj.body_b]);
    if (!joint.ok()) return at(joint.status(), "joints[" + std::to_string(i) + "]", "joint");
  }
  return world;
}

Result<JointId> create_scene_joint(World& world, const SceneJoint& joint, BodyId body_a,
                                   BodyId body_b) {
  return std::visit(
      [&](auto def) {
        def.body_a = body_a;
        def.body_b = body_b;
        return create(world, def);
      },
      joint.def);
}

}  // namespace fulcrum
