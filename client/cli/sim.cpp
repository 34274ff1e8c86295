// fulcrum sim: build a scene, step it, report the state hash, timing and accuracy figures.
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <limits>
#include <ostream>
#include <string>

#include "command.h"
#include "fulcrum/scene.h"
#include "fulcrum/world.h"
#include "json_writer.h"

namespace fulcrum::cli {
namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

struct SimReport {
  std::string scene;
  int64_t ticks = 0;
  uint64_t hash = 0;
  double wall_ms = 0.0;
  WorldMetrics metrics;

  double ms_per_step() const { return ticks > 0 ? wall_ms / static_cast<double>(ticks) : 0.0; }
};

void print_text(const SimReport& r, std::ostream& out) {
  const WorldMetrics& m = r.metrics;
  out << "scene:        " << r.scene << "\n"
      << "bodies:       " << m.body_count << "\n"
      << "tick:         " << m.tick << "\n"
      << "state hash:   " << hex64(r.hash) << "\n"
      << "wall time:    " << num(r.wall_ms) << " ms total, " << num(r.ms_per_step()) << " ms/step\n"
      << "penetration:  max " << num(m.max_penetration) << " m, mean " << num(m.mean_penetration)
      << " m\n"
      << "energy:       kinetic " << num(m.kinetic_energy) << " J, potential "
      << num(m.potential_energy) << " J\n"
      << "momentum:     linear (" << num(m.linear_momentum.x()) << ", "
      << num(m.linear_momentum.y()) << ") kg m/s, angular " << num(m.angular_momentum)
      << " kg m^2/s\n"
      << "max speed:    " << num(m.max_speed) << " m/s\n"
      << "awake bodies: " << m.awake_body_count << "\n"
      << "contacts:     " << m.contact_count << "\n";
}

// Keys follow the Protobuf JSON mapping (lowerCamelCase), like the scene files.
void print_json(const SimReport& r, std::ostream& out) {
  const WorldMetrics& m = r.metrics;
  JsonWriter w(out);
  w.field("scene", r.scene);
  w.field("bodyCount", m.body_count);
  w.field("ticks", r.ticks);
  w.field("tick", m.tick);
  w.field("stateHash", hex64(r.hash));
  w.field("wallMs", r.wall_ms);
  w.field("msPerStep", r.ms_per_step());
  w.field("maxPenetration", m.max_penetration);
  w.field("meanPenetration", m.mean_penetration);
  w.field("kineticEnergy", m.kinetic_energy);
  w.field("potentialEnergy", m.potential_energy);
  w.begin_object("linearMomentum");
  w.field("x", m.linear_momentum.x());
  w.field("y", m.linear_momentum.y());
  w.end_object();
  w.field("angularMomentum", m.angular_momentum);
  w.field("maxSpeed", m.max_speed);
  w.field("awakeBodyCount", m.awake_body_count);
  w.field("contactCount", m.contact_count);
  w.finish();
}

}  // namespace

int run_sim(const Invocation& inv) {
  // The command line is checked whole before any scene is loaded.
  const std::optional<std::string> ticks_text = inv.args.value("ticks");
  if (!ticks_text) return inv.usage_error("missing --ticks N");
  std::string error;
  const std::optional<int64_t> ticks =
      parse_int(*ticks_text, 0, std::numeric_limits<int64_t>::max(), &error);
  if (!ticks) return inv.usage_error("--ticks: " + error);

  LoadedScene loaded;
  int exit_code = kExitOk;
  if (!load_scene_from_args(inv, &loaded, &exit_code)) return exit_code;

  Result<World> world = build_world(loaded.scene);
  if (!world.ok()) return inv.fail(world.status().message());

  SimReport report;
  report.scene = loaded.label;
  report.ticks = *ticks;
  // Only stepping is timed: building the world is not part of the per-step cost.
  const auto start = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < *ticks; ++i) world->step();
  const auto stop = std::chrono::steady_clock::now();
  report.wall_ms = std::chrono::duration<double, std::milli>(stop - start).count();
  report.hash = world->state_hash();
  report.metrics = world->metrics();

  if (inv.args.has("json")) {
    print_json(report, inv.out);
  } else {
    print_text(report, inv.out);
  }
  return kExitOk;
}

}  // namespace fulcrum::cli
