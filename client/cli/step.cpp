// fulcrum step: step a world on the server N ticks.
#include <cstdio>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_step(const Invocation& inv) {
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 0, &exit_code);
  if (!world) return exit_code;
  if (inv.args.positional().size() < 2) return inv.usage_error("missing N (ticks to step)");
  std::string error;
  std::optional<int64_t> ticks = parse_int(inv.args.positional()[1], 1, 0xffffffffLL, &error);
  if (!ticks) return inv.usage_error("N: " + error);
  std::optional<int64_t> expected;
  if (auto t = inv.args.value("expected-tick")) {
    expected = parse_int(*t, 0, int64_t{1} << 62, &error);
    if (!expected) return inv.usage_error("--expected-tick: " + error);
  }
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<client::StepResult> r = client->step(*world, static_cast<uint32_t>(*ticks), expected);
  if (!r.ok()) return inv.fail(r.status().message());
  char ms[32];
  std::snprintf(ms, sizeof ms, "%.3f", r->step_ms);
  inv.out << "world " << *world << ": tick " << r->tick << ", state hash " << hex64(r->state_hash)
          << ", " << r->awake_body_count << " awake, " << ms << " ms on the server\n";
  return kExitOk;
}

}  // namespace fulcrum::cli
