// The coloured contact lanes (engine/src/contact_lanes.h): the colouring's invariants, which
// make any order within a colour (lanes, threads) give the same bits, and the instruction paths'
// equality on scenes with every kind of lane (two-point and one-point manifolds, static and
// kinematic partners, padding, overflow).
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <variant>
#include <vector>

#include "contact_lanes.h"
#include "fulcrum/simd.h"
#include "fulcrum/state.h"
#include "lane_checks.h"
#include "scene_fixture.h"
#include "world_impl.h"

namespace fulcrum::testing {
namespace {

// A plank on the ground carrying `balls` balls: the plank touches balls + 1 bodies.
SceneDef loaded_plank(int balls) {
  SceneDef s;
  scenes::add_ground(&s, 40.0);
  SceneBody plank;
  plank.def.type = BodyType::kDynamic;
  plank.def.position = Vec2(0.0, 0.1);
  ShapeDef board;
  board.geometry = make_box(0.5 * balls, 0.1);
  plank.shapes.push_back(board);
  s.bodies.push_back(plank);
  for (int i = 0; i < balls; ++i) {
    SceneBody ball;
    ball.def.type = BodyType::kDynamic;
    ball.def.position = Vec2(-0.5 * balls + 0.5 + i, 0.6);
    ShapeDef shape;
    shape.geometry = Circle{Vec2::Zero(), 0.4};
    ball.shapes.push_back(shape);
    s.bodies.push_back(ball);
  }
  return s;
}

// Checks the last tick's colouring of `w` (its world state after the tick is unchanged).
void expect_valid_colouring(const World& w) {
  const WorldImpl& impl = w.impl();
  const ColouredContacts& cc = impl.coloured_contacts;
  const SolverScratch& s = impl.solver_scratch;
  ASSERT_EQ(cc.lane_of_row.size(), s.row_bodies.size());
  ASSERT_EQ(static_cast<int>(cc.colour_start.size()), cc.colours + 1);
  // Every row has its own lane, holding its bodies (the ones it was coloured by).
  std::set<int> lanes_used(cc.lane_of_row.begin(), cc.lane_of_row.end());
  EXPECT_EQ(lanes_used.size(), s.row_bodies.size());
  for (size_t k = 0; k < s.row_bodies.size(); ++k) {
    const int lane = cc.lane_of_row[k];
    const ContactBlock& b = cc.blocks[lane / kBlockLanes];
    EXPECT_EQ(b.ia[lane % kBlockLanes], s.row_bodies[k].ia);
    EXPECT_EQ(b.ib[lane % kBlockLanes], s.row_bodies[k].ib);
  }
  expect_each_body_written_once_per_colour(cc.blocks, cc.colour_start, cc.colours, s.bodies);
}

TEST(ContactLanes, ColoursNeverShareADynamicBody) {
  World w = build(pyramid(20));
  for (int i = 0; i < 30; ++i) w.step();
  const ColouredContacts& cc = w.impl().coloured_contacts;
  // 210 boxes, about 2 contacts each: many blocks, no overflow (a box touches at most 6).
  EXPECT_GT(w.impl().solver_scratch.row_bodies.size(), 300u);
  EXPECT_EQ(cc.overflow, 0);
  expect_valid_colouring(w);
}

TEST(ContactLanes, ABodyWithMoreContactsThanColoursOverflows) {
  World w = build(loaded_plank(40));
  for (int i = 0; i < 10; ++i) w.step();
  const ColouredContacts& cc = w.impl().coloured_contacts;
  // The plank touches 40 balls and the ground: 41 contacts, at most kMaxColours coloured.
  EXPECT_EQ(w.impl().solver_scratch.row_bodies.size(), 41u);
  EXPECT_EQ(cc.overflow, 41 - kMaxColours);
  expect_valid_colouring(w);
  // The overflow is solved one by one like any other row: the balls rest on the plank.
  for (int i = 0; i < 120; ++i) w.step();
  EXPECT_LT(w.metrics().max_penetration, 0.01);
  EXPECT_LT(w.metrics().max_speed, 0.05);
}

// A pass's rule as solve_group makes it for the world's settings.
LaneRule pass_rule(const WorldImpl& impl, bool use_bias) {
  const WorldSettings& set = impl.settings;
  const double h = set.dt / set.substeps;
  LaneRule rule;
  rule.inv_h = 1.0 / h;
  rule.max_speed = set.max_correction_speed;
  rule.use_bias = use_bias;
  rule.soft = make_softness(set.contact_hertz, set.contact_damping_ratio, h);
  rule.static_soft = make_softness(2.0 * set.contact_hertz, set.contact_damping_ratio, h);
  return rule;
}

// The last relax pass of a substep gathers the next substep's warm start (LaneRule::warm_next):
// what it adds to the rows is, bit for bit, what a warm-start pass applies to bodies at rest
// with the impulses the relax pass leaves, on every path and with an overflow. Most rows are
// not zero: the pyramid's and the plank's contacts carry loads.
void expect_relax_gathers_the_warm_start(const SceneDef& scene) {
  for (SimdPath path : supported_simd_paths()) {
    ASSERT_TRUE(set_simd_path(path).ok());
    World w = build(scene);
    for (int i = 0; i < 30; ++i) w.step();
    WorldImpl& impl = w.impl();
    ColouredContacts& cc = impl.coloured_contacts;
    LargeVector<SolverBody> bodies = impl.solver_scratch.bodies;
    std::vector<VelocityBefore> gathered(bodies.size());
    LaneRule relax = pass_rule(impl, false);
    relax.warm_next = gathered.data();
    solve_coloured(cc, bodies.data(), relax, nullptr);
    expect_gathered_warm_start(
        gathered, bodies, [&](SolverBody* rest) { warm_start_coloured(cc, rest, nullptr); },
        simd_path_name(path));
  }
  ASSERT_TRUE(set_simd_path(SimdPath::kAuto).ok());
}

TEST(ContactLanes, TheLastRelaxPassGathersTheWarmStartAWarmStartPassApplies) {
  expect_relax_gathers_the_warm_start(pyramid(12));
  expect_relax_gathers_the_warm_start(loaded_plank(40));
}

// Without joints or restitution, solve_group takes the next substep's warm start as each body's
// change of velocity over the substep (less its forces and speed caps) instead of gathering it:
// the warm start and each pass change the velocities by J^T of the impulses they add, at anchors
// fixed for the tick, so a substep changes them by J^T of its final impulses, what a warm-start
// pass applies to bodies at rest. Equal to rounding: the changes are about g h = 0.04 m/s here,
// each summed over a few dozen rows in another order, far below 1e-12.
TEST(ContactLanes, ASubstepsChangeOfVelocityIsTheWarmStartOfItsFinalImpulses) {
  for (SimdPath path : supported_simd_paths()) {
    ASSERT_TRUE(set_simd_path(path).ok());
    World w = build(pyramid(12));
    for (int i = 0; i < 30; ++i) w.step();
    WorldImpl& impl = w.impl();
    ColouredContacts& cc = impl.coloured_contacts;
    const LargeVector<SolverBody> before = impl.solver_scratch.bodies;
    LargeVector<SolverBody> bodies = before;
    warm_start_coloured(cc, bodies.data(), nullptr);
    solve_coloured(cc, bodies.data(), pass_rule(impl, true), nullptr);
    solve_coloured(cc, bodies.data(), pass_rule(impl, true), nullptr);
    solve_coloured(cc, bodies.data(), pass_rule(impl, false), nullptr);
    LargeVector<SolverBody> at_rest = bodies;
    for (SolverBody& b : at_rest) b.vx = b.vy = b.w = 0.0;
    warm_start_coloured(cc, at_rest.data(), nullptr);
    int loaded = 0;
    for (size_t i = 0; i < bodies.size(); ++i) {
      EXPECT_NEAR(bodies[i].vx - before[i].vx, at_rest[i].vx, 1e-12) << simd_path_name(path);
      EXPECT_NEAR(bodies[i].vy - before[i].vy, at_rest[i].vy, 1e-12) << simd_path_name(path);
      EXPECT_NEAR(bodies[i].w - before[i].w, at_rest[i].w, 1e-12) << simd_path_name(path);
      loaded += at_rest[i].vy > 0.01;
    }
    EXPECT_GT(loaded, static_cast<int>(bodies.size()) / 2) << simd_path_name(path);
  }
  ASSERT_TRUE(set_simd_path(SimdPath::kAuto).ok());
}

TEST(ContactLanes, EveryPathGivesTheScalarBits) {
  expect_simd_paths_agree(pyramid(12), 120);
  expect_simd_paths_agree(loaded_plank(40), 60);
}

// Any thread count gives one thread's state hash at every tick, on scenes large enough that
// the step shares out its colours, narrow phase and integration.
void expect_threads_agree(const SceneDef& scene, int ticks) {
  std::vector<uint64_t> reference;
  for (int threads = 1; threads <= 4; ++threads) {
    World w = build(scene);
    ASSERT_TRUE(w.set_threads(threads).ok());
    EXPECT_EQ(w.threads(), threads);
    for (int i = 0; i < ticks; ++i) {
      w.step();
      if (threads == 1) {
        reference.push_back(w.state_hash());
      } else {
        ASSERT_EQ(w.state_hash(), reference[i]) << threads << " threads, tick " << i + 1;
      }
      if (threads == 1 && i == 10) {
        // The scene really is shared out (before it falls asleep): colours of several chunks.
        const ColouredContacts& cc = w.impl().coloured_contacts;
        EXPECT_GE(w.impl().solver_scratch.row_bodies.size(), 256u);
        EXPECT_GE(cc.colour_start[1] - cc.colour_start[0], 2 * kBlocksPerChunk);
      }
    }
  }
}

TEST(ContactLanes, EveryThreadCountGivesOneThreadsBits) {
  expect_threads_agree(pyramid(24), 90);
  SceneDef plank = loaded_plank(40);
  scenes::PyramidOptions p;
  p.base = 24;
  p.origin = Vec2(60.0, 0.0);
  scenes::add_ground(&plank, 100.0);
  scenes::add_pyramid(&plank, p);
  expect_threads_agree(plank, 60);
}

// Two wide boxes on the ground, a ball resting on each (bodies 1 to 4: boxes, then balls).
SceneDef balls_on_boxes() {
  SceneDef s;
  s.settings.enable_sleep = false;  // rows that stay
  scenes::add_ground(&s, 20.0);
  auto add = [&](Vec2 at, const Geometry& g) {
    SceneBody b;
    b.def.type = BodyType::kDynamic;
    b.def.position = at;
    ShapeDef shape;
    shape.geometry = g;
    b.shapes.push_back(shape);
    s.bodies.push_back(b);
  };
  add(Vec2(-3.0, 0.25), make_box(1.5, 0.25));
  add(Vec2(3.0, 0.25), make_box(1.5, 0.25));
  add(Vec2(-3.5, 0.9), Circle{Vec2::Zero(), 0.4});
  add(Vec2(3.0, 0.9), Circle{Vec2::Zero(), 0.4});
  return s;
}

// A tick whose rows have the slots of the last layout's, their bodies as dynamic as then,
// keeps that layout; any other lays its rows out anew. Either way the bits are those of a world
// restored from its own snapshot before every tick (a new world lays its rows out every tick).
// Moving the second ball onto the first box keeps the number of rows but not their colours:
// both balls' rows now write the first box.
TEST(ContactLanes, AKeptLayoutGivesTheBitsOfANewOne) {
  auto edit = [](World& w, int tick) {
    const BodyId ball = w.bodies()[4];
    if (tick == 10) {  // a push: the same rows, new velocities
      ASSERT_TRUE(w.apply_linear_impulse(ball, Vec2(0.3, 0.0), Vec2(3.0, 1.2)).ok());
    } else if (tick == 20) {  // onto the first box, beside the other ball
      ASSERT_TRUE(w.set_transform(ball, Vec2(-2.4, 0.9), 0.0).ok());
    }
  };
  int64_t settled = 0;
  size_t rows = 0;
  expect_restored_every_tick_agrees(balls_on_boxes(), 60, edit, [&](const World& kept, int tick) {
    expect_valid_colouring(kept);
    const int64_t layouts = kept.impl().coloured_contacts.layouts;
    if (tick == 1) settled = layouts;
    if (tick == 19) {
      EXPECT_EQ(layouts, settled);  // the same rows from the second tick to the move
    }
    if (tick == 20) {
      EXPECT_EQ(layouts, settled + 1);
    }
    rows = kept.impl().solver_scratch.row_bodies.size();
  });
  EXPECT_EQ(rows, 4u);
}

void add_bouncing_ball(SceneDef* s, Vec2 at, double radius) {
  SceneBody ball;
  ball.def.type = BodyType::kDynamic;
  ball.def.position = at;
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), radius};
  shape.restitution = 0.5;
  ball.shapes.push_back(shape);
  s->bodies.push_back(ball);
}

// Balls of restitution 0.5 rained onto a pyramid of boxes without it, and one ball dropped
// alone from 5 m (the last body): bouncing lanes share blocks with lanes that do not bounce,
// in colours and in the overflow (the loaded plank's balls bounce too).
SceneDef bouncing_rain() {
  SceneDef s = loaded_plank(40);
  for (SceneBody& b : s.bodies) {
    for (ShapeDef& shape : b.shapes) {
      if (std::holds_alternative<Circle>(shape.geometry)) shape.restitution = 0.5;
    }
  }
  scenes::PyramidOptions p;
  p.base = 16;
  p.origin = Vec2(28.0, 0.0);
  scenes::add_pyramid(&s, p);
  for (int i = 0; i < 200; ++i) {
    add_bouncing_ball(&s, Vec2(20.0 + 0.8 * (i % 25), 18.0 + 0.8 * (i / 25)), 0.3);
  }
  add_bouncing_ball(&s, Vec2(-30.0, 5.0), 0.5);
  return s;
}

TEST(ContactLanes, BouncingLanesGiveTheScalarBitsOnEveryPathAndThreadCount) {
  const SceneDef scene = bouncing_rain();
  expect_simd_paths_agree(scene, 120);
  expect_threads_agree(scene, 120);
}

TEST(ContactLanes, ABallLeavesTheGroundAtHalfItsSpeedOfImpact) {
  World w = build(bouncing_rain());
  const BodyId lone = w.bodies().back();
  // Falling 4.5 m onto the ground (its top at y = 0), the ball meets it at sqrt(2 g 4.5) m/s
  // whichever substep the contact closes in; it leaves at half that speed. The lanes track
  // the speed at impact substep by substep (the speed at the tick's start would be up to
  // g dt = 0.17 m/s short); 0.5 % of 9.5 m/s is what the soft contact's give may cost.
  const double impact = std::sqrt(2.0 * 10.0 * 4.5);
  double rebound = 0.0;
  for (int i = 0; i < 90; ++i) {
    w.step();
    rebound = std::max(rebound, w.body_state(lone)->linear_velocity.y());
  }
  EXPECT_NEAR(rebound, 0.5 * impact, 0.005 * impact);
}

// Seven free boxes far apart, without gravity, spinning from rest to past the turn-rate cap:
// the bodies are integrated in lanes of 2 or 4 and the rest one by one, and a lane group whose
// turn per substep exceeds pi/4 takes det_sincos lane by lane.
SceneDef free_spins() {
  SceneDef s;
  s.settings.gravity = Vec2::Zero();
  const double rates[] = {0.0, 0.5, -3.0, 150.0, 200.0, -300.0, 1000.0};
  for (int i = 0; i < 7; ++i) {
    SceneBody b;
    b.def.type = BodyType::kDynamic;
    b.def.position = Vec2(10.0 * i, 0.0);
    b.def.angular_velocity = rates[i];
    b.def.linear_velocity = Vec2(i == 6 ? 500.0 : 0.0, 0.0);
    ShapeDef box;
    box.geometry = make_box(0.5, 0.25);
    b.shapes.push_back(box);
    s.bodies.push_back(b);
  }
  return s;
}

TEST(ContactLanes, FreeSpinsTurnByTheirRateOnEveryPath) {
  const SceneDef scene = free_spins();
  expect_simd_paths_agree(scene, 30);
  World w = build(scene);
  w.step();
  const std::vector<BodyId> ids = w.bodies();
  // -300 rad/s turns 1.25 rad a substep (beyond pi/4: det_sincos reduces it), -5 rad a tick;
  // four normalized products of rotations are within a few ulp of the exact one.
  const Transform xf = w.body_state(ids[5])->transform;
  EXPECT_NEAR(xf.q.c, std::cos(-5.0), 1e-13);
  EXPECT_NEAR(xf.q.s, std::sin(-5.0), 1e-13);
  // 1000 rad/s is capped at half a turn a substep, pi / h; 500 m/s at max_linear_speed.
  const double h = scene.settings.dt / scene.settings.substeps;
  EXPECT_DOUBLE_EQ(w.body_state(ids[6])->angular_velocity, M_PI / h);
  EXPECT_DOUBLE_EQ(w.body_state(ids[6])->linear_velocity.x(), scene.settings.max_linear_speed);
}

TEST(ContactLanes, ThreadsAreCheckedAndSurviveARestore) {
  World w = build(pyramid(4));
  EXPECT_FALSE(w.set_threads(0).ok());
  Status too_many = w.set_threads(World::kMaxThreads + 1);
  ASSERT_FALSE(too_many.ok());
  EXPECT_NE(too_many.message().find("threads"), std::string::npos);
  EXPECT_EQ(w.threads(), 1);
  ASSERT_TRUE(w.set_threads(3).ok());
  for (int i = 0; i < 5; ++i) w.step();
  WorldSnapshot snap = w.snapshot();
  ASSERT_TRUE(w.restore(snap).ok());
  EXPECT_EQ(w.threads(), 3);  // an execution setting, not state
  ASSERT_TRUE(w.set_threads(1).ok());
  EXPECT_EQ(w.threads(), 1);
}

TEST(ContactLanes, PathNamesParseAndUnsupportedPathsAreRefused) {
  for (SimdPath p : {SimdPath::kAuto, SimdPath::kScalar, SimdPath::kLanes2, SimdPath::kLanes4,
                     SimdPath::kAvx512}) {
    Result<SimdPath> parsed = parse_simd_path(simd_path_name(p));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, p);
  }
  Result<SimdPath> bad = parse_simd_path("avx1024");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("avx1024"), std::string::npos);
  // The scalar and 2-lane paths run on every CPU Fulcrum builds for.
  std::vector<SimdPath> supported = supported_simd_paths();
  ASSERT_GE(supported.size(), 2u);
  EXPECT_EQ(supported[0], SimdPath::kScalar);
  EXPECT_EQ(supported[1], SimdPath::kLanes2);
  ASSERT_TRUE(set_simd_path(SimdPath::kAuto).ok());
  EXPECT_NE(active_simd_path(), SimdPath::kAuto);  // auto resolves to a path this CPU runs
}

}  // namespace
}  // namespace fulcrum::testing
