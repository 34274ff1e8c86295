// Behavioural and physical facts about the world: integration, contacts, friction, particles,
// sleeping, events, filtering, queries, bad input and determinism.
#include "fulcrum/world.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <vector>

#include "fulcrum/joints.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"
#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {
namespace {

BodyId add_ground(World& w, double half_width = 50.0, double friction = 0.6) {
  BodyDef def;
  def.position = Vec2(0.0, -1.0);
  BodyId ground = *w.create_body(def);
  ShapeDef sd;
  sd.geometry = make_box(half_width, 1.0);
  sd.friction = friction;
  EXPECT_TRUE(w.create_shape(ground, sd).ok());
  return ground;
}

BodyId add_box(World& w, const Vec2& p, double half = 0.5, double angle = 0.0,
               double friction = 0.6, BodyType type = BodyType::kDynamic) {
  BodyDef def;
  def.type = type;
  def.position = p;
  def.angle = angle;
  BodyId id = *w.create_body(def);
  ShapeDef sd;
  sd.geometry = make_box(half, half);
  sd.friction = friction;
  EXPECT_TRUE(w.create_shape(id, sd).ok());
  return id;
}

BodyId add_ball(World& w, const Vec2& p, double r, BodyType type = BodyType::kDynamic,
                double restitution = 0.0) {
  BodyDef def;
  def.type = type;
  def.position = p;
  BodyId id = *w.create_body(def);
  ShapeDef sd;
  sd.geometry = Circle{Vec2::Zero(), r};
  sd.restitution = restitution;
  EXPECT_TRUE(w.create_shape(id, sd).ok());
  return id;
}

Vec2 position(const World& w, BodyId id) {
  return w.body_state(id)->transform.p;
}
Vec2 velocity(const World& w, BodyId id) {
  return w.body_state(id)->linear_velocity;
}

// Free fall is symplectic Euler exactly, substep by substep: v += h g, then the displacement
// d += h v, and at the end of the tick y += d, in that order, bit for bit. The closed form
// y0 + g h^2 n (n + 1) / 2 over all n substeps agrees to rounding (1e-9 m is ~1e5 ulps at
// 100 m, far above the few thousand roundings of 2400 additions, far below any physical error).
TEST(WorldTest, FreeFallIsSymplecticEulerToTheLastBit) {
  World w;
  BodyId ball = add_ball(w, Vec2(0.0, 100.0), 0.5);
  const int substeps = w.settings().substeps;
  const double h = w.settings().dt / substeps;
  const double g = w.settings().gravity.y();
  double v = 0.0, y = 100.0;
  for (int tick = 1; tick <= 600; ++tick) {
    w.step();
    double d = 0.0;
    for (int k = 0; k < substeps; ++k) {
      v = v + h * g;
      d = d + h * v;
    }
    y = y + d;
    ASSERT_EQ(velocity(w, ball).y(), v) << "tick " << tick;
    ASSERT_EQ(position(w, ball).y(), y) << "tick " << tick;
    ASSERT_EQ(position(w, ball).x(), 0.0);
    double n = tick * substeps;
    ASSERT_NEAR(y, 100.0 + g * h * h * n * (n + 1) / 2.0, 1e-9);
  }
}

// A box landing with restitution 0 stays down: after first touching it never rises by more
// than the allowed slop (5 mm) above its resting height, and never moves up faster than
// 0.1 m/s (the speculative contact stops it at the surface; nothing should push it back).
TEST(WorldTest, BoxLandingWithoutRestitutionDoesNotBounce) {
  World w;
  add_ground(w);
  BodyId box = add_box(w, Vec2(0.0, 3.0));
  bool landed = false;
  for (int i = 0; i < 300; ++i) {
    w.step();
    double y = position(w, box).y();
    if (y < 0.51) landed = true;
    if (landed) {
      EXPECT_LT(y, 0.5 + 0.005) << "tick " << i;
      EXPECT_LT(velocity(w, box).y(), 0.1) << "tick " << i;
    }
  }
  EXPECT_TRUE(landed);
  EXPECT_NEAR(position(w, box).y(), 0.5, 0.01);  // rests within 2 x slop of touching
}

// A friction ramp: a box on a slope at angle a sticks when tan(a) < mu, and otherwise slides
// with acceleration g (sin a - mu cos a). Tolerance 2 %: the sliding box's contact row is
// solved exactly each tick, so what remains is the discretisation of the start.
struct Ramp {
  World world;
  BodyId box;
  Vec2 down;  // unit vector down the slope
};

Ramp make_ramp(double angle_deg, double mu) {
  Ramp r;
  double a = angle_deg * kPi / 180.0;
  SinCos sc = det_sincos(a);
  BodyDef gd;
  gd.angle = -a;  // slope falls toward +x
  BodyId ground = *r.world.create_body(gd);
  ShapeDef sd;
  sd.geometry = make_box(50.0, 1.0);
  sd.friction = mu;
  EXPECT_TRUE(r.world.create_shape(ground, sd).ok());
  // Surface normal (sin a, cos a); the box centre sits 1 + 0.5 above the slab centre.
  Vec2 normal(sc.sin, sc.cos);
  r.box = add_box(r.world, 1.5 * normal, 0.5, -a, mu);
  r.down = Vec2(sc.cos, -sc.sin);
  return r;
}

TEST(WorldTest, FrictionRampSticksBelowTheFrictionAngle) {
  // tan(25 deg) = 0.466 < 0.6.
  Ramp r = make_ramp(25.0, 0.6);
  Vec2 start = position(r.world, r.box);
  for (int i = 0; i < 120; ++i) r.world.step();
  // Resting contact creeps by less than a millimetre (warm-started friction holds it).
  EXPECT_LT(distance(position(r.world, r.box), start), 1e-3);
}

TEST(WorldTest, FrictionRampSlidesWithTheCoulombAcceleration) {
  const double angle = 35.0, mu = 0.3;  // tan(35 deg) = 0.70 > 0.3
  Ramp r = make_ramp(angle, mu);
  double a = angle * kPi / 180.0;
  double expected = 10.0 * (std::sin(a) - mu * std::cos(a));
  // Let it settle onto the slope, then measure the acceleration over one second.
  for (int i = 0; i < 30; ++i) r.world.step();
  double v0 = dot(velocity(r.world, r.box), r.down);
  for (int i = 0; i < 60; ++i) r.world.step();
  double v1 = dot(velocity(r.world, r.box), r.down);
  EXPECT_NEAR((v1 - v0) / 1.0, expected, 0.02 * expected);
}

// Particles: no rotation, fall under gravity, rest on the ground at their radius, and two
// particles in a head-on collision conserve momentum exactly (equal and opposite impulses).
TEST(WorldTest, ParticlesFallRestAndCollide) {
  World w;
  w.set_settings([] {
     WorldSettings s;
     s.gravity = Vec2(0.0, -10.0);
     return s;
   }())
      .ok();
  add_ground(w);
  BodyId p = add_ball(w, Vec2(0.0, 2.0), 0.25, BodyType::kParticle);
  EXPECT_EQ(w.body_state(p)->rotational_inertia, 0.0);
  for (int i = 0; i < 120; ++i) w.step();
  EXPECT_NEAR(position(w, p).y(), 0.25, 0.01);  // within 2 x slop of touching
  EXPECT_EQ(w.body_state(p)->angular_velocity, 0.0);

  World space(WorldSettings{.gravity = Vec2::Zero()});
  BodyId a = add_ball(space, Vec2(-2.0, 0.0), 0.5, BodyType::kParticle);
  BodyId b = add_ball(space, Vec2(2.0, 0.0), 0.5, BodyType::kParticle);
  ASSERT_TRUE(space.set_linear_velocity(a, Vec2(3.0, 0.0)).ok());
  ASSERT_TRUE(space.set_linear_velocity(b, Vec2(-1.0, 0.0)).ok());
  double momentum0 = space.metrics().linear_momentum.x();
  bool touched = false;
  for (int i = 0; i < 120; ++i) {
    space.step();
    touched = touched || !space.events().contact_begin.empty();
  }
  EXPECT_TRUE(touched);
  EXPECT_NEAR(space.metrics().linear_momentum.x(), momentum0, 1e-12);
  // Inelastic (restitution 0): they end moving together at the centre-of-mass velocity.
  EXPECT_NEAR(velocity(space, a).x(), 1.0, 1e-6);
  EXPECT_NEAR(velocity(space, b).x(), 1.0, 1e-6);
}

// A settled pyramid falls asleep (and costs nothing: no awake bodies), and a ball dropped on
// it wakes it.
TEST(WorldTest, PyramidSleepsAndABallWakesIt) {
  SceneDef scene;
  scenes::add_ground(&scene, 20.0);
  scenes::PyramidOptions opts;
  opts.base = 6;
  scenes::add_pyramid(&scene, opts);
  World w = std::move(build_world(scene).value());
  for (int i = 0; i < 240; ++i) w.step();
  EXPECT_EQ(w.metrics().awake_body_count, 0);
  BodyId ball = add_ball(w, Vec2(0.0, 10.0), 0.5);
  EXPECT_EQ(w.metrics().awake_body_count, 1);
  int most_awake = 0;
  for (int i = 0; i < 90; ++i) {
    w.step();
    most_awake = std::max(most_awake, w.metrics().awake_body_count);
  }
  // The ball landed on the top box (top surface at 6 m) and woke the whole pyramid, which
  // touches itself everywhere: 21 boxes plus the ball.
  EXPECT_NEAR(position(w, ball).y(), 6.5, 0.05);
  EXPECT_EQ(most_awake, 22);
}

TEST(WorldTest, ContactAndSensorEventsInOrder) {
  World w;
  add_ground(w);
  BodyId box = add_box(w, Vec2(0.0, 1.0));
  BodyDef sd_body;
  BodyId sensor_body = *w.create_body(sd_body);
  ShapeDef sensor;
  sensor.geometry = make_offset_box(1.0, 0.2, Vec2(0.0, 0.75), 0.0);
  sensor.is_sensor = true;
  ShapeId sensor_shape = *w.create_shape(sensor_body, sensor);
  (void)sensor_body;
  int begins = 0, sensor_begins = 0;
  for (int i = 0; i < 60; ++i) {
    w.step();
    begins += static_cast<int>(w.events().contact_begin.size());
    for (const SensorEvent& e : w.events().sensor_begin) {
      EXPECT_EQ(e.sensor, sensor_shape);
      ++sensor_begins;
    }
  }
  EXPECT_EQ(begins, 1);         // box meets ground once
  EXPECT_EQ(sensor_begins, 1);  // the box passes into the sensor once
  // The sensor did not hold the box up.
  EXPECT_NEAR(position(w, box).y(), 0.5, 0.01);
  ASSERT_TRUE(w.destroy_body(box).ok());
  w.step();
}

TEST(WorldTest, FilterGroupsAndMasks) {
  World w(WorldSettings{.gravity = Vec2::Zero()});
  auto make = [&](double x, double vx, Filter f) {
    BodyDef def;
    def.type = BodyType::kDynamic;
    def.position = Vec2(x, 0.0);
    def.linear_velocity = Vec2(vx, 0.0);
    BodyId id = *w.create_body(def);
    ShapeDef sd;
    sd.geometry = Circle{Vec2::Zero(), 0.5};
    sd.filter = f;
    EXPECT_TRUE(w.create_shape(id, sd).ok());
    return id;
  };
  BodyId a = make(-2.0, 2.0, Filter{1, ~0ull, -1});
  BodyId b = make(2.0, -2.0, Filter{1, ~0ull, -1});  // same negative group: pass through
  for (int i = 0; i < 120; ++i) w.step();
  EXPECT_GT(position(w, a).x(), 1.0);
  EXPECT_LT(position(w, b).x(), -1.0);
}

TEST(WorldTest, QueriesAreExactAndOrdered) {
  World w;
  add_ground(w);
  std::vector<BodyId> boxes;
  for (int i = 0; i < 5; ++i) boxes.push_back(add_box(w, Vec2(2.0 * i, 0.5)));
  // A ray along y = 0.5 from the left hits the left face of the first box at x = -0.5.
  auto hit = w.ray_cast_closest(Vec2(-5.0, 0.5), Vec2(20.0, 0.0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->point.x(), -0.5, 1e-12);
  EXPECT_NEAR(hit->normal.x(), -1.0, 1e-12);
  EXPECT_NEAR(hit->fraction, 4.5 / 20.0, 1e-12);
  auto all = w.ray_cast_all(Vec2(-5.0, 0.5), Vec2(20.0, 0.0));
  ASSERT_EQ(all.size(), 5u);
  for (size_t i = 1; i < all.size(); ++i) EXPECT_LT(all[i - 1].fraction, all[i].fraction);
  // Boxes overlapping x in [1, 5] above the ground: those centred at 2 and 4.
  auto over = w.overlap_aabb(AABB{Vec2(1.0, 0.2), Vec2(5.0, 0.8)});
  ASSERT_EQ(over.size(), 2u);
  EXPECT_EQ(w.shape_info(over[0])->body, boxes[1]);
  EXPECT_EQ(w.shape_info(over[1])->body, boxes[2]);
  auto at = w.overlap_point(Vec2(4.1, 0.5));
  ASSERT_EQ(at.size(), 1u);
  EXPECT_EQ(w.shape_info(at[0])->body, boxes[2]);
}

// Bad input is refused with a message naming the field, and the world is unchanged.
TEST(WorldTest, BadInputIsRefusedAndChangesNothing) {
  World w;
  add_ground(w);
  BodyId box = add_box(w, Vec2(0.0, 2.0));
  uint64_t before = w.state_hash();

  BodyDef nan_def;
  nan_def.position = Vec2(std::nan(""), 0.0);
  auto r1 = w.create_body(nan_def);
  ASSERT_FALSE(r1.ok());
  EXPECT_NE(r1.status().message().find("body.position"), std::string::npos);

  ShapeDef neg;
  neg.density = -1.0;
  auto r2 = w.create_shape(box, neg);
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.status().message().find("density"), std::string::npos);

  Polygon poly;
  std::vector<Vec2> concave{Vec2(0, 0), Vec2(2, 0), Vec2(1, 0.2), Vec2(2, 2), Vec2(0, 2)};
  EXPECT_FALSE(make_polygon(concave, 0.0, &poly).ok());
  std::vector<Vec2> too_few{Vec2(0, 0), Vec2(1, 0)};
  EXPECT_FALSE(make_polygon(too_few, 0.0, &poly).ok());

  ShapeDef capsule;
  capsule.geometry = Capsule{Vec2(1, 1), Vec2(1, 1), 0.5};
  auto r3 = w.create_shape(box, capsule);
  ASSERT_FALSE(r3.ok());
  EXPECT_NE(r3.status().message().find("capsule"), std::string::npos);

  BodyId stale{box.index, box.generation + 7};
  auto r4 = w.set_linear_velocity(stale, Vec2(1, 0));
  EXPECT_EQ(r4.code(), StatusCode::kNotFound);
  EXPECT_FALSE(w.set_transform(box, Vec2(INFINITY, 0), 0).ok());
  EXPECT_FALSE(w.apply_force_to_center(box, Vec2(0, std::nan(""))).ok());
  WorldSettings bad;
  bad.dt = 0.0;
  auto r5 = w.set_settings(bad);
  ASSERT_FALSE(r5.ok());
  EXPECT_NE(r5.message().find("settings.dt"), std::string::npos);

  EXPECT_EQ(w.state_hash(), before);
  EXPECT_EQ(w.body_count(), 2);

  // A destroyed body's handle goes stale; its index is reused with a new generation.
  ASSERT_TRUE(w.destroy_body(box).ok());
  EXPECT_FALSE(w.is_valid(box));
  EXPECT_EQ(w.destroy_body(box).code(), StatusCode::kNotFound);
  BodyId again = add_box(w, Vec2(0.0, 2.0));
  EXPECT_EQ(again.index, box.index);
  EXPECT_NE(again.generation, box.generation);
  EXPECT_FALSE(w.is_valid(box));
}

TEST(WorldTest, SceneErrorsNameTheBody) {
  SceneDef scene;
  scenes::add_ground(&scene, 10.0);
  SceneBody b;
  b.def.type = BodyType::kDynamic;
  ShapeDef sd;
  sd.geometry = Circle{Vec2::Zero(), -1.0};
  b.shapes.push_back(sd);
  scene.bodies.push_back(b);
  auto r = build_world(scene);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("bodies[1].shapes[0]"), std::string::npos)
      << r.status().message();
  EXPECT_NE(r.status().message().find("radius"), std::string::npos) << r.status().message();
}

// The same scene in two processes gives the same state hash at every tick.
std::vector<uint64_t> hash_trace(int ticks) {
  World world = std::move(build_world(scenes::builtin("mixed").value()).value());
  std::vector<uint64_t> trace;
  for (int i = 0; i < ticks; ++i) {
    world.step();
    trace.push_back(world.state_hash());
  }
  return trace;
}

TEST(WorldTest, SameHashesInTwoProcesses) {
  const int ticks = 240;
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::vector<uint64_t> trace = hash_trace(ticks);
    ssize_t n = write(fds[1], trace.data(), trace.size() * sizeof(uint64_t));
    _exit(n == static_cast<ssize_t>(trace.size() * sizeof(uint64_t)) ? 0 : 1);
  }
  close(fds[1]);
  std::vector<uint64_t> theirs(ticks);
  size_t got = 0;
  char* buf = reinterpret_cast<char*>(theirs.data());
  while (got < theirs.size() * sizeof(uint64_t)) {
    ssize_t n = read(fds[0], buf + got, theirs.size() * sizeof(uint64_t) - got);
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  close(fds[0]);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_EQ(got, theirs.size() * sizeof(uint64_t));
  std::vector<uint64_t> ours = hash_trace(ticks);
  for (int i = 0; i < ticks; ++i) ASSERT_EQ(ours[i], theirs[i]) << "tick " << i;
  // And the hash really tracks the state: it changes while things move.
  EXPECT_NE(ours[10], ours[11]);
}

}  // namespace
}  // namespace fulcrum

namespace fulcrum {
namespace {

// The broad phase finds exactly the pairs brute force finds: after stepping a jumble of
// shapes, every pair of shapes whose fat boxes overlap and that may collide has a contact, and
// no other pair has one.
// Static bodies' shapes live in a broad-phase tree of their own (engine/src/broad_phase.cpp):
// queries and new pairs find shapes in both trees, and a static shape teleported into a
// moving one's box makes a contact.
TEST(WorldTest, StaticShapesHaveATreeOfTheirOwn) {
  World w(WorldSettings{.gravity = Vec2::Zero()});
  add_ground(w);
  std::vector<BodyId> pegs, balls;
  for (int i = 0; i < 10; ++i)
    pegs.push_back(add_box(w, Vec2(3.0 * i, 2.0), 0.25, 0.0, 0.6, BodyType::kStatic));
  for (int i = 0; i < 10; ++i) balls.push_back(add_ball(w, Vec2(3.0 * i, 4.0), 0.5));
  add_box(w, Vec2(-5.0, 4.0), 0.5, 0.0, 0.6, BodyType::kKinematic);
  const WorldImpl& impl = w.impl();
  EXPECT_EQ(impl.static_tree.proxy_count(), 11);  // the ground and the pegs
  EXPECT_EQ(impl.tree.proxy_count(), 11);         // the balls and the kinematic box
  // A ray down through ball 2 and peg 2 to the ground: ball, peg, ground, closest first.
  auto all = w.ray_cast_all(Vec2(6.0, 10.0), Vec2(0.0, -20.0));
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(w.shape_info(all[0].shape)->body, balls[2]);
  EXPECT_EQ(w.shape_info(all[1].shape)->body, pegs[2]);
  EXPECT_NEAR(all[1].point.y(), 2.25, 1e-12);
  auto closest = w.ray_cast_closest(Vec2(6.0, 3.0), Vec2(0.0, -20.0));  // below the ball
  ASSERT_TRUE(closest.has_value());
  EXPECT_EQ(w.shape_info(closest->shape)->body, pegs[2]);
  auto at = w.overlap_point(Vec2(3.1, 2.1));
  ASSERT_EQ(at.size(), 1u);
  EXPECT_EQ(w.shape_info(at[0])->body, pegs[1]);
  EXPECT_EQ(w.overlap_aabb(AABB{Vec2(2.5, 1.5), Vec2(3.5, 4.5)}).size(), 2u);  // peg and ball 1
  for (int i = 0; i < 5; ++i) w.step();
  // Peg 0 moved into ball 0 (at rest, in no contact): the pair is found and the ball pushed.
  ASSERT_TRUE(w.set_transform(pegs[0], Vec2(0.0, 3.6), 0.0).ok());
  for (int i = 0; i < 30; ++i) w.step();
  EXPECT_EQ(impl.static_tree.proxy_count(), 11);
  EXPECT_GT(w.body_state(balls[0])->center.y(), 4.3);         // clear of the peg's top at 3.85
  EXPECT_DOUBLE_EQ(w.body_state(balls[1])->center.y(), 4.0);  // untouched
  EXPECT_TRUE(impl.tree.validate());
  EXPECT_TRUE(impl.static_tree.validate());
}

// Every pair of shapes whose fat boxes overlap and that may collide has a contact, and no other
// pair has one, once the step's pair and contact stages have run again.
void expect_contacts_match_fat_boxes(World& w) {
  // Pairs are created and dropped at the start of a step: run those two stages once more so
  // that the contacts reflect the fat boxes as they are now.
  ++w.impl().step_stamp;  // a new step's stamp, as World::step sets it
  w.impl().update_pairs();
  w.impl().collide();

  const WorldImpl& impl = w.impl();
  std::vector<std::pair<int, int>> expected, actual;
  for (int a = 0; a < static_cast<int>(impl.shapes.size()); ++a) {
    for (int b = a + 1; b < static_cast<int>(impl.shapes.size()); ++b) {
      if (!impl.shapes[a].alive || !impl.shapes[b].alive || !impl.should_collide(a, b)) continue;
      if (impl.tree_of(impl.shapes[a])
              .fat_aabb(impl.shapes[a].proxy)
              .overlaps(impl.tree_of(impl.shapes[b]).fat_aabb(impl.shapes[b].proxy))) {
        expected.emplace_back(a, b);
      }
    }
  }
  // A sleeping island's contacts are not revisited until it wakes (that is what makes sleep
  // free), so a contact between two non-awake bodies may outlive its overlap: leave those out
  // of the "no extra contacts" check, but not out of the "no missing contacts" check.
  std::vector<std::pair<int, int>> asleep;
  for (const Contact& c : impl.contacts) {
    if (!c.alive) continue;
    std::pair<int, int> key(std::min(c.shape_a, c.shape_b), std::max(c.shape_a, c.shape_b));
    bool awake = impl.bodies[c.body_a].awake || impl.bodies[c.body_b].awake;
    (awake ? actual : asleep).push_back(key);
  }
  for (const auto& key : asleep) {
    if (std::binary_search(expected.begin(), expected.end(), key)) actual.push_back(key);
  }
  std::sort(actual.begin(), actual.end());
  EXPECT_GT(expected.size(), 100u);
  std::vector<std::pair<int, int>> missing, extra;
  std::set_difference(expected.begin(), expected.end(), actual.begin(), actual.end(),
                      std::back_inserter(missing));
  std::set_difference(actual.begin(), actual.end(), expected.begin(), expected.end(),
                      std::back_inserter(extra));
  EXPECT_TRUE(missing.empty()) << missing.size() << " pairs without a contact, first ("
                               << (missing.empty() ? -1 : missing[0].first) << ", "
                               << (missing.empty() ? -1 : missing[0].second) << ")";
  EXPECT_TRUE(extra.empty()) << extra.size() << " contacts without overlap, first ("
                             << (extra.empty() ? -1 : extra[0].first) << ", "
                             << (extra.empty() ? -1 : extra[0].second) << ")";
}

TEST(WorldTest, BroadPhaseMatchesBruteForce) {
  World w(WorldSettings{.gravity = Vec2(0.0, -10.0)});
  add_ground(w, 30.0);
  uint64_t state = 12345;
  auto next = [&]() {  // a fixed-seed LCG, so the scene is the same everywhere
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  for (int i = 0; i < 300; ++i) {
    BodyDef def;
    def.type = i % 5 == 0 ? BodyType::kParticle : BodyType::kDynamic;
    def.position = Vec2(-20.0 + 40.0 * next(), 1.0 + 30.0 * next());
    def.angle = 3.0 * next();
    BodyId id = *w.create_body(def);
    ShapeDef sd;
    if (def.type == BodyType::kParticle || i % 3 == 0) {
      sd.geometry = Circle{Vec2::Zero(), 0.2 + 0.3 * next()};
    } else if (i % 3 == 1) {
      sd.geometry = make_box(0.2 + 0.4 * next(), 0.2 + 0.4 * next());
    } else {
      sd.geometry = Capsule{Vec2(-0.3, 0.0), Vec2(0.3, 0.0), 0.2};
    }
    sd.filter.group_index = i % 7 == 0 ? -1 : 0;  // some never meet each other
    ASSERT_TRUE(w.create_shape(id, sd).ok());
  }
  for (int i = 0; i < 90; ++i) w.step();
  expect_contacts_match_fat_boxes(w);
}

// When most shapes moved, new pairs are found by walking the moving tree with itself and with
// the static tree (broad_phase.cpp, join_moves) instead of a query per shape: the same pairs.
// A crowd flying apart in zero gravity over static pegs, with filter bits that part some.
TEST(WorldTest, BroadPhaseWalkOfTreesMatchesBruteForce) {
  World w(WorldSettings{.gravity = Vec2::Zero()});
  uint64_t state = 777;
  auto next = [&]() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  for (int i = 0; i < 60; ++i) {
    add_box(w, Vec2(-15.0 + 30.0 * next(), -15.0 + 30.0 * next()), 0.3, 0.0, 0.6,
            BodyType::kStatic);
  }
  for (int i = 0; i < 700; ++i) {
    BodyDef def;
    def.type = BodyType::kDynamic;
    def.position = Vec2(-8.0 + 16.0 * next(), -8.0 + 16.0 * next());
    // Fast enough (over 0.1 m a tick) to leave its fat box every tick.
    def.linear_velocity = Vec2(next() < 0.5 ? -12.0 : 12.0, -20.0 + 40.0 * next());
    def.angular_velocity = -3.0 + 6.0 * next();
    BodyId id = *w.create_body(def);
    ShapeDef sd;
    sd.geometry = i % 2 == 0 ? Geometry{Circle{Vec2::Zero(), 0.3}} : Geometry{make_box(0.3, 0.2)};
    sd.filter.category_bits = uint64_t{1} << (i % 3);
    sd.filter.mask_bits = i % 4 == 0 ? ~(uint64_t{1} << (i % 3)) : ~uint64_t{0};
    ASSERT_TRUE(w.create_shape(id, sd).ok());
  }
  for (int i = 0; i < 2; ++i) w.step();
  // The walk is used when at least half the moving tree's leaves (and 256) moved.
  ASSERT_GE(2 * w.impl().move_buffer.size(), static_cast<size_t>(w.impl().tree.proxy_count()));
  ASSERT_GE(w.impl().move_buffer.size(), 256u);
  expect_contacts_match_fat_boxes(w);
}

// A shape's broad-phase box reaches the speculative distance past it, and a moving shape's a
// margin more: an eighth of its half-diagonal, at most aabb_margin. Small boxes a little beyond
// contact reach of each other then make no contact at all, a pair within it always does, and
// a box drifting inside its fat box never comes within the speculative distance of its edge.
TEST(WorldTest, FatBoxesReachTheSpeculativeDistanceAndAMarginByShape) {
  const WorldSettings settings{.gravity = Vec2::Zero()};
  const double speculative = settings.speculative_distance;
  World w(settings);
  const double small_half = 0.125;
  BodyId small = add_box(w, Vec2(0.0, 0.0), small_half);
  BodyId big = add_box(w, Vec2(0.0, 10.0), 5.0);  // half-diagonal 7.1 m: the margin is capped
  BodyId fixed = add_box(w, Vec2(0.0, -10.0), 1.0, 0.0, 0.6, BodyType::kStatic);
  const WorldImpl& impl = w.impl();
  auto fat_box = [&](BodyId id) { return impl.fat_boxes[impl.bodies[id.index].shapes.front()]; };
  auto expect_reach = [&](BodyId id, double half, double reach) {
    const AABB fat = fat_box(id);
    const Vec2 centre = position(w, id);
    EXPECT_NEAR(fat.upper.x() - centre.x(), half + reach, 1e-12);
    EXPECT_NEAR(centre.y() - fat.lower.y(), half + reach, 1e-12);
  };
  expect_reach(small, small_half, speculative + 0.125 * small_half * std::sqrt(2.0));
  expect_reach(big, 5.0, speculative + settings.aabb_margin);
  expect_reach(fixed, 1.0, speculative);

  // A row of small boxes 10 cm apart: each box's reach is 4.2 cm, so boxes under 8.4 cm apart
  // would meet. None makes a contact (with a fixed 10 cm margin every neighbour would).
  World row(settings);
  for (int i = 0; i < 10; ++i) add_box(row, Vec2(0.35 * i, 0.0), small_half);
  // And one pair 1.5 cm apart, within the speculative distance: a touching contact.
  add_box(row, Vec2(0.0, 5.0), small_half);
  add_box(row, Vec2(0.265, 5.0), small_half);
  row.step();
  int alive = 0;
  for (const Contact& c : row.impl().contacts) alive += c.alive ? 1 : 0;
  EXPECT_EQ(alive, 1);
  EXPECT_EQ(row.metrics().contact_count, 1);

  // A box crossing the world at 0.3 m/s (5 mm a tick, under its 1.7 cm margin) and turning: at
  // every tick its fat box holds its box widened by the speculative distance and swept by
  // the next tick's travel.
  World drift(WorldSettings{.gravity = Vec2::Zero(), .enable_sleep = false});
  BodyDef def;
  def.type = BodyType::kDynamic;
  def.linear_velocity = Vec2(0.3, -0.1);
  def.angular_velocity = 0.7;
  BodyId mover = *drift.create_body(def);
  ShapeDef sd;
  sd.geometry = make_box(small_half, 0.5 * small_half);
  ASSERT_TRUE(drift.create_shape(mover, sd).ok());
  int moves = 0;
  AABB last = drift.impl().fat_boxes[0];
  for (int t = 0; t < 300; ++t) {
    drift.step();
    const BodyState state = *drift.body_state(mover);
    const AABB fat = drift.impl().fat_boxes[0];
    AABB need = compute_aabb(sd.geometry, state.transform).fattened(speculative);
    const Vec2 travel = drift.settings().dt * state.linear_velocity;
    need.lower += travel.cwiseMin(Vec2::Zero());
    need.upper += travel.cwiseMax(Vec2::Zero());
    ASSERT_TRUE(fat.contains(need)) << "tick " << t + 1;
    moves += fat.lower != last.lower ? 1 : 0;
    last = fat;
  }
  // Its travel along x alone (5 mm a tick) uses up the 1.75 cm margin within 4 ticks, so the
  // box moves often (76 times as built); but the margin spares it most ticks.
  EXPECT_GT(moves, 40);
  EXPECT_LT(moves, 150);

  // The same box at 1.5 m/s (25 mm a tick, more than half its margin): no margin. Its fat box
  // is its box swept by the tick's travel and widened by the speculative distance alone, and it
  // still holds what the next tick needs.
  World fast(WorldSettings{.gravity = Vec2::Zero(), .enable_sleep = false});
  def.linear_velocity = Vec2(1.5, -0.2);
  BodyId runner = *fast.create_body(def);
  ASSERT_TRUE(fast.create_shape(runner, sd).ok());
  for (int t = 0; t < 60; ++t) {
    fast.step();
    const BodyState state = *fast.body_state(runner);
    const AABB fat = fast.impl().fat_boxes[0];
    // Swept, then widened, as the broad phase rounds it.
    AABB need = compute_aabb(sd.geometry, state.transform);
    const Vec2 travel = fast.settings().dt * state.linear_velocity;
    need.lower += travel.cwiseMin(Vec2::Zero());
    need.upper += travel.cwiseMax(Vec2::Zero());
    need = need.fattened(speculative);
    ASSERT_TRUE(fat.contains(need)) << "tick " << t + 1;
    // Moved this tick (the sweep of the tick before reached only this tick's start), and to
    // exactly what it needs: 1e-12 m is rounding.
    EXPECT_NEAR(fat.upper.x(), need.upper.x(), 1e-12) << "tick " << t + 1;
    EXPECT_NEAR(fat.lower.y(), need.lower.y(), 1e-12) << "tick " << t + 1;
  }
}

// The narrow phase takes each awake shape's box from where the broad phase placed it after the
// bodies last moved (WorldImpl::AwakeBox::placed) instead of working it out again. A placed box
// must be the shape's box at its body's transform now, to the bit, whatever moved the body: the
// ticks, set_transform, a shape added to a moving body. After a restore nothing is placed until
// the bodies move (the narrow phase works those boxes out itself).
TEST(WorldTest, PlacedBoxesAreTheShapesBoxesAtTheirBodiesTransforms) {
  World w;
  add_ground(w);
  std::vector<BodyId> boxes;
  for (int i = 0; i < 12; ++i) {
    boxes.push_back(add_box(w, Vec2(0.3 * (i % 4), 0.6 + 1.1 * (i / 4)), 0.25, 0.3 * i));
  }
  // Counts the placed boxes, checking each against compute_aabb.
  auto placed = [](const World& world) {
    const WorldImpl& impl = world.impl();
    int n = 0;
    for (size_t si = 0; si < impl.shapes.size() && si < impl.awake_boxes.size(); ++si) {
      const Shape& s = impl.shapes[si];
      const WorldImpl::AwakeBox& r = impl.awake_boxes[si];
      if (!s.alive || !r.placed) continue;
      const AABB want = compute_aabb(s.geometry, impl.bodies[s.body].xf);
      EXPECT_TRUE(r.box.lower == want.lower && r.box.upper == want.upper) << "shape " << si;
      EXPECT_EQ(r.type, geometry_type(s.geometry)) << "shape " << si;
      ++n;
    }
    return n;
  };
  const int shapes = 13;  // the ground and the boxes
  EXPECT_EQ(placed(w), shapes);
  for (int t = 0; t < 40; ++t) w.step();
  EXPECT_EQ(placed(w), shapes);
  ASSERT_TRUE(w.set_transform(boxes[5], Vec2(3.0, 2.0), 0.7).ok());
  EXPECT_EQ(placed(w), shapes);
  ShapeDef sd;
  sd.geometry = Circle{Vec2(0.2, 0.0), 0.1};
  ASSERT_TRUE(w.create_shape(boxes[7], sd).ok());
  EXPECT_EQ(placed(w), shapes + 1);
  for (int t = 0; t < 10; ++t) w.step();
  EXPECT_EQ(placed(w), shapes + 1);

  World copy;
  ASSERT_TRUE(copy.restore(w.snapshot()).ok());
  EXPECT_EQ(placed(copy), 0);
  copy.step();
  w.step();
  EXPECT_GT(placed(copy), 0);
  EXPECT_EQ(copy.snapshot().state_hash, w.snapshot().state_hash);
}

// The budgets skip reading the bodies' records in a world without joints or kinematic bodies
// (plan_budgets), trusting WorldImpl::kinematic_bodies: it counts the alive kinematic bodies
// through creation, destruction (a freed slot reused by another type) and restore. With a
// kinematic body awake the tick is no one-pass tick: the pile beside it keeps its passes.
TEST(WorldTest, KinematicBodiesAreCountedThroughEditsAndRestore) {
  World w;
  add_ground(w);
  auto count = [](const World& world) {
    int n = 0;
    for (const Body& b : world.impl().bodies) n += b.alive && b.type == BodyType::kKinematic;
    EXPECT_EQ(world.impl().kinematic_bodies, n);
    return n;
  };
  const BodyId k1 = add_box(w, Vec2(-4.0, 3.0), 0.5, 0.0, 0.6, BodyType::kKinematic);
  add_box(w, Vec2(4.0, 3.0), 0.5, 0.0, 0.6, BodyType::kKinematic);
  add_box(w, Vec2(0.0, 0.5), 0.5);
  EXPECT_EQ(count(w), 2);
  ASSERT_TRUE(w.destroy_body(k1).ok());
  EXPECT_EQ(count(w), 1);
  add_box(w, Vec2(0.0, 1.6), 0.5);  // reuses k1's slot as a dynamic body
  EXPECT_EQ(count(w), 1);
  for (int t = 0; t < 30; ++t) w.step();
  EXPECT_EQ(w.metrics().max_velocity_iterations, w.impl().settings.velocity_iterations);
  World copy;
  ASSERT_TRUE(copy.restore(w.snapshot()).ok());
  EXPECT_EQ(count(copy), 1);
  copy.step();
  w.step();
  EXPECT_EQ(copy.snapshot().state_hash, w.snapshot().state_hash);
}

// The broad phase boxes each shape from its packed outline (WorldImpl::shape_box), not from
// its geometry: the box must be compute_aabb's to the last bit for every kind of shape (a
// polygon with more vertices than the outline holds is read from the shape), for a slot reused
// by another kind of shape, and after a restore, which derives the outlines again.
TEST(WorldTest, ShapeOutlinesBoxEveryShapeAsItsGeometryDoes) {
  World w;
  BodyDef def;
  def.type = BodyType::kStatic;
  const BodyId body = *w.create_body(def);
  Polygon rounded;
  const Vec2 triangle[] = {Vec2(-0.3, -0.2), Vec2(0.4, -0.1), Vec2(0.1, 0.5)};
  ASSERT_TRUE(make_polygon(triangle, 0.05, &rounded).ok());
  Polygon hexagon;
  std::vector<Vec2> six;
  for (int i = 0; i < 6; ++i) {
    const Rot q = Rot::from_angle(i * 3.14159265358979323846 / 3.0);
    six.push_back(Vec2(0.7 * q.c + 0.2, 0.7 * q.s - 0.1));
  }
  ASSERT_TRUE(make_polygon(six, 0.0, &hexagon).ok());
  const std::vector<Geometry> kinds = {
      Circle{Vec2(0.3, -0.2), 0.4},
      Capsule{Vec2(-0.5, 0.1), Vec2(0.6, -0.2), 0.15},
      Segment{Vec2(-1.0, -0.0), Vec2(1.0, -0.0)},  // -0 corners at the origin
      make_offset_box(0.5, 0.25, Vec2(0.1, 0.2), 0.3),
      rounded,
      hexagon,
  };
  std::vector<ShapeId> ids;
  for (const Geometry& g : kinds) {
    ShapeDef sd;
    sd.geometry = g;
    ids.push_back(*w.create_shape(body, sd));
  }
  // The hexagon's slot reused by a circle and the circle's by a hexagon (freed slots are
  // taken last first).
  ASSERT_TRUE(w.destroy_shape(ids[0]).ok());
  ASSERT_TRUE(w.destroy_shape(ids[5]).ok());
  for (const Geometry& g : {Geometry(Circle{Vec2::Zero(), 0.2}), Geometry(hexagon)}) {
    ShapeDef sd;
    sd.geometry = g;
    ASSERT_TRUE(w.create_shape(body, sd).ok());
  }
  World restored;
  ASSERT_TRUE(restored.restore(w.snapshot()).ok());
  auto same_bits = [](const AABB& a, const AABB& b) {
    const double x[] = {a.lower.x(), a.lower.y(), a.upper.x(), a.upper.y()};
    const double y[] = {b.lower.x(), b.lower.y(), b.upper.x(), b.upper.y()};
    return std::memcmp(x, y, sizeof(x)) == 0;
  };
  int checked = 0;
  for (const World* world : {&w, &restored}) {
    const WorldImpl& impl = world->impl();
    for (size_t si = 0; si < impl.shapes.size(); ++si) {
      if (!impl.shapes[si].alive) continue;
      // At the origin (-0, -0) unturned a segment along x has -0 corners.
      for (const Transform& xf :
           {Transform{Vec2(-0.0, -0.0), Rot{}}, Transform{Vec2(-3.25, 1.5), Rot::from_angle(0.7)},
            Transform{Vec2(2.0, -0.5), Rot::from_angle(-2.1)},
            Transform{Vec2(0.25, 4.0), Rot::from_angle(3.14159265358979323846)}}) {
        const AABB want = compute_aabb(impl.shapes[si].geometry, xf);
        EXPECT_TRUE(same_bits(impl.shape_box(static_cast<int>(si), xf), want))
            << "shape " << si << " (" << shape_type_name(geometry_type(impl.shapes[si].geometry))
            << ") at angle " << xf.q.angle();
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 2 * 6 * 4);
}

// The budgets' walk over the joint pool reads each joint's packed head (WorldImpl::JointHead),
// not the joint: the heads must follow every creation, destruction and slot reuse, and a restore.
TEST(WorldTest, JointHeadsFollowTheJointsThroughEditsAndRestore) {
  World w;
  add_ground(w);
  std::vector<BodyId> balls;
  for (int i = 0; i < 6; ++i) balls.push_back(add_ball(w, Vec2(1.0 * i, 4.0), 0.3));
  auto revolute = [&](BodyId a, BodyId b) {
    RevoluteJointDef def;
    def.body_a = a;
    def.body_b = b;
    def.local_anchor_a = Vec2(0.5, 0.0);
    def.local_anchor_b = Vec2(-0.5, 0.0);
    return *w.create_revolute_joint(def);
  };
  auto distance = [&](BodyId a, BodyId b) {
    DistanceJointDef def;
    def.body_a = a;
    def.body_b = b;
    return *w.create_distance_joint(def);
  };
  const JointId first = revolute(balls[0], balls[1]);
  revolute(balls[1], balls[2]);
  const JointId third = distance(balls[2], balls[3]);
  revolute(balls[3], balls[4]);
  auto check = [](const World& world, int alive) {
    const WorldImpl& impl = world.impl();
    ASSERT_EQ(impl.joint_heads.size(), impl.joints.size());
    int live = 0;
    for (size_t ji = 0; ji < impl.joints.size(); ++ji) {
      const Joint& j = impl.joints[ji];
      const WorldImpl::JointHead& h = impl.joint_heads[ji];
      EXPECT_EQ(h.alive, j.alive) << "joint " << ji;
      live += h.alive;
      if (!j.alive) continue;
      EXPECT_EQ(h.body_a, j.body_a) << "joint " << ji;
      EXPECT_EQ(h.body_b, j.body_b) << "joint " << ji;
      EXPECT_EQ(h.type, j.type) << "joint " << ji;
    }
    EXPECT_EQ(live, alive);
  };
  check(w, 4);
  ASSERT_TRUE(w.destroy_joint(first).ok());
  ASSERT_TRUE(w.destroy_joint(third).ok());
  check(w, 2);
  distance(balls[4], balls[5]);                // the third's slot, another kind and other bodies
  revolute(balls[5], balls[0]);                // the first's
  ASSERT_TRUE(w.destroy_body(balls[1]).ok());  // and its joint with it
  check(w, 3);
  for (int t = 0; t < 5; ++t) w.step();
  World copy;
  ASSERT_TRUE(copy.restore(w.snapshot()).ok());
  check(copy, 3);
  copy.step();
  w.step();
  EXPECT_EQ(copy.snapshot().state_hash, w.snapshot().state_hash);
}

// A tick keeps its world's workers spinning from its first stage to its last and lets them
// sleep after it: every busy span it opens is closed, however many of its stages share the
// work (the large pyramid loads its bodies and solves its contacts on the threads). A span
// left open would keep the workers spinning between ticks.
TEST(WorldTest, AThreadedTickLeavesItsWorkersFreeToSleep) {
  World world = std::move(build_world(scenes::builtin("large_pyramid").value()).value());
  ASSERT_TRUE(world.set_threads(2).ok());
  for (int t = 0; t < 3; ++t) {
    world.step();
    ASSERT_NE(world.impl().pool, nullptr);
    EXPECT_FALSE(world.impl().pool->busy()) << "after tick " << t;
  }
}

// With sleep off every awake body's rest timer is zero after a tick, whether the world just
// turned sleep off with its bodies resting or was restored from a snapshot taken mid-rest
// (update_sleep clears the timers once and then trusts them to stay zero).
TEST(WorldTest, RestTimersAreZeroWithSleepOffAfterATurnOrARestore) {
  World w;
  add_ground(w);
  const BodyId box = add_box(w, Vec2(0.0, 0.5), 0.5);
  for (int t = 0; t < 20; ++t) w.step();  // resting, not yet asleep (0.5 s to sleep)
  auto timer = [&](const World& world) {
    return world.impl().bodies[world.impl().body_index(box)].sleep_time;
  };
  ASSERT_GT(timer(w), 0.0);
  const WorldSnapshot mid_rest = w.snapshot();
  const WorldSettings on = w.settings();
  WorldSettings off = on;
  off.enable_sleep = false;
  ASSERT_TRUE(w.set_settings(off).ok());
  w.step();
  EXPECT_EQ(timer(w), 0.0);
  w.step();
  EXPECT_EQ(timer(w), 0.0);
  // Restored over itself (its timers cleared once already), then sleep off again.
  ASSERT_TRUE(w.restore(mid_rest).ok());
  ASSERT_GT(timer(w), 0.0);
  ASSERT_TRUE(w.set_settings(off).ok());
  w.step();
  EXPECT_EQ(timer(w), 0.0);
  // Back on, the timers run again.
  ASSERT_TRUE(w.set_settings(on).ok());
  w.step();
  EXPECT_GT(timer(w), 0.0);
}

// A kinematic platform moving sideways carries a box resting on it (friction), and is not
// pushed by it (infinite mass). The box starts at rest and friction accelerates it at mu g,
// so it ends v^2 / (2 mu g) = 1 / 12 m behind the platform; 1 cm covers the discrete start.
TEST(WorldTest, KinematicPlatformCarriesABox) {
  World w;
  BodyId platform = add_box(w, Vec2(0.0, 0.0), 2.0, 0.0, 0.6, BodyType::kKinematic);
  ASSERT_TRUE(w.set_linear_velocity(platform, Vec2(1.0, 0.0)).ok());
  BodyId box = add_box(w, Vec2(0.0, 2.5));
  for (int i = 0; i < 180; ++i) w.step();
  // 3 s at 1 m/s: the platform moved exactly 3 m.
  EXPECT_NEAR(position(w, platform).x(), 3.0, 1e-9);
  EXPECT_NEAR(position(w, platform).y(), 0.0, 1e-12);
  EXPECT_NEAR(position(w, box).x(), 3.0 - 1.0 / (2.0 * 0.6 * 10.0), 0.01);
  EXPECT_NEAR(velocity(w, box).x(), 1.0, 1e-6);
  EXPECT_NEAR(position(w, box).y(), 2.5, 0.01);
}

// A ball dropped onto chain terrain rolls down it and never falls through a segment.
TEST(WorldTest, BallStaysOnChainTerrain) {
  World w;
  BodyId terrain = *w.create_body(BodyDef{});
  ChainDef chain;
  for (int i = 0; i <= 20; ++i) chain.points.push_back(Vec2(-10.0 + i, -0.3 * (-10.0 + i)));
  ASSERT_TRUE(w.create_chain(terrain, chain).ok());
  BodyId ball = add_ball(w, Vec2(-8.0, 4.0), 0.3);
  for (int i = 0; i < 240; ++i) {
    w.step();
    Vec2 p = position(w, ball);
    if (p.x() > 9.5) break;  // left the end of the chain
    // Above the line y = -0.3 x by at least the radius (less 2 x slop) when measured along
    // its normal.
    double distance_to_line = (p.y() + 0.3 * p.x()) / std::sqrt(1.0 + 0.09);
    ASSERT_GT(distance_to_line, 0.3 - 0.01) << "tick " << i;
  }
  EXPECT_GT(position(w, ball).x(), -8.0 + 1.0);  // it rolled downhill
}

}  // namespace
}  // namespace fulcrum

namespace fulcrum {
namespace {

// Quadratic drag F = -c v |v|: a falling ball approaches the terminal speed sqrt(m g / c)
// (within 0.5 %). The update, gravity then v / (1 + h c |v| / m) per substep h, settles on
// its own fixed point v^2 + h g v = m g / c exactly (within 1e-9), h g / 2 below the
// continuous answer.
TEST(WorldTest, QuadraticDragGivesTheTerminalVelocity) {
  World w;
  BodyDef def;
  def.type = BodyType::kDynamic;
  def.position = Vec2(0.0, 1000.0);
  def.drag = 0.05;
  BodyId id = *w.create_body(def);
  ShapeDef sd;
  sd.geometry = Circle{Vec2::Zero(), 0.5};
  ASSERT_TRUE(w.create_shape(id, sd).ok());
  double m = w.body_state(id)->mass;
  for (int i = 0; i < 1200; ++i) w.step();
  double terminal = std::sqrt(m * 10.0 / 0.05);
  double speed = -w.body_state(id)->linear_velocity.y();
  EXPECT_NEAR(speed, terminal, 0.005 * terminal);
  double hg = w.settings().dt / w.settings().substeps * 10.0;
  double fixed_point = 0.5 * (-hg + std::sqrt(hg * hg + 4.0 * m * 10.0 / 0.05));
  EXPECT_NEAR(speed, fixed_point, 1e-9 * fixed_point);
  BodyDef bad = def;
  bad.drag = -1.0;
  EXPECT_NE(w.create_body(bad).status().message().find("body.drag"), std::string::npos);
}

}  // namespace
}  // namespace fulcrum
