// Every refusal names the field at fault by its path in the request, as the proto spells it
// ("batch.edits[0].create_shape.shape.polygon.vertices[2]"). The test starts from valid
// requests that set every field they can (a scene of every shape and joint kind, one edit of
// each kind, each query), breaks one field at a time through protobuf reflection (NaN, huge,
// negative, zero, an unknown enum value, a cleared message), sends each broken request to the
// server in-process, and walks the request's descriptor along the path each refusal names:
// every component must be a field of the message before it, indexed only when repeated.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>
#include <google/protobuf/reflection.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/scene.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"
#include "server.h"
#include "stats.h"

namespace fulcrum {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;

// Empty when `path` names a field of `type` ("a.b[3].c"); else why not.
std::string walk(const Descriptor* type, const std::string& path) {
  size_t start = 0;
  while (start <= path.size()) {
    size_t end = path.find('.', start);
    if (end == std::string::npos) end = path.size();
    std::string part = path.substr(start, end - start);
    bool indexed = false;
    if (const size_t bracket = part.find('['); bracket != std::string::npos) {
      if (part.back() != ']') return "'" + part + "' is not name[index]";
      for (size_t i = bracket + 1; i + 1 < part.size(); ++i) {
        if (part[i] < '0' || part[i] > '9') return "'" + part + "' has a non-numeric index";
      }
      part.resize(bracket);
      indexed = true;
    }
    if (type == nullptr) return "'" + part + "' follows a field that is not a message";
    const FieldDescriptor* field = type->FindFieldByName(part);
    if (field == nullptr && end == path.size() && !indexed &&
        type->FindOneofByName(part) != nullptr) {
      return {};  // a oneof's name, for "set one of its members"
    }
    if (field == nullptr) return "'" + part + "' is not a field of " + type->full_name();
    if (indexed && !field->is_repeated()) return "'" + part + "' is indexed but not repeated";
    type = field->type() == FieldDescriptor::TYPE_MESSAGE ? field->message_type() : nullptr;
    start = end + 1;
  }
  return {};
}

TEST(FieldPaths, TheWalkerKnowsAFieldFromANonField) {
  const Descriptor* request = v1::ApplyEditsRequest::descriptor();
  EXPECT_EQ(walk(request, "batch.edits[0].create_shape.shape.polygon.vertices[2].x"), "");
  EXPECT_EQ(walk(request, "batch.edits"), "");
  EXPECT_NE(walk(request, "batch.edits[0].create_shape.polygon"), "");
  EXPECT_NE(walk(request, "batch.edits[0].set_gravity.settings.gravity"), "");
  EXPECT_NE(walk(request, "batch[0]"), "");
  EXPECT_NE(walk(request, "batch.edits[0].set_velocity.linear.x.y"), "");
}

// One broken copy of `prototype` per (present field, bad value), recursing into present
// messages (the first two elements of repeated ones).
void mutations(const Message& prototype, std::vector<std::pair<std::string, Message*>>* out,
               const std::function<Message*(const Message&)>& root_copy,
               const std::function<Message*(Message*)>& locate, const std::string& at, int depth) {
  if (depth > 8) return;
  const Reflection* r = prototype.GetReflection();
  std::vector<const FieldDescriptor*> fields;
  r->ListFields(prototype, &fields);
  for (const FieldDescriptor* f : fields) {
    const std::string name = at.empty() ? f->name() : at + "." + f->name();
    auto broken = [&](const std::string& what, const std::function<void(Message*)>& set) {
      Message* copy = root_copy(prototype);
      set(locate(copy));
      out->emplace_back(name + " = " + what, copy);
    };
    if (f->is_repeated()) {
      if (f->type() != FieldDescriptor::TYPE_MESSAGE) continue;
      broken("[]", [&](Message* m) { m->GetReflection()->ClearField(m, f); });
      const int n = std::min(r->FieldSize(prototype, f), 2);
      for (int i = 0; i < n; ++i) {
        const std::string element = name + "[" + std::to_string(i) + "]";
        mutations(
            r->GetRepeatedMessage(prototype, f, i), out, root_copy,
            [&, f, i](Message* root) {
              Message* m = locate(root);
              return m->GetReflection()->MutableRepeatedMessage(m, f, i);
            },
            element, depth + 1);
      }
      continue;
    }
    switch (f->cpp_type()) {
      case FieldDescriptor::CPPTYPE_MESSAGE:
        broken("unset", [&](Message* m) { m->GetReflection()->ClearField(m, f); });
        mutations(
            r->GetMessage(prototype, f), out, root_copy,
            [&, f](Message* root) {
              Message* m = locate(root);
              return m->GetReflection()->MutableMessage(m, f);
            },
            name, depth + 1);
        break;
      case FieldDescriptor::CPPTYPE_DOUBLE:
        for (double v : {std::nan(""), -1.0, 0.0, 1e300, -1e300}) {
          char text[32];
          std::snprintf(text, sizeof text, "%g", v);
          broken(text, [&](Message* m) { m->GetReflection()->SetDouble(m, f, v); });
        }
        break;
      case FieldDescriptor::CPPTYPE_INT32:
        for (int32_t v : {-1, 0, std::numeric_limits<int32_t>::max()}) {
          broken(std::to_string(v), [&](Message* m) { m->GetReflection()->SetInt32(m, f, v); });
        }
        break;
      case FieldDescriptor::CPPTYPE_INT64:
        for (int64_t v : {int64_t{-1}, std::numeric_limits<int64_t>::max()}) {
          broken(std::to_string(v), [&](Message* m) { m->GetReflection()->SetInt64(m, f, v); });
        }
        break;
      case FieldDescriptor::CPPTYPE_UINT32:
        for (uint32_t v : {0u, std::numeric_limits<uint32_t>::max()}) {
          broken(std::to_string(v), [&](Message* m) { m->GetReflection()->SetUInt32(m, f, v); });
        }
        break;
      case FieldDescriptor::CPPTYPE_UINT64:
        for (uint64_t v : {uint64_t{0}, std::numeric_limits<uint64_t>::max()}) {
          broken(std::to_string(v), [&](Message* m) { m->GetReflection()->SetUInt64(m, f, v); });
        }
        break;
      case FieldDescriptor::CPPTYPE_ENUM:
        broken("999", [&](Message* m) { m->GetReflection()->SetEnumValue(m, f, 999); });
        broken("0", [&](Message* m) { m->GetReflection()->SetEnumValue(m, f, 0); });
        break;
      case FieldDescriptor::CPPTYPE_BOOL:
        broken("flipped", [&](Message* m) {
          m->GetReflection()->SetBool(m, f, !m->GetReflection()->GetBool(*m, f));
        });
        break;
      case FieldDescriptor::CPPTYPE_STRING:
        broken("\"../x\"", [&](Message* m) { m->GetReflection()->SetString(m, f, "../x"); });
        break;
      default:
        break;
    }
  }
}

std::vector<std::pair<std::string, Message*>> all_mutations(const Message& request) {
  std::vector<std::pair<std::string, Message*>> out;
  mutations(
      request, &out,
      [&](const Message&) {
        Message* copy = request.New();
        copy->CopyFrom(request);
        return copy;
      },
      [](Message* root) { return root; }, "", 0);
  return out;
}

// A scene with every shape kind, a chain, and every joint kind with its options on.
v1::Scene rich_scene() {
  SceneDef scene;
  scene.settings.gravity = Vec2(0, -10);
  SceneBody ground;
  ground.def.type = BodyType::kStatic;
  ShapeDef seg;
  seg.geometry = Segment{Vec2(-20, 0), Vec2(20, 0)};
  seg.density = 0.0;
  ground.shapes.push_back(seg);
  ChainDef chain;
  chain.points = {Vec2(-20, 10), Vec2(-20, 0), Vec2(20, 0), Vec2(20, 10)};
  ground.chains.push_back(chain);
  scene.bodies.push_back(ground);
  for (int i = 0; i < 3; ++i) {
    SceneBody b;
    b.def.type = BodyType::kDynamic;
    b.def.position = Vec2(2.0 * i, 2.0);
    b.def.linear_velocity = Vec2(0.5, 0);
    b.def.angular_velocity = 0.1;
    b.def.linear_damping = 0.1;
    b.def.user_data = 7;
    ShapeDef circle;
    circle.geometry = Circle{Vec2(0, 0), 0.4};
    circle.density = 1.0;
    circle.filter.category_bits = 2;
    circle.filter.group_index = -1;
    ShapeDef capsule;
    capsule.geometry = Capsule{Vec2(-0.3, 0), Vec2(0.3, 0), 0.2};
    capsule.density = 1.0;
    ShapeDef box;
    box.geometry = make_box(0.5, 0.25);
    box.density = 2.0;
    box.friction = 0.4;
    box.restitution = 0.1;
    b.shapes = {circle, capsule, box};
    scene.bodies.push_back(b);
  }
  DistanceJointDef distance;
  distance.length = distance.min_length = 1.0;
  distance.max_length = 2.0;
  distance.hertz = 2.0;
  distance.damping_ratio = 0.5;
  RevoluteJointDef revolute;
  revolute.enable_limit = revolute.enable_motor = revolute.enable_spring = true;
  revolute.lower_angle = -0.5;
  revolute.upper_angle = 0.5;
  revolute.max_motor_torque = 10.0;
  revolute.hertz = 1.0;
  PrismaticJointDef prismatic;
  prismatic.enable_limit = prismatic.enable_motor = prismatic.enable_spring = true;
  prismatic.lower_translation = -1.0;
  prismatic.upper_translation = 1.0;
  prismatic.max_motor_force = 10.0;
  prismatic.hertz = 1.0;
  WheelJointDef wheel;
  wheel.enable_limit = wheel.enable_motor = true;
  wheel.lower_translation = -0.2;
  wheel.upper_translation = 0.2;
  wheel.max_motor_torque = 5.0;
  WeldJointDef weld;
  weld.linear_hertz = weld.angular_hertz = 3.0;
  MotorJointDef motor;
  scene.joints.push_back({1, 2, distance});
  scene.joints.push_back({2, 3, revolute});
  scene.joints.push_back({1, 3, prismatic});
  scene.joints.push_back({0, 1, wheel});
  scene.joints.push_back({0, 2, weld});
  scene.joints.push_back({0, 3, motor});
  return scene_to_proto(scene, "rich");
}

class FieldPathsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server::ServerOptions options;
    options.listen = "127.0.0.1:0";
    auto started = server::Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    stub_ = v1::Physics::NewStub(
        grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()));
  }

  // A fresh world of the rich scene; handles of its bodies, shapes and joints.
  uint64_t fresh_world(v1::CreateWorldReply* reply) {
    v1::CreateWorldRequest request;
    *request.mutable_scene() = rich_scene();
    grpc::ClientContext context;
    grpc::Status s = stub_->CreateWorld(&context, request, reply);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return reply->world_id();
  }

  // Checks one refusal of a request of `type`; records what it saw.
  void check(const Descriptor* type, const std::string& broken, const grpc::Status& status) {
    if (status.ok()) return;
    ++refusals_;
    const std::string field = server::field_of(status.error_message());
    if (field.empty()) {
      unnamed_.insert(status.error_message());
      return;
    }
    const std::string why = walk(type, field);
    EXPECT_EQ(why, "") << "after " << broken << ": \"" << status.error_message() << "\"";
  }

  std::string unnamed_text() const {
    std::string out = "refusals that name no field:";
    for (const std::string& m : unnamed_) out += "\n  " + m;
    return out;
  }

  std::unique_ptr<server::Server> server_;
  std::unique_ptr<v1::Physics::Stub> stub_;
  int refusals_ = 0;
  std::set<std::string> unnamed_;
};

TEST_F(FieldPathsTest, CreateWorldRefusalsNameRealFields) {
  v1::CreateWorldRequest request;
  *request.mutable_scene() = rich_scene();
  for (auto& [broken, message] : all_mutations(request)) {
    std::unique_ptr<Message> owned(message);
    v1::CreateWorldReply reply;
    grpc::ClientContext context;
    grpc::Status status =
        stub_->CreateWorld(&context, static_cast<const v1::CreateWorldRequest&>(*owned), &reply);
    check(v1::CreateWorldRequest::descriptor(), broken, status);
    if (status.ok()) {
      v1::DeleteWorldRequest del;
      del.set_world_id(reply.world_id());
      v1::DeleteWorldReply gone;
      grpc::ClientContext c2;
      ASSERT_TRUE(stub_->DeleteWorld(&c2, del, &gone).ok());
    }
  }
  EXPECT_GT(refusals_, 100);
  EXPECT_TRUE(unnamed_.empty()) << unnamed_text();
}

// One valid edit of each kind on the rich world.
std::vector<v1::Edit> edit_templates(const v1::CreateWorldReply& world) {
  (void)world;
  auto handle = [](v1::Handle* h, int32_t index) {
    h->set_index(index);
    h->set_generation(1);
  };
  std::vector<v1::Edit> edits;
  v1::Scene scene = rich_scene();
  v1::Edit e;
  *e.mutable_create_body() = scene.bodies(1);
  edits.push_back(e);
  e.Clear();
  *e.mutable_create_body() = scene.bodies(0);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_destroy_body(), 1);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_create_shape()->mutable_body(), 2);
  *e.mutable_create_shape()->mutable_shape() = scene.bodies(1).shapes(2);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_destroy_shape(), 4);
  edits.push_back(e);
  for (int j = 0; j < scene.joints_size(); ++j) {
    e.Clear();
    handle(e.mutable_create_joint()->mutable_body_a(), 1);
    handle(e.mutable_create_joint()->mutable_body_b(), 2);
    *e.mutable_create_joint()->mutable_joint() = scene.joints(j);
    edits.push_back(e);
  }
  e.Clear();
  handle(e.mutable_destroy_joint(), 0);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_transform()->mutable_body(), 1);
  e.mutable_set_transform()->mutable_position()->set_x(1);
  e.mutable_set_transform()->set_angle(0.5);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_velocity()->mutable_body(), 1);
  e.mutable_set_velocity()->mutable_linear()->set_x(1);
  e.mutable_set_velocity()->set_angular(0.5);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_apply_force()->mutable_body(), 1);
  e.mutable_apply_force()->mutable_force()->set_x(1);
  e.mutable_apply_force()->mutable_point()->set_y(1);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_apply_impulse()->mutable_body(), 1);
  e.mutable_apply_impulse()->mutable_impulse()->set_x(1);
  e.mutable_apply_impulse()->mutable_point()->set_y(1);
  e.mutable_apply_impulse()->set_angular_impulse(0.5);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_apply_torque()->mutable_body(), 1);
  e.mutable_apply_torque()->set_torque(2);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_material()->mutable_shape(), 3);
  e.mutable_set_material()->set_friction(0.3);
  e.mutable_set_material()->set_restitution(0.2);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_filter()->mutable_shape(), 3);
  e.mutable_set_filter()->mutable_filter()->set_category_bits(4);
  e.mutable_set_filter()->mutable_filter()->set_mask_bits(5);
  e.mutable_set_filter()->mutable_filter()->set_group_index(-2);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_motor()->mutable_joint(), 1);
  e.mutable_set_motor()->set_speed(1.0);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_joint_target()->mutable_joint(), 5);
  e.mutable_set_joint_target()->mutable_target()->set_x(1);
  edits.push_back(e);
  e.Clear();
  e.mutable_set_gravity()->set_y(-9);
  edits.push_back(e);
  e.Clear();
  *e.mutable_set_settings() = scene.settings();
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_awake()->mutable_body(), 1);
  e.mutable_set_awake()->set_awake(false);
  edits.push_back(e);
  e.Clear();
  handle(e.mutable_set_constant_force()->mutable_body(), 1);
  e.mutable_set_constant_force()->mutable_force()->set_x(2);
  e.mutable_set_constant_force()->set_torque(0.5);
  edits.push_back(e);
  e.Clear();
  v1::Attractor* pull = e.mutable_set_attractors()->add_attractors();
  pull->mutable_point()->set_y(3);
  pull->set_strength(5);
  pull->set_min_distance(1);
  edits.push_back(e);
  return edits;
}

TEST_F(FieldPathsTest, ApplyEditsRefusalsNameRealFields) {
  v1::CreateWorldReply world;
  uint64_t id = fresh_world(&world);
  for (const v1::Edit& edit : edit_templates(world)) {
    v1::ApplyEditsRequest request;
    request.set_world_id(id);
    *request.mutable_batch()->add_edits() = edit;
    request.mutable_batch()->add_edits();  // an empty second edit: "no edit given"
    for (auto& [broken, message] : all_mutations(request)) {
      std::unique_ptr<Message> owned(message);
      auto& mutated = static_cast<v1::ApplyEditsRequest&>(*owned);
      mutated.set_world_id(id);
      v1::ApplyEditsReply reply;
      grpc::ClientContext context;
      check(v1::ApplyEditsRequest::descriptor(), broken,
            stub_->ApplyEdits(&context, mutated, &reply));
      // The batch always fails at its empty second edit, so the world never changes.
    }
  }
  EXPECT_GT(refusals_, 300);
  EXPECT_TRUE(unnamed_.empty()) << unnamed_text();
}

TEST_F(FieldPathsTest, OtherCallsRefusalsNameRealFields) {
  v1::CreateWorldReply world;
  const uint64_t id = fresh_world(&world);
  auto run = [&](const Message& request, const std::function<grpc::Status(const Message&)>& call) {
    for (auto& [broken, message] : all_mutations(request)) {
      std::unique_ptr<Message> owned(message);
      check(request.GetDescriptor(), broken, call(*owned));
    }
  };
  v1::StepRequest step;
  step.set_world_id(id);
  step.set_ticks(1);
  step.set_expected_tick(0);
  run(step, [&](const Message& m) {
    v1::StepReply reply;
    grpc::ClientContext context;
    return stub_->Step(&context, static_cast<const v1::StepRequest&>(m), &reply);
  });
  for (int kind = 0; kind < 3; ++kind) {
    v1::QueryRequest query;
    query.set_world_id(id);
    query.mutable_filter()->set_category_bits(1);
    query.mutable_filter()->set_mask_bits(3);
    if (kind == 0) {
      query.mutable_ray_cast()->mutable_origin()->set_y(5);
      query.mutable_ray_cast()->mutable_translation()->set_y(-10);
      query.mutable_ray_cast()->set_all(true);
    } else if (kind == 1) {
      query.mutable_aabb()->mutable_lower()->set_x(-1);
      query.mutable_aabb()->mutable_upper()->set_x(1);
    } else {
      query.mutable_point()->mutable_point()->set_x(0.5);
    }
    run(query, [&](const Message& m) {
      v1::QueryReply reply;
      grpc::ClientContext context;
      return stub_->Query(&context, static_cast<const v1::QueryRequest&>(m), &reply);
    });
  }
  v1::SetRunModeRequest run_mode;
  run_mode.set_world_id(id);
  run_mode.set_mode(v1::RUN_MODE_PAUSED);
  run_mode.set_max_catch_up_ticks(5);
  run(run_mode, [&](const Message& m) {
    v1::SetRunModeReply reply;
    grpc::ClientContext context;
    return stub_->SetRunMode(&context, static_cast<const v1::SetRunModeRequest&>(m), &reply);
  });
  v1::GetSnapshotRequest get;
  get.set_world_id(id);
  v1::GetSnapshotReply snapshot;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(stub_->GetSnapshot(&context, get, &snapshot).ok());
  }
  v1::RestoreSnapshotRequest restore;
  restore.set_world_id(id);
  *restore.mutable_snapshot() = snapshot.snapshot();
  run(restore, [&](const Message& m) {
    v1::RestoreSnapshotReply reply;
    grpc::ClientContext context;
    return stub_->RestoreSnapshot(&context, static_cast<const v1::RestoreSnapshotRequest&>(m),
                                  &reply);
  });
  EXPECT_GT(refusals_, 20);
  EXPECT_TRUE(unnamed_.empty()) << unnamed_text();
}

// The refusals an outside client found wrong, as they read now.
TEST_F(FieldPathsTest, RefusalsSpellPathsAsTheProtoDoes) {
  v1::CreateWorldReply world;
  const uint64_t id = fresh_world(&world);
  auto refusal = [&](const std::function<void(v1::EditBatch*)>& fill) {
    v1::ApplyEditsRequest request;
    request.set_world_id(id);
    fill(request.mutable_batch());
    v1::ApplyEditsReply reply;
    grpc::ClientContext context;
    return stub_->ApplyEdits(&context, request, &reply).error_message();
  };
  EXPECT_EQ(
      refusal([](v1::EditBatch* b) { b->add_edits()->mutable_set_gravity()->set_x(std::nan("")); }),
      "batch.edits[0].set_gravity: must be finite (got (nan, 0))");
  EXPECT_EQ(refusal([](v1::EditBatch* b) {
              v1::SetVelocity* v = b->add_edits()->mutable_set_velocity();
              v->mutable_body()->set_index(1);
              v->mutable_body()->set_generation(1);
              v->set_angular(std::nan(""));
            }),
            "batch.edits[0].set_velocity.angular: must be finite (got nan)");
  EXPECT_EQ(refusal([](v1::EditBatch* b) {
              v1::CreateShape* c = b->add_edits()->mutable_create_shape();
              c->mutable_body()->set_index(1);
              c->mutable_body()->set_generation(1);
              c->mutable_shape()->mutable_polygon()->add_vertices();
            }).rfind("batch.edits[0].create_shape.shape.polygon", 0),
            0u);
  EXPECT_EQ(refusal([](v1::EditBatch* b) {
              b->add_edits()->mutable_set_gravity()->set_y(-9.8);
              b->add_edits();
            }),
            "batch.edits[1]: no edit given (set exactly one of its kinds)");
  const std::string joint = refusal([](v1::EditBatch* b) {
    v1::CreateJoint* c = b->add_edits()->mutable_create_joint();
    c->mutable_body_a()->set_index(1);
    c->mutable_body_a()->set_generation(1);
    c->mutable_body_b()->set_index(2);
    c->mutable_body_b()->set_generation(1);
    c->mutable_joint()->mutable_distance()->set_length(2.0);
    c->mutable_joint()->mutable_distance()->set_max_length(1.0);
  });
  EXPECT_EQ(joint.rfind("batch.edits[0].create_joint.joint.distance.max_length: ", 0), 0u) << joint;

  v1::RestoreSnapshotRequest restore;
  restore.set_world_id(id);
  restore.mutable_snapshot()->set_format("fulcrum.snapshot");
  restore.mutable_snapshot()->set_version(1);
  restore.mutable_snapshot()->set_payload("x");
  v1::RestoreSnapshotReply reply;
  grpc::ClientContext context;
  const std::string damaged = stub_->RestoreSnapshot(&context, restore, &reply).error_message();
  EXPECT_EQ(damaged.rfind("snapshot.checksum: ", 0), 0u) << damaged;
  EXPECT_EQ(damaged.find("snapshot: snapshot"), std::string::npos) << damaged;
}

}  // namespace
}  // namespace fulcrum
