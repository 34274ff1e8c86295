// The plain revolute points in lanes (engine/src/joint_lanes.h): the colouring's invariants,
// which make any order within a colour (lanes, threads) give the same bits; the overflow and
// the rows left to the one-by-one solver; and the instruction paths' and thread counts'
// equality on worlds with every kind of lane (static partners, padding, overflow, capped
// feedback).
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
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

// Checks the last tick's colourings of `w`: the plain points' and the other revolute joints'.
void expect_valid_colouring(const World& w) {
  const WorldImpl& impl = w.impl();
  const ColouredPoints& cp = impl.coloured_points;
  const ColouredRevolutes& rv = cp.revolutes;
  const SolverScratch& s = impl.solver_scratch;
  // A revolute joint's JointRow is not kept on a tick that keeps its layout: its slots are.
  const std::vector<SolverScratch::RowSlots>& rows = s.joint_row_slots;
  ASSERT_EQ(cp.lane_of_row.size(), rows.size());
  ASSERT_EQ(static_cast<int>(cp.colour_start.size()), cp.colours + 1);
  ASSERT_EQ(static_cast<int>(rv.colour_start.size()), rv.colours + 1);
  // Every revolute joint has its own lane holding its bodies, among the points' blocks or the
  // other revolute joints'; every other row is left to the one-by-one solver, in row order.
  std::set<int> points_used, revolutes_used;
  std::vector<int> others;
  for (size_t k = 0; k < rows.size(); ++k) {
    const int lane = cp.lane_of_row[k];
    if (!rows[k].plain_point && !rows[k].revolute) {
      EXPECT_EQ(lane, -1);
      others.push_back(static_cast<int>(k));
      continue;
    }
    ASSERT_GE(lane, 0);
    const PointBlock* b = nullptr;
    if (rows[k].plain_point) {
      EXPECT_TRUE(points_used.insert(lane).second);
      b = &cp.blocks[lane / kBlockLanes];
    } else {
      EXPECT_TRUE(revolutes_used.insert(lane).second);
      b = &rv.blocks[lane / kBlockLanes];
    }
    EXPECT_EQ(b->ia[lane % kBlockLanes], rows[k].ia);
    EXPECT_EQ(b->ib[lane % kBlockLanes], rows[k].ib);
  }
  EXPECT_EQ(static_cast<int>(points_used.size()), cp.points);
  EXPECT_EQ(static_cast<int>(revolutes_used.size()), rv.joints);
  EXPECT_EQ(cp.other_rows, others);
  expect_each_body_written_once_per_colour(cp.blocks, cp.colour_start, cp.colours, s.bodies);
  expect_each_body_written_once_per_colour(rv.blocks, rv.colour_start, rv.colours, s.bodies);
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

TEST(JointLanes, AHubWithMorePinsThanColoursOverflowsAndLimitedJointsHaveLanesOfTheirOwn) {
  World w = build(wheel(30, 0.0));
  w.step();
  const ColouredPoints& cp = w.impl().coloured_points;
  // 31 joints on the hub: 30 plain points (the anchor's and 29 spokes'), 24 coloured, 6 in the
  // overflow; the limited spoke is coloured on its own, among the other revolute joints.
  EXPECT_EQ(cp.points, 30);
  EXPECT_EQ(cp.colours, kMaxColours);
  const int overflow_blocks = static_cast<int>(cp.blocks.size()) - cp.colour_start[cp.colours];
  EXPECT_EQ(overflow_blocks, 1);
  EXPECT_EQ(cp.revolutes.joints, 1);
  EXPECT_EQ(cp.revolutes.colours, 1);
  EXPECT_TRUE(cp.other_rows.empty());
  expect_valid_colouring(w);
  // The wheel turns as one body: after 2 s every pin holds within a millimetre.
  for (int i = 0; i < 120; ++i) w.step();
  EXPECT_TRUE(all_finite(w));
  EXPECT_LT(w.metrics().max_joint_error, 1e-3);
}

// The last relax pass of a substep gathers the lanes' next warm start (PointRule::warm_next):
// what it adds to the rows is, bit for bit, what the lanes' warm-start pass applies to bodies at
// rest with the impulses the relax pass leaves, on every path, after `ticks` ticks of `scene`.
void expect_relax_gathers_the_warm_start(const SceneDef& scene, int ticks) {
  for (SimdPath path : supported_simd_paths()) {
    ASSERT_TRUE(set_simd_path(path).ok());
    World w = build(scene);
    for (int i = 0; i < ticks; ++i) w.step();
    WorldImpl& impl = w.impl();
    ColouredPoints& cp = impl.coloured_points;
    ASSERT_GT(cp.points + cp.revolutes.joints, 100);
    LargeVector<SolverBody> bodies = impl.solver_scratch.bodies;
    std::vector<VelocityBefore> gathered(bodies.size());
    PointRule relax;
    relax.use_bias = false;
    relax.warm_next = gathered.data();
    relax.h = impl.settings.dt / impl.settings.substeps;
    relax.inv_h = 1.0 / relax.h;
    solve_points(cp, bodies.data(), impl.solver_scratch.body_extras.data(), relax, nullptr);
    expect_gathered_warm_start(
        gathered, bodies, [&](SolverBody* rest) { warm_start_points(cp, rest, nullptr); },
        simd_path_name(path));
  }
  ASSERT_TRUE(set_simd_path(SimdPath::kAuto).ok());
}

TEST(JointLanes, TheLastRelaxPassGathersTheWarmStartAWarmStartPassApplies) {
  expect_relax_gathers_the_warm_start(grid(9), 30);
}

// The passes of a tick as solve_group runs them, for every count of substeps and iterations:
// a pass reads the lanes' 1 / det K only when a pass since the bodies last moved kept it, and a
// pass keeps it only when a later pass reads it before they move again.
TEST(JointLanes, APassReadsTheKeptInverseDeterminantOnlyBeforeTheBodiesMove) {
  for (int substeps = 1; substeps <= 4; ++substeps) {
    for (int vel = 0; vel <= 3; ++vel) {
      for (int relax = 0; relax <= 3; ++relax) {
        SCOPED_TRACE(::testing::Message() << substeps << " x " << vel << " + " << relax);
        bool kept = false;         // kept since the bodies last moved
        bool wanted = false;       // a pass kept it and none has read it yet
        bool kept_unread = false;  // a keep the bodies' motion made useless
        auto pass = [&](PointMassUse u) {
          EXPECT_FALSE(u.read && u.keep);
          if (u.read) {
            EXPECT_TRUE(kept);
            wanted = false;
          }
          if (u.keep) {
            kept = true;
            wanted = true;
          }
        };
        auto move = [&] {
          kept_unread = kept_unread || wanted;
          kept = wanted = false;
        };
        move();
        for (int sub = 0; sub < substeps; ++sub) {
          for (int it = 0; it < vel; ++it) pass(PointMassUse::velocity(sub, it, vel, relax));
          move();
          for (int it = 0; it < relax; ++it) {
            pass(PointMassUse::relax(sub, it, substeps, vel, relax));
          }
        }
        move();
        EXPECT_FALSE(kept_unread);
      }
    }
  }
}

uint64_t bits(double x) {
  return std::bit_cast<uint64_t>(x);
}

// The same bits whether a pass works out 1 / det K or reads what the pass before kept: a biased
// pass that keeps it, then two relax passes from the same bodies and impulses, one reading it.
TEST(JointLanes, AKeptInverseDeterminantGivesTheBitsOfOneWorkedOut) {
  for (SimdPath path : supported_simd_paths()) {
    ASSERT_TRUE(set_simd_path(path).ok());
    SCOPED_TRACE(simd_path_name(path));
    World w = build(wheel(30, 0.5));
    for (int i = 0; i < 3; ++i) w.step();
    WorldImpl& impl = w.impl();
    ColouredPoints& cp = impl.coloured_points;
    ASSERT_GT(cp.points, 20);
    LargeVector<SolverBody> bodies = impl.solver_scratch.bodies;
    PointRule rule;
    rule.rate = 30.0;
    rule.max_speed = impl.settings.max_correction_speed;
    rule.h = impl.settings.dt / impl.settings.substeps;
    rule.inv_h = 1.0 / rule.h;
    rule.mass.keep = true;
    solve_points(cp, bodies.data(), impl.solver_scratch.body_extras.data(), rule, nullptr);
    PointRule relax = rule;
    relax.use_bias = false;
    relax.mass.keep = false;
    ColouredPoints worked = cp;
    LargeVector<SolverBody> worked_bodies = bodies;
    solve_points(worked, worked_bodies.data(), impl.solver_scratch.body_extras.data(), relax,
                 nullptr);
    relax.mass.read = true;
    solve_points(cp, bodies.data(), impl.solver_scratch.body_extras.data(), relax, nullptr);
    for (size_t i = 0; i < bodies.size(); ++i) {
      EXPECT_EQ(bits(bodies[i].vx), bits(worked_bodies[i].vx)) << i;
      EXPECT_EQ(bits(bodies[i].vy), bits(worked_bodies[i].vy)) << i;
      EXPECT_EQ(bits(bodies[i].w), bits(worked_bodies[i].w)) << i;
    }
    for (size_t k = 0; k < cp.blocks.size(); ++k) {
      for (int l = 0; l < kBlockLanes; ++l) {
        EXPECT_EQ(bits(cp.blocks[k].ix[l]), bits(worked.blocks[k].ix[l]));
        EXPECT_EQ(bits(cp.blocks[k].iy[l]), bits(worked.blocks[k].iy[l]));
      }
    }
    // The relax pass changed the wheel's speeds: the comparison is not of untouched bodies.
    EXPECT_NE(bits(bodies[2].vx), bits(impl.solver_scratch.bodies[2].vx));
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

// 50 ragdolls (limited, braked revolute joints: lanes of their own), and six two-link chains of
// limited joints hanging from the ground.
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

// The same with every joint a weld joint at the revolute joint's anchors, its angle soft
// (rows of their own, a group per ragdoll; the chains hang from the ground, the static slot,
// so their rows are one group).
SceneDef welded_ragdolls_and_hanging_chains() {
  SceneDef s = ragdolls_and_hanging_chains();
  for (SceneJoint& joint : s.joints) {
    const auto& revolute = std::get<RevoluteJointDef>(joint.def);
    WeldJointDef weld;
    weld.local_anchor_a = revolute.local_anchor_a;
    weld.local_anchor_b = revolute.local_anchor_b;
    weld.reference_angle = revolute.reference_angle;
    weld.angular_hertz = 2.0;
    weld.angular_damping_ratio = 0.7;
    joint.def = weld;
  }
  return s;
}

// Ragdolls with every angle row a revolute joint has: limits, joint friction (a motor at speed
// 0) and springs toward their rest angles, as the benchmark's rain has them; `count` of them
// dropped onto the ground from 2 m, with one more wheel turned by a motor at 3 rad/s.
SceneDef sprung_ragdolls(int count) {
  SceneDef s;
  scenes::add_ground(&s, 60.0);
  for (int i = 0; i < count; ++i) {
    scenes::HumanOptions o;
    o.feet = Vec2(-0.8 * count / 2 + 0.8 * i, 2.0 + 0.3 * (i % 4));
    o.group = -(i + 1);
    o.hertz = 5.0;
    o.damping_ratio = 0.5;
    scenes::add_human(&s, o);
  }
  s.bodies.push_back(ball(Vec2(0.0, 8.0), 0.5));
  RevoluteJointDef motor;
  motor.local_anchor_a = Vec2(0.0, 8.0);
  motor.enable_motor = true;
  motor.motor_speed = 3.0;
  motor.max_motor_torque = 50.0;
  s.joints.push_back(SceneJoint{0, static_cast<int>(s.bodies.size()) - 1, motor});
  return s;
}

TEST(JointLanes, RevoluteJointsWithAngleRowsAreColouredInLanesOfTheirOwn) {
  SceneDef scene = sprung_ragdolls(20);
  World w = build(scene);
  for (int i = 0; i < 30; ++i) w.step();
  const ColouredPoints& cp = w.impl().coloured_points;
  // Every joint has angle rows: none is a plain point, none is left to the one-by-one solver.
  EXPECT_EQ(cp.points, 0);
  EXPECT_EQ(cp.revolutes.joints, static_cast<int>(scene.joints.size()));
  EXPECT_TRUE(cp.other_rows.empty());
  // A ragdoll's torso holds the most joints (its neck, shoulders and hips): a handful of
  // colours, no overflow.
  EXPECT_LE(cp.revolutes.colours, 6);
  EXPECT_EQ(cp.revolutes.colour_start[cp.revolutes.colours],
            static_cast<int>(cp.revolutes.blocks.size()));
  expect_valid_colouring(w);
  // The wheel's motor holds its speed within a hundredth (it needs 2.2 N m of its 50 at most),
  // and the ragdolls' limits hold within a degree.
  const BodyId wheel = w.bodies().back();
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_NEAR(w.body_state(wheel).value().angular_velocity, 3.0, 0.01);
  EXPECT_TRUE(all_finite(w));
  EXPECT_LT(w.metrics().max_joint_error, 0.02);
}

TEST(JointLanes, TheLastRelaxPassGathersTheRevoluteJointsWarmStart) {
  expect_relax_gathers_the_warm_start(sprung_ragdolls(20), 60);
}

TEST(JointLanes, EveryPathGivesTheScalarBitsOfTheRevoluteJoints) {
  expect_simd_paths_agree(sprung_ragdolls(24), 120);
}

TEST(JointLanes, EveryThreadCountGivesOneThreadsBitsOfTheRevoluteJoints) {
  // 60 ragdolls: 600 joints, colours of several chunks each.
  expect_thread_counts_agree(sprung_ragdolls(60), 90, {1, 2, 3, 4}, [](const World& w) {
    const ColouredRevolutes& rv = w.impl().coloured_points.revolutes;
    EXPECT_GE(rv.colour_start[1] - rv.colour_start[0], 2 * kBlocksPerChunk);
  });
}

// Checks the last tick's groups of the rows that are not plain points (ColouredPoints).
void expect_valid_groups(const World& w) {
  const ColouredPoints& cp = w.impl().coloured_points;
  const LargeVector<JointRow>& rows = w.impl().solver_scratch.joint_rows;
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
  SceneDef scene = welded_ragdolls_and_hanging_chains();
  World one = build(scene);
  one.step();
  // 512 rows of weld joints; one thread needs no groups.
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
  expect_thread_counts_agree(
      welded_ragdolls_and_hanging_chains(), 90, {1, 2, 3, 4}, [](const World& w) {
        EXPECT_EQ(w.impl().coloured_points.chunk_start.empty(), w.threads() == 1);
      });
}

}  // namespace
}  // namespace fulcrum::testing
