// Edit batches: each edit maps onto one World call. Atomicity comes from a snapshot taken
// before the first edit and restored if any edit is refused, so a half-applied batch is never
// visible.
#include "edit_convert.h"

#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fulcrum/state.h"
#include "scene_convert.h"
#include "validation.h"

namespace fulcrum {

namespace {

Vec2 get(const v1::Vec2& v) {
  return Vec2(v.x(), v.y());
}
BodyId body(const v1::Handle& h) {
  return BodyId{h.index(), h.generation()};
}
ShapeId shape(const v1::Handle& h) {
  return ShapeId{h.index(), h.generation()};
}
JointId joint(const v1::Handle& h) {
  return JointId{h.index(), h.generation()};
}

// What a handle in an edit names.
enum class HandleKind { kBody, kShape, kJoint };

// Calls visit(handle, kind, "field.path") for every handle the edit holds (an absent one reads
// as the empty default); stops at the first error. Every edit kind that holds a handle is
// listed here.
template <typename Visit>
Status for_each_handle(const v1::Edit& e, Visit visit) {
  using K = HandleKind;
  switch (e.kind_case()) {
    case v1::Edit::kDestroyBody:
      return visit(e.destroy_body(), K::kBody, "destroy_body");
    case v1::Edit::kCreateShape:
      return visit(e.create_shape().body(), K::kBody, "create_shape.body");
    case v1::Edit::kDestroyShape:
      return visit(e.destroy_shape(), K::kShape, "destroy_shape");
    case v1::Edit::kCreateJoint:
      FULCRUM_RETURN_IF_ERROR(visit(e.create_joint().body_a(), K::kBody, "create_joint.body_a"));
      return visit(e.create_joint().body_b(), K::kBody, "create_joint.body_b");
    case v1::Edit::kDestroyJoint:
      return visit(e.destroy_joint(), K::kJoint, "destroy_joint");
    case v1::Edit::kSetTransform:
      return visit(e.set_transform().body(), K::kBody, "set_transform.body");
    case v1::Edit::kSetVelocity:
      return visit(e.set_velocity().body(), K::kBody, "set_velocity.body");
    case v1::Edit::kApplyForce:
      return visit(e.apply_force().body(), K::kBody, "apply_force.body");
    case v1::Edit::kApplyImpulse:
      return visit(e.apply_impulse().body(), K::kBody, "apply_impulse.body");
    case v1::Edit::kApplyTorque:
      return visit(e.apply_torque().body(), K::kBody, "apply_torque.body");
    case v1::Edit::kSetMaterial:
      return visit(e.set_material().shape(), K::kShape, "set_material.shape");
    case v1::Edit::kSetFilter:
      return visit(e.set_filter().shape(), K::kShape, "set_filter.shape");
    case v1::Edit::kSetMotor:
      return visit(e.set_motor().joint(), K::kJoint, "set_motor.joint");
    case v1::Edit::kSetJointTarget:
      return visit(e.set_joint_target().joint(), K::kJoint, "set_joint_target.joint");
    case v1::Edit::kSetAwake:
      return visit(e.set_awake().body(), K::kBody, "set_awake.body");
    case v1::Edit::kSetConstantForce:
      return visit(e.set_constant_force().body(), K::kBody, "set_constant_force.body");
    case v1::Edit::kCreateBody:
    case v1::Edit::kSetAttractors:
    case v1::Edit::kSetGravity:
    case v1::Edit::kSetSettings:
    case v1::Edit::KIND_NOT_SET:
      break;
  }
  return {};
}

// `h` must belong to a mutable edit; the default instance an absent handle reads as has no
// scene_index and is never written.
Status resolve_scene_index(const v1::Handle& handle, HandleKind kind, const std::string& path,
                           const SceneHandles& scene) {
  if (!handle.has_scene_index()) return {};
  v1::Handle* h = const_cast<v1::Handle*>(&handle);
  const std::string field = path + ".scene_index";
  if (h->index() != 0 || h->generation() != 0) {
    return invalid_argument(field + ": give scene_index or index and generation, not both");
  }
  const int64_t i = h->scene_index();
  if (kind == HandleKind::kShape) {
    return invalid_argument(field + ": shapes have no scene index (name a shape by its handle)");
  }
  const bool body = kind == HandleKind::kBody;
  const int64_t count = static_cast<int64_t>(body ? scene.bodies.size() : scene.joints.size());
  if (i < 0 || i >= count) {
    return invalid_argument(field + ": no " + (body ? "body " : "joint ") + std::to_string(i) +
                            " in the scene (" + std::to_string(count) +
                            (body ? " bodies)" : " joints)"));
  }
  const int32_t index = body ? scene.bodies[i].index : scene.joints[i].index;
  const uint32_t generation = body ? scene.bodies[i].generation : scene.joints[i].generation;
  h->clear_scene_index();
  h->set_index(index);
  h->set_generation(generation);
  return {};
}

Status exhausted(std::string message) {
  return Status(StatusCode::kResourceExhausted, std::move(message));
}

std::string text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
std::string text(const v1::Vec2& v) {
  return "(" + text(v.x()) + ", " + text(v.y()) + ")";
}

// The engine's message with its leading `from` (a definition's name) replaced by `to`, the
// proto's spelling of that place; an empty `to` drops it, and the message's separator with it
// when nothing of the path remains.
Status renamed(const Status& s, const std::string& from, const std::string& to) {
  if (s.ok() || s.message().rfind(from, 0) != 0) return s;
  std::string rest = s.message().substr(from.size());
  if (to.empty() && !rest.empty() && (rest[0] == '.' || rest[0] == ':')) {
    rest = rest[0] == '.' ? rest.substr(1) : rest.substr(rest.find_first_not_of(": "));
  }
  return Status(s.code(), to + rest);
}

Status apply_one(World* w, const v1::Edit& e, const std::string& path, const EditLimits& limits,
                 EditOutcome* out) {
  switch (e.kind_case()) {
    case v1::Edit::kCreateBody: {
      if (limits.max_bodies > 0 && w->body_count() >= limits.max_bodies) {
        return exhausted(path + ": would make " + std::to_string(w->body_count() + 1) +
                         " bodies; this server allows " + std::to_string(limits.max_bodies) +
                         " per world (max_bodies)");
      }
      SceneBody sb;
      FULCRUM_RETURN_IF_ERROR(scene_body_from_proto(e.create_body(), path, &sb));
      size_t adding = sb.shapes.size();
      for (const ChainDef& c : sb.chains) adding += chain_segment_count(c);
      FULCRUM_RETURN_IF_ERROR(
          check_new_shapes(limits, w->shape_count(), sb.def.type, 0, adding, path + ".shapes"));
      // The engine names its definitions ("body.", "shape.", "chain."); the proto's Body holds
      // the body's fields itself and its shapes and chains in lists.
      Result<BodyId> id = w->create_body(sb.def);
      if (!id.ok()) return renamed(id.status(), "body.", "");
      out->bodies.push_back(*id);
      for (size_t j = 0; j < sb.shapes.size(); ++j) {
        Result<ShapeId> sid = w->create_shape(*id, sb.shapes[j]);
        if (!sid.ok()) return renamed(sid.status(), "shape", "shapes[" + std::to_string(j) + "]");
        out->shapes.push_back(*sid);
      }
      for (size_t j = 0; j < sb.chains.size(); ++j) {
        auto ids = w->create_chain(*id, sb.chains[j]);
        if (!ids.ok()) return renamed(ids.status(), "chain", "chains[" + std::to_string(j) + "]");
        out->shapes.insert(out->shapes.end(), ids->begin(), ids->end());
      }
      return {};
    }
    case v1::Edit::kDestroyBody:
      return w->destroy_body(body(e.destroy_body()));
    case v1::Edit::kCreateShape: {
      ShapeDef def;
      FULCRUM_RETURN_IF_ERROR(
          scene_shape_from_proto(e.create_shape().shape(), path + ".shape", &def));
      if (limits.max_shapes > 0 || limits.max_shapes_per_body > 0) {
        Result<BodyState> on = w->body_state(body(e.create_shape().body()));
        Result<int> count = w->body_shape_count(body(e.create_shape().body()));
        if (on.ok() && count.ok()) {  // a stale handle is refused by create_shape below
          FULCRUM_RETURN_IF_ERROR(
              check_new_shapes(limits, w->shape_count(), on->type, *count, 1, path + ".shape"));
        }
      }
      Result<ShapeId> id = w->create_shape(body(e.create_shape().body()), def);
      if (!id.ok()) return id.status();
      out->shapes.push_back(*id);
      return {};
    }
    case v1::Edit::kDestroyShape:
      return w->destroy_shape(shape(e.destroy_shape()));
    case v1::Edit::kCreateJoint: {
      const v1::CreateJoint& c = e.create_joint();
      if (c.joint().has_target()) {
        TargetJointDef def;
        FULCRUM_RETURN_IF_ERROR(target_joint_from_proto(c.joint(), path + ".joint", &def));
        def.body_a = body(c.body_a());
        def.body_b = body(c.body_b());
        Result<JointId> id = w->create_target_joint(def);
        if (!id.ok()) return id.status();
        out->joints.push_back(*id);
        return {};
      }
      v1::Joint j = c.joint();  // the scene form, between "body 0" and "body 1"
      j.set_body_a(0);
      j.set_body_b(1);
      SceneJoint sj;
      FULCRUM_RETURN_IF_ERROR(scene_joint_from_proto(j, path + ".joint", 2, &sj));
      Result<JointId> id = create_scene_joint(*w, sj, body(c.body_a()), body(c.body_b()));
      if (!id.ok()) return id.status();
      out->joints.push_back(*id);
      return {};
    }
    case v1::Edit::kDestroyJoint:
      return w->destroy_joint(joint(e.destroy_joint()));
    case v1::Edit::kSetTransform: {
      const v1::SetTransform& t = e.set_transform();
      return w->set_transform(body(t.body()), get(t.position()), t.angle());
    }
    case v1::Edit::kSetVelocity: {
      const v1::SetVelocity& v = e.set_velocity();
      // Both checked (validation.h, the engine's rules) before either is set, so one edit
      // never half-applies.
      FULCRUM_RETURN_IF_ERROR(check_finite("linear", get(v.linear())));
      FULCRUM_RETURN_IF_ERROR(check_finite("angular", v.angular()));
      FULCRUM_RETURN_IF_ERROR(w->set_linear_velocity(body(v.body()), get(v.linear())));
      return w->set_angular_velocity(body(v.body()), v.angular());
    }
    case v1::Edit::kApplyForce: {
      const v1::ApplyForce& f = e.apply_force();
      return f.has_point() ? w->apply_force(body(f.body()), get(f.force()), get(f.point()))
                           : w->apply_force_to_center(body(f.body()), get(f.force()));
    }
    case v1::Edit::kApplyImpulse: {
      const v1::ApplyImpulse& i = e.apply_impulse();
      FULCRUM_RETURN_IF_ERROR(check_finite("angular_impulse", i.angular_impulse()));
      Result<BodyState> state = w->body_state(body(i.body()));
      if (!state.ok()) return state.status();
      Vec2 point = i.has_point() ? get(i.point()) : state->center;
      FULCRUM_RETURN_IF_ERROR(w->apply_linear_impulse(body(i.body()), get(i.impulse()), point));
      if (i.angular_impulse() != 0.0) {
        return w->apply_angular_impulse(body(i.body()), i.angular_impulse());
      }
      return {};
    }
    case v1::Edit::kApplyTorque:
      return w->apply_torque(body(e.apply_torque().body()), e.apply_torque().torque());
    case v1::Edit::kSetMaterial: {
      const v1::SetMaterial& m = e.set_material();
      return w->set_shape_material(shape(m.shape()), m.friction(), m.restitution());
    }
    case v1::Edit::kSetFilter:
      return w->set_shape_filter(shape(e.set_filter().shape()),
                                 scene_filter_from_proto(e.set_filter().filter()));
    case v1::Edit::kSetMotor:
      FULCRUM_RETURN_IF_ERROR(check_finite("speed", e.set_motor().speed()));
      return w->set_motor_speed(joint(e.set_motor().joint()), e.set_motor().speed());
    case v1::Edit::kSetJointTarget:
      return w->set_joint_target(joint(e.set_joint_target().joint()),
                                 get(e.set_joint_target().target()));
    case v1::Edit::kSetGravity: {
      // The edit is the gravity vector itself.
      if (!is_finite(get(e.set_gravity()))) {
        return invalid_argument("must be finite (got " + text(e.set_gravity()) + ")");
      }
      WorldSettings s = w->settings();
      s.gravity = get(e.set_gravity());
      return renamed(w->set_settings(s), "settings.gravity", "");
    }
    case v1::Edit::kSetSettings: {
      // The edit is a WorldSettings message: the engine's "settings.dt" is its field "dt".
      WorldSettings s = w->settings();
      FULCRUM_RETURN_IF_ERROR(world_settings_from_proto(e.set_settings(), path, &s));
      return renamed(w->set_settings(s), "settings.", "");
    }
    case v1::Edit::kSetAwake:
      return w->set_awake(body(e.set_awake().body()), e.set_awake().awake());
    case v1::Edit::kSetConstantForce: {
      const v1::SetConstantForce& f = e.set_constant_force();
      return w->set_constant_force(body(f.body()), get(f.force()), f.torque());
    }
    case v1::Edit::kSetAttractors: {
      const v1::SetAttractors& a = e.set_attractors();
      std::vector<AttractorDef> list(a.attractors_size());
      for (int i = 0; i < a.attractors_size(); ++i) {
        FULCRUM_RETURN_IF_ERROR(scene_attractor_from_proto(
            a.attractors(i), path + ".attractors[" + std::to_string(i) + "]", &list[i]));
      }
      return w->set_attractors(list);
    }
    case v1::Edit::KIND_NOT_SET:
      break;
  }
  return invalid_argument("no edit given (set exactly one of its kinds)");
}

// "edits[3].set_velocity" + ".linear: ..." when the message starts with a field path, or
// + ": ..." when it is a sentence ("body {3, 1} is stale", "no edit given").
Status located(const Status& s, const std::string& path) {
  const std::string& m = s.message();
  if (m.rfind(path, 0) == 0) return s;  // already names the path
  const size_t head_end = m.find_first_of(".:[ ");
  const bool field_first = head_end != std::string::npos && head_end > 0 && m[head_end] != ' ' &&
                           (m[0] >= 'a' && m[0] <= 'z') &&
                           m.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_") == head_end;
  return Status(s.code(), path + (field_first ? "." : ": ") + m);
}

}  // namespace

Result<EditOutcome> apply_edit_batch(World* world, const v1::EditBatch& batch, size_t max_edits) {
  EditLimits limits;
  limits.max_edits = max_edits;
  return apply_edit_batch(world, batch, limits);
}

Result<EditOutcome> apply_edit_batch(World* world, const v1::EditBatch& batch,
                                     const EditLimits& limits) {
  if (batch.edits_size() == 0) return invalid_argument("edits: the batch is empty");
  if (static_cast<size_t>(batch.edits_size()) > limits.max_edits) {
    return Status(StatusCode::kResourceExhausted,
                  "edits: " + std::to_string(batch.edits_size()) + " edits, at most " +
                      std::to_string(limits.max_edits) + " per batch (max_edits)");
  }
  // Scene indices are for edit scripts, whose readers resolve them; a world does not know
  // which of its bodies came from a scene.
  for (int i = 0; i < batch.edits_size(); ++i) {
    Status st = for_each_handle(batch.edits(i), [&](const v1::Handle& h, HandleKind,
                                                    const char* field) {
      if (!h.has_scene_index()) return Status();
      return invalid_argument("edits[" + std::to_string(i) + "]." + field +
                              ".scene_index: only edit scripts name bodies by scene index "
                              "(fulcrum sim or replay record --edits resolve it); give the handle");
    });
    if (!st.ok()) return st;
  }
  WorldSnapshot before = world->snapshot();
  const uint64_t work_before = world->edit_work();
  EditOutcome out;
  auto refuse = [&](const Status& st) -> Result<EditOutcome> {
    // The snapshot came from this world a moment ago; putting it back cannot fail.
    Status back = world->restore(before);
    (void)back;
    return st;
  };
  for (int i = 0; i < batch.edits_size(); ++i) {
    const v1::Edit& e = batch.edits(i);
    std::string path = "edits[" + std::to_string(i) + "]";
    if (limits.keep_going && i % 64 == 0) {  // asking may cost more than an edit
      if (Status go = limits.keep_going(); !go.ok()) {
        return refuse(go.with_prefix("stopped before " + path + ", nothing applied: "));
      }
    }
    if (e.kind_case() != v1::Edit::KIND_NOT_SET) {
      path += "." + std::string(e.GetDescriptor()->FindFieldByNumber(e.kind_case())->name());
    }
    Status st = apply_one(world, e, path, limits, &out);
    if (!st.ok()) return refuse(located(st, path));
    const uint64_t work = world->edit_work() - work_before;
    if (limits.max_work > 0 && work > limits.max_work) {
      return refuse(exhausted(
          path + ": the batch's edits up to here did " + std::to_string(work) +
          " units of work (shapes created, broad-phase boxes their wake queries visited); this "
          "server allows " +
          std::to_string(limits.max_work) +
          " per batch (max_batch_work). Shapes that overlap many others cost the most."));
    }
  }
  return out;
}

SceneHandles scene_handles(const World& built) {
  return SceneHandles{built.bodies(), built.joints()};
}

Result<v1::EditScript> load_edit_script(const std::string& path, const EditScriptOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return not_found(path + ": cannot open the edit script");
  std::ostringstream text;
  text << in.rdbuf();
  v1::EditScript script;
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = false;
  auto status = google::protobuf::util::JsonStringToMessage(text.str(), &script, parse);
  if (!status.ok()) return invalid_argument(path + ": " + std::string(status.message()));
  for (int i = 0; i < script.entries_size(); ++i) {
    const std::string entry = path + ": entries[" + std::to_string(i) + "]";
    const int64_t tick = script.entries(i).tick();
    if (tick < 0) return invalid_argument(entry + ".tick: must be >= 0");
    if (options.end_tick >= 0 && tick >= options.end_tick) {
      return invalid_argument(entry + ".tick: " + std::to_string(tick) +
                              " is not before the run's end at tick " +
                              std::to_string(options.end_tick) +
                              ": a batch applies before the step from its tick, so this one would "
                              "never apply");
    }
    if (options.scene == nullptr) continue;
    v1::EditBatch* batch = script.mutable_entries(i)->mutable_batch();
    for (int j = 0; j < batch->edits_size(); ++j) {
      // The handles belong to `script`, which is not const: resolving may write them.
      FULCRUM_RETURN_IF_ERROR(for_each_handle(
          batch->edits(j), [&](const v1::Handle& h, HandleKind kind, const char* field) {
            return resolve_scene_index(h, kind,
                                       entry + ".batch.edits[" + std::to_string(j) + "]." + field,
                                       *options.scene);
          }));
    }
  }
  std::stable_sort(
      script.mutable_entries()->begin(), script.mutable_entries()->end(),
      [](const v1::TimedEdits& a, const v1::TimedEdits& b) { return a.tick() < b.tick(); });
  return script;
}

}  // namespace fulcrum
