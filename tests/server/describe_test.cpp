// DescribeWorld through the client library against the server in-process: a scene with every
// shape kind and two joints comes back exactly as the scene built it, the description follows
// edits that create and destroy bodies and drag joints, and an unknown world is NOT_FOUND.
#include <gtest/gtest.h>

#include <string>
#include <variant>

#include "fulcrum/client.h"
#include "fulcrum/scene.h"
#include "scene_convert.h"
#include "server.h"

namespace fulcrum {
namespace {

using server::Server;
using server::ServerOptions;

// One body of each kind of shape: a static ground box with a chain and a segment, a circle
// with user data, a rounded polygon, a capsule on a revolute joint to it, and a distance joint.
constexpr const char* kScene = R"({
  "name": "describe",
  "bodies": [
    {"type": "BODY_TYPE_STATIC", "userData": "7",
     "shapes": [{"box": {"halfWidth": 20, "halfHeight": 0.5, "center": {"x": 0, "y": -0.5}}},
                {"segment": {"point1": {"x": -20, "y": 8}, "point2": {"x": -15, "y": 3}}}],
     "chains": [{"points": [{"x": 15, "y": 0}, {"x": 18, "y": 2}, {"x": 20, "y": 6}],
                 "friction": 0.3, "userData": "9"}]},
    {"type": "BODY_TYPE_DYNAMIC", "position": {"x": -3, "y": 2}, "userData": "42",
     "shapes": [{"circle": {"center": {"x": 0.25, "y": 0}, "radius": 0.75}, "density": 2,
                 "filter": {"categoryBits": "2", "maskBits": "5", "groupIndex": -3}}]},
    {"type": "BODY_TYPE_DYNAMIC", "position": {"x": 1, "y": 3}, "angle": 0.5,
     "shapes": [{"polygon": {"vertices": [{"x": -1, "y": -0.5}, {"x": 1, "y": -0.5},
                                           {"x": 0.5, "y": 0.5}, {"x": -0.5, "y": 0.5}],
                             "radius": 0.1}, "friction": 0.9, "restitution": 0.2}]},
    {"type": "BODY_TYPE_DYNAMIC", "position": {"x": 4, "y": 3}, "linearDamping": 0.5,
     "gravityScale": 0.5, "fixedRotation": true,
     "shapes": [{"capsule": {"center1": {"x": -0.6, "y": 0}, "center2": {"x": 0.6, "y": 0},
                             "radius": 0.3}, "isSensor": false}]}
  ],
  "joints": [
    {"bodyA": 2, "bodyB": 3, "localAnchorA": {"x": 1.5, "y": 0}, "localAnchorB": {"x": -1.5, "y": 0},
     "revolute": {}},
    {"bodyA": 0, "bodyB": 1, "localAnchorA": {"x": -3, "y": 6}, "localAnchorB": {"x": 0, "y": 0.5},
     "collideConnected": true, "distance": {"length": 3.5, "minLength": 0}}
  ]
})";

class DescribeWorldTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.listen = "127.0.0.1:0";
    auto started = Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    client::ClientOptions copts;
    copts.address = server_->address();
    client_ = client::Client::connect(copts);
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<client::Client> client_;
};

Vec2 vec(const v1::Vec2& v) {
  return Vec2(v.x(), v.y());
}

// Bit-for-bit equality: the description is read from the engine's own doubles.
void expect_same(const Vec2& a, const Vec2& b, const std::string& what) {
  EXPECT_EQ(a.x(), b.x()) << what;
  EXPECT_EQ(a.y(), b.y()) << what;
}

// The described shape is the engine's geometry from the scene, field for field.
void expect_same_geometry(const Geometry& want, const v1::Shape& got, const std::string& what) {
  if (const auto* c = std::get_if<Circle>(&want)) {
    ASSERT_TRUE(got.has_circle()) << what;
    expect_same(c->center, vec(got.circle().center()), what + ".center");
    EXPECT_EQ(c->radius, got.circle().radius()) << what;
  } else if (const auto* cap = std::get_if<Capsule>(&want)) {
    ASSERT_TRUE(got.has_capsule()) << what;
    expect_same(cap->center1, vec(got.capsule().center1()), what + ".center1");
    expect_same(cap->center2, vec(got.capsule().center2()), what + ".center2");
    EXPECT_EQ(cap->radius, got.capsule().radius()) << what;
  } else if (const auto* s = std::get_if<Segment>(&want)) {
    ASSERT_TRUE(got.has_segment()) << what;
    expect_same(s->point1, vec(got.segment().point1()), what + ".point1");
    expect_same(s->point2, vec(got.segment().point2()), what + ".point2");
  } else if (const auto* p = std::get_if<Polygon>(&want)) {
    ASSERT_TRUE(got.has_polygon()) << what;
    ASSERT_EQ(got.polygon().vertices_size(), p->count) << what;
    for (int i = 0; i < p->count; ++i) {
      expect_same(p->vertices[i], vec(got.polygon().vertices(i)), what + ".vertices");
    }
    EXPECT_EQ(p->radius, got.polygon().radius()) << what;
  }
}

TEST_F(DescribeWorldTest, ShapesAndJointsMatchTheScene) {
  Result<SceneDef> scene = parse_scene_json(kScene);
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  Result<client::WorldSummary> made = client_->create_world_json(kScene);
  ASSERT_TRUE(made.ok()) << made.status().message();
  ASSERT_TRUE(client_->step(made->id, 3).ok());

  Result<v1::DescribeWorldReply> d = client_->describe_world(made->id);
  ASSERT_TRUE(d.ok()) << d.status().message();
  Result<client::WorldSummary> info = client_->get_world(made->id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(d->world_id(), made->id);
  EXPECT_EQ(d->tick(), 3);
  EXPECT_EQ(d->state_hash(), info->state_hash);

  ASSERT_EQ(d->bodies_size(), static_cast<int>(scene->bodies.size()));
  for (int i = 0; i < d->bodies_size(); ++i) {
    const SceneBody& want = scene->bodies[i];
    const v1::DescribedBody& got = d->bodies(i);
    const std::string where = "bodies[" + std::to_string(i) + "]";
    EXPECT_EQ(got.handle().index(), made->bodies[i].index) << where;
    EXPECT_EQ(got.handle().generation(), made->bodies[i].generation) << where;
    EXPECT_EQ(got.body().type(), static_cast<v1::BodyType>(want.def.type)) << where;
    EXPECT_EQ(got.body().user_data(), want.def.user_data) << where;
    EXPECT_EQ(got.body().linear_damping(), want.def.linear_damping) << where;
    EXPECT_EQ(got.body().gravity_scale(), want.def.gravity_scale) << where;
    EXPECT_EQ(got.body().fixed_rotation(), want.def.fixed_rotation) << where;
    EXPECT_TRUE(got.body().chains().empty()) << where;
    // Shapes in creation order: the body's own, then each chain's segments.
    std::vector<ShapeDef> shapes = want.shapes;
    for (const ChainDef& c : want.chains) {
      for (size_t k = 0; k + 1 < c.points.size(); ++k) {
        ShapeDef s;
        s.geometry = Segment{c.points[k], c.points[k + 1]};
        s.density = 0.0;
        s.friction = c.friction;
        s.restitution = c.restitution;
        s.filter = c.filter;
        s.user_data = c.user_data;
        shapes.push_back(s);
      }
    }
    ASSERT_EQ(got.body().shapes_size(), static_cast<int>(shapes.size())) << where;
    ASSERT_EQ(got.shapes_size(), got.body().shapes_size()) << where;
    for (size_t k = 0; k < shapes.size(); ++k) {
      const v1::Shape& s = got.body().shapes(static_cast<int>(k));
      const std::string what = where + ".shapes[" + std::to_string(k) + "]";
      expect_same_geometry(shapes[k].geometry, s, what);
      if (!std::holds_alternative<Segment>(shapes[k].geometry)) {
        EXPECT_EQ(s.density(), shapes[k].density) << what;
      }
      EXPECT_EQ(s.friction(), shapes[k].friction) << what;
      EXPECT_EQ(s.restitution(), shapes[k].restitution) << what;
      EXPECT_EQ(s.filter().category_bits(), shapes[k].filter.category_bits) << what;
      EXPECT_EQ(s.filter().mask_bits(), shapes[k].filter.mask_bits) << what;
      EXPECT_EQ(s.filter().group_index(), shapes[k].filter.group_index) << what;
      EXPECT_EQ(s.user_data(), shapes[k].user_data) << what;
    }
  }
  // The static ground has not moved; its position and angle are the scene's.
  expect_same(vec(d->bodies(0).body().position()), Vec2::Zero(), "ground position");
  EXPECT_EQ(d->bodies(0).body().angle(), 0.0);

  ASSERT_EQ(d->joints_size(), 2);
  const v1::DescribedJoint& pin = d->joints(0);
  EXPECT_EQ(pin.type(), v1::JOINT_TYPE_REVOLUTE);
  EXPECT_EQ(pin.handle().index(), made->joints[0].index);
  EXPECT_EQ(pin.body_a().index(), made->bodies[2].index);
  EXPECT_EQ(pin.body_b().index(), made->bodies[3].index);
  expect_same(vec(pin.local_anchor_a()), Vec2(1.5, 0), "revolute anchor a");
  expect_same(vec(pin.local_anchor_b()), Vec2(-1.5, 0), "revolute anchor b");
  const v1::DescribedJoint& rope = d->joints(1);
  EXPECT_EQ(rope.type(), v1::JOINT_TYPE_DISTANCE);
  EXPECT_TRUE(rope.collide_connected());
  expect_same(vec(rope.local_anchor_a()), Vec2(-3, 6), "distance anchor a");
  // Body A is the static ground at the origin: its world anchor is its local one.
  expect_same(vec(rope.anchor_a()), Vec2(-3, 6), "distance world anchor a");
}

TEST_F(DescribeWorldTest, FollowsEditsThatCreateAndDestroyBodiesAndDragJoints) {
  Result<client::WorldSummary> made = client_->create_world_json(kScene);
  ASSERT_TRUE(made.ok()) << made.status().message();

  v1::EditBatch create;
  v1::Body* b = create.add_edits()->mutable_create_body();
  b->set_type(v1::BODY_TYPE_DYNAMIC);
  b->mutable_position()->set_x(-6);
  b->mutable_position()->set_y(5);
  b->set_user_data(1234);
  b->add_shapes()->mutable_circle()->set_radius(0.4);
  Result<client::EditResult> created = client_->apply_edits(made->id, create);
  ASSERT_TRUE(created.ok()) << created.status().message();
  ASSERT_EQ(created->bodies.size(), 1u);
  const BodyId ball = created->bodies[0];

  // A drag: a target joint from the static ground to the new ball, then moved.
  v1::EditBatch drag;
  v1::CreateJoint* cj = drag.add_edits()->mutable_create_joint();
  cj->mutable_body_a()->set_index(made->bodies[0].index);
  cj->mutable_body_a()->set_generation(made->bodies[0].generation);
  cj->mutable_body_b()->set_index(ball.index);
  cj->mutable_body_b()->set_generation(ball.generation);
  cj->mutable_joint()->mutable_target()->mutable_target()->set_x(-6);
  cj->mutable_joint()->mutable_target()->mutable_target()->set_y(5);
  Result<client::EditResult> dragged = client_->apply_edits(made->id, drag);
  ASSERT_TRUE(dragged.ok()) << dragged.status().message();
  ASSERT_EQ(dragged->joints.size(), 1u);
  v1::EditBatch move;
  v1::SetJointTarget* st = move.add_edits()->mutable_set_joint_target();
  st->mutable_joint()->set_index(dragged->joints[0].index);
  st->mutable_joint()->set_generation(dragged->joints[0].generation);
  st->mutable_target()->set_x(-5);
  st->mutable_target()->set_y(7);
  ASSERT_TRUE(client_->apply_edits(made->id, move).ok());

  Result<v1::DescribeWorldReply> d = client_->describe_world(made->id);
  ASSERT_TRUE(d.ok()) << d.status().message();
  ASSERT_EQ(d->bodies_size(), 5);
  const v1::DescribedBody& added = d->bodies(4);
  EXPECT_EQ(added.handle().index(), ball.index);
  EXPECT_EQ(added.body().user_data(), 1234u);
  ASSERT_EQ(added.body().shapes_size(), 1);
  EXPECT_EQ(added.body().shapes(0).circle().radius(), 0.4);
  ASSERT_EQ(d->joints_size(), 3);
  const v1::DescribedJoint& target = d->joints(2);
  EXPECT_EQ(target.type(), v1::JOINT_TYPE_TARGET);
  EXPECT_EQ(target.body_b().index(), ball.index);
  expect_same(vec(target.anchor_a()), Vec2(-5, 7), "target");

  // Destroying the ball takes its drag joint with it; destroying the circle body its rope.
  v1::EditBatch destroy;
  for (BodyId gone : {ball, made->bodies[1]}) {
    v1::Handle* h = destroy.add_edits()->mutable_destroy_body();
    h->set_index(gone.index);
    h->set_generation(gone.generation);
  }
  ASSERT_TRUE(client_->apply_edits(made->id, destroy).ok());
  d = client_->describe_world(made->id);
  ASSERT_TRUE(d.ok()) << d.status().message();
  ASSERT_EQ(d->bodies_size(), 3);
  for (const v1::DescribedBody& body : d->bodies()) {
    EXPECT_NE(body.handle().index(), ball.index);
    EXPECT_NE(body.handle().index(), made->bodies[1].index);
  }
  ASSERT_EQ(d->joints_size(), 1);
  EXPECT_EQ(d->joints(0).type(), v1::JOINT_TYPE_REVOLUTE);
}

TEST_F(DescribeWorldTest, ScenesRefuseTargetJoints) {
  Result<client::WorldSummary> made = client_->create_world_json(R"({
    "bodies": [{}, {"type": "BODY_TYPE_DYNAMIC", "shapes": [{"circle": {}}]}],
    "joints": [{"bodyA": 0, "bodyB": 1, "target": {}}]})");
  ASSERT_FALSE(made.ok());
  EXPECT_EQ(made.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(made.status().message().find("joints[0].target"), std::string::npos)
      << made.status().message();
}

// A drag joint's refusals name the field, and body A must be static (the target's frame).
TEST_F(DescribeWorldTest, BadDragJointsAreRefusedByField) {
  Result<client::WorldSummary> made = client_->create_world_json(kScene);
  ASSERT_TRUE(made.ok()) << made.status().message();
  auto drag = [&](int body_a, double hertz, bool anchor_a) {
    v1::EditBatch batch;
    v1::CreateJoint* cj = batch.add_edits()->mutable_create_joint();
    cj->mutable_body_a()->set_index(made->bodies[body_a].index);
    cj->mutable_body_a()->set_generation(made->bodies[body_a].generation);
    cj->mutable_body_b()->set_index(made->bodies[1].index);
    cj->mutable_body_b()->set_generation(made->bodies[1].generation);
    cj->mutable_joint()->mutable_target()->set_hertz(hertz);
    if (anchor_a) cj->mutable_joint()->mutable_local_anchor_a()->set_x(1);
    return client_->apply_edits(made->id, batch).status();
  };
  Status zero_hertz = drag(0, 0.0, false);
  EXPECT_EQ(zero_hertz.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(zero_hertz.message().find("edits[0].create_joint.joint.target.hertz"),
            std::string::npos)
      << zero_hertz.message();
  Status anchor = drag(0, 5.0, true);
  EXPECT_NE(anchor.message().find("joint.local_anchor_a"), std::string::npos) << anchor.message();
  Status dynamic_frame = drag(2, 5.0, false);
  EXPECT_EQ(dynamic_frame.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(dynamic_frame.message().find("must be a static body"), std::string::npos)
      << dynamic_frame.message();
  Result<v1::DescribeWorldReply> d = client_->describe_world(made->id);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->joints_size(), 2);  // the scene's; nothing was added
}

TEST_F(DescribeWorldTest, UnknownWorldIsNotFound) {
  Result<v1::DescribeWorldReply> d = client_->describe_world(77);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), StatusCode::kNotFound);
  EXPECT_NE(d.status().message().find("world_id"), std::string::npos) << d.status().message();
  EXPECT_NE(d.status().message().find("77"), std::string::npos) << d.status().message();
}

}  // namespace
}  // namespace fulcrum
