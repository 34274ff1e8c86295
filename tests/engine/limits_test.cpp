// Work that grows with the input: a body's shapes cost linear time to add, edit work counts
// what overlapping shapes cost, the contact limit refuses a tick without changing anything,
// and build_world refuses scenes past its limits before (or while) building them.
#include <gtest/gtest.h>

#include <cmath>

#include "fulcrum/scene.h"
#include "fulcrum/state.h"
#include "fulcrum/world.h"

namespace fulcrum {
namespace {

ShapeDef circle(Vec2 center, double radius = 0.1) {
  ShapeDef def;
  def.geometry = Circle{center, radius};
  def.density = 1.0;
  return def;
}

BodyDef dynamic_at(Vec2 position) {
  BodyDef def;
  def.type = BodyType::kDynamic;
  def.position = position;
  return def;
}

// n dynamic one-circle bodies, all at the origin: n (n - 1) / 2 overlapping pairs.
World heap_of_circles(int n) {
  World w{WorldSettings{}};
  for (int i = 0; i < n; ++i) {
    BodyId b = w.create_body(dynamic_at(Vec2::Zero())).value();
    EXPECT_TRUE(w.create_shape(b, circle(Vec2::Zero(), 0.5)).ok());
  }
  return w;
}

// Mass is kept as running sums while shapes are added; restore recomputes the sums from the
// shapes. Both must give the same bits, or a restored world would drift from the original the
// next time a shape is added.
TEST(Limits, IncrementalMassEqualsARecomputation) {
  World a{WorldSettings{}};
  BodyId body = a.create_body(dynamic_at(Vec2(1, 2))).value();
  for (int i = 0; i < 50; ++i) {
    ASSERT_TRUE(a.create_shape(body, circle(Vec2(0.3 * i, 0.1 * (i % 7)), 0.05 + 0.01 * i)).ok());
  }
  World b{WorldSettings{}};
  ASSERT_TRUE(b.restore(a.snapshot()).ok());
  ASSERT_TRUE(a.create_shape(body, circle(Vec2(-1, 0.5), 0.2)).ok());
  ASSERT_TRUE(b.create_shape(body, circle(Vec2(-1, 0.5), 0.2)).ok());
  EXPECT_EQ(a.state_hash(), b.state_hash());
  // Destroying a shape recomputes from scratch; adding another afterwards must still agree.
  const ShapeId first = a.body_shapes(body).value()[3];
  ASSERT_TRUE(a.destroy_shape(first).ok());
  ASSERT_TRUE(b.destroy_shape(first).ok());
  ASSERT_TRUE(a.create_shape(body, circle(Vec2(2, -0.5), 0.3)).ok());
  ASSERT_TRUE(b.create_shape(body, circle(Vec2(2, -0.5), 0.3)).ok());
  EXPECT_EQ(a.state_hash(), b.state_hash());
  EXPECT_EQ(a.body_state(body)->mass, b.body_state(body)->mass);
  EXPECT_EQ(a.shape_count(), 51);
  EXPECT_EQ(a.body_shape_count(body).value(), 51);
}

// Shapes side by side cost a few units each; shapes on top of each other cost one unit per
// overlapping box, so the work is quadratic in their number, which is what servers bound.
TEST(Limits, EditWorkCountsOverlaps) {
  World spread{WorldSettings{}};
  BodyId body = spread.create_body(dynamic_at(Vec2::Zero())).value();
  const int n = 4000;
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(spread.create_shape(body, circle(Vec2((i % 100) * 0.5, (i / 100) * 0.5))).ok());
  }
  // One unit per shape plus its own box and at most its neighbours' fattened boxes.
  EXPECT_LE(spread.edit_work(), static_cast<uint64_t>(12 * n));
  EXPECT_GE(spread.edit_work(), static_cast<uint64_t>(2 * n));

  const int m = 300;
  World heap = heap_of_circles(m);
  // The k-th shape's wake query visits the k - 1 boxes before it and its own.
  EXPECT_GE(heap.edit_work(), static_cast<uint64_t>(m) * (m - 1) / 2);
}

// A tick whose broad phase would pass the contact limit does not run: the state hash, the
// tick and the moved-shape buffer stay as they were, so raising the limit lets the very same
// tick run as it would have without a limit. At two threads the pairs are found in chunks;
// the refusal must be the same.
TEST(Limits, ContactLimitRefusesATickAndChangesNothing) {
  for (int threads : {1, 2}) {
    const int n = 300;  // 44 850 overlapping pairs, above the 256 moved shapes of the chunks
    World limited = heap_of_circles(n);
    World unlimited = heap_of_circles(n);
    ASSERT_TRUE(limited.set_threads(threads).ok());
    ASSERT_TRUE(limited.set_contact_limit(1000).ok());
    const uint64_t before = limited.state_hash();
    Status refused = limited.try_step();
    EXPECT_EQ(refused.code(), StatusCode::kResourceExhausted);
    EXPECT_NE(refused.message().find("contact limit of 1000"), std::string::npos)
        << refused.message();
    EXPECT_EQ(limited.state_hash(), before);
    EXPECT_EQ(limited.tick(), 0);
    EXPECT_EQ(limited.metrics().contact_count, 0);

    ASSERT_TRUE(limited.set_contact_limit(n * (n - 1) / 2).ok());  // exactly enough
    ASSERT_TRUE(limited.try_step().ok());
    unlimited.step();
    EXPECT_EQ(limited.state_hash(), unlimited.state_hash()) << "threads " << threads;
    EXPECT_EQ(limited.tick(), 1);
  }
  World w{WorldSettings{}};
  EXPECT_EQ(w.set_contact_limit(-1).code(), StatusCode::kInvalidArgument);
}

TEST(Limits, BuildWorldRefusesScenesPastItsLimits) {
  SceneDef scene;
  SceneBody ground;
  ground.def.type = BodyType::kStatic;
  for (int i = 0; i < 40; ++i) ground.shapes.push_back(circle(Vec2(i, 0)));
  scene.bodies.push_back(ground);
  SceneBody wheel;
  wheel.def = dynamic_at(Vec2(0, 5));
  for (int i = 0; i < 20; ++i) wheel.shapes.push_back(circle(Vec2(0.1 * i, 0)));
  scene.bodies.push_back(wheel);

  WorkLimits limits;
  limits.max_shapes_per_body = 20;  // the static ground's 40 do not count
  EXPECT_TRUE(build_world(scene, limits).ok());
  limits.max_shapes_per_body = 19;
  Result<World> too_many = build_world(scene, limits);
  EXPECT_EQ(too_many.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(too_many.status().message().find("bodies[1].shapes: would put 20 shapes"),
            std::string::npos)
      << too_many.status().message();
  limits = {};
  limits.max_shapes = 59;
  EXPECT_NE(build_world(scene, limits).status().message().find("max_shapes"), std::string::npos);

  // 200 circles on one spot: about 20 000 units of work, refused at a limit of 5 000 while
  // building, before the quadratic rest.
  SceneDef heap;
  for (int i = 0; i < 200; ++i) {
    SceneBody b;
    b.def = dynamic_at(Vec2::Zero());
    b.shapes.push_back(circle(Vec2::Zero(), 0.5));
    heap.bodies.push_back(b);
  }
  limits = {};
  limits.max_work = 5000;
  Result<World> heavy = build_world(heap, limits);
  EXPECT_EQ(heavy.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(heavy.status().message().find("max_batch_work"), std::string::npos)
      << heavy.status().message();

  int asked = 0;
  limits = {};
  limits.keep_going = [&]() -> Status {
    return ++asked > 100 ? Status(StatusCode::kCancelled, "the call was cancelled") : Status();
  };
  EXPECT_EQ(build_world(heap, limits).status().code(), StatusCode::kCancelled);
  EXPECT_EQ(asked, 101);  // asked once per body, stopped at the 101st
}

// Finite is not enough: numbers beyond kMaxInputMagnitude (1e12) are refused wherever a user
// gives them, with the field and the rule named, and nothing changes. Before this rule a body at
// 1e308 m passed and turned the world to NaN within a tick.
TEST(Limits, NumbersBeyondTheInputMagnitudeAreRefused) {
  World w{WorldSettings{}};
  BodyId b = w.create_body(dynamic_at(Vec2(0, 1))).value();
  ASSERT_TRUE(w.create_shape(b, circle(Vec2::Zero(), 0.5)).ok());

  Result<BodyId> far = w.create_body(dynamic_at(Vec2(0, 1e308)));
  ASSERT_FALSE(far.ok());
  EXPECT_EQ(far.status().message(),
            "body.position: each coordinate must be at most 1e12 in magnitude (got (0, 1e+308))");
  // The bound itself is accepted, just past it is not.
  EXPECT_TRUE(w.set_transform(b, Vec2(-kMaxInputMagnitude, 1), 0).ok());
  ASSERT_TRUE(w.set_transform(b, Vec2(0, 1), 0).ok());
  const uint64_t after_moves = w.state_hash();
  EXPECT_FALSE(w.set_transform(b, Vec2(std::nextafter(kMaxInputMagnitude, 1e300), 0), 0).ok());
  const Status impulse = w.apply_linear_impulse(b, Vec2(1e300, 0), Vec2(0, 1));
  EXPECT_EQ(impulse.message(),
            "impulse: each coordinate must be at most 1e12 in magnitude (got "
            "(1.0000000000000001e+300, 0))");
  EXPECT_FALSE(w.apply_torque(b, -1e13).ok());
  EXPECT_FALSE(w.set_angular_velocity(b, 2e12).ok());
  EXPECT_EQ(w.state_hash(), after_moves);

  ShapeDef huge = circle(Vec2::Zero(), 1e13);
  const Status radius = w.create_shape(b, huge).status();
  EXPECT_EQ(radius.message(), "shape.circle.radius: must be at most 1e12 in magnitude (got 1e+13)");
  WorldSettings settings;
  settings.gravity = Vec2(0, -1e200);
  EXPECT_EQ(w.set_settings(settings).message(),
            "settings.gravity: each coordinate must be at most 1e12 in magnitude (got (0, "
            "-9.9999999999999997e+199))");
  EXPECT_EQ(w.state_hash(), after_moves);

  // Inside the bound the step stays finite: a body launched at the largest speed and spin it
  // may be given, under the largest gravity, far from the origin.
  World edge{WorldSettings{}};
  settings.gravity = Vec2(0, -kMaxInputMagnitude);
  ASSERT_TRUE(edge.set_settings(settings).ok());
  BodyDef def = dynamic_at(Vec2(kMaxInputMagnitude, -kMaxInputMagnitude));
  def.linear_velocity = Vec2(kMaxInputMagnitude, kMaxInputMagnitude);
  def.angular_velocity = -kMaxInputMagnitude;
  BodyId fast = edge.create_body(def).value();
  ASSERT_TRUE(edge.create_shape(fast, circle(Vec2::Zero(), kMaxInputMagnitude)).ok());
  ASSERT_TRUE(edge.apply_linear_impulse(fast, Vec2(kMaxInputMagnitude, 0), Vec2(0, 0)).ok());
  for (int t = 0; t < 10; ++t) edge.step();
  const BodyState s = edge.body_state(fast).value();
  EXPECT_TRUE(std::isfinite(s.center.x()) && std::isfinite(s.center.y()) &&
              std::isfinite(s.linear_velocity.x()) && std::isfinite(s.angular_velocity));
}

// Found by fuzzing (tests/fuzz/findings/edits/tiny-density): a box of density 5e-322 gave a
// body an infinite inverse mass. Positive densities below 1e-12 are refused; at 1e-12 a body
// under the largest impulse stays finite.
TEST(Limits, DensitiesTooSmallToInvertAreRefused) {
  World w{WorldSettings{}};
  BodyId b = w.create_body(dynamic_at(Vec2(0, 1))).value();
  ShapeDef tiny = circle(Vec2::Zero(), 0.5);
  tiny.density = 4.59481050632359e-322;
  EXPECT_EQ(w.create_shape(b, tiny).status().message(),
            "shape.density: must be 0 or at least 1e-12 (got 4.5948105063235929e-322)");
  tiny.density = 0.0;
  EXPECT_TRUE(w.create_shape(b, tiny).ok()) << "a massless shape";
  ShapeDef light = circle(Vec2(1, 0), kGeometryTolerance);
  light.density = 1e-12;
  ASSERT_TRUE(w.create_shape(b, light).ok());
  ASSERT_TRUE(w.apply_linear_impulse(b, Vec2(kMaxInputMagnitude, 0), Vec2(1, 1)).ok());
  for (int t = 0; t < 5; ++t) w.step();
  const BodyState s = w.body_state(b).value();
  EXPECT_TRUE(std::isfinite(s.center.x()) && std::isfinite(s.linear_velocity.x()) &&
              std::isfinite(s.angular_velocity));
}

}  // namespace
}  // namespace fulcrum
