// Pinned golden state hashes: the final state hash and a hash over every tick's state hash of
// each golden scenario (golden_scenes.h), as literals. Any change to any bit the simulation
// produces, at any tick of any scenario, fails this test.
//
// Changing the engine's behaviour ON PURPOSE (a solver change, a new field in the state hash,
// a changed scenario) means updating the literals below: build, run
//   build/bin/fulcrum_golden
// and copy each line's two hashes into kPinned (the line is "name ticks final combined"). Say
// in the commit message why the hashes changed, and bump kDeterminismFingerprint
// (fulcrum/fingerprint.h) with kFingerprint and kResults below: clients of another build are
// then told they differ instead of desynchronising. Changing them by accident (a refactor that
// should not alter results) is exactly what this test exists to catch: find the cause instead.
#include <gtest/gtest.h>

#include <cinttypes>
#include <cstdio>
#include <ostream>
#include <string>
#include <vector>

#include "fulcrum/fingerprint.h"
#include "golden_scenes.h"

namespace fulcrum::golden {
namespace {

struct Pinned {
  const char* name;
  int ticks;
  uint64_t final_hash;
  uint64_t combined_hash;
};

// clang-format off
constexpr Pinned kPinned[] = {
    {"pyramid",    240, 0xd799a1d74bbfd4dbull, 0xca27c7dbb0f5f8ebull},
    {"ragdolls",   240, 0xd53d67e5463bd827ull, 0xdfb040a06487f087ull},
    {"rope_cloth", 240, 0x7bf913818aaef204ull, 0x613e43ab6198b1daull},
    {"sleep_wake", 480, 0xde5037d7a197997cull, 0xb2698aaccec8b02eull},
    {"edits",      480, 0x42eb1916c630f8caull, 0x230c197adc33b57dull},
    {"joints",     360, 0xd2e53e8464e50d77ull, 0xf03b81d7af2baaebull},
    {"lanes",      240, 0xdf72937b3741cd4bull, 0x9f111466ec019c6bull},
    {"recovery",   240, 0xa86413db8be86232ull, 0x3975e5783f2ad0feull},
    {"pins",       180, 0xfd4d2cc9141a4d78ull, 0x84e70d2189dc247aull},
};
// clang-format on

// The fingerprint these results carry, and a hash over kPinned that ties the two together.
constexpr char kFingerprint[] = "fulcrum-results-18";
constexpr uint64_t kResults = 0x2108eec573e37c9cull;

// gtest prints a failing parameter with this (rather than its bytes).
void PrintTo(const Pinned& pinned, std::ostream* os) {
  *os << pinned.name;
}

std::string hex(uint64_t x) {
  char text[19];
  std::snprintf(text, sizeof(text), "0x%016" PRIx64, x);
  return text;
}

const GoldenScenario& scenario_named(const std::string& name) {
  for (const GoldenScenario& s : golden_scenarios()) {
    if (name == s.name) return s;
  }
  ADD_FAILURE() << "no golden scenario named " << name;
  return golden_scenarios().front();
}

TEST(GoldenTest, EveryScenarioIsPinned) {
  ASSERT_EQ(std::size(kPinned), golden_scenarios().size());
  for (size_t i = 0; i < std::size(kPinned); ++i) {
    EXPECT_STREQ(kPinned[i].name, golden_scenarios()[i].name);
    EXPECT_EQ(kPinned[i].ticks, golden_scenarios()[i].ticks) << kPinned[i].name;
  }
}

TEST(GoldenTest, TheFingerprintNamesThesePinnedResults) {
  std::vector<uint64_t> all;
  for (const Pinned& p : kPinned) all.push_back(p.combined_hash);
  EXPECT_EQ(hex(combine_hashes(all)), hex(kResults))
      << "kPinned changed: bump kDeterminismFingerprint, then set kFingerprint and kResults";
  EXPECT_STREQ(kDeterminismFingerprint, kFingerprint);
}

class GoldenHashTest : public testing::TestWithParam<Pinned> {};

TEST_P(GoldenHashTest, MatchesPinnedHashes) {
  const Pinned& pinned = GetParam();
  const GoldenScenario& scenario = scenario_named(pinned.name);
  std::vector<uint64_t> hashes = run_golden(scenario);
  ASSERT_EQ(hashes.size(), static_cast<size_t>(pinned.ticks));
  // The message gives the line to paste into kPinned when the change is intended.
  EXPECT_EQ(hex(hashes.back()), hex(pinned.final_hash))
      << pinned.name << ": now {\"" << pinned.name << "\", " << pinned.ticks << ", "
      << hex(hashes.back()) << "ull, " << hex(combine_hashes(hashes)) << "ull}";
  EXPECT_EQ(hex(combine_hashes(hashes)), hex(pinned.combined_hash)) << pinned.name;
}

// Two runs in one process agree at every tick (no state leaks between worlds).
TEST_P(GoldenHashTest, RepeatsWithinAProcess) {
  const GoldenScenario& scenario = scenario_named(GetParam().name);
  EXPECT_EQ(run_golden(scenario), run_golden(scenario)) << scenario.name;
}

std::string scenario_name(const testing::TestParamInfo<Pinned>& param) {
  return param.param.name;
}
INSTANTIATE_TEST_SUITE_P(Scenarios, GoldenHashTest, testing::ValuesIn(kPinned), scenario_name);

// The scenarios cover what they say they cover.

bool asleep(const World& world, uint64_t first_tag, int count) {
  bool all = true;
  for (BodyId id : world.bodies()) {
    BodyState state = *world.body_state(id);
    if (state.user_data >= first_tag && state.user_data < first_tag + count) {
      all = all && !state.awake;
    }
  }
  return all;
}

bool any_awake(const World& world, uint64_t first_tag, int count) {
  bool any = false;
  for (BodyId id : world.bodies()) {
    BodyState state = *world.body_state(id);
    if (state.user_data >= first_tag && state.user_data < first_tag + count) {
      any = any || state.awake;
    }
  }
  return any;
}

TEST(GoldenTest, SleepWakeSleepsThenWakes) {
  const GoldenScenario& scenario = scenario_named("sleep_wake");
  World world = scenario.build();
  auto step_to = [&](int64_t tick) {
    while (world.tick() < tick) {
      scenario.edits(world, world.tick());
      world.step();
    }
  };
  step_to(kSleepWakeDropTick);
  EXPECT_TRUE(asleep(world, kTagStack, kStackBoxes))
      << "the stack should be asleep when the ball is dropped";
  EXPECT_TRUE(asleep(world, kTagPyramid, kPyramidBoxes)) << "the pyramid should be asleep";
  step_to(kSleepWakeDropTick + 30);
  EXPECT_TRUE(any_awake(world, kTagStack, kStackBoxes)) << "the ball should have woken the stack";
  EXPECT_TRUE(asleep(world, kTagPyramid, kPyramidBoxes)) << "the ball should not reach the pyramid";
  step_to(kSleepWakeImpulseTick);
  EXPECT_TRUE(asleep(world, kTagPyramid, kPyramidBoxes)) << "the pyramid should still be asleep";
  step_to(kSleepWakeImpulseTick + 1);
  EXPECT_TRUE(any_awake(world, kTagPyramid, kPyramidBoxes))
      << "the impulse should have woken the pyramid";
}

TEST(GoldenTest, JointsBridgeBreaks) {
  const GoldenScenario& scenario = scenario_named("joints");
  World world = scenario.build();
  int broken = 0;
  for (int i = 0; i < scenario.ticks; ++i) {
    scenario.edits(world, world.tick());
    world.step();
    broken += static_cast<int>(world.events().joints_broken.size());
  }
  EXPECT_EQ(broken, 1) << "the bridge's middle joint should break under the boxes";
}

}  // namespace
}  // namespace fulcrum::golden
