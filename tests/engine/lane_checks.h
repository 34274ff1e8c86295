// Checks the contact and joint lane tests share: within a colour, every body the lanes write
// is written by one lane only, and only bodies of finite mass are written; a relax pass's
// gathered warm start is what a warm-start pass applies to bodies at rest.
#pragma once

#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "contact_lanes.h"

namespace fulcrum::testing {

// Block: ContactBlock or PointBlock (ia, ib, write_a, write_b per lane), in a vector of any
// allocator (the contact lanes' is LaneAllocator).
template <class Block, class Allocator>
void expect_each_body_written_once_per_colour(const std::vector<Block, Allocator>& blocks,
                                              const std::vector<int>& colour_start, int colours,
                                              const LargeVector<SolverBody>& bodies) {
  for (int c = 0; c < colours; ++c) {
    std::set<int> written;
    for (int k = colour_start[c]; k < colour_start[c + 1]; ++k) {
      const Block& b = blocks[k];
      for (int l = 0; l < kBlockLanes; ++l) {
        for (auto [slot, write] :
             {std::pair{b.ia[l], b.write_a[l]}, std::pair{b.ib[l], b.write_b[l]}}) {
          EXPECT_EQ(write != 0, bodies[slot].inv_mass > 0.0);
          if (write) {
            EXPECT_TRUE(written.insert(slot).second) << "colour " << c << " slot " << slot;
          }
        }
      }
    }
  }
}

// `gathered` (LaneRule::warm_next, PointRule::warm_next) equals, bit for bit, the velocities
// `warm` (a warm-start pass) gives `bodies` set at rest, and most rows carry a load.
template <class WarmFn>
void expect_gathered_warm_start(const std::vector<VelocityBefore>& gathered,
                                LargeVector<SolverBody> at_rest, WarmFn warm, const char* path) {
  ASSERT_EQ(gathered.size(), at_rest.size());
  for (SolverBody& b : at_rest) b.vx = b.vy = b.w = 0.0;
  warm(at_rest.data());
  int loaded = 0;
  for (size_t i = 0; i < at_rest.size(); ++i) {
    EXPECT_EQ(gathered[i].vx, at_rest[i].vx) << path << " slot " << i;
    EXPECT_EQ(gathered[i].vy, at_rest[i].vy) << path << " slot " << i;
    EXPECT_EQ(gathered[i].w, at_rest[i].w) << path << " slot " << i;
    loaded += gathered[i].vy != 0.0;
  }
  EXPECT_GT(loaded, static_cast<int>(at_rest.size()) / 2) << path;
}

}  // namespace fulcrum::testing
