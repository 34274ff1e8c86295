// The pins' cost by grid size: an n x n grid of circles pinned to their neighbours (the joint
// grid's scene at any size), at fixed substeps so that sizes compare, each run stepped from a
// new world and the fastest run kept. The fastest of several short runs is what a shared,
// noisy machine measures best: a pass that fits the caches (n = 20, 760 pins) against one that
// streams more than a core's L2 (n = 100, 19 800 pins).
//   fulcrum_pin_grid_bench [--size N] [--steps S] [--runs R] [--substeps K]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/world.h"

namespace {

using fulcrum::BodyType;
using fulcrum::Vec2;

struct Options {
  int size = 100;
  int steps = 100;
  int runs = 5;
  int substeps = 14;  // the joint grid's budget at the defaults
};

// The value of `--name VALUE` in [lo, hi], or a message naming what is wrong.
bool parse_int(const char* name, const char* text, int lo, int hi, int* out) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < lo || v > hi) {
    std::fprintf(stderr, "fulcrum_pin_grid_bench: %s must be an integer in [%d, %d], got '%s'\n",
                 name, lo, hi, text);
    return false;
  }
  *out = static_cast<int>(v);
  return true;
}

fulcrum::SceneDef pin_grid(const Options& o) {
  fulcrum::SceneDef s;
  s.settings.enable_sleep = false;
  s.settings.substeps = o.substeps;
  s.settings.max_substeps = o.substeps;  // no budget: every size runs the same passes
  fulcrum::Filter filter;                // the circles never touch one another
  filter.category_bits = 2;
  filter.mask_bits = ~uint64_t{2};
  const int n = o.size;
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < n; ++i) {
      const bool fixed = i == 0 && k >= n / 2 - 3 && k <= n / 2 + 3;
      fulcrum::SceneBody body;
      body.def.type = fixed ? BodyType::kStatic : BodyType::kDynamic;
      body.def.position = Vec2(k, -i);
      fulcrum::ShapeDef shape;
      shape.geometry = fulcrum::Circle{Vec2::Zero(), 0.4};
      shape.filter = filter;
      body.shapes.push_back(shape);
      s.bodies.push_back(body);
    }
  }
  auto pin = [&](int a, int b, const Vec2& anchor_a, const Vec2& anchor_b) {
    fulcrum::RevoluteJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    s.joints.push_back(fulcrum::SceneJoint{a, b, def});
  };
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < n; ++i) {
      if (i > 0) pin(k * n + i - 1, k * n + i, Vec2(0, -0.5), Vec2(0, 0.5));
      if (k > 0) pin((k - 1) * n + i, k * n + i, Vec2(0.5, 0), Vec2(-0.5, 0));
    }
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf(
          "usage: fulcrum_pin_grid_bench [--size N] [--steps S] [--runs R] "
          "[--substeps K]\n");
      return 0;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "fulcrum_pin_grid_bench: %s needs a value\n", arg.c_str());
      return 2;
    }
    const char* value = argv[++i];
    bool ok = false;
    if (arg == "--size") {
      ok = parse_int("--size", value, 2, 400, &o.size);
    } else if (arg == "--steps") {
      ok = parse_int("--steps", value, 1, 100000, &o.steps);
    } else if (arg == "--runs") {
      ok = parse_int("--runs", value, 1, 1000, &o.runs);
    } else if (arg == "--substeps") {
      ok = parse_int("--substeps", value, 1, 64, &o.substeps);
    } else {
      std::fprintf(stderr, "fulcrum_pin_grid_bench: unknown option '%s' (see --help)\n",
                   arg.c_str());
    }
    if (!ok) return 2;
  }
  const fulcrum::SceneDef scene = pin_grid(o);
  std::vector<double> ms;
  for (int r = 0; r < o.runs; ++r) {
    auto built = fulcrum::build_world(scene);
    if (!built.ok()) {
      std::fprintf(stderr, "fulcrum_pin_grid_bench: %s\n", built.status().message().c_str());
      return 1;
    }
    fulcrum::World& world = *built;
    for (int i = 0; i < 5; ++i) world.step();  // the first layouts and warm starts
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < o.steps; ++i) world.step();
    const auto t1 = std::chrono::steady_clock::now();
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count() / o.steps);
  }
  std::sort(ms.begin(), ms.end());
  const int pins = 2 * o.size * (o.size - 1);
  std::printf(
      "| size | pins | substeps | steps | runs | ms/step (fastest) | ns per pin per substep |\n"
      "|---|---|---|---|---|---|---|\n"
      "| %d | %d | %d | %d | %d | %.4f | %.2f |\n",
      o.size, pins, o.substeps, o.steps, o.runs, ms.front(), 1e6 * ms.front() / pins / o.substeps);
  return 0;
}
