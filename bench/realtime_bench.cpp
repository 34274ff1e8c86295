// How many 1000-body worlds one fulcrum-server keeps in real time at 60 Hz. The server runs
// in-process on loopback (its real-time pool with --threads workers); for K = 1, 2, 3, ... it
// creates K worlds of a 990-box pyramid with sleeping off (every body awake and in contact for
// the whole run), puts them all on the clock, lets them warm up, then counts over a window the
// ticks run and the ticks dropped (due ticks skipped because the server fell behind, see
// server/src/clock.h). A K is sustained when at most 1 % of the due ticks are dropped. Prints a
// Markdown table; stops after two K in a row that are not sustained, or at --max-worlds.
//   fulcrum_realtime_bench [--threads N] [--seconds S] [--max-worlds K] [--base B]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "fulcrum/client.h"
#include "server.h"

namespace {

using Clock = std::chrono::steady_clock;

[[noreturn]] void die(const std::string& what) {
  std::fprintf(stderr, "fulcrum_realtime_bench: %s\n", what.c_str());
  std::exit(1);
}

std::string scene_json(int base) {
  return R"({"name": "pyramid)" + std::to_string(base) +
         R"(", "settings": {"gravity": {"x": 0, "y": -10}, "dt": 0.016666666666666666,
             "enableSleep": false},
             "builders": [{"ground": {"halfWidth": 60}}, {"pyramid": {"base": )" +
         std::to_string(base) + "}}]}";
}

struct Totals {
  int64_t run = 0;
  int64_t dropped = 0;
  int64_t late_wakes = 0;
};

Totals totals(fulcrum::client::Client* client, const std::vector<uint64_t>& ids) {
  Totals t;
  for (uint64_t id : ids) {
    auto w = client->get_world(id);
    if (!w.ok()) die("get_world: " + w.status().message());
    t.run += w->run.ticks_run;
    t.dropped += w->run.ticks_dropped;
    t.late_wakes += w->run.late_wakes;
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  double seconds = 5.0;
  int max_worlds = 8;
  int base = 44;  // 44 rows: 990 boxes, plus the ground
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--threads") {
      threads = std::atoi(argv[i + 1]);
    } else if (flag == "--seconds") {
      seconds = std::atof(argv[i + 1]);
    } else if (flag == "--max-worlds") {
      max_worlds = std::atoi(argv[i + 1]);
    } else if (flag == "--base") {
      base = std::atoi(argv[i + 1]);
    } else {
      die("unknown flag " + flag);
    }
  }
  if (threads < 1 || seconds <= 0 || max_worlds < 1 || base < 1) die("bad flag value");

  fulcrum::server::ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.worker_threads = threads;
  auto server = fulcrum::server::Server::start(options);
  if (!server.ok()) die(server.status().message());
  fulcrum::client::ClientOptions copts;
  copts.address = (*server)->address();
  auto client = fulcrum::client::Client::connect(copts);
  const std::string json = scene_json(base);

  // The cost of one tick of one world, stepped as fast as possible (no clock).
  double tick_ms = 0;
  int bodies = 0;
  {
    auto w = client->create_world_json(json);
    if (!w.ok()) die("create: " + w.status().message());
    bodies = w->body_count;
    auto r = client->step(w->id, 120);
    if (!r.ok()) die("step: " + r.status().message());
    tick_ms = r->step_ms / 120.0;
    (void)client->delete_world(w->id);
  }
  std::printf(
      "real-time bench: %d bodies per world (pyramid of %d rows, sleeping off), 60 Hz, "
      "%d pool threads, %.1f s window after 1 s warm-up\n",
      bodies, base, threads, seconds);
  std::printf("one world stepped flat out: %.3f ms per tick (%.0f %% of a 16.7 ms tick)\n\n",
              tick_ms, 100.0 * tick_ms / (1000.0 / 60.0));
  std::printf(
      "| worlds | ticks due | ticks run | ticks dropped | dropped %% | late wakes | "
      "sustained |\n|---|---|---|---|---|---|---|\n");

  int sustained = 0;
  int misses_in_a_row = 0;
  for (int k = 1; k <= max_worlds && misses_in_a_row < 2; ++k) {
    std::vector<uint64_t> ids;
    for (int i = 0; i < k; ++i) {
      auto w = client->create_world_json(json);
      if (!w.ok()) die("create: " + w.status().message());
      ids.push_back(w->id);
    }
    for (uint64_t id : ids) {
      auto r = client->set_run_mode(id, fulcrum::client::RunMode::kRealTime);
      if (!r.ok()) die("run: " + r.status().message());
    }
    std::this_thread::sleep_for(std::chrono::seconds(1));
    const Totals a = totals(client.get(), ids);
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    const Totals b = totals(client.get(), ids);
    for (uint64_t id : ids) (void)client->delete_world(id);

    const int64_t run = b.run - a.run;
    const int64_t dropped = b.dropped - a.dropped;
    const int64_t due = run + dropped;
    const double rate = due > 0 ? 100.0 * static_cast<double>(dropped) / due : 0.0;
    const bool ok = rate <= 1.0;
    if (ok) {
      sustained = k;
      misses_in_a_row = 0;
    } else {
      ++misses_in_a_row;
    }
    std::printf("| %d | %lld | %lld | %lld | %.1f | %lld | %s |\n", k, static_cast<long long>(due),
                static_cast<long long>(run), static_cast<long long>(dropped), rate,
                static_cast<long long>(b.late_wakes - a.late_wakes), ok ? "yes" : "no");
    std::fflush(stdout);
  }
  std::printf("\nsustained in real time (<= 1 %% of ticks dropped): %d worlds of %d bodies\n",
              sustained, bodies);
  (*server)->shutdown(std::chrono::milliseconds(0));
  return 0;
}
