// fulcrum sim: build a scene, step it, report the state hash, timing and accuracy figures: the
// world at the last tick, and the largest errors over the whole run with the tick of each.
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "command.h"
#include "edit_script.h"
#include "fulcrum/scene.h"
#include "fulcrum/world.h"
#include "json_writer.h"
#include "set_settings.h"
#include "sim_trace.h"

namespace fulcrum::cli {
namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

// The largest value of one figure over the run and the first tick it was reached at; tick -1
// while the figure has stayed at 0.
struct Peak {
  double value = 0.0;
  int64_t tick = -1;

  void offer(double v, int64_t at) {
    if (v > value) {
      value = v;
      tick = at;
    }
  }
};

// Step time of one kind of tick.
struct StepTime {
  int64_t ticks = 0;
  double ms = 0.0;

  double per_step() const { return ticks > 0 ? ms / static_cast<double>(ticks) : 0.0; }
};

// Figures over the whole run, each from World::metrics() after every step (the engine's own
// measures: the overlap of contact points, JointState::linear_error, body speeds, energies).
struct RunFigures {
  int64_t first_tick = 0;  // the tick the run started from
  int64_t ticks_per_second = 60;
  Peak penetration;
  Peak penetration_after_first_second;  // HARD_CASES samples every tick after the first second
  Peak joint_error;
  Peak speed;
  // Mechanical energy E = kinetic + potential, where the potential energy of each dynamic body
  // is -m (g . c) (gravity scaled by the body's gravity_scale, c its centre of mass): height
  // times weight under the usual downward gravity. Drift is E - E0, E0 before the first step.
  double initial_energy = 0.0;
  double final_energy = 0.0;
  Peak energy_gain;     // largest E - E0
  Peak energy_loss;     // largest E0 - E
  StepTime awake;       // ticks that started with at least one body awake
  StepTime asleep;      // ticks that started with every body asleep
  Peak budget_islands;  // islands given more substeps than the world's
  int max_substeps = 0;
  int max_relax = 0;

  void start(const WorldMetrics& m, double dt) {
    first_tick = m.tick;
    initial_energy = final_energy = m.kinetic_energy + m.potential_energy;
    ticks_per_second = std::max<int64_t>(1, std::llround(1.0 / dt));
  }
  void after_step(const WorldMetrics& m, bool started_awake, double ms) {
    (started_awake ? awake : asleep).ticks += 1;
    (started_awake ? awake : asleep).ms += ms;
    penetration.offer(m.max_penetration, m.tick);
    if (m.tick - first_tick > ticks_per_second) {
      penetration_after_first_second.offer(m.max_penetration, m.tick);
    }
    joint_error.offer(m.max_joint_error, m.tick);
    budget_islands.offer(m.budget_islands, m.tick);
    max_substeps = std::max(max_substeps, m.max_substeps);
    max_relax = std::max(max_relax, m.max_relax_iterations);
    speed.offer(m.max_speed, m.tick);
    final_energy = m.kinetic_energy + m.potential_energy;
    energy_gain.offer(final_energy - initial_energy, m.tick);
    energy_loss.offer(initial_energy - final_energy, m.tick);
  }
};

struct SimReport {
  std::string scene;
  int64_t ticks = 0;
  uint64_t hash = 0;
  double wall_ms = 0.0;
  WorldMetrics metrics;
  int joint_count = 0;
  int substeps = 0;  // the world's setting
  RunFigures run;

  double ms_per_step() const { return ticks > 0 ? wall_ms / static_cast<double>(ticks) : 0.0; }
};

std::string at_tick(const Peak& p, const std::string& unit) {
  if (p.tick < 0) return "0" + unit;
  return num(p.value) + unit + " at tick " + std::to_string(p.tick);
}

void print_text(const SimReport& r, std::ostream& out) {
  const WorldMetrics& m = r.metrics;
  const RunFigures& run = r.run;
  out << "scene:        " << r.scene << "\n"
      << "bodies:       " << m.body_count << "\n"
      << "tick:         " << m.tick << "\n"
      << "state hash:   " << hex64(r.hash) << "\n"
      << "wall time:    " << num(r.wall_ms) << " ms total, " << num(r.ms_per_step()) << " ms/step\n"
      << "ms/step:      " << num(run.awake.per_step()) << " over " << run.awake.ticks
      << " ticks with bodies awake, " << num(run.asleep.per_step()) << " over " << run.asleep.ticks
      << " ticks asleep\n"
      << "penetration:  max " << num(m.max_penetration) << " m, mean " << num(m.mean_penetration)
      << " m\n"
      << "joint error:  max " << num(m.max_joint_error) << " m\n"
      << "energy:       kinetic " << num(m.kinetic_energy) << " J, potential "
      << num(m.potential_energy) << " J\n"
      << "momentum:     linear (" << num(m.linear_momentum.x()) << ", "
      << num(m.linear_momentum.y()) << ") kg m/s, angular " << num(m.angular_momentum)
      << " kg m^2/s\n"
      << "max speed:    " << num(m.max_speed) << " m/s\n"
      << "awake bodies: " << m.awake_body_count << "\n"
      << "contacts:     " << m.contact_count << "\n"
      << "budgets:      " << m.budget_islands << " islands; up to " << m.max_substeps
      << " substeps (world " << r.substeps << "), " << m.max_relax_iterations << " relax passes\n";
  if (r.ticks == 0) return;
  out << "largest over the run (ticks " << run.first_tick + 1 << " to " << m.tick
      << ", measured after each step):\n"
      << "  penetration:  " << at_tick(run.penetration, " m") << "; after the first second "
      << at_tick(run.penetration_after_first_second, " m") << "\n"
      << "  joint error:  "
      << (r.joint_count == 0 ? std::string("none (no joints)") : at_tick(run.joint_error, " m"))
      << "\n"
      << "  speed:        " << at_tick(run.speed, " m/s") << "\n"
      << "  budgets:      " << at_tick(run.budget_islands, " islands") << "; up to "
      << run.max_substeps << " substeps (world " << r.substeps << "), " << run.max_relax
      << " relax passes\n"
      << "  energy drift: gain " << at_tick(run.energy_gain, " J") << ", loss "
      << at_tick(run.energy_loss, " J") << "; at the end "
      << num(run.final_energy - run.initial_energy) << " J\n"
      << "                of E0 " << num(run.initial_energy)
      << " J (kinetic + potential; potential: -m g . c at each dynamic body's centre of mass)\n";
}

void peak_fields(JsonWriter& w, const std::string& key, const Peak& p) {
  w.field(key, p.value);
  if (p.tick < 0) {
    w.null_field(key + "Tick");
  } else {
    w.field(key + "Tick", p.tick);
  }
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
  w.field("maxJointError", m.max_joint_error);
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
  w.field("budgetIslands", m.budget_islands);
  w.field("maxSubsteps", m.max_substeps);
  w.field("maxRelaxIterations", m.max_relax_iterations);
  w.field("jointCount", r.joint_count);
  // Over the run: the largest of each figure after every step, with its tick (null: never
  // above 0).
  const RunFigures& run = r.run;
  w.begin_object("run");
  w.field("firstTick", run.first_tick);
  peak_fields(w, "maxPenetration", run.penetration);
  peak_fields(w, "maxPenetrationAfterFirstSecond", run.penetration_after_first_second);
  peak_fields(w, "maxJointError", run.joint_error);
  peak_fields(w, "maxSpeed", run.speed);
  peak_fields(w, "maxBudgetIslands", run.budget_islands);
  w.field("maxSubsteps", run.max_substeps);
  w.field("maxRelaxIterations", run.max_relax);
  w.field("initialEnergy", run.initial_energy);
  w.field("finalEnergy", run.final_energy);
  peak_fields(w, "maxEnergyGain", run.energy_gain);
  peak_fields(w, "maxEnergyLoss", run.energy_loss);
  w.field("awakeTicks", run.awake.ticks);
  w.field("awakeMsPerStep", run.awake.per_step());
  w.field("asleepTicks", run.asleep.ticks);
  w.field("asleepMsPerStep", run.asleep.per_step());
  w.end_object();
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
  const std::optional<std::string> trace_path = inv.args.value("trace");
  int64_t trace_every = 1;
  if (auto k = inv.args.value("trace-every")) {
    if (!trace_path) return inv.usage_error("--trace-every: only with --trace FILE");
    std::optional<int64_t> parsed = parse_int(*k, 1, std::numeric_limits<int64_t>::max(), &error);
    if (!parsed) return inv.usage_error("--trace-every: " + error);
    trace_every = *parsed;
  }
  std::vector<BodyId> trace_bodies;
  if (auto list = inv.args.value("trace-bodies")) {
    if (!trace_path) return inv.usage_error("--trace-bodies: only with --trace FILE");
    std::optional<std::vector<BodyId>> ids = parse_body_list(*list, &error);
    if (!ids) return inv.usage_error("--trace-bodies: " + error);
    trace_bodies = std::move(*ids);
  }
  Result<std::vector<SettingOverride>> overrides = parse_setting_overrides(inv.args.values("set"));
  if (!overrides.ok()) return inv.usage_error(overrides.status().message());
  {
    // Names and values are checked against the defaults now; the scene's own settings below.
    WorldSettings defaults;
    Status st = apply_setting_overrides(*overrides, &defaults);
    if (!st.ok()) return inv.usage_error(st.message());
  }

  LoadedScene loaded;
  int exit_code = kExitOk;
  if (!load_scene_from_args(inv, &loaded, &exit_code)) return exit_code;
  if (Status st = apply_setting_overrides(*overrides, &loaded.scene.settings); !st.ok()) {
    return inv.usage_error(st.message());
  }

  Result<World> world = build_world(loaded.scene);
  if (!world.ok()) return inv.fail(scene_error(loaded, world.status()));
  // Read against the world just built: scene indices name its bodies and joints.
  std::optional<EditScriptRun> script;
  if (auto edits = inv.args.value("edits")) {
    Result<EditScriptRun> read = EditScriptRun::load(*edits, *world, *ticks);
    if (!read.ok()) return inv.fail(read.status().message());
    script = std::move(read).value();
  }
  std::unique_ptr<TraceWriter> trace;
  if (trace_path) {
    // A body an edit creates is traced from its creation on (empty cells before); without
    // edits, a handle the scene did not give is a mistake.
    for (const BodyId& id : trace_bodies) {
      if (!script && !world->is_valid(id)) {
        return inv.usage_error("--trace-bodies: no body " + std::to_string(id.index) + ":" +
                               std::to_string(id.generation) + " in the scene (" +
                               std::to_string(world->body_count()) + " bodies, handles 0:1 to " +
                               std::to_string(world->body_count() - 1) + ":1)");
      }
    }
    auto opened = TraceWriter::open(*trace_path, trace_bodies);
    if (!opened.ok()) return inv.fail(opened.status().message());
    trace = std::move(opened).value();
  }

  SimReport report;
  report.scene = loaded.label;
  report.ticks = *ticks;
  report.joint_count = static_cast<int>(world->joints().size());
  report.substeps = world->settings().substeps;
  WorldMetrics metrics = world->metrics();
  report.run.start(metrics, world->settings().dt);
  // Only World::step() is timed: building the world and measuring it are not part of the
  // per-step cost.
  std::vector<v1::EditBatch> applied;
  for (int64_t i = 0; i < *ticks; ++i) {
    if (script) {
      applied.clear();
      if (Status st = script->apply_due(&*world, &applied); !st.ok()) return inv.fail(st.message());
      // Edits wake bodies (and create them): count the tick by the world the step starts from.
      if (!applied.empty()) metrics.awake_body_count = world->metrics().awake_body_count;
    }
    const bool started_awake = metrics.awake_body_count > 0;
    const auto start = std::chrono::steady_clock::now();
    world->step();
    const auto stop = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(stop - start).count();
    report.wall_ms += ms;
    metrics = world->metrics();
    report.run.after_step(metrics, started_awake, ms);
    if (trace && metrics.tick % trace_every == 0) trace->write(*world, metrics);
  }
  if (trace) {
    if (Status st = trace->close(); !st.ok()) return inv.fail(st.message());
  }
  report.hash = world->state_hash();
  report.metrics = metrics;

  if (inv.args.has("json")) {
    print_json(report, inv.out);
  } else {
    print_text(report, inv.out);
  }
  return kExitOk;
}

}  // namespace fulcrum::cli
