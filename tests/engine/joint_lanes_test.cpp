// The plain revolute points in lanes (engine/src/joint_lanes.h): the colouring's invariants,
// which make any order within a colour (lanes, threads) give the same bits; the overflow and
// the rows left to the one-by-one solver; and the instruction paths' and thread counts'
// equality on worlds with every kind of lane (static partners, padding, overflow, capped
// feedback).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <vector>

#include "fulcrum/simd.h"
#include "fulcrum/trig.h"
#include "joint_lanes.h"
#include "lane_checks.h"
#include "scene_fixture.h"
#include "world_impl.h"

namespace fulcrum::testing {
namespace {

SceneBody ball(const Vec2& at, double radius, BodyType type = BodyType::kDynamic) {
  SceneBody b;
  b.def.type = type;
  b.def.position = at;
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), radius};
  b.shapes.push_back(shape);
  return b;
}

void pin(SceneDef* s, int a, int b, const Vec2& world_anchor) {
  RevoluteJointDef def;
  def.local_anchor_a = world_anchor - s->bodies[a].def.position;
  def.local_anchor_b = world_anchor - s->bodies[b].def.position;
  s->joints.push_back(SceneJoint{a, b, def});
}

// n x n circles 1 m apart, each pinned to its right and lower neighbours at the midpoint
// (HARD_CASES 9 in small); the top row's first and last circles are static.
SceneDef grid(int n) {
  SceneDef s;
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      const bool fixed = row == 0 && (col == 0 || col == n - 1);
      s.bodies.push_back(
          ball(Vec2(col, 20.0 - row), 0.4, fixed ? BodyType::kStatic : BodyType::kDynamic));
    }
  }
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      const int i = row * n + col;
      if (col + 1 < n) pin(&s, i, i + 1, Vec2(col + 0.5, 20.0 - row));
      if (row + 1 < n) pin(&s, i, i + n, Vec2(col, 19.5 - row));
    }
  }
  return s;
}

// A wheel: a dynamic hub pinned to a static anchor, with `spokes` balls pinned to it around
// its rim (more than kMaxColours: the hub is in every one), one of them by a revolute joint
// with an angle limit (not a plain point). Without gravity, every joint created `apart` from
// its place, so that the feedback runs at its cap. The hub is ten times as dense as the spokes:
// at equal density 20 or more spokes of this wheel outweigh its inertia so far that the pins
// swing apart, with or without lanes.
SceneDef wheel(int spokes, double apart) {
  SceneDef s;
  s.settings.gravity = Vec2::Zero();
  s.bodies.push_back(ball(Vec2::Zero(), 0.1, BodyType::kStatic));
  s.bodies.push_back(ball(Vec2::Zero(), 1.0));
  s.bodies.back().shapes[0].density = 10.0;
  pin(&s, 0, 1, Vec2::Zero());
  for (int k = 0; k < spokes; ++k) {
    const double a = 2.0 * kPi * k / spokes;
    const Vec2 dir(std::cos(a), std::sin(a));
    s.bodies.push_back(ball((3.0 + apart) * dir, 0.2));
    s.bodies.back().def.linear_velocity = Vec2(-dir.y(), dir.x());
    RevoluteJointDef def;  // the hub's point 3 m out to the spoke's centre
    def.local_anchor_a = 3.0 * dir;
    s.joints.push_back(SceneJoint{1, static_cast<int>(s.bodies.size()) - 1, def});
  }
  auto& limited = std::get<RevoluteJointDef>(s.joints.back().def);
  limited.enable_limit = true;
  limited.lower_angle = -0.5;
  limited.upper_angle = 0.5;
  return s;
}

// Checks the last tick's colouring of `w`.
void expect_valid_colouring(const World& w) {
  const WorldImpl& impl = w.impl();
  const ColouredPoints& cp = impl.coloured_points;
  const SolverScratch& s = impl.solver_scratch;
  // A pin's JointRow is not kept on a tick that keeps its layout: its slots are.
  const std::vector<SolverScratch::RowSlots>& rows = s.joint_row_slots;
  ASSERT_EQ(cp.lane_of_row.size(), rows.size());
  ASSERT_EQ(static_cast<int>(cp.colour_start.size()), cp.colours + 1);
  // Every plain point has its own lane holding its bodies; every other row is left to the
  // one-by-one solver, in row order.
  std::set<int> lanes_used;
  std::vector<int> others;
  for (size_t k = 0; k < rows.size(); ++k) {
    const int lane = cp.lane_of_row[k];
    if (!rows[k].plain_point) {
      EXPECT_EQ(lane, -1);
      others.push_back(static_cast<int>(k));
      continue;
    }
    ASSERT_GE(lane, 0);
    EXPECT_TRUE(lanes_used.insert(lane).second);
    const PointBlock& b = cp.blocks[lane / kBlockLanes];
    EXPECT_EQ(b.ia[lane % kBlockLanes], rows[k].ia);
    EXPECT_EQ(b.ib[lane % kBlockLanes], rows[k].ib);
  }
  EXPECT_EQ(static_cast<int>(lanes_used.size()), cp.points);
  EXPECT_EQ(cp.other_rows, others);
  expect_each_body_written_once_per_colour(cp.blocks, cp.colour_start, cp.colours, s.bodies);
}

TEST(JointLanes, ColoursNeverShareAMovableBody) {
  World w = build(grid(12));
  for (int i = 0; i < 20; ++i) w.step();
  const ColouredPoints& cp = w.impl().coloured_points;
  // 264 pins; a circle holds at most 4, so a handful of colours and no overflow.
  EXPECT_EQ(cp.points, 264);
  EXPECT_LE(cp.colours, 6);
  EXPECT_EQ(cp.colour_start[cp.colours], static_cast<int>(cp.blocks.size()));
  EXPECT_TRUE(cp.other_rows.empty());
  expect_valid_colouring(w);
}

TEST(JointLanes, AHubWithMorePinsThanColoursOverflowsAndLimitedJointsStayRows) {
  World w = build(wheel(30, 0.0));
  w.step();
  const ColouredPoints& cp = w.impl().coloured_points;
  // 31 joints on the hub: 30 plain points (the anchor's and 29 spokes'), 24 coloured, 6 in the
  // overflow; the limited spoke is a row of its own.
  EXPECT_EQ(cp.points, 30);
  EXPECT_EQ(cp.colours, kMaxColours);
  const int overflow_blocks = static_cast<int>(cp.blocks.size()) - cp.colour_start[cp.colours];
  EXPECT_EQ(overflow_blocks, 1);
  EXPECT_EQ(cp.other_rows.size(), 1u);
  expect_valid_colouring(w);
  // The wheel turns as one body: after 2 s every pin holds within a millimetre.
  for (int i = 0; i < 120; ++i) w.step();
  EXPECT_TRUE(all_finite(w));
  EXPECT_LT(w.metrics().max_joint_error, 1e-3);
}

// The last relax pass of a substep gathers the pins' next warm start (PointRule::warm_next):
// what it adds to the rows is, bit for bit, what the pins' warm-start pass applies to bodies at
// rest with the impulses the relax pass leaves, on every path.
TEST(JointLanes, TheLastRelaxPassGathersTheWarmStartAWarmStartPassApplies) {
  for (SimdPath path : supported_simd_paths()) {
    ASSERT_TRUE(set_simd_path(path).ok());
    World w = build(grid(9));
    for (int i = 0; i < 30; ++i) w.step();
    WorldImpl& impl = w.impl();
    ColouredPoints& cp = impl.coloured_points;
    ASSERT_GT(cp.points, 100);
    std::vector<SolverBody> bodies = impl.solver_scratch.bodies;
    std::vector<VelocityBefore> gathered(bodies.size());
    PointRule relax;
    relax.use_bias = false;
    relax.warm_next = gathered.data();
    solve_points(cp, bodies.data(), relax, nullptr);
    expect_gathered_warm_start(
        gathered, bodies, [&](SolverBody* rest) { warm_start_points(cp, rest, nullptr); },
        simd_path_name(path));
  }
  ASSERT_TRUE(set_simd_path(SimdPath::kAuto).ok());
}

TEST(JointLanes, EveryPathGivesTheScalarBits) {
  expect_simd_paths_agree(grid(9), 90);
  // Pins 0.5 m out of place close at the cap: the capped lanes' own arithmetic.
  SceneDef apart = wheel(30, 0.5);
  World probe = build(apart);
  probe.step();
  EXPECT_GT(probe.metrics().max_joint_error, 0.3);
  expect_simd_paths_agree(apart, 60);
}

TEST(JointLanes, EveryThreadCountGivesOneThreadsBits) {
  // 760 pins: colours of several chunks each.
  expect_thread_counts_agree(grid(20), 60, {1, 2, 3, 4}, [](const World& w) {
    const ColouredPoints& cp = w.impl().coloured_points;
    EXPECT_GE(cp.colour_start[1] - cp.colour_start[0], 2 * kBlocksPerChunk);
  });
}

// A tick whose rows are the last tick's joints with the same slots and kinds keeps its layout
// and writes the pins straight into their lanes; an edit that changes a row lays the points out
// anew. Either way the bits are those of a world restored from its own snapshot before every
// tick (a new world: it lays its points out at every tick).
TEST(JointLanes, AKeptLayoutGivesTheBitsOfANewOne) {
  auto edit = [](World& w, int tick) {
    const std::vector<BodyId> bodies = w.bodies();
    if (tick == 10) {  // a pin less: every later row moves up one
      ASSERT_TRUE(w.destroy_joint(w.joints()[7]).ok());
    } else if (tick == 20) {  // a limited joint: a row that is not a pin
      RevoluteJointDef def;
      def.body_a = bodies[8];
      def.body_b = bodies[15];
      def.local_anchor_a = Vec2(0.5, -0.5);
      def.local_anchor_b = Vec2(-0.5, 0.5);
      def.enable_limit = true;
      def.lower_angle = -0.2;
      def.upper_angle = 0.2;
      ASSERT_TRUE(w.create_revolute_joint(def).ok());
    } else if (tick == 30) {  // a body moved: the same rows, every pin of it with new anchors
      const BodyState b = w.body_state(bodies[20]).value();
      ASSERT_TRUE(
          w.set_transform(bodies[20], b.transform.p + Vec2(0.1, -0.05), b.transform.q.angle() + 0.3)
              .ok());
    } else if (tick == 40) {  // threads: the other rows grouped for them
      ASSERT_TRUE(w.set_threads(2).ok());
    }
  };
  int64_t layouts = 0;
  double joint_error = 0.0;
  expect_restored_every_tick_agrees(grid(6), 60, edit, [&](const World& kept, int) {
    expect_valid_colouring(kept);
    layouts = kept.impl().coloured_points.layouts;
    joint_error = kept.metrics().max_joint_error;
  });
  // Laid out at the first tick and after the joint destroyed, the joint created and the
  // threads: the moved body kept its layout.
  EXPECT_EQ(layouts, 4);
  EXPECT_GT(joint_error, 0.0);
}

// 50 ragdolls (limited revolute joints: rows of their own, a group per ragdoll), and six
// two-link chains of limited joints hanging from the ground: the ground is the static slot, so
// those chains' rows are one group.
SceneDef ragdolls_and_hanging_chains() {
  SceneDef s = scenes::builtin("ragdolls").value();
  const int ground = 0;
  for (int k = 0; k < 6; ++k) {
    const double x = -20.0 + 8.0 * k;
    for (int link = 0; link < 2; ++link) {
      s.bodies.push_back(ball(Vec2(x, 30.0 - link), 0.3));
      const int b = static_cast<int>(s.bodies.size()) - 1;
      RevoluteJointDef def;
      const Vec2 anchor(x, 30.5 - link);
      def.local_anchor_a = anchor - s.bodies[link == 0 ? ground : b - 1].def.position;
      def.local_anchor_b = anchor - s.bodies[b].def.position;
      def.enable_limit = true;
      def.lower_angle = -0.3;
      def.upper_angle = 0.3;
      s.joints.push_back(SceneJoint{link == 0 ? ground : b - 1, b, def});
    }
  }
  return s;
}

// Checks the last tick's groups of the rows that are not plain points (ColouredPoints).
void expect_valid_groups(const World& w) {
  const ColouredPoints& cp = w.impl().coloured_points;
  const std::vector<JointRow>& rows = w.impl().solver_scratch.joint_rows;
  ASSERT_GE(cp.chunk_start.size(), 3u);
  ASSERT_EQ(cp.chunk_start.front(), 0);
  ASSERT_EQ(cp.chunk_start.back(), static_cast<int>(cp.grouped_rows.size()));
  // The same rows as other_rows.
  std::vector<int> sorted = cp.grouped_rows;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted, cp.other_rows);
  std::map<int, int> chunk_of_slot, last_row_of_slot;
  for (size_t c = 0; c + 1 < cp.chunk_start.size(); ++c) {
    if (c + 2 < cp.chunk_start.size()) {
      EXPECT_GE(cp.chunk_start[c + 1] - cp.chunk_start[c], kRowsPerJointChunk);
    }
    for (int i = cp.chunk_start[c]; i < cp.chunk_start[c + 1]; ++i) {
      const int k = cp.grouped_rows[i];
      for (int slot : {rows[k].ia, rows[k].ib}) {
        // A slot is written by one chunk only, by its rows in row order.
        auto [chunk, fresh] = chunk_of_slot.emplace(slot, static_cast<int>(c));
        EXPECT_EQ(chunk->second, static_cast<int>(c)) << "slot " << slot;
        if (!fresh) {
          EXPECT_LT(last_row_of_slot[slot], k) << "slot " << slot;
        }
        last_row_of_slot[slot] = k;
      }
    }
  }
}

TEST(JointLanes, OtherRowsInGroupsShareNoBodyAcrossChunks) {
  SceneDef scene = ragdolls_and_hanging_chains();
  World one = build(scene);
  one.step();
  // 512 rows of limited joints; one thread needs no groups.
  EXPECT_EQ(one.impl().coloured_points.other_rows.size(), 512u);
  EXPECT_TRUE(one.impl().coloured_points.chunk_start.empty());
  World two = build(scene);
  ASSERT_TRUE(two.set_threads(2).ok());
  for (int i = 0; i < 90; ++i) {
    two.step();
    if (i == 0 || i == 89) expect_valid_groups(two);
  }
}

TEST(JointLanes, GroupsOfOtherRowsGiveOneThreadsBits) {
  // The ragdolls fall, land and tangle for 1.5 s, their groups shared among threads.
  expect_thread_counts_agree(ragdolls_and_hanging_chains(), 90, {1, 2, 3, 4}, [](const World& w) {
    EXPECT_EQ(w.impl().coloured_points.chunk_start.empty(), w.threads() == 1);
  });
}

}  // namespace
}  // namespace fulcrum::testing
