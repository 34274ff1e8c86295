// fulcrum_sweep: speed against error (issue 6). Runs every HARD_CASES scene over a grid of
// solver settings and writes, per case and setting, the median ms per step, each error measure
// that applies to the case, pass or fail against the case's HARD_CASES criterion (measured as
// tests/engine/*cases*_test.cpp measure it), and the final state hash. The criteria are the
// probes of hard_case_probes.h, which fulcrum_box2d_compare judges its cases by too; only the
// bullet's (case 17), which runs worlds of its own, is here.
//
//   build/bin/fulcrum_sweep                          # the full grid, into docs/sweep
//   build/bin/fulcrum_sweep --cases vertical_stack,10 --repeats 5 --out /tmp/sweep
//   build/bin/fulcrum_sweep --smoke --out /tmp/smoke # CI: 4 settings, 20 ticks, a few seconds
//
// Outputs in --out: sweep.csv (one row per case and setting), sweep.md (a table per case, the
// cheapest passing setting and the Pareto front marked) and one SVG per case (ms per step
// against the case's main error, log-log, Pareto front drawn, points labelled).
//
// The grid: velocity_iterations 1, 2, 4, 8, 16, 32 for the soft step (4 substeps, 1 relax
// pass, soft contacts at the scene's contact_hertz) and for the classic step (1 substep, no
// relax pass, contact_hertz 0: rigid Baumgarte with slop) with split impulses off and on; and
// substeps 1, 2, 4, 8 at 2 iterations for the soft step. Every other setting is the scene's own:
// the settings that individual tests pin (contact_hertz 60 for the arch, joint_hertz and
// substeps for the joint cases) are not applied, so the sweep shows what the grid alone does.
//
// Timing: ms per step is the mean over steps 1..T-1 of a run (step 0 builds the first contacts,
// as in fulcrum_bench), median over --repeats runs; only World::step() is inside the clock. The
// error run is the first repeat; the others rerun the timing window 0..T-1 only (the engine is
// deterministic, and the sweep checks that each repeat reaches the same state hash there). The
// expensive scenes run fewer ticks than HARD_CASES asks, and the four largest run once (see
// all_cases()), so that the whole grid fits in under 10 minutes on a 2-core machine; their pass
// column judges the criterion over the ticks run.
#include <algorithm>
#include <array>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "fulcrum/reference.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/state.h"
#include "fulcrum/trig.h"
#include "fulcrum/world.h"
#include "hard_case_probes.h"
#include "svg_plot.h"
#ifdef FULCRUM_SWEEP_BOX2D
#include "box2d_run.h"
#endif

namespace {

using fulcrum::BodyId;
using fulcrum::BodyState;
using fulcrum::BodyType;
using fulcrum::DistanceJointDef;
using fulcrum::JointId;
using fulcrum::JointState;
using fulcrum::RevoluteJointDef;
using fulcrum::SceneBody;
using fulcrum::SceneDef;
using fulcrum::SceneJoint;
using fulcrum::ShapeDef;
using fulcrum::Vec2;
using fulcrum::World;
using fulcrum::WorldMetrics;
using fulcrum::WorldSettings;
// The views, probes and measure names of hard_case_probes.h.
using namespace fulcrum::bench;  // NOLINT(google-build-using-namespace)

[[noreturn]] void die(const std::string& message) {
  std::fprintf(stderr, "fulcrum_sweep: %s\n", message.c_str());
  std::exit(2);
}

// --- The settings grid ------------------------------------------------------------------------

// Every setting but `adaptive` runs with budgets off (max_substeps = substeps), so that it
// means what its label says; `adaptive` is the default: soft 4x2 with per-island budgets.
enum class Family { kSoft, kClassic, kClassicSplit, kSoftSubsteps, kAdaptive };
constexpr int kFamilyCount = 5;
const char* const kFamilyNames[kFamilyCount] = {"soft", "classic", "classic_split", "soft_substeps",
                                                "adaptive"};
const char* const kFamilyLegend[kFamilyCount] = {"soft, 4 substeps", "classic", "classic + split",
                                                 "soft, 2 iterations", "adaptive (default)"};

struct Setting {
  Family family = Family::kSoft;
  int substeps = 4;
  int iterations = 2;

  bool soft() const { return family != Family::kClassic && family != Family::kClassicSplit; }
  // "soft 4x2" (substeps x iterations), "classic 8", "split 8", "adaptive".
  std::string label() const {
    if (family == Family::kAdaptive) return "adaptive";
    if (soft()) return "soft " + std::to_string(substeps) + "x" + std::to_string(iterations);
    return (family == Family::kClassic ? "classic " : "split ") + std::to_string(iterations);
  }
  // The short label on the plots: "4x2", "c8", "s8".
  std::string short_label() const {
    if (family == Family::kAdaptive) return "ad";
    if (soft()) return std::to_string(substeps) + "x" + std::to_string(iterations);
    return (family == Family::kClassic ? "c" : "s") + std::to_string(iterations);
  }
  bool is_default() const { return family == Family::kAdaptive; }
  // Passes over all rows per tick: velocity and relax passes per substep, plus the 3 default
  // pseudo-velocity passes with split impulses. The tie-break when timings are within noise.
  int passes() const {
    if (soft()) return substeps * (iterations + 1);
    return iterations + (family == Family::kClassicSplit ? WorldSettings{}.position_iterations : 0);
  }

  void apply(WorldSettings* s) const {
    s->substeps = substeps;
    s->velocity_iterations = iterations;
    if (family != Family::kAdaptive) s->max_substeps = substeps;
    if (soft()) {
      s->relax_iterations = 1;
      s->split_impulses = false;
    } else {
      s->relax_iterations = 0;
      s->contact_hertz = 0.0;
      s->split_impulses = family == Family::kClassicSplit;
    }
  }
};

std::vector<Setting> full_grid() {
  std::vector<Setting> grid;
  for (Family f : {Family::kSoft, Family::kClassic, Family::kClassicSplit}) {
    for (int it : {1, 2, 4, 8, 16, 32}) grid.push_back({f, f == Family::kSoft ? 4 : 1, it});
  }
  // Substeps 1, 2, 4, 8 at 2 iterations; 4 x 2 is the soft row above (the default).
  for (int sub : {1, 2, 8}) grid.push_back({Family::kSoftSubsteps, sub, 2});
  grid.push_back({Family::kAdaptive, 4, 2});
  return grid;
}

std::vector<Setting> smoke_grid() {
  return {{Family::kAdaptive, 4, 2},
          {Family::kSoft, 4, 2},
          {Family::kClassic, 1, 4},
          {Family::kClassicSplit, 1, 4}};
}

// --- Error measures ---------------------------------------------------------------------------

// The CSV column of each error measure (hard_case_probes.h says what each is).
const char* const kMeasureCsv[kMeasureCount] = {
    "max_penetration_m", "mean_penetration_m", "max_displacement_m",     "bodies_out",
    "max_joint_error_m", "max_stretch",        "max_limit_error_rad",    "energy_drift",
    "max_speed_m_s",     "analytic_error",     "ref_velocity_error_m_s", "ref_angular_error_rad_s"};

// --- A scene the registry does not hold (case 16 is built in its test) -----------------------

// Case 16: a particle (radius 0.05) on a 1 m rod (a distance joint) from a static pivot at the
// origin, released at 5 degrees. As tests/engine/joint_test.cpp Case16PendulumOnADistanceJoint.
constexpr double kPendulumAngle = 5.0 * fulcrum::kPi / 180.0;
SceneDef pendulum() {
  SceneDef s;
  s.bodies.push_back(SceneBody{});
  SceneBody bob;
  bob.def.type = BodyType::kParticle;
  fulcrum::SinCos sc = fulcrum::det_sincos(kPendulumAngle);
  bob.def.position = Vec2(sc.sin, -sc.cos);
  ShapeDef shape;
  shape.geometry = fulcrum::Circle{Vec2::Zero(), 0.05};
  bob.shapes.push_back(shape);
  s.bodies.push_back(bob);
  s.joints.push_back(SceneJoint{0, 1, DistanceJointDef{}});
  return s;
}

SceneDef builtin(const char* name) {
  auto s = fulcrum::scenes::builtin(name);
  if (!s.ok()) die(s.status().to_string());
  return std::move(s).value();
}

// --- Building and running ---------------------------------------------------------------------

// fulcrum::build_world, keeping the joint handles (the public World does not list its joints).
// Creates everything in the same order, so the world is the same one, bit for bit (checked
// against build_world's state hash by check_builder below).
struct Built {
  World world;
  std::vector<BodyId> bodies;
  std::vector<JointId> joints;
};

// World::create_*_joint by definition type, for each joint type a SceneJoint can hold.
fulcrum::Result<JointId> create_joint(World& w, const DistanceJointDef& d) {
  return w.create_distance_joint(d);
}
fulcrum::Result<JointId> create_joint(World& w, const RevoluteJointDef& d) {
  return w.create_revolute_joint(d);
}
fulcrum::Result<JointId> create_joint(World& w, const fulcrum::WeldJointDef& d) {
  return w.create_weld_joint(d);
}
fulcrum::Result<JointId> create_joint(World& w, const fulcrum::PrismaticJointDef& d) {
  return w.create_prismatic_joint(d);
}
fulcrum::Result<JointId> create_joint(World& w, const fulcrum::WheelJointDef& d) {
  return w.create_wheel_joint(d);
}
fulcrum::Result<JointId> create_joint(World& w, const fulcrum::MotorJointDef& d) {
  return w.create_motor_joint(d);
}

Built build(const SceneDef& scene) {
  Built b{World(scene.settings), {}, {}};
  for (const SceneBody& sb : scene.bodies) {
    auto body = b.world.create_body(sb.def);
    if (!body.ok()) die(body.status().to_string());
    b.bodies.push_back(*body);
    for (const ShapeDef& shape : sb.shapes) {
      if (auto r = b.world.create_shape(*body, shape); !r.ok()) die(r.status().to_string());
    }
    for (const fulcrum::ChainDef& chain : sb.chains) {
      if (auto r = b.world.create_chain(*body, chain); !r.ok()) die(r.status().to_string());
    }
  }
  for (const SceneJoint& sj : scene.joints) {
    auto joint = std::visit(
        [&](auto def) {
          def.body_a = b.bodies[sj.body_a];
          def.body_b = b.bodies[sj.body_b];
          return create_joint(b.world, def);
        },
        sj.def);
    if (!joint.ok()) die(joint.status().to_string());
    b.joints.push_back(*joint);
  }
  return b;
}

void check_builder(const SceneDef& scene) {
  auto reference = fulcrum::build_world(scene);
  if (!reference.ok()) die(reference.status().to_string());
  Built mine = build(scene);
  reference->step();
  mine.world.step();
  if (reference->state_hash() != mine.world.state_hash()) {
    die("the sweep's scene builder differs from build_world");
  }
}

// A probe's view of one run of the sweep: Fulcrum's world, read on demand, with the metrics the
// runner took after the tick (World::metrics(): penetration and energy, as the engine reports
// them) and the engine's own joint states.
class WorldView final : public View {
 public:
  WorldView(const Built& built, const SceneDef& scene, const WorldMetrics& metrics, int ticks)
      : View(scene, static_cast<int>(built.world.tick()), ticks), b_(built), wm_(metrics) {}

  BodyPose body(size_t i) const override {
    BodyState s = b_.world.body_state(b_.bodies[i]).value();
    return {s.transform, s.center, s.linear_velocity, s.angular_velocity};
  }
  JointReading joint(size_t k) const override {
    JointState s = b_.world.joint_state(b_.joints[k]).value();
    return {s.linear_error, s.angular_error, s.length};
  }
  double max_penetration() const override { return wm_.max_penetration; }
  double kinetic_energy() const override { return wm_.kinetic_energy; }
  double mechanical_energy() const override { return wm_.kinetic_energy + wm_.potential_energy; }

 private:
  const Built& b_;
  const WorldMetrics& wm_;
};

struct Case {
  int id = 0;
  std::string name;
  std::string criterion;  // the HARD_CASES pass column, as the sweep measures it
  std::function<SceneDef()> scene;
  int ticks = 600;         // ticks run (HARD_CASES length unless the case says otherwise)
  int timing_ticks = 600;  // steps 1..timing_ticks-1 are timed
  Measure main = kMaxPenetration;
  double limit = 0.0;  // the main error's pass limit (0: none drawn)
  // The measures that apply, with the name each goes by in this case (first: the main one).
  std::vector<std::pair<Measure, std::string>> labels;
  std::string ticks_note;  // why the tick count differs from HARD_CASES, if it does
  // Run once whatever --repeats says: the four largest scenes, whose one run already takes
  // seconds per setting (ms per step is then the mean over that run's timed steps).
  bool single_run = false;
  // The tick at whose start the velocity error against the reference solver is measured (0:
  // not measured; see reference_error()).
  int reference_tick = 0;
};

bool applies(const Case& c, Measure m) {
  return std::any_of(c.labels.begin(), c.labels.end(), [&](const auto& l) { return l.first == m; });
}

// --- The cases, each with its HARD_CASES criterion --------------------------------------------

// Case 17: the bullet never passes through the wall. As tests/engine/hard_cases_more_test.cpp
// Case17Bullet: from `count` start positions spread over one tick's travel, at 300 m/s (from
// x = -10), 30 and 15 m/s (from x = -2); a run passes through when the centre reaches x >= 0
// within 1 s. displacement = the deepest the bullet's leading edge got past the wall's front
// face (x = -0.05); bodies out = pass-throughs.
// Fulcrum's own: it builds and runs worlds of its own beside the case's, so it stays here.
class BulletProbe : public Probe {
  struct Trial {
    double speed, start_x;
    int count;
  };
  bool smoke_;  // a CI run: 4 starts per speed (2 at 15 m/s)

 public:
  explicit BulletProbe(bool smoke) : smoke_(smoke) {}
  void finish(const View& v, Measures* m) override {
    const int n = smoke_ ? 4 : 100;
    int through = 0;
    double deepest = 0.0;
    for (Trial t : {Trial{300.0, -10.0, n}, Trial{30.0, -2.0, n}, Trial{15.0, -2.0, n / 2}}) {
      for (int i = 0; i < t.count; ++i) {
        SceneDef s = builtin("bullet");
        s.settings = v.scene().settings;
        SceneBody& bullet = s.bodies.back();
        bullet.def.linear_velocity = Vec2(t.speed, 0.0);
        bullet.def.position = Vec2(t.start_x - t.speed * s.settings.dt * i / t.count, 5.0);
        Built b = build(s);
        bool passed = false;
        for (int k = 0; k < 60; ++k) {
          b.world.step();
          double x = b.world.body_state(b.bodies.back()).value().center.x();
          passed = passed || !(x < 0.0);
          deepest = std::max(deepest, x + 0.05 - (-0.05));
        }
        through += passed;
      }
    }
    m->set(kDisplacement, deepest);
    m->set(kBodiesOut, through);
    m->check(through == 0, std::to_string(through) + " pass-throughs");
  }
};

std::vector<Case> all_cases() {
  const auto pen = std::pair{kMaxPenetration, std::string("max penetration (m)")};
  const auto mean = std::pair{kMeanPenetration, std::string("mean penetration (m)")};
  const auto speed = std::pair{kMaxSpeed, std::string("max speed (m/s)")};
  const auto joint = std::pair{kJointError, std::string("max joint error (m)")};
  std::vector<Case> cases;
  auto scene = [](const char* name) { return [name] { return builtin(name); }; };
  // clang-format off
  cases.push_back({1, "vertical_stack", "top box moves < 5 cm sideways; penetration <= 2 x slop",
      scene("vertical_stack"), 600, 600, kDisplacement, 0.05,
      {{kDisplacement, "top box drift (m)"}, pen, mean, {kBodiesOut, "boxes moved >= 5 cm"},
       speed}, ""});
  cases.push_back({2, "large_pyramid",
      "no box moves > 0.5 m; top box drops < 10 cm after settling; penetration <= 2 x slop",
      scene("large_pyramid"), 75, 75, kMaxPenetration, 0.01,
      {pen, mean, {kDisplacement, "largest move (m)"}, {kBodiesOut, "boxes moved > 0.5 m"}, speed},
      "75 ticks of 500, one run (top box settled at tick 30, penetration over ticks 61..75)",
      true});
  cases.push_back({3, "many_pyramids", "no box moves > 0.5 m; penetration <= 2 x slop",
      scene("many_pyramids"), 200, 200, kMaxPenetration, 0.01,
      {pen, mean, {kDisplacement, "largest move (m)"}, {kBodiesOut, "boxes moved > 0.5 m"}, speed},
      "200 ticks of 500, one run", true});
  cases.push_back({4, "mass_ratio_100", "no box moves > 10 cm; penetration < 5 cm",
      scene("mass_ratio_100"), 600, 600, kDisplacement, 0.10,
      {{kDisplacement, "largest move (m)"}, pen, mean, {kBodiesOut, "boxes moved >= 10 cm"},
       speed}, ""});
  cases.push_back({5, "mass_ratio_400",
      "small boxes within 0.25 m sideways and above 0.4 m; big box ends above 10.5 m; "
      "penetration < 10 cm",
      scene("mass_ratio_400"), 600, 600, kMaxPenetration, 0.10,
      {pen, mean, {kDisplacement, "small box pushed (m)"}, {kBodiesOut, "small-box criteria missed"}, speed},
      ""});
  cases.push_back({6, "overlap_recovery",
      "overlap <= 2 x slop at 2 s; speed < 3 m/s at every tick; no centre moves >= 5 cm after 2 s",
      scene("overlap_recovery"), 300, 300, kMaxSpeed, 3.0,
      {speed, pen, mean, {kDisplacement, "moved after 2 s (m)"},
       {kBodiesOut, "boxes moved after 2 s"}}, ""});
  cases.push_back({7, "arch", "crown drops < 2 cm at every tick", scene("arch"), 600, 600,
      kDisplacement, 0.02, {{kDisplacement, "crown drop (m)"}, pen, mean, speed},
      ""});
  cases.push_back({8, "confined",
      "no centre reaches the walls (|x|, |y| < 10.5); kinetic energy after 3 s never above its "
      "3 s value", scene("confined"), 600, 60, kEnergyDrift, 0.0,
      {{kEnergyDrift, "KE rise after 3 s (x)"}, pen, mean, {kDisplacement, "largest |x|, |y| (m)"},
       {kBodiesOut, "circles out"}, speed}, "timed over steps 1..59"});
  cases.push_back({9, "joint_grid", "no NaN; largest joint separation < 10 cm",
      scene("joint_grid"), 80, 80, kJointError, 0.10, {joint, speed},
      "80 ticks of 500, one run (at the default the error grows to 0.49 m by then, 0.55 m at "
      "its peak near tick 110)", true});
  cases.push_back({10, "heavy_chain", "largest joint separation < 5 cm; no energy gain",
      scene("heavy_chain"), 600, 600, kJointError, 0.05,
      {joint, {kEnergyDrift, "energy gain (of |E0|)"}, speed},
      ""});
  cases.push_back({11, "bridge",
      "largest joint separation < 5 cm; sag steady (middle plank moves < 1 cm in the last "
      "second, no plank on the ground)",
      scene("bridge"), 600, 120, kJointError, 0.05,
      {joint, {kDisplacement, "sag swing, last 1 s (m)"},
       {kBodiesOut, "planks on the ground"}, speed},
      "timed over steps 1..119"});
  cases.push_back({12, "ragdolls", "no NaN; joint separation < 5 cm; limits passed by < 0.05 rad",
      scene("ragdolls"), 600, 60, kJointError, 0.05,
      {joint, {kLimitError, "past a limit (rad)"}, pen, mean, {kBodiesOut, "ragdolls not down"},
       speed}, "timed over steps 1..59"});
  cases.push_back({13, "cloth", "no constraint stretched more than 5 %; no NaN", scene("cloth"),
      240, 60, kStretch, 0.05, {{kStretch, "max stretch"}, joint, speed}, "240 ticks of 600 (the stretch peaks in the first jerk), timed over steps 1..59"});
  cases.push_back({14, "bounce", "bounce height ratios e^2 = 0.25 +- 2 %", scene("bounce"), 600,
      600, kAnalytic, 0.02, {{kAnalytic, "ratio error"}, pen, speed}, ""});
  cases.push_back({15, "slide", "slides 2.5 m +- 2 % and stops", scene("slide"), 300, 300,
      kAnalytic, 0.02, {{kAnalytic, "distance error"}, pen, speed}, ""});
  cases.push_back({16, "pendulum", "period 2 pi sqrt(L/g) +- 0.5 %; amplitude does not grow",
      pendulum, 1200, 1200, kAnalytic, 0.005,
      {{kAnalytic, "period error"}, {kEnergyDrift, "amplitude growth"}, joint},
      ""});
  cases.push_back({17, "bullet", "never passes through (100 starts at 300 m/s, 100 at 30, 50 at 15)",
      scene("bullet"), 60, 60, kDisplacement, 0.10,
      {{kDisplacement, "deepest past the face (m)"}, {kBodiesOut, "pass-throughs"}, pen},
      ""});
  cases.push_back({18, "tumbler", "no box leaves the drum; motor speed within 1 %",
      scene("tumbler"), 90, 90, kMaxPenetration, 0.0,
      {pen, mean, {kDisplacement, "largest drum coordinate (m)"}, {kBodiesOut, "boxes out"}, speed},
      "90 ticks of 750, one run (the boxes land; the drum turns 37 deg)",
      true});
  cases.push_back({19, "very_heavy_chain", "largest joint separation < 5 cm; no energy gain",
      scene("very_heavy_chain"), 600, 600, kJointError, 0.05,
      {joint, {kEnergyDrift, "energy gain (of |E0|)"}, speed},
      ""});
  cases.push_back({20, "thin_planks",
      "top plank moves < 1 cm; penetration <= 2 x slop; none passes through another",
      scene("thin_planks"), 600, 600, kDisplacement, 0.01,
      {{kDisplacement, "top plank move (m)"}, pen, mean,
       {kBodiesOut, "planks passed through"}, speed}, ""});
  // clang-format on
  // The velocity error against the reference solver, where one reference solve is cheap (tens
  // of milliseconds for most states, about a second at the cap): the small stack, the mass-ratio
  // pyramid and the 400:1 pair, the heavy chain. At tick 60, after a second of settling.
  for (Case& c : cases) {
    if (c.id == 1 || c.id == 4 || c.id == 5 || c.id == 10) {
      c.reference_tick = 60;
      c.labels.push_back({kRefVelocity, "velocity error vs reference, tick 60 (m/s)"});
      c.labels.push_back({kRefAngular, "angular velocity error vs reference, tick 60 (rad/s)"});
    }
  }
  return cases;
}

// The velocity error of the world's own setting over the tick starting now (reference.h): the
// reference solve of this tick against one step of a copy. Every body is woken on the copy
// first (a settled island may be asleep, with nothing to solve; waking changes no position,
// velocity or impulse). Outside the timed steps.
double g_reference_seconds = 0.0;  // spent in reference_error, reported at the end

void reference_error(const World& world, const std::string& what, Measures* m) {
  auto start = std::chrono::steady_clock::now();
  World copy(world.settings());
  if (fulcrum::Status st = copy.restore(world.snapshot()); !st.ok()) die(st.to_string());
  for (BodyId id : copy.bodies()) (void)copy.set_awake(id, true);
  // A cap of 1e5 sweeps (about a second on the 55-box pyramid) keeps the sweep in its time
  // budget; the few solves that reach it (collapsing piles) are reported on stderr.
  fulcrum::ReferenceOptions options;
  options.max_iterations = 100000;
  auto e = fulcrum::setting_velocity_error(copy, copy.settings(), options);
  if (!e.ok()) die(what + ": reference: " + e.status().to_string());
  if (!e->reference.converged) {
    std::fprintf(stderr, "fulcrum_sweep: %s: the reference stopped at residual %.3g N s\n",
                 what.c_str(), e->reference.residual);
  }
  m->set(kRefVelocity, e->error.max_linear);
  m->set(kRefAngular, e->error.max_angular);
  g_reference_seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// --- Running the grid -------------------------------------------------------------------------

struct Row {
  const Case* c = nullptr;
  Setting setting;
  int ticks = 0, timed_steps = 0, repeats = 0;
  int most_substeps = 0;  // the most substeps any island ran in the run (budgets)
  double ms_per_step = 0.0;
  Measures m;
  uint64_t hash = 0;
  bool pareto = false, cheapest = false;

  double main_error() const { return m.value[c->main].value_or(0.0); }
};

// Box2D 2.4.1 on the same scene (its twin: box2d_twin.h), once per case, judged by the same
// probe: the peer's point on each plot. Cases whose twin fulcrum_box2d_compare judges.
struct Peer {
  bool ran = false;
  double ms_per_step = 0.0;
  Measures m;
};
constexpr const char* kPeerLabel = "Box2D 2.4.1 (8+3, float)";

bool has_twin(const Case& c) {
  for (int id : {1, 2, 3, 4, 5, 9, 10, 11, 12, 13, 19, 20}) {
    if (c.id == id) return true;
  }
  return false;
}

constexpr double kShortRunMs = 100.0;  // timed total of the first run, ms
constexpr int kShortRunRepeats = 9;

Row run(const Case& c, const Setting& setting, int repeats, bool smoke) {
  Row row;
  row.c = &c;
  row.setting = setting;
  row.ticks = smoke ? std::min(c.ticks, 20) : c.ticks;
  const int timing_ticks = smoke ? row.ticks : std::min(c.timing_ticks, row.ticks);
  row.timed_steps = timing_ticks - 1;
  if (c.single_run) repeats = 1;
  row.repeats = repeats;
  SceneDef scene = c.scene();
  setting.apply(&scene.settings);

  std::vector<double> times;
  uint64_t window_hash = 0;
  for (int r = 0; r < repeats; ++r) {
    const bool measure = r == 0;
    const int ticks = measure ? row.ticks : timing_ticks;
    Built b = build(scene);
    // The case's criterion: hard_case_probes.h's, but for the bullet's (here).
    std::unique_ptr<Probe> probe =
        c.id == 17 ? std::make_unique<BulletProbe>(smoke) : hard_case_probe(c.id);
    WorldMetrics wm;  // after the last tick measured (before the first, for begin())
    if (measure) {
      wm = b.world.metrics();
      probe->begin(WorldView(b, scene, wm, row.ticks));
    }
    double timed = 0.0, max_pen = 0.0, mean_sum = 0.0, speed = 0.0, joint = 0.0;
    int sampled = 0;
    // The reference tick; a smoke run (20 ticks) takes it at tick 10.
    const int reference_tick = smoke ? std::min(c.reference_tick, row.ticks / 2) : c.reference_tick;
    for (int t = 0; t < ticks; ++t) {
      if (measure && reference_tick > 0 && t == reference_tick) {
        reference_error(b.world, c.name + " " + setting.label(), &row.m);
      }
      auto t0 = std::chrono::steady_clock::now();
      b.world.step();
      auto t1 = std::chrono::steady_clock::now();
      if (t >= 1 && t < timing_ticks)
        timed += std::chrono::duration<double, std::milli>(t1 - t0).count();
      if (t + 1 == timing_ticks) {
        uint64_t h = b.world.state_hash();
        if (r == 0) window_hash = h;
        if (h != window_hash) {
          std::fprintf(stderr, "fulcrum_sweep: %s %s: repeat %d reached another state\n",
                       c.name.c_str(), setting.label().c_str(), r);
        }
      }
      if (!measure) continue;
      wm = b.world.metrics();
      if (wm.tick > 60) {  // the HARD_CASES sampling: every tick after the first second
        max_pen = std::max(max_pen, wm.max_penetration);
        mean_sum += wm.mean_penetration;
        ++sampled;
      }
      speed = std::max(speed, wm.max_speed);
      joint = std::max(joint, wm.max_joint_error);
      row.most_substeps = std::max(row.most_substeps, wm.max_substeps);
      probe->after_tick(WorldView(b, scene, wm, row.ticks));
    }
    times.push_back(timed / std::max(1, timing_ticks - 1));
    // Runs this short (the small scenes take microseconds per step) are at the mercy of one
    // context switch on a shared machine: time them at least kShortRunRepeats times.
    if (measure && !smoke && !c.single_run && timed < kShortRunMs) {
      repeats = std::max(repeats, kShortRunRepeats);
    }
    if (!measure) continue;
    Measures& m = row.m;
    if (applies(c, kMaxPenetration)) m.set(kMaxPenetration, max_pen);
    if (applies(c, kMeanPenetration)) m.set(kMeanPenetration, sampled ? mean_sum / sampled : 0.0);
    if (applies(c, kMaxSpeed)) m.set(kMaxSpeed, speed);
    if (applies(c, kJointError)) m.set(kJointError, joint);
    WorldView end(b, scene, wm, row.ticks);
    m.check(all_finite(end), "NaN or infinity");
    probe->finish(end, &m);
    row.hash = b.world.state_hash();
  }
  std::sort(times.begin(), times.end());
  row.ms_per_step = times[times.size() / 2];
  row.repeats = repeats;
  return row;
}

// Marks the Pareto front (no other setting both cheaper and more accurate on the main error)
// and the cheapest passing setting of one case.
void mark(std::vector<Row*>& rows) {
  std::vector<Row*> by_cost = rows;
  std::sort(by_cost.begin(), by_cost.end(), [](const Row* a, const Row* b) {
    if (a->ms_per_step != b->ms_per_step) return a->ms_per_step < b->ms_per_step;
    return a->main_error() < b->main_error();
  });
  double best = 1e300;
  for (Row* r : by_cost) {
    if (r->main_error() < best) {
      r->pareto = true;
      best = r->main_error();
    }
  }
  // Timings closer than kTie are within this machine's noise: among the passing settings that
  // close to the fastest one, the one with the fewest solver passes is the cheapest.
  constexpr double kTie = 1.10;
  Row* cheapest = nullptr;
  for (Row* r : by_cost) {
    if (!r->m.pass()) continue;
    if (!cheapest) {
      cheapest = r;
    } else if (r->ms_per_step <= kTie * cheapest->ms_per_step &&
               r->setting.passes() < cheapest->setting.passes()) {
      cheapest = r;
    }
  }
  if (cheapest) cheapest->cheapest = true;
}

// --- Output -----------------------------------------------------------------------------------

const char* const kCsvHeader =
    "case_id,case,setting,family,substeps,velocity_iterations,relax_iterations,contact_hertz,"
    "split_impulses,most_substeps,ticks,timed_steps,repeats,ms_per_step,max_penetration_m,mean_"
    "penetration_m,"
    "max_displacement_m,bodies_out,max_joint_error_m,max_stretch,max_limit_error_rad,"
    "energy_drift,max_speed_m_s,analytic_error,ref_velocity_error_m_s,ref_angular_error_rad_s,"
    "main_error,pass,pareto,cheapest_pass,failed,"
    "state_hash";

std::string csv_row(const Row& r) {
  WorldSettings s = r.c->scene().settings;
  r.setting.apply(&s);
  std::string failed;
  for (const std::string& f : r.m.failed) failed += (failed.empty() ? "" : " / ") + f;
  std::replace(failed.begin(), failed.end(), ',', ' ');
  char hash[32];
  std::snprintf(hash, sizeof hash, "%016" PRIx64, r.hash);
  std::string out = std::to_string(r.c->id) + "," + r.c->name + "," + r.setting.label() + "," +
                    kFamilyNames[static_cast<int>(r.setting.family)] + "," +
                    std::to_string(s.substeps) + "," + std::to_string(s.velocity_iterations) + "," +
                    std::to_string(s.relax_iterations) + "," + num(s.contact_hertz) + "," +
                    (s.split_impulses ? "1" : "0") + "," + std::to_string(r.most_substeps) + "," +
                    std::to_string(r.ticks) + "," + std::to_string(r.timed_steps) + "," +
                    std::to_string(r.repeats) + "," + num(r.ms_per_step, 4);
  for (int k = 0; k < kMeasureCount; ++k) {
    out += ",";
    if (r.m.value[k]) out += num(*r.m.value[k], 4);
  }
  out += "," + num(r.main_error(), 4) + "," + (r.m.pass() ? "1" : "0") + "," +
         (r.pareto ? "1" : "0") + "," + (r.cheapest ? "1" : "0") + "," + failed + "," + hash;
  return out + "\n";
}

std::string svg_name(const Case& c) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "case%02d_%s.svg", c.id, c.name.c_str());
  return buf;
}

std::string plot(const Case& c, const std::vector<Row*>& rows, const Peer& peer) {
  fulcrum::bench::SvgScatter p;
  p.title = "Case " + std::to_string(c.id) + ": " + c.name;
  p.x_label = "ms per step (log)";
  p.y_label = c.labels.front().second + " (log)";
  for (const char* g : kFamilyLegend) p.groups.push_back(g);
  if (peer.ran) {
    p.groups.push_back(kPeerLabel);
    p.points.push_back({peer.ms_per_step, peer.m.value[c.main].value_or(0.0), "b2d", kFamilyCount,
                        peer.m.pass(), false});
  }
  std::vector<const Row*> front;
  for (const Row* r : rows) {
    p.points.push_back({r->ms_per_step, r->main_error(), r->setting.short_label(),
                        static_cast<int>(r->setting.family), r->m.pass(), r->cheapest});
    if (r->pareto) front.push_back(r);
  }
  std::sort(front.begin(), front.end(),
            [](const Row* a, const Row* b) { return a->ms_per_step < b->ms_per_step; });
  for (const Row* r : front) p.line.emplace_back(r->ms_per_step, r->main_error());
  p.line_label = "Pareto front";
  if (c.limit > 0.0) {
    p.y_limit = c.limit;
    p.y_limit_label = "pass limit " + num(c.limit);
  }
  p.filled_label = "passes";
  p.hollow_label = "fails";
  p.ring_label = "cheapest pass";
  p.note =
      "labels: SxI = soft, S substeps x I iterations; cN = classic, sN = classic + split, "
      "N iterations; ad = adaptive (the default); b2d = Box2D 2.4.1";
  return fulcrum::bench::to_svg(p);
}

// A table cell's text, its pipes escaped.
std::string md_escape(const std::string& text) {
  std::string out;
  for (char ch : text) out += ch == '|' ? std::string("\\|") : std::string(1, ch);
  return out;
}

std::string md_cell(const Row& r, Measure m) {
  if (!r.m.value[m]) return "-";
  double v = *r.m.value[m];
  if (m == kBodiesOut) return std::to_string(static_cast<long long>(v));
  return num(v);
}

std::string markdown(const std::vector<Case>& cases, const std::vector<Row>& rows,
                     const std::vector<Peer>& peers, const std::string& command, double seconds,
                     const std::string& load) {
  std::ostringstream o;
  o << "# Speed against error: the hard cases over the solver settings grid\n\n";
  o << "Written by `" << command << "` in " << num(seconds, 3) << " s on "
    << std::thread::hardware_concurrency() << " hardware threads (load average " << load
    << "). ms/step: mean over the timed steps of a run, median of the repeats (the `repeats` "
       "column of sweep.csv; at least 9 when a run's timed steps take under 0.1 s in all); only "
       "`World::step()` is timed. The cheapest passing setting is the fastest one, except that "
       "a passing setting within 10 % of its time and with fewer solver passes per tick wins "
       "(differences that small are noise here). *front*: on the Pareto front of ms/step "
       "against the case's main error (the first error column). Errors are measured as the tests "
       "measure them "
       "(`tests/engine/*cases*_test.cpp`); *pass* is the HARD_CASES criterion. Settings: "
       "`soft SxI` = S substeps, I velocity iterations, 1 relax pass, soft contacts; "
       "`classic I` = 1 substep, I iterations, no relax, contact_hertz 0 (rigid Baumgarte); "
       "`split I` = the same with split impulses; these run with budgets off (`max_substeps` = "
       "substeps). The default is `adaptive`: soft 4x2 with per-island budgets (an island whose "
       "joints or contacts need it runs more substeps; docs/solver.md, Budgets). "
       "Every other setting is the scene's own (no per-test pinned settings).\n\n";
  o << "## Summary\n\n| # | case | ticks | cheapest passing setting | ms/step | default (adaptive) "
       "| default fails on | Box2D 2.4.1 (8+3): verdict, ms/step |\n"
       "|---|---|---|---|---|---|---|---|\n";
  for (const Case& c : cases) {
    const Row *cheapest = nullptr, *def = nullptr;
    int ticks = 0;
    for (const Row& r : rows) {
      if (r.c != &c) continue;
      ticks = r.ticks;
      if (r.cheapest) cheapest = &r;
      if (r.setting.is_default()) def = &r;
    }
    std::string fails;
    if (def) {
      for (const std::string& f : def->m.failed) fails += (fails.empty() ? "" : " / ") + f;
    }
    o << "| " << c.id << " | " << c.name << " | " << ticks << " | "
      << (cheapest ? cheapest->setting.label() : "none passes") << " | "
      << (cheapest ? num(cheapest->ms_per_step) : "-") << " | "
      << (def ? (def->m.pass() ? "pass" : "**fail**") : "not run") << " | "
      << (fails.empty() ? "-" : md_escape(fails)) << " |";
    const Peer& peer = peers[static_cast<size_t>(&c - cases.data())];
    if (peer.ran) {
      o << " " << (peer.m.pass() ? "pass" : "fail") << ", " << num(peer.ms_per_step) << " |\n";
    } else {
      o << " - |\n";
    }
  }
  for (const Case& c : cases) {
    o << "\n## " << c.id << ". " << c.name << "\n\nPass: " << c.criterion << ".";
    if (!c.ticks_note.empty()) o << " Sweep: " << c.ticks_note << ".";
    o << " Plot: [" << svg_name(c) << "](" << svg_name(c) << ").\n\n| setting | ms/step |";
    for (const auto& l : c.labels) o << " " << md_escape(l.second) << " |";
    o << " pass | |\n|---|---|";
    for (size_t k = 0; k < c.labels.size(); ++k) o << "---|";
    o << "---|---|\n";
    for (const Row& r : rows) {
      if (r.c != &c) continue;
      o << "| " << r.setting.label();
      if (r.setting.is_default()) {
        o << " (default"
          << (r.most_substeps > r.setting.substeps
                  ? "; up to " + std::to_string(r.most_substeps) + " substeps"
                  : std::string())
          << ")";
      }
      o << " | " << num(r.ms_per_step) << " |";
      for (const auto& l : c.labels) o << " " << md_cell(r, l.first) << " |";
      o << " " << (r.m.pass() ? "pass" : "fail") << " | ";
      std::string notes;
      if (r.cheapest) notes = "**cheapest pass**";
      if (r.pareto) notes += std::string(notes.empty() ? "" : ", ") + "front";
      o << notes << " |\n";
    }
    const Peer& peer = peers[static_cast<size_t>(&c - cases.data())];
    if (peer.ran) {
      o << "| " << kPeerLabel << " | " << num(peer.ms_per_step) << " |";
      for (const auto& l : c.labels) {
        o << " " << (peer.m.value[l.first] ? num(*peer.m.value[l.first]) : std::string("-"))
          << " |";
      }
      o << " " << (peer.m.pass() ? "pass" : "fail") << " | peer |\n";
    }
  }
  return o.str();
}

void write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) die("cannot write " + path.string());
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "docs/sweep", case_list;
  int repeats = 3;
  bool smoke = false;
  std::string command = "fulcrum_sweep";
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    command += " " + a;
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) die(a + " needs a value");
      command += " " + std::string(argv[i + 1]);
      return argv[++i];
    };
    if (a == "--out") {
      out_dir = value();
    } else if (a == "--cases") {
      case_list = value();
    } else if (a == "--repeats") {
      repeats = std::max(1, std::atoi(value().c_str()));
    } else if (a == "--smoke") {
      smoke = true;
    } else {
      std::fprintf(stderr,
                   "usage: fulcrum_sweep [--out DIR] [--cases NAME|NUMBER,...] [--repeats N] "
                   "[--smoke]\n");
      return 2;
    }
  }
  if (smoke) repeats = std::min(repeats, 1);

  std::vector<Case> cases = all_cases();
  if (!case_list.empty()) {
    std::vector<Case> chosen;
    for (const std::string& want : split_list(case_list)) {
      auto it = std::find_if(cases.begin(), cases.end(), [&](const Case& c) {
        return c.name == want || std::to_string(c.id) == want;
      });
      if (it == cases.end()) die("no case '" + want + "'");
      chosen.push_back(*it);
    }
    cases = chosen;
  }
  const std::vector<Setting> grid = smoke ? smoke_grid() : full_grid();

  const std::string load_before = load_average();
  auto start = std::chrono::steady_clock::now();
  std::vector<Row> rows;
  rows.reserve(cases.size() * grid.size());
  std::vector<Peer> peers(cases.size());
  for (const Case& c : cases) {
    check_builder(c.scene());
#ifdef FULCRUM_SWEEP_BOX2D
    if (has_twin(c)) {
      const int ticks = smoke ? std::min(c.ticks, 20) : c.ticks;
      const int timing = smoke ? ticks : std::min(c.timing_ticks, ticks);
      fulcrum::bench::Box2DRun b2 =
          fulcrum::bench::run_box2d(c.scene(), hard_case_probe(c.id), applies(c, kMaxPenetration),
                                    applies(c, kJointError), ticks, timing);
      Peer& peer = peers[static_cast<size_t>(&c - cases.data())];
      peer.ran = true;
      peer.ms_per_step = b2.ms_per_step;
      peer.m = b2.m;
      std::fprintf(stderr, "%9s %2d %-16s %-12s %9.4f ms/step  %s %-10s %s\n", "", c.id,
                   c.name.c_str(), "box2d 2.4.1", peer.ms_per_step, c.labels.front().second.c_str(),
                   num(peer.m.value[c.main].value_or(0.0)).c_str(),
                   peer.m.pass() ? "pass" : "FAIL");
    }
#endif
    for (const Setting& s : grid) {
      rows.push_back(run(c, s, repeats, smoke));
      const Row& r = rows.back();
      double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::fprintf(stderr, "[%6.1f s] %2d %-16s %-12s %9.4f ms/step  %s %-10s %s\n", elapsed, c.id,
                   c.name.c_str(), s.label().c_str(), r.ms_per_step,
                   r.c->labels.front().second.c_str(), num(r.main_error()).c_str(),
                   r.m.pass() ? "pass" : "FAIL");
    }
  }
  for (const Case& c : cases) {
    std::vector<Row*> mine;
    for (Row& r : rows) {
      if (r.c == &c) mine.push_back(&r);
    }
    mark(mine);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::string load = load_before + " before, " + load_average() + " after";

  std::filesystem::path dir(out_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) die("cannot create " + out_dir + ": " + ec.message());
  std::string csv = std::string(kCsvHeader) + "\n";
  for (const Row& r : rows) csv += csv_row(r);
  write_file(dir / "sweep.csv", csv);
  write_file(dir / "sweep.md", markdown(cases, rows, peers, command, seconds, load));
  for (const Case& c : cases) {
    std::vector<Row*> mine;
    for (Row& r : rows) {
      if (r.c == &c) mine.push_back(&r);
    }
    write_file(dir / svg_name(c), plot(c, mine, peers[static_cast<size_t>(&c - cases.data())]));
  }
  std::printf("fulcrum_sweep: %zu cases x %zu settings in %.1f s (reference solves %.1f s) -> %s\n",
              cases.size(), grid.size(), seconds, g_reference_seconds, out_dir.c_str());
  return 0;
}
