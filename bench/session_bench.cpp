// What a multiplayer session costs. Prints Markdown tables; figures go in docs/multiplayer.md
// with the machine and date.
//   fulcrum_session_bench [--repeats N] [--ticks N] [--players 2,8,32] [--clock-delay 2]
//                         [--server PATH]
//                         [--only rollback|latency|bytes]
//
// Rollback (fulcrum/rollback.h): when the server confirms a tick whose inputs differ from the
// prediction, a PredictedWorld copies its confirmed world into the predicted world
// (World::copy_state) and steps again up to the present. A rollback of N ticks is that copy and
// N steps, engine only (no network, no protobuf), on 1000-body worlds. The table also shows
// what a snapshot and a checked restore cost, the way to the same state across processes. The
// deepest rollback that fits in one 60 Hz frame (16.7 ms) leaves nothing of the frame for the game.
//
// Latency and bytes (session_net.cpp) run a real fulcrum-server process on loopback.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fulcrum/geometry.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/state.h"
#include "session_bench.h"

namespace {

using Clock = std::chrono::steady_clock;
using fulcrum::SceneDef;
using fulcrum::Vec2;
using fulcrum::World;

constexpr double kFrameMs = 1000.0 / 60.0;

template <typename F>
double median_ms(int repeats, F f) {
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const auto a = Clock::now();
    f();
    t.push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

fulcrum::SceneBody dynamic(const Vec2& at, fulcrum::Geometry geometry) {
  fulcrum::SceneBody body;
  body.def.type = fulcrum::BodyType::kDynamic;
  body.def.position = at;
  body.def.enable_sleep = false;  // every body moves every tick: the worst case to restore
  fulcrum::ShapeDef shape;
  shape.geometry = geometry;
  body.shapes.push_back(shape);
  return body;
}

// 1000 boxes of 0.8 m dropped from a 25 x 40 grid into a bin 26 m wide, measured once they are
// a settling pile (2 s): every body in contact, a game's worst case.
SceneDef pile() {
  SceneDef scene;
  fulcrum::scenes::add_ground(&scene, 14.0);
  for (double x : {-13.5, 13.5}) {
    fulcrum::SceneBody wall;
    wall.def.position = Vec2(x, 25.0);
    fulcrum::ShapeDef shape;
    shape.geometry = fulcrum::make_box(0.5, 25.0);
    wall.shapes.push_back(shape);
    scene.bodies.push_back(std::move(wall));
  }
  for (int i = 0; i < 1000; ++i) {
    scene.bodies.push_back(
        dynamic(Vec2(-12.0 + i % 25, 1.0 + i / 25), fulcrum::make_box(0.4, 0.4)));
  }
  return scene;
}

struct Case {
  const char* name;
  SceneDef (*scene)();
  int settle;  // ticks stepped before measuring
};

// | scene | ... | rollback 1/4/8/16 ticks | deepest in one frame |
void rollback_table(int repeats) {
  std::printf(
      "## Rollback: the confirmed world copied, N ticks stepped again (ms)\n\n"
      "| scene | bodies | contacts | step (of 16) | snapshot | restore | copy | 1 tick | 4 ticks "
      "| 8 ticks | 16 ticks | deepest in 16.7 ms (measured) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const Case cases[] = {{"drifting_1000", fulcrum::session_bench::drifting, 60},
                        {"box_pile_1000", pile, 120}};
  for (const Case& c : cases) {
    auto built = fulcrum::build_world(c.scene());
    if (!built.ok()) {
      std::fprintf(stderr, "%s: %s\n", c.name, built.status().message().c_str());
      std::exit(1);
    }
    World confirmed = std::move(built).value();
    for (int i = 0; i < c.settle; ++i) confirmed.step();
    World predicted;
    auto rollback = [&](int ticks) {
      predicted.copy_state(confirmed);
      for (int i = 0; i < ticks; ++i) predicted.step();
    };
    const double restore_ms = median_ms(repeats, [&] { rollback(0); });
    fulcrum::WorldSnapshot kept;
    const double snapshot_ms = median_ms(repeats, [&] { kept = confirmed.snapshot(); });
    const double checked_ms = median_ms(repeats, [&] {
      if (!predicted.restore(kept).ok()) std::exit(1);
    });
    double ms[4];
    const int depths[4] = {1, 4, 8, 16};
    for (int k = 0; k < 4; ++k) ms[k] = median_ms(repeats, [&] { rollback(depths[k]); });
    // One step, from the 16-tick figure (a single step is too short to time alone).
    const double per_tick = (ms[3] - restore_ms) / 16.0;
    int deepest = static_cast<int>(std::floor((kFrameMs - restore_ms) / per_tick));
    double deepest_ms = median_ms(repeats, [&] { rollback(deepest); });
    while (deepest > 0 && deepest_ms > kFrameMs) {
      --deepest;
      deepest_ms = median_ms(repeats, [&] { rollback(deepest); });
    }
    std::printf(
        "| %s | %d | %d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %d ticks (%.2f "
        "ms) "
        "|\n",
        c.name, confirmed.body_count(), confirmed.metrics().contact_count, per_tick, snapshot_ms,
        checked_ms, restore_ms, ms[0], ms[1], ms[2], ms[3], deepest, deepest_ms);
  }
  std::printf("\n");
}

}  // namespace

namespace fulcrum::session_bench {

// Declared in session_bench.h; load_bench's drifting_1000, where some bodies touch.
SceneDef drifting() {
  SceneDef scene;
  scene.settings.gravity = Vec2::Zero();
  for (int i = 0; i < 1000; ++i) {
    SceneBody b = dynamic(Vec2(i % 40, i / 40), Circle{Vec2::Zero(), 0.25});
    b.def.linear_velocity = Vec2(2.0 * std::sin(i * 1.7), 2.0 * std::cos(i * 2.3));
    b.def.angular_velocity = std::sin(i * 0.9);
    scene.bodies.push_back(std::move(b));
  }
  return scene;
}

SceneDef stacks() {
  SceneDef scene;
  scenes::add_ground(&scene, 210.0);
  for (int i = 0; i < 200; ++i) {
    scenes::StackOptions stack;
    stack.count = 5;
    stack.box_size = 0.5;
    stack.offset = 0.0;
    stack.origin = Vec2(-199.0 + 2.0 * i, 0.0);
    scenes::add_stack(&scene, stack);
  }
  return scene;
}

}  // namespace fulcrum::session_bench

// "2,8,32" as numbers.
std::vector<int> parse_list(const char* text) {
  std::vector<int> out;
  for (const char* p = text; *p;) {
    out.push_back(std::max(1, std::atoi(p)));
    while (*p && *p != ',') ++p;
    if (*p == ',') ++p;
  }
  return out;
}

int main(int argc, char** argv) {
  int repeats = 15;
  std::string only;
  fulcrum::session_bench::NetOptions net;
  net.server = FULCRUM_SERVER_BIN;
  net.players = {2, 8, 32};
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    const char* value = argv[i + 1];
    if (flag == "--repeats") {
      repeats = std::max(1, std::atoi(value));
    } else if (flag == "--ticks") {
      net.ticks = std::max(40, std::atoi(value));
    } else if (flag == "--clock-delay") {
      net.clock_delay = std::max(1, std::atoi(value));
    } else if (flag == "--players") {
      net.players = parse_list(value);
    } else if (flag == "--server") {
      net.server = value;
    } else if (flag == "--only") {
      only = value;
    } else {
      std::fprintf(stderr, "fulcrum_session_bench: unknown flag %s\n", argv[i]);
      return 2;
    }
  }
  if (only.empty() || only == "rollback") rollback_table(repeats);
  if (only.empty() || only == "latency") fulcrum::session_bench::latency_table(net);
  if (only.empty() || only == "bytes") fulcrum::session_bench::bytes_table(net);
  return 0;
}
