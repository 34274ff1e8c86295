// SyncTest: proves, in one process and without a server, that a game's use of Fulcrum is
// deterministic, the way a rollback client needs it to be. After every tick it rolls the world
// back `check_distance` ticks, asks the game again for the inputs of each of those ticks (from
// the restored world), re-simulates them, and compares every state hash with the first pass.
//
// What it catches: game logic whose inputs depend on something outside the world and the tick
// (wall time, an unseeded random source, a counter kept across calls, the order of an
// unordered container), inputs built from state a rollback does not restore, and anything the
// world's snapshot would fail to carry. A mismatch names the tick, both hashes, whether the
// game's inputs differed from the first pass, and the first field of the world that differs.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>

#include "fulcrum/state.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/edit.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::client {

// The game's part of tick `tick`, at that tick boundary, before the tick is stepped: it fills
// `inputs` (applied as one edit batch right after, the way a session applies players' inputs)
// and may also change `world` directly through the engine's API. Called once per tick in the
// first pass and again for every re-simulated tick, on the restored world. A non-OK status
// stops the test and is returned.
using GameTick = std::function<Status(int64_t tick, World& world, v1::EditBatch* inputs)>;

struct SyncTestOptions {
  int check_distance = 8;  // ticks rolled back and re-simulated after every tick, 1 to 128
};

struct SyncTestCounters {
  int64_t ticks = 0;              // ticks advanced (first pass)
  int64_t rollbacks = 0;          // one after every tick
  int64_t resimulated_ticks = 0;  // ticks stepped again
  int deepest_rollback = 0;       // ticks
};

class SyncTest {
 public:
  // INVALID_ARGUMENT when check_distance is out of range or `game` is empty.
  static Result<std::unique_ptr<SyncTest>> start(World world, const SyncTestOptions& options,
                                                 GameTick game);

  // One tick: the game's inputs applied, the world stepped; then the last min(check_distance,
  // ticks) ticks rolled back and re-simulated. A mismatch is DATA_LOSS (the world is left as
  // the first pass had it); inputs the engine refuses are returned as the engine words them,
  // prefixed with the tick.
  Status advance();
  // advance() `ticks` times, stopping at the first error.
  Status run(int64_t ticks);

  const World& world() const { return world_; }
  const SyncTestCounters& counters() const { return counters_; }

  // For tests of SyncTest itself: called on each snapshot kept for a rollback, before it is
  // stored (e.g. to leave a field out, as a snapshot that forgot some state would).
  void set_snapshot_hook(std::function<void(WorldSnapshot*)> hook) { hook_ = std::move(hook); }

 private:
  SyncTest(World world, const SyncTestOptions& options, GameTick game);

  // One tick of the world at its boundary `tick`: the game's inputs, then the step. The batch's
  // encoding is returned in `*encoded` (to compare passes).
  Status tick_once(std::string* encoded);
  Status rollback_and_compare(int distance);

  struct Kept {
    int64_t tick = 0;         // the boundary the snapshot was taken at
    WorldSnapshot before;     // the world at that boundary, before the tick's inputs
    std::string inputs;       // the first pass's inputs for the tick, encoded
    uint64_t hash_after = 0;  // the state hash after the tick
  };

  World world_;
  const SyncTestOptions options_;
  const GameTick game_;
  std::deque<Kept> kept_;  // the last check_distance ticks, oldest first
  SyncTestCounters counters_;
  std::function<void(WorldSnapshot*)> hook_;
};

}  // namespace fulcrum::client
