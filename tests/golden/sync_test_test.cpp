// SyncTest (fulcrum/sync_test.h): over the golden scenarios, rolling back 8 ticks after every
// tick and re-simulating finds no mismatch; a game whose inputs depend on a hidden counter, and
// a snapshot that leaves the warm-start impulses out, are both caught at the tick they bite.
#include <gtest/gtest.h>

#include "fulcrum/sync_test.h"
#include "golden_scenes.h"

namespace fulcrum::client {
namespace {

using golden::GoldenScenario;

// The scenario's own edits as the game's tick (it changes the world directly, no inputs).
GameTick scenario_game(const GoldenScenario& scenario) {
  return [&scenario](int64_t tick, World& world, v1::EditBatch*) {
    scenario.edits(world, tick);
    return Status();
  };
}

TEST(SyncTest, GoldenScenariosRollBackEightTicksWithoutAMismatch) {
  for (const GoldenScenario& scenario : golden::golden_scenarios()) {
    SCOPED_TRACE(scenario.name);
    // 120 ticks each: the first contacts, joints loading, and for sleep_wake and edits their
    // early edits; the golden test itself covers the full runs.
    const int ticks = std::min(scenario.ticks, 120);
    const std::vector<uint64_t> expected = golden::run_golden(scenario);
    Result<std::unique_ptr<SyncTest>> sync =
        SyncTest::start(scenario.build(), SyncTestOptions{8}, scenario_game(scenario));
    ASSERT_TRUE(sync.ok()) << sync.status().message();
    Status ran = (*sync)->run(ticks);
    ASSERT_TRUE(ran.ok()) << ran.message();
    // The world is the first pass's: the golden hash of that tick.
    EXPECT_EQ((*sync)->world().tick(), ticks);
    EXPECT_EQ((*sync)->world().state_hash(), expected[ticks - 1]);
    const SyncTestCounters& c = (*sync)->counters();
    EXPECT_EQ(c.ticks, ticks);
    EXPECT_EQ(c.rollbacks, ticks);
    EXPECT_EQ(c.deepest_rollback, 8);
    // 1 + 2 + ... + 7 for the first seven ticks, then 8 a tick.
    EXPECT_EQ(c.resimulated_ticks, 28 + 8 * (ticks - 7));
  }
}

// The pyramid's top box is pushed at tick 10 by an impulse the game takes from a counter it
// keeps across calls: the first pass pushes with 1 N s, the re-simulation with 2.
TEST(SyncTest, InputsThatDependOnAHiddenCounterAreCaughtAtTheirTick) {
  const GoldenScenario& scenario = golden::golden_scenarios().front();  // pyramid
  int calls = 0;
  GameTick game = [&](int64_t tick, World& world, v1::EditBatch* inputs) {
    if (tick != 10) return Status();
    ++calls;
    v1::Edit* edit = inputs->add_edits();
    v1::ApplyImpulse* push = edit->mutable_apply_impulse();
    BodyId top = world.bodies().back();
    push->mutable_body()->set_index(top.index);
    push->mutable_body()->set_generation(top.generation);
    push->mutable_impulse()->set_x(calls);
    return Status();
  };
  Result<std::unique_ptr<SyncTest>> sync = SyncTest::start(scenario.build(), {}, game);
  ASSERT_TRUE(sync.ok());
  Status ran = (*sync)->run(40);
  ASSERT_EQ(ran.code(), StatusCode::kDataLoss) << ran.message();
  EXPECT_NE(ran.message().find("sync test at tick 11: tick 11 re-simulated after a rollback of 8 "
                               "ticks"),
            std::string::npos)
      << ran.message();
  EXPECT_NE(ran.message().find("the game's inputs for tick 10 differ from the first pass's"),
            std::string::npos)
      << ran.message();
  EXPECT_NE(ran.message().find("first difference: bodies["), std::string::npos) << ran.message();
  // The world is left as the first pass had it, at tick 11.
  EXPECT_EQ((*sync)->world().tick(), 11);
  EXPECT_EQ((*sync)->counters().ticks, 11);
}

// A snapshot that forgot the manifolds' accumulated impulses (the warm-start cache) restores a
// world that is not the one it was taken from: the restore's own hash check refuses it at the
// first rollback after the pyramid's boxes touch.
TEST(SyncTest, ASnapshotThatLeavesTheWarmStartOutIsCaught) {
  const GoldenScenario& scenario = golden::golden_scenarios().front();  // pyramid
  Result<std::unique_ptr<SyncTest>> sync =
      SyncTest::start(scenario.build(), {}, scenario_game(scenario));
  ASSERT_TRUE(sync.ok());
  (*sync)->set_snapshot_hook([](WorldSnapshot* s) {
    for (Contact& c : s->contacts) {
      for (ManifoldPoint& p : c.manifold.points) p.normal_impulse = p.tangent_impulse = 0.0;
    }
  });
  Status ran = (*sync)->run(60);
  ASSERT_EQ(ran.code(), StatusCode::kDataLoss) << ran.message();
  EXPECT_NE(ran.message().find("failed: snapshot"), std::string::npos) << ran.message();
  EXPECT_NE(ran.message().find("does not hash to the recorded state_hash"), std::string::npos)
      << ran.message();
}

TEST(SyncTest, OptionsOutOfRangeAreRefused) {
  const GoldenScenario& scenario = golden::golden_scenarios().front();
  Result<std::unique_ptr<SyncTest>> zero =
      SyncTest::start(scenario.build(), SyncTestOptions{0}, scenario_game(scenario));
  EXPECT_EQ(zero.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(zero.status().message(), "check_distance: must be 1 to 128 (got 0)");
  EXPECT_EQ(SyncTest::start(scenario.build(), {}, nullptr).status().message(), "game: required");
}

}  // namespace
}  // namespace fulcrum::client
