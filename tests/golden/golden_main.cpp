// Prints one line per golden scenario:
//   name ticks final_hash combined_hash
// with both hashes as 16 hex digits; combined_hash covers every tick's hash, so a difference
// at any tick shows. tools/determinism.sh and tools/cross_aarch64.sh compare this output
// between builds; golden_test.cpp pins it.
//
// Usage: fulcrum_golden [--per-tick] [--simd PATH] [--threads N] [scenario...]
//   no scenario names: every scenario, in order
//   --per-tick: one line "name tick hash" per tick instead (tick = World::tick() after the
//               step, from 1), for finding the first tick at which two builds differ
//   --simd PATH: the contact solver's instruction path (scalar, lanes2, lanes4, avx512, auto); an
//               error, not a fallback, when this CPU cannot run it
//   --threads N: World::set_threads(N) for every scenario (default 1)
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fulcrum/simd.h"
#include "golden_scenes.h"

int main(int argc, char** argv) {
  using fulcrum::golden::GoldenScenario;
  bool per_tick = false;
  int threads = 1;
  std::vector<std::string> wanted;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--per-tick") == 0) {
      per_tick = true;
    } else if (std::strcmp(argv[i], "--threads") == 0 && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
      if (threads < 1 || threads > fulcrum::World::kMaxThreads) {
        std::fprintf(stderr, "fulcrum_golden: --threads %s: expected 1 to %d\n", argv[i],
                     fulcrum::World::kMaxThreads);
        return 2;
      }
    } else if (std::strcmp(argv[i], "--simd") == 0 && i + 1 < argc) {
      fulcrum::Result<fulcrum::SimdPath> path = fulcrum::parse_simd_path(argv[++i]);
      fulcrum::Status set = path.ok() ? fulcrum::set_simd_path(*path) : path.status();
      if (!set.ok()) {
        std::fprintf(stderr, "fulcrum_golden: %s\n", set.message().c_str());
        return 2;
      }
    } else {
      wanted.emplace_back(argv[i]);
    }
  }
  size_t printed = 0;
  for (const GoldenScenario& scenario : fulcrum::golden::golden_scenarios()) {
    bool selected = wanted.empty();
    for (const std::string& name : wanted) selected = selected || name == scenario.name;
    if (!selected) continue;
    std::vector<uint64_t> hashes = fulcrum::golden::run_golden(scenario, threads);
    if (per_tick) {
      for (size_t t = 0; t < hashes.size(); ++t) {
        std::printf("%s %zu %016" PRIx64 "\n", scenario.name, t + 1, hashes[t]);
      }
    } else {
      std::printf("%s %d %016" PRIx64 " %016" PRIx64 "\n", scenario.name, scenario.ticks,
                  hashes.empty() ? uint64_t{0} : hashes.back(),
                  fulcrum::golden::combine_hashes(hashes));
    }
    std::fflush(stdout);
    ++printed;
  }
  if (printed == 0 || printed < wanted.size()) {
    std::fprintf(stderr, "fulcrum_golden: unknown scenario name; known:");
    for (const GoldenScenario& s : fulcrum::golden::golden_scenarios()) {
      std::fprintf(stderr, " %s", s.name);
    }
    std::fprintf(stderr, "\n");
    return 1;
  }
  return 0;
}
