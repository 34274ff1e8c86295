// fulcrum_reference: the reference solver's cost and the velocity error of the solver settings
// against it from one fixed state (docs/accuracy.md, "The reference solver").
//
//   build/bin/fulcrum_reference                      # vertical_stack mass_ratio_100 bridge
//   build/bin/fulcrum_reference vertical_stack arch
//
// For each scene (sleeping off, so that a settled island still has rows to solve) and each
// family, the world is settled for 60 ticks at the family's own middle setting (soft 4x2, the
// default; split 8: the classic step with split impulses), so that the warm-start impulses
// belong to the family. From that state the reference solve of tick 61 is timed (median of 5)
// and, for 1 to 32 velocity iterations, one step of the family is compared with it
// (fulcrum::setting_velocity_error): the largest and the RMS |v - v_ref| over the bodies.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "fulcrum/reference.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"

namespace {

using fulcrum::WorldSettings;

void soft(WorldSettings* s, int iterations) {
  s->velocity_iterations = iterations;
}

void split(WorldSettings* s, int iterations) {
  s->substeps = 1;
  s->velocity_iterations = iterations;
  s->relax_iterations = 0;
  s->contact_hertz = 0.0;
  s->split_impulses = true;
}

int run(const std::string& name) {
  auto scene = fulcrum::scenes::builtin(name);
  if (!scene.ok()) {
    std::fprintf(stderr, "fulcrum_reference: %s\n", scene.status().to_string().c_str());
    return 2;
  }
  scene->settings.enable_sleep = false;
  struct Family {
    const char* name;
    void (*apply)(WorldSettings*, int);
    int settle_iterations;
  };
  for (Family f : {Family{"soft 4x", soft, 2}, Family{"split ", split, 8}}) {
    fulcrum::SceneDef s = *scene;
    f.apply(&s.settings, f.settle_iterations);
    auto world = fulcrum::build_world(s);
    if (!world.ok()) {
      std::fprintf(stderr, "fulcrum_reference: %s\n", world.status().to_string().c_str());
      return 2;
    }
    for (int t = 0; t < 60; ++t) world->step();
    std::vector<double> ms;
    fulcrum::ReferenceSolution ref;
    for (int r = 0; r < 5; ++r) {
      auto t0 = std::chrono::steady_clock::now();
      auto solved = fulcrum::solve_reference(*world);
      auto t1 = std::chrono::steady_clock::now();
      if (!solved.ok()) {
        std::fprintf(stderr, "fulcrum_reference: %s\n", solved.status().to_string().c_str());
        return 2;
      }
      ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      ref = *solved;
    }
    std::sort(ms.begin(), ms.end());
    std::printf(
        "%s, settled at %s%d: %zu bodies, rows: %d equality, %d normal, %d friction, %d "
        "bounded; %s: residual %.3g N s (%s), %d sweeps, %d direct solves%s, %.2f ms\n",
        name.c_str(), f.name, f.settle_iterations, ref.bodies.size(), ref.equality_rows,
        ref.normal_rows, ref.friction_rows, ref.bounded_rows, ref.method.c_str(), ref.residual,
        ref.converged ? "converged" : "cap reached", ref.iterations, ref.direct_solves,
        ref.regularized ? " (singular: regularized)" : "", ms[ms.size() / 2]);
    for (int it : {1, 2, 4, 8, 16, 32}) {
      WorldSettings settings = world->settings();
      f.apply(&settings, it);
      auto e = fulcrum::setting_velocity_error(*world, settings);
      if (!e.ok()) {
        std::fprintf(stderr, "fulcrum_reference: %s\n", e.status().to_string().c_str());
        return 2;
      }
      std::printf("  %s%-2d  max |dv| %.3g m/s  rms %.3g m/s  max |dw| %.3g rad/s\n", f.name, it,
                  e->error.max_linear, e->error.rms_linear, e->error.max_angular);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> names;
  for (int i = 1; i < argc; ++i) names.push_back(argv[i]);
  if (names.empty()) names = {"vertical_stack", "mass_ratio_100", "bridge"};
  for (const std::string& n : names) {
    if (int rc = run(n); rc != 0) return rc;
  }
  return 0;
}
