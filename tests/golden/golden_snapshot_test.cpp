// Snapshot round trip over every golden scenario: save part-way, restore into a new world, then
// step both 1000 ticks (with the scenario's edits): the hashes agree at every tick.
#include <gtest/gtest.h>

#include "fulcrum/state.h"
#include "golden_scenes.h"

namespace fulcrum::golden {
namespace {

class GoldenSnapshot : public ::testing::TestWithParam<size_t> {};

TEST_P(GoldenSnapshot, RestoredWorldMatchesForAThousandTicks) {
  const GoldenScenario& sc = golden_scenarios()[GetParam()];
  World original = sc.build();
  // Save in the middle of the scenario's scripted part, where its edits are still coming.
  const int64_t save_at = sc.ticks / 2;
  while (original.tick() < save_at) {
    sc.edits(original, original.tick());
    original.step();
  }
  World restored;
  Status st = restored.restore(original.snapshot());
  ASSERT_TRUE(st.ok()) << sc.name << ": " << st.message();
  for (int i = 0; i < 1000; ++i) {
    sc.edits(original, original.tick());
    sc.edits(restored, restored.tick());
    original.step();
    restored.step();
    ASSERT_EQ(original.state_hash(), restored.state_hash())
        << sc.name << ": differs at tick " << original.tick();
  }
}

INSTANTIATE_TEST_SUITE_P(Scenarios, GoldenSnapshot,
                         ::testing::Range(size_t{0}, golden_scenarios().size()),
                         [](const ::testing::TestParamInfo<size_t>& param) {
                           return std::string(golden_scenarios()[param.param].name);
                         });

}  // namespace
}  // namespace fulcrum::golden
