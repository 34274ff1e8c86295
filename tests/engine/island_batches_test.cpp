// Islands solved in batches (WorldImpl::solve_in_batches, budget.cpp): a world of many islands
// solved a few islands at a time gives the bits of one group, at any thread count, and a world
// where the batches' solves would couple (here, a contact with restitution) is solved as one
// group.
#include <gtest/gtest.h>

#include <vector>

#include "fulcrum/world.h"
#include "scene_fixture.h"
#include "world_impl.h"

namespace fulcrum::testing {
namespace {

constexpr int kTicks = 12;

// The benchmark's 400 pyramids of 55 boxes on 20 shelves: 22 000 bodies in 400 islands, above
// the size from which islands are batched (8192 awake bodies).
World grid(bool batched, int threads = 1) {
  World w = build("many_pyramids_grid");
  w.impl().batch_islands = batched;
  EXPECT_TRUE(w.set_threads(threads).ok());
  return w;
}

TEST(IslandBatches, ManyIslandsInBatchesGiveOneGroupsBits) {
  World batched = grid(true);
  World whole = grid(false);
  for (int tick = 1; tick <= kTicks; ++tick) {
    batched.step();
    whole.step();
    ASSERT_EQ(batched.state_hash(), whole.state_hash()) << "tick " << tick;
    // 22 000 bodies in batches of at least 2048 whole pyramids of 55: at most 11 batches.
    EXPECT_GE(batched.impl().island_batch_count, 2) << "tick " << tick;
    EXPECT_LE(batched.impl().island_batch_count, 11) << "tick " << tick;
    EXPECT_EQ(whole.impl().island_batch_count, 0);
  }
  EXPECT_GT(batched.metrics().contact_count, 40000);  // the pyramids rest on their contacts
}

TEST(IslandBatches, TwoThreadsShareEachBatch) {
  World two = grid(true, 2);
  World one = grid(false, 1);
  for (int tick = 1; tick <= kTicks; ++tick) {
    two.step();
    one.step();
    ASSERT_EQ(two.state_hash(), one.state_hash()) << "tick " << tick;
    EXPECT_GE(two.impl().island_batch_count, 2) << "tick " << tick;
  }
}

TEST(IslandBatches, RestitutionKeepsOneGroupUntilItIsGone) {
  World batched = grid(true);
  World whole = grid(false);
  // One box of the first pyramid bounces: its contacts have restitution.
  auto bounce = [](World& w, double restitution) {
    const BodyId box = w.bodies()[1];  // body 0 is the first shelf
    const ShapeId shape = w.body_shapes(box)->front();
    ASSERT_TRUE(w.set_shape_material(shape, 0.6, restitution).ok());
  };
  for (int tick = 1; tick <= kTicks; ++tick) {
    if (tick == 3) {
      bounce(batched, 0.5);
      bounce(whole, 0.5);
    }
    if (tick == 8) {
      bounce(batched, 0.0);
      bounce(whole, 0.0);
    }
    batched.step();
    whole.step();
    ASSERT_EQ(batched.state_hash(), whole.state_hash()) << "tick " << tick;
    if (tick >= 3 && tick < 8) {
      EXPECT_EQ(batched.impl().island_batch_count, 0) << "tick " << tick;
    } else {
      EXPECT_GE(batched.impl().island_batch_count, 2) << "tick " << tick;
    }
  }
}

}  // namespace
}  // namespace fulcrum::testing
