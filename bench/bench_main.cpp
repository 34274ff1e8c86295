// fulcrum_bench: a table runner over the shared scene builders. For each scene it steps the
// world N times, R times over, and reports the median ms per step (steps 1..N-1: step 0 builds
// the first contacts and is excluded), the largest penetration and joint error at the end, the
// number of bodies that moved more than 0.5 m, and the final state hash.
//
//   build/bin/fulcrum_bench                       # the default table
//   build/bin/fulcrum_bench --scene large_pyramid --steps 500 --repeats 5
//   build/bin/fulcrum_bench --iterations 4 --csv  # CSV instead of Markdown
//   build/bin/fulcrum_bench --threads 2 --simd scalar  # World::set_threads, the solver's path
#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/simd.h"
#include "fulcrum/world.h"

namespace {

struct Entry {
  std::string scene;
  int steps;
};

struct Row {
  std::string scene;
  int bodies = 0;
  int steps = 0;
  double ms_per_step = 0.0;
  double max_penetration = 0.0;
  double max_joint_error = 0.0;
  int moved = 0;
  uint64_t hash = 0;
};

Row run(const Entry& e, int repeats, int iterations, int threads) {
  Row row;
  row.scene = e.scene;
  row.steps = e.steps;
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    fulcrum::SceneDef scene = fulcrum::scenes::builtin(e.scene).value();
    if (iterations > 0) scene.settings.velocity_iterations = iterations;
    fulcrum::World world = std::move(fulcrum::build_world(scene).value());
    if (!world.set_threads(threads).ok()) std::exit(2);
    // Scenes that edit themselves (rain) do so before every step, inside the timed loop, as
    // Box2D v3's benchmark app does.
    std::unique_ptr<fulcrum::scenes::SceneDriver> driver = fulcrum::scenes::builtin_driver(e.scene);
    auto step = [&](int i) {
      if (driver != nullptr && !driver->before_step(world, i).ok()) std::exit(1);
      world.step();
    };
    std::vector<fulcrum::Vec2> start;
    for (fulcrum::BodyId id : world.bodies()) start.push_back(world.body_state(id)->center);
    step(0);
    double penetration = 0.0;
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 1; i < e.steps; ++i) step(i);
    auto t1 = std::chrono::steady_clock::now();
    times.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count() / (e.steps - 1));
    penetration = std::max(penetration, world.metrics().max_penetration);
    row.max_joint_error = world.metrics().max_joint_error;
    int moved = -1;  // a driven scene's bodies come and go: not measured
    if (driver == nullptr) {
      moved = 0;
      int k = 0;
      for (fulcrum::BodyId id : world.bodies()) {
        fulcrum::BodyState s = *world.body_state(id);
        if (s.type != fulcrum::BodyType::kStatic && fulcrum::distance(s.center, start[k]) > 0.5) {
          ++moved;
        }
        ++k;
      }
    }
    row.bodies = world.body_count();
    row.max_penetration = penetration;
    row.moved = moved;
    row.hash = world.state_hash();
  }
  std::sort(times.begin(), times.end());
  row.ms_per_step = times[times.size() / 2];
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<Entry> table = {{"large_pyramid", 500},
                              {"many_pyramids", 500},
                              {"many_pyramids_grid", 200},
                              {"tumbler", 750},
                              {"particle_pile", 300},
                              {"circle_pile", 300},
                              {"joint_grid", 500},
                              {"cloth", 600},
                              {"ragdolls", 600},
                              {"ragdoll_rain", 300},
                              {"rain", 1000},
                              {"smash", 300},
                              {"spinner", 500},
                              {"very_heavy_chain", 600},
                              {"thin_planks", 600}};
  std::vector<Entry> chosen;
  int repeats = 3, steps = 0, iterations = 0, threads = 1;
  bool csv = false;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "fulcrum_bench: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--scene") {
      chosen.push_back({value(), 0});
    } else if (a == "--steps") {
      steps = std::atoi(value());
    } else if (a == "--repeats") {
      repeats = std::max(1, std::atoi(value()));
    } else if (a == "--iterations") {
      iterations = std::atoi(value());
    } else if (a == "--csv") {
      csv = true;
    } else if (a == "--threads") {
      threads = std::atoi(value());
      if (threads < 1 || threads > fulcrum::World::kMaxThreads) {
        std::fprintf(stderr, "fulcrum_bench: --threads: expected 1 to %d\n",
                     fulcrum::World::kMaxThreads);
        return 2;
      }
    } else if (a == "--simd") {
      auto path = fulcrum::parse_simd_path(value());
      fulcrum::Status set = path.ok() ? fulcrum::set_simd_path(*path) : path.status();
      if (!set.ok()) {
        std::fprintf(stderr, "fulcrum_bench: --simd: %s\n", set.message().c_str());
        return 2;
      }
    } else {
      std::fprintf(
          stderr,
          "usage: fulcrum_bench [--scene NAME]... [--steps N] [--repeats R] "
          "[--iterations K] [--threads N] [--simd scalar|lanes2|lanes4|avx512|auto] [--csv]\n");
      return 2;
    }
  }
  if (chosen.empty()) chosen = table;
  for (Entry& e : chosen) {
    if (steps > 0) e.steps = steps;
    if (e.steps == 0) {
      auto it = std::find_if(table.begin(), table.end(),
                             [&](const Entry& t) { return t.scene == e.scene; });
      e.steps = it != table.end() ? it->steps : 500;
    }
    if (!fulcrum::scenes::builtin(e.scene).ok()) {
      std::fprintf(stderr, "fulcrum_bench: %s\n",
                   fulcrum::scenes::builtin(e.scene).status().message().c_str());
      return 2;
    }
  }
  if (csv) {
    std::printf(
        "scene,bodies,steps,ms_per_step,max_penetration_m,max_joint_error_m,moved_over_0.5m,state_"
        "hash\n");
  } else {
    std::printf(
        "| scene | bodies | steps | ms/step (median of %d) | max penetration (m) | max joint error "
        "(m) | moved > 0.5 m | "
        "state hash |\n",
        repeats);
    std::printf("|---|---|---|---|---|---|---|---|\n");
  }
  for (const Entry& e : chosen) {
    Row r = run(e, repeats, iterations, threads);
    if (csv) {
      std::printf("%s,%d,%d,%.4f,%.6f,%.6f,%d,%016" PRIx64 "\n", r.scene.c_str(), r.bodies, r.steps,
                  r.ms_per_step, r.max_penetration, r.max_joint_error, r.moved, r.hash);
    } else {
      std::string moved = r.moved < 0 ? "-" : std::to_string(r.moved);
      std::printf("| %s | %d | %d | %.3f | %.4f | %.4f | %s | %016" PRIx64 " |\n", r.scene.c_str(),
                  r.bodies, r.steps, r.ms_per_step, r.max_penetration, r.max_joint_error,
                  moved.c_str(), r.hash);
    }
    std::fflush(stdout);
  }
  return 0;
}
