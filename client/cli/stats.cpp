// fulcrum stats: a server's counters, one `name value` line each (stable names, for scripts).
#include <cstdio>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_stats(const Invocation& inv) {
  int exit_code = kExitOk;
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<v1::ServerStats> stats = client->get_stats();
  if (!stats.ok()) return inv.fail(stats.status().message());
  const v1::ServerStats& s = *stats;
  char line[160];
  auto count = [&](const char* name, unsigned long long value) {
    std::snprintf(line, sizeof line, "%-20s %llu\n", name, value);
    inv.out << line;
  };
  auto ms = [&](const char* name, double value) {
    std::snprintf(line, sizeof line, "%-20s %.3f\n", name, value);
    inv.out << line;
  };
  ms("uptime_s", s.uptime_s());
  count("worlds", s.worlds());
  count("worlds_created", s.worlds_created());
  count("worlds_deleted", s.worlds_deleted());
  count("worlds_restored", s.worlds_restored());
  count("ticks_stepped", s.ticks_stepped());
  ms("step_ms_total", s.step_ms_total());
  ms("step_ms_max", s.step_ms_max());
  count("streams_open", s.streams_open());
  count("streams_opened", s.streams_opened());
  count("frames_sent", s.frames_sent());
  count("frames_coalesced", s.frames_coalesced());
  count("frames_encoded", s.frames_encoded());
  count("readers_too_slow", s.readers_too_slow());
  count("recordings_started", s.recordings_started());
  count("recordings_failed", s.recordings_failed());
  count("hash_reports", s.hash_reports());
  count("desyncs", s.desyncs());
  count("resyncs", s.resyncs());
  for (const v1::CodeCount& c : s.refused()) {
    const std::string name = "refused." + c.code();
    count(name.c_str(), c.count());
  }
  return kExitOk;
}

}  // namespace fulcrum::cli
