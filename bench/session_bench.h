// What fulcrum_session_bench's files share: the worlds it measures and the tables over the
// network (session_net.cpp).
#pragma once

#include <string>
#include <vector>

#include "fulcrum/scene.h"

namespace fulcrum::session_bench {

// 1000 circles of radius 0.25 m on a 40 x 25 grid 1 m apart in zero gravity, each with its own
// velocity (up to 2 m/s) and sleeping off: every body moves every tick, as in load_bench's
// drifting_1000. Scene bodies 0 to 999.
SceneDef drifting();
// A ground (scene body 0) and 200 stacks of five 0.5 m boxes (bodies 1 to 1000), 2 m apart,
// sleeping on: a world at rest until the players push it, as in tests/server/relay_test.cpp.
SceneDef stacks();

struct NetOptions {
  std::string server;        // the fulcrum-server binary
  std::vector<int> players;  // player counts of the latency table
  int ticks = 400;           // ticks per latency row
  int clock_delay = 2;       // input_delay of the latency rows on the clock
  int bytes_ticks = 240;     // ticks on the server's clock for the bytes table
};

// Input-to-confirmation latency turn by turn (SEAL_RULE_ALL_INPUTS), p50 and p99, for each
// player count, on a fulcrum-server child process on loopback.
void latency_table(const NetOptions& options);

// Bytes per client per tick: the session stream against StreamFrames (every body or the changed
// ones, exact or quantized), 4 players on the server's clock at 60 Hz.
void bytes_table(const NetOptions& options);

}  // namespace fulcrum::session_bench
