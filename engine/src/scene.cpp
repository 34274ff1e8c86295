#include "fulcrum/scene.h"

#include <string>

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

}  // namespace

Result<World> build_world(const SceneDef& scene) {
  FULCRUM_RETURN_IF_ERROR(validate_settings(scene.settings));
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
  World world(scene.settings);
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneBody& sb = scene.bodies[i];
    std::string where = "bodies[" + std::to_string(i) + "]";
    Result<BodyId> body = world.create_body(sb.def);
    if (!body.ok()) return at(body.status(), where, "body");
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
  }
  return world;
}

}  // namespace fulcrum
