// fulcrum step: step a world on the server N ticks, optionally writing every k-th tick of the
// bodies named to a CSV file (StepTrajectory: nothing is skipped).
#include <cstdio>
#include <fstream>
#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

namespace {

// One row per body per sample, every double with 17 significant digits (exact on reading).
void write_csv_row(std::ostream& out, const client::TrajectorySample& s,
                   const client::BodyFrame& b) {
  char line[512];
  std::snprintf(line, sizeof line, "%lld,%s,%d,%u,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d\n",
                static_cast<long long>(s.tick), hex64(s.state_hash).c_str(), b.id.index,
                b.id.generation, b.position.x(), b.position.y(), b.angle, b.linear_velocity.x(),
                b.linear_velocity.y(), b.angular_velocity, b.awake ? 1 : 0);
  out << line;
}

}  // namespace

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
  const std::optional<std::string> csv_path = inv.args.value("trajectory");
  client::TrajectoryOptions trajectory;
  trajectory.ticks = static_cast<uint32_t>(*ticks);
  trajectory.expected_tick = expected;
  if (auto every = inv.args.value("every")) {
    std::optional<int64_t> k = parse_int(*every, 1, 0xffffffffLL, &error);
    if (!k) return inv.usage_error("--every: " + error);
    if (!csv_path) return inv.usage_error("--every: only with --trajectory");
    trajectory.every_ticks = static_cast<uint32_t>(*k);
  }
  if (auto bodies = inv.args.value("bodies")) {
    std::optional<std::vector<BodyId>> ids = parse_body_list(*bodies, &error);
    if (!ids) return inv.usage_error("--bodies: " + error);
    if (!csv_path) return inv.usage_error("--bodies: only with --trajectory");
    trajectory.bodies = std::move(*ids);
  }
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  uint64_t samples = 0;
  std::ofstream file;
  const bool to_file = csv_path && *csv_path != "-";
  if (to_file) {
    file.open(*csv_path, std::ios::binary | std::ios::trunc);
    if (!file) return inv.fail("--trajectory: cannot write " + *csv_path);
  }
  std::ostream& csv = to_file ? file : inv.out;
  auto run = [&]() -> Result<client::StepResult> {
    if (!csv_path) return client->step(*world, static_cast<uint32_t>(*ticks), expected);
    csv << "tick,state_hash,body_index,body_generation,x,y,angle,vx,vy,angular_velocity,awake\n";
    return client->step_trajectory(*world, trajectory, [&](const client::TrajectorySample& s) {
      for (const client::BodyFrame& b : s.bodies) write_csv_row(csv, s, b);
      ++samples;
      return csv ? Status() : Status(StatusCode::kInternal, "--trajectory: writing failed");
    });
  };
  Result<client::StepResult> r = run();
  if (to_file) {
    file.close();
    if (r.ok() && !file) return inv.fail("--trajectory: cannot write " + *csv_path);
  }
  if (csv_path && !to_file) {
    if (!r.ok()) return inv.fail(r.status().message());
    return kExitOk;  // stdout holds the CSV alone
  }
  if (!r.ok()) return inv.fail(r.status().message());
  char ms[32];
  std::snprintf(ms, sizeof ms, "%.3f", r->step_ms);
  inv.out << "world " << *world << ": tick " << r->tick << ", state hash " << hex64(r->state_hash)
          << ", " << r->awake_body_count << " awake, " << ms << " ms on the server\n";
  if (csv_path) inv.out << samples << " samples written to " << *csv_path << "\n";
  return kExitOk;
}

}  // namespace fulcrum::cli
