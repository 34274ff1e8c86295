// The coloured contact lanes (engine/src/contact_lanes.h): the colouring's invariants, which
// make any order within a colour (lanes, threads) give the same bits, and the instruction paths'
// equality on scenes with every kind of lane (two-point and one-point manifolds, static and
// kinematic partners, padding, overflow).
#include <gtest/gtest.h>

#include <set>
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
