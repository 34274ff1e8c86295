// PairSet (engine/src/pair_set.h): the broad phase's "does this pair have a contact" set. It
// must answer exactly as a std::set does through any sequence of inserts and erases, including
// the erase-heavy churn of contacts that come and go and keys whose probe runs wrap around the
// end of the array.
#include "pair_set.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <set>
#include <vector>

namespace fulcrum {
namespace {

TEST(PairSet, AnswersAsAnOrderedSetThroughChurn) {
  std::mt19937_64 rng(5);
  PairSet set;
  std::set<uint64_t> want;
  // Pair keys of shapes below 300: dense enough that probe runs collide and wrap.
  auto random_key = [&] {
    const uint64_t a = rng() % 300, b = a + 1 + rng() % 299;
    return (a << 32) | b;
  };
  for (int round = 0; round < 20000; ++round) {
    const uint64_t key = random_key();
    const double r = static_cast<double>(rng() >> 11) * 0x1.0p-53;
    // Phases: grow, churn, shrink, so that the set both grows its array and empties it.
    const double p_insert = round < 8000 ? 0.8 : (round < 14000 ? 0.5 : 0.2);
    if (r < p_insert) {
      EXPECT_EQ(set.insert(key), want.insert(key).second);
    } else {
      EXPECT_EQ(set.erase(key), want.erase(key) == 1);
    }
    ASSERT_EQ(set.size(), want.size());
    if (round % 500 == 0) {
      for (uint64_t a = 0; a < 300; a += 7) {
        for (uint64_t b = a + 1; b < 300; b += 5) {
          const uint64_t k = (a << 32) | b;
          ASSERT_EQ(set.contains(k), want.count(k) == 1) << "round " << round;
        }
      }
    }
  }
  for (uint64_t k : want) EXPECT_TRUE(set.contains(k));
  // Emptied one by one, every key is gone and nothing else was ever there.
  for (uint64_t k : std::vector<uint64_t>(want.begin(), want.end())) ASSERT_TRUE(set.erase(k));
  EXPECT_EQ(set.size(), 0u);
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(set.contains(random_key()));
  set.clear();
  EXPECT_FALSE(set.erase(42));
  EXPECT_TRUE(set.insert(42));
  EXPECT_TRUE(set.contains(42));
}

}  // namespace
}  // namespace fulcrum
