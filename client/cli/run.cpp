// fulcrum run / fulcrum pause: put a world on the server's real-time clock, or take it off.
#include <cstdio>
#include <limits>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_run(const Invocation& inv) {
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 0, &exit_code);
  if (!world) return exit_code;
  std::optional<uint32_t> cap;
  if (auto text = inv.args.value("max-catch-up")) {
    std::string error;
    std::optional<int64_t> parsed = parse_int(*text, 1, 1000, &error);
    if (!parsed) return inv.usage_error("--max-catch-up: " + error);
    cap = static_cast<uint32_t>(*parsed);
  }
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<client::RunModeResult> r = client->set_run_mode(*world, client::RunMode::kRealTime, cap);
  if (!r.ok()) return inv.fail(r.status().message());
  Result<client::WorldSummary> w = client->get_world(*world);
  if (!w.ok()) return inv.fail(w.status().message());
  char hz[32];
  std::snprintf(hz, sizeof hz, "%g", w->run.dt > 0 ? 1.0 / w->run.dt : 0.0);
  inv.out << "world " << *world << ": real time at " << hz << " Hz from tick " << w->run.start_tick
          << " (at most " << w->run.max_catch_up_ticks << " ticks per wake when behind)\n";
  return kExitOk;
}

int run_pause(const Invocation& inv) {
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 0, &exit_code);
  if (!world) return exit_code;
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<client::RunModeResult> r = client->set_run_mode(*world, client::RunMode::kPaused);
  if (!r.ok()) return inv.fail(r.status().message());
  Result<client::WorldSummary> w = client->get_world(*world);
  if (!w.ok()) return inv.fail(w.status().message());
  inv.out << "world " << *world << ": paused at tick " << r->tick << ", state hash "
          << hex64(w->state_hash) << "; last run: " << w->run.ticks_run << " ticks in real time, "
          << w->run.ticks_dropped << " dropped\n";
  return kExitOk;
}

}  // namespace fulcrum::cli
