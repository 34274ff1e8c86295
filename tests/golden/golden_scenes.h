// Golden scenarios: small fixed worlds, each stepped a fixed number of ticks with fixed edits
// between ticks, whose per-tick state hashes are pinned (golden_test.cpp) and compared across
// builds, compilers and CPUs (tools/determinism.sh, tools/cross_aarch64.sh).
//
// This library links only fulcrum_engine and fulcrum_scenes (no protobuf, no gRPC) so that it
// cross-compiles for aarch64 on its own.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "fulcrum/world.h"

namespace fulcrum::golden {

struct GoldenScenario {
  const char* name;  // one word, as printed by the fulcrum_golden binary
  int ticks;         // World::step() calls
  // A fresh world at tick 0. Aborts with a message if the scene is refused: the scenarios are
  // fixed programs, so that is a bug in them or a changed engine rule, never user input.
  std::function<World()> build;
  // The edits made at the tick boundary before the step that advances the world from `tick`
  // to `tick + 1` (called with tick == world.tick(); always callable, often a no-op). A pure
  // function of the world's state and the tick: it captures no mutable state and finds its
  // bodies through World::bodies() and their user_data, so it may be called on a world
  // restored from a snapshot and continues exactly as on the original.
  std::function<void(World&, int64_t tick)> edits;
};

// sleep_wake: a ball is dropped onto the sleeping stack before this tick's step, and the
// sleeping pyramid gets an impulse before kSleepWakeImpulseTick's (tests check that both were
// asleep then and woke). Its bodies carry these user_data tags.
inline constexpr int64_t kSleepWakeDropTick = 180;
inline constexpr int64_t kSleepWakeImpulseTick = 360;
inline constexpr uint64_t kTagStack = 100;  // + box number from the bottom: 5 boxes
inline constexpr int kStackBoxes = 5;
inline constexpr uint64_t kTagPyramid = 200;  // + box number, bottom row first: 6 boxes
inline constexpr int kPyramidBoxes = 6;
inline constexpr uint64_t kTagDroppedBall = 300;

// Every scenario, in a fixed order.
const std::vector<GoldenScenario>& golden_scenarios();

// build(), then `ticks` times: edits(world, world.tick()); world.step(); record
// world.state_hash(). Returns one hash per tick (the last is the final state's). `threads`:
// World::set_threads for the run (any count must give the same hashes).
std::vector<uint64_t> run_golden(const GoldenScenario& scenario, int threads = 1);

// One 64-bit hash over a sequence of tick hashes, order-sensitive: a difference at any tick
// changes it.
uint64_t combine_hashes(std::span<const uint64_t> hashes);

}  // namespace fulcrum::golden
