// What determinism costs: the state hash against a step, and the size and speed of snapshots
// and deltas. Prints one Markdown table; figures go in the README and the issue notes.
//   fulcrum_state_bench [--repeats N]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "fulcrum/scenes.h"
#include "fulcrum/state.h"
#include "snapshot_convert.h"

namespace {

using Clock = std::chrono::steady_clock;
using fulcrum::World;

template <typename F>
double median_ms(int repeats, F f) {
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    auto a = Clock::now();
    f();
    t.push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

World build(const char* name) {
  auto scene = fulcrum::scenes::builtin(name);
  auto world = fulcrum::build_world(*scene);
  return std::move(world).value();
}

struct Row {
  const char* scene;
  int settle;  // ticks stepped before measuring
};

}  // namespace

int main(int argc, char** argv) {
  int repeats = 5;
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "--repeats") == 0) repeats = std::max(1, std::atoi(argv[i + 1]));
  }
  std::printf(
      "| scene | bodies | awake | step ms | hash ms | hash/step | snapshot bytes/body | "
      "save+encode ms | decode+restore ms | delta B/moving body (bodies) | delta B/body "
      "(all) |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  const Row rows[] = {{"large_pyramid", 60},
                      {"ragdolls", 120},
                      {"vertical_stack", 600},
                      {"many_pyramids", 60},
                      {"cloth", 60}};
  for (const Row& row : rows) {
    World w = build(row.scene);
    for (int i = 0; i < row.settle; ++i) w.step();
    const int bodies = w.body_count();
    const int awake = w.metrics().awake_body_count;
    // Steps measured in place: the scene is settled, so a few more ticks barely change it.
    double step_ms = median_ms(repeats, [&] { w.step(); });
    volatile uint64_t sink = 0;
    double hash_ms = median_ms(repeats, [&] { sink = sink + w.state_hash(); });
    std::string bytes;
    double save_ms = median_ms(repeats, [&] { bytes = fulcrum::encode_snapshot(w); });
    World restored;
    double restore_ms =
        median_ms(repeats, [&] { (void)fulcrum::restore_encoded(&restored, bytes); });
    fulcrum::v1::Snapshot base = fulcrum::snapshot_to_proto(w.snapshot());
    w.step();
    fulcrum::v1::SnapshotDelta delta =
        fulcrum::make_delta(base, fulcrum::snapshot_to_proto(w.snapshot()));
    size_t moved_bytes = 0;
    for (const auto& m : delta.moved()) moved_bytes += m.ByteSizeLong() + 2;  // + tag, length
    double per_moving =
        delta.moved_size() > 0 ? static_cast<double>(moved_bytes) / delta.moved_size() : 0.0;
    std::printf("| %s | %d | %d | %.3f | %.3f | %.1f%% | %.0f | %.2f | %.2f | %.1f | %.1f |\n",
                row.scene, bodies, awake, step_ms, hash_ms, 100.0 * hash_ms / step_ms,
                static_cast<double>(bytes.size()) / bodies, save_ms, restore_ms, per_moving,
                static_cast<double>(delta.ByteSizeLong()) / bodies);
  }
  return 0;
}
