// The one place where proto scene messages (proto/fulcrum/v1/scene.proto) meet the engine's
// definition structs. The engine never sees protobuf; servers and clients never build engine
// definitions from wire data by hand.
#pragma once

#include <string>
#include <string_view>

#include "fulcrum/scene.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/scene.pb.h"

namespace fulcrum {

// Builds the scene: the builtin first, then the builders, then the explicit bodies. Every
// value is checked against its documented range; errors name the field path, e.g.
// "bodies[2].shapes[0].box.half_width: must be > 0 (got -1)".
Result<SceneDef> scene_from_proto(const v1::Scene& proto);

// The scene as explicit bodies (no builders, no builtin) with every settings field written
// out. Exact: scene_from_proto(scene_to_proto(s)) reproduces s bit for bit, boxes included.
v1::Scene scene_to_proto(const SceneDef& scene, std::string_view name = {});

// Protobuf JSON mapping (lowerCamelCase names; "NaN" parses but is then refused). Unknown
// fields are an error.
Result<SceneDef> parse_scene_json(std::string_view json);
// Reads and parses a scene file; errors are prefixed with the path.
Result<SceneDef> load_scene_json(const std::string& path);

// Pretty-printed JSON of scene_to_proto(scene, name). Doubles are printed with enough digits
// to parse back to the same bits.
std::string scene_to_json(const SceneDef& scene, std::string_view name = {});

// Pieces of the scene conversion that the snapshot and edit conversions share. Paths prefix
// error messages (e.g. "edits[3].create_body").
void world_settings_to_proto(const WorldSettings& s, v1::WorldSettings* out);
// Present fields replace those in *s; each is range-checked.
Status world_settings_from_proto(const v1::WorldSettings& p, const std::string& path,
                                 WorldSettings* s);
Status scene_body_from_proto(const v1::Body& p, const std::string& path, SceneBody* body);
Status scene_shape_from_proto(const v1::Shape& p, const std::string& path, ShapeDef* def);
Filter scene_filter_from_proto(const v1::Filter& p);
void scene_filter_to_proto(const Filter& f, v1::Filter* out);
// body_a and body_b index a list of body_count bodies.
Status scene_joint_from_proto(const v1::Joint& p, const std::string& path, int body_count,
                              SceneJoint* out);
// Checked as the engine checks it (finite, within kMaxInputMagnitude, min_distance > 0).
Status scene_attractor_from_proto(const v1::Attractor& p, const std::string& path,
                                  AttractorDef* out);
// Every field written.
void scene_attractor_to_proto(const AttractorDef& a, v1::Attractor* out);
// A Joint whose kind is `target` (edits only), without its bodies.
Status target_joint_from_proto(const v1::Joint& p, const std::string& path, TargetJointDef* def);

}  // namespace fulcrum
