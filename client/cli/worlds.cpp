// fulcrum worlds: the worlds a server holds.
#include <cstdio>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_worlds(const Invocation& inv) {
  int exit_code = kExitOk;
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<std::vector<client::WorldSummary>> worlds = client->list_worlds();
  if (!worlds.ok()) return inv.fail(worlds.status().message());
  char line[512];
  std::snprintf(line, sizeof line, "%-6s %-16s %10s %8s %8s %-16s %8s %-9s %8s %s\n", "id", "name",
                "tick", "bodies", "awake", "state hash", "watchers", "mode", "dropped",
                "recording");
  inv.out << line;
  for (const client::WorldSummary& w : *worlds) {
    const std::string recording =
        w.recording.name.empty() ? "-"
                                 : w.recording.name + (w.recording.active ? " (on)" : " (closed)");
    std::snprintf(line, sizeof line, "%-6llu %-16s %10lld %8d %8d %-16s %8u %-9s %8lld %s\n",
                  static_cast<unsigned long long>(w.id), w.name.c_str(),
                  static_cast<long long>(w.tick), w.body_count, w.awake_body_count,
                  hex64(w.state_hash).c_str(), w.watchers,
                  w.run.mode == client::RunMode::kRealTime ? "real-time" : "paused",
                  static_cast<long long>(w.run.ticks_dropped), recording.c_str());
    inv.out << line;
  }
  return kExitOk;
}

}  // namespace fulcrum::cli
