// fulcrum_box2d_compare: the hard cases of issue 6 side by side in Fulcrum and Box2D 2.4.1, in
// one process. Box2D's world is the twin of the very SceneDef Fulcrum builds from (box2d_twin.h:
// same bodies, outlines, masses, materials and joints), so both start from the same state.
//
// Three engines per case: Box2D 2.4.1 (8 velocity and 3 position iterations, its float
// defaults otherwise), Fulcrum at its default (the soft step, 4 substeps x 2 iterations) and
// Fulcrum's classic step at 8 iterations (1 substep, rigid Baumgarte contacts). They are stepped
// in alternation, `--chunk` ticks at a time, so that all three see the same machine load;
// only the step call is inside the clock. ms per step is the mean over steps 1..N-1 of a run
// (step 0 builds the first contacts), median over the case's runs (3, or 1 for the three largest
// scenes; --repeats sets it for all). The error measures are read from the body states of the
// first run (joint separation and limits from both bodies' world anchors and angles,
// penetration from each engine's own contacts), the same code for both engines, and each case
// is judged by the probe of hard_case_probes.h that fulcrum_sweep judges it by.
//
//   build/bin/fulcrum_box2d_compare                          # every case, Markdown on stdout
//   build/bin/fulcrum_box2d_compare --markdown docs/box2d.md # the same, also into the doc
//   build/bin/fulcrum_box2d_compare --cases 2,9 --repeats 5
//   build/bin/fulcrum_box2d_compare --cases tumbler --ticks 300 # any builtin scene
#include <sys/utsname.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <box2d/box2d.h>

#include "bench_text.h"
#include "box2d_run.h"
#include "box2d_twin.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/world.h"
#include "hard_case_probes.h"

namespace {

using fulcrum::BodyId;
using fulcrum::BodyState;
using fulcrum::BodyType;
using fulcrum::SceneBody;
using fulcrum::SceneDef;
using fulcrum::SceneJoint;
using fulcrum::ShapeDef;
using fulcrum::Vec2;
using fulcrum::World;
using fulcrum::WorldSettings;
using fulcrum::bench::BodyMass;
// The views, probes and measure names of hard_case_probes.h.
using namespace fulcrum::bench;  // NOLINT(google-build-using-namespace)

[[noreturn]] void die(const std::string& message) {
  std::fprintf(stderr, "fulcrum_box2d_compare: %s\n", message.c_str());
  std::exit(2);
}

constexpr double kPi = 3.14159265358979323846;

// --- Engines ---------------------------------------------------------------------------------

// The three columns of every case, with the names the CSV gives them.
enum EngineKind { kBox2D, kFulcrumSoft, kFulcrumClassic, kEngineCount };
const char* const kEngineKeys[kEngineCount] = {"box2d", "fulcrum_default", "fulcrum_classic8"};

// Fulcrum's classic step at 8 iterations, as fulcrum_sweep's "classic 8": 1 substep, no relax
// pass, contact_hertz 0 (rigid Baumgarte with slop), split impulses off; the rest (joint
// softness included) is the scene's own.
void apply_classic8(WorldSettings* s) {
  s->substeps = 1;
  s->velocity_iterations = 8;
  s->relax_iterations = 0;
  s->contact_hertz = 0.0;
  s->split_impulses = false;
  s->max_substeps = 1;  // budgets off: the classic step as it is
}

std::string soft_label(const WorldSettings& s) {
  return "soft " + std::to_string(s.substeps) + "x" + std::to_string(s.velocity_iterations);
}

// --- Error measures --------------------------------------------------------------------------

// The measures this comparison reports, in its CSV's column order, with their column names.
const std::pair<Measure, const char*> kColumns[] = {
    {kMaxPenetration, "max_penetration_m"}, {kJointError, "max_joint_error_m"},
    {kLimitError, "max_limit_error_rad"},   {kStretch, "max_stretch"},
    {kDisplacement, "displacement_m"},      {kBodiesOut, "bodies_out"},
    {kEnergyDrift, "energy_gain"}};

// --- Cases, each with its HARD_CASES criterion ----------------------------------------------

SceneDef builtin(const std::string& name) {
  auto s = fulcrum::scenes::builtin(name);
  if (!s.ok()) die(s.status().to_string());
  return std::move(s).value();
}

struct Case {
  int id = 0;  // HARD_CASES number (0: another builtin scene)
  std::string name;
  std::string criterion;
  std::function<SceneDef()> scene;
  int ticks = 600;
  // The measures that apply, with the name each goes by in this case.
  std::vector<std::pair<Measure, std::string>> labels;
  // Runs to take the median of, unless --repeats says otherwise: one for the three largest
  // scenes, whose one run already times 499 steps of each engine in alternation.
  int repeats = 3;
};

std::vector<Case> all_cases() {
  const auto pen = std::pair{kMaxPenetration, std::string("max penetration (m)")};
  const auto joint = std::pair{kJointError, std::string("max joint separation (m)")};
  auto scene = [](const char* name) { return [name] { return builtin(name); }; };
  std::vector<Case> c;
  // clang-format off
  c.push_back({1, "vertical_stack", "top box moves < 5 cm sideways; penetration <= 2 x slop",
      scene("vertical_stack"), 600,
      {{kDisplacement, "top box drift (m)"}, pen, {kBodiesOut, "boxes moved >= 5 cm sideways"}}});
  c.push_back({2, "large_pyramid",
      "no box moves > 0.5 m; top box drops < 10 cm after settling; penetration <= 2 x slop",
      scene("large_pyramid"), 500,
      {pen, {kBodiesOut, "boxes moved > 0.5 m"}, {kDisplacement, "largest move (m)"}}, 1});
  c.push_back({3, "many_pyramids", "no box moves > 0.5 m; penetration <= 2 x slop",
      scene("many_pyramids"), 500,
      {pen, {kBodiesOut, "boxes moved > 0.5 m"}, {kDisplacement, "largest move (m)"}}, 1});
  c.push_back({4, "mass_ratio_100", "no box moves >= 10 cm; penetration < 5 cm",
      scene("mass_ratio_100"), 600,
      {{kDisplacement, "largest move (m)"}, pen, {kBodiesOut, "boxes moved >= 10 cm"}}});
  c.push_back({5, "mass_ratio_400",
      "small boxes within 0.25 m sideways and above 0.4 m; big box ends above 10.5 m; "
      "penetration < 10 cm",
      scene("mass_ratio_400"), 600,
      {pen, {kDisplacement, "small box pushed (m)"}, {kBodiesOut, "small-box criteria missed"}}});
  c.push_back({9, "joint_grid", "no NaN; largest joint separation < 10 cm", scene("joint_grid"),
      500, {joint}, 1});
  c.push_back({10, "heavy_chain", "largest joint separation < 5 cm; no energy gain",
      scene("heavy_chain"),
      600, {joint, {kEnergyDrift, "energy gain (of |E0|)"}}});
  c.push_back({11, "bridge",
      "largest joint separation < 5 cm; sag steady (middle plank moves < 1 cm in the last "
      "second, no plank on the ground)",
      scene("bridge"), 600, {joint, {kDisplacement, "sag swing, last 1 s (m)"},
       {kBodiesOut, "planks on the ground"}}});
  c.push_back({12, "ragdolls", "no NaN; joint separation < 5 cm; limits passed by < 0.05 rad",
      scene("ragdolls"), 600,
      {joint, {kLimitError, "past a limit (rad)"}, pen, {kBodiesOut, "ragdolls not down"}}});
  c.push_back({13, "cloth", "no constraint stretched 5 % or more; no NaN", scene("cloth"), 600,
      {{kStretch, "max stretch"}, joint}});
  c.push_back({19, "very_heavy_chain", "largest joint separation < 5 cm; no energy gain",
      scene("very_heavy_chain"), 600, {joint, {kEnergyDrift, "energy gain (of |E0|)"}}});
  c.push_back({20, "thin_planks",
      "top plank moves < 1 cm; penetration <= 2 x slop; none passes through another",
      scene("thin_planks"), 600,
      {{kDisplacement, "top plank move (m)"}, pen, {kBodiesOut, "planks passed through"}}});
  // clang-format on
  return c;
}

Case generic_case(const std::string& name) {
  builtin(name);  // dies with the list of known scenes when there is no such scene
  return {0,
          name,
          "",
          [name] { return builtin(name); },
          500,
          {{kMaxPenetration, "max penetration (m)"},
           {kJointError, "max joint separation (m)"},
           {kBodiesOut, "bodies moved > 0.5 m"},
           {kDisplacement, "largest move (m)"}}};
}

bool applies(const Case& c, Measure m) {
  return std::any_of(c.labels.begin(), c.labels.end(), [&](const auto& l) { return l.first == m; });
}

// --- Running ---------------------------------------------------------------------------------

struct Options {
  int repeats = 0;  // 0: each case's own
  int ticks = 0;    // 0: each case's own
  int chunk = 20;
  int b2_vel = 8;
  int b2_pos = 3;
  fulcrum::bench::TwinOptions twin;
};

struct Column {
  std::string label;
  double ms_per_step = 0.0;
  Measures m;
};

struct CaseRun {
  const Case* c = nullptr;
  int ticks = 0, repeats = 0;
  int dynamic_bodies = 0, joints = 0;
  std::array<Column, kEngineCount> col;
  std::vector<std::string> twin_notes;

  double ratio(EngineKind k) const {
    double b = col[kBox2D].ms_per_step;
    return b > 0.0 ? col[k].ms_per_step / b : 0.0;
  }
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

CaseRun run_case(const Case& c, const Options& o) {
  CaseRun run;
  run.c = &c;
  const SceneDef scene = c.scene();
  SceneDef classic = scene;
  apply_classic8(&classic.settings);
  const std::vector<BodyMass> masses = fulcrum::bench::fulcrum_masses(scene);
  run.ticks = std::max(2, o.ticks > 0 ? o.ticks : c.ticks);
  run.repeats = o.repeats > 0 ? o.repeats : c.repeats;
  for (const SceneBody& b : scene.bodies) run.dynamic_bodies += is_dynamic(b);
  run.joints = static_cast<int>(scene.joints.size());
  run.col[kBox2D].label = "Box2D " + std::to_string(o.b2_vel) + "+" + std::to_string(o.b2_pos);
  run.col[kFulcrumSoft].label = "Fulcrum default (" + soft_label(scene.settings) + " + budgets)";
  run.col[kFulcrumClassic].label = "Fulcrum classic 8";

  std::array<std::vector<double>, kEngineCount> times;
  for (int r = 0; r < run.repeats; ++r) {
    const bool measure = r == 0;
    fulcrum::bench::TwinNotes notes;
    std::array<std::unique_ptr<Engine>, kEngineCount> engines;
    engines[kBox2D] =
        std::make_unique<Box2DEngine>(scene, masses, o.twin, o.b2_vel, o.b2_pos, &notes);
    engines[kFulcrumSoft] = std::make_unique<FulcrumEngine>(scene);
    engines[kFulcrumClassic] = std::make_unique<FulcrumEngine>(classic);
    if (measure) run.twin_notes = notes.lines();

    std::array<std::vector<Pose>, kEngineCount> poses;
    std::array<std::vector<JointReading>, kEngineCount> readings;
    std::array<std::unique_ptr<Probe>, kEngineCount> probes;
    std::array<double, kEngineCount> timed{}, pen{}, joint{};
    // What a probe sees of engine e after `tick` ticks.
    auto view = [&](int e, int tick) {
      return PoseView(scene, masses, poses[e], readings[e], *engines[e], tick, run.ticks);
    };
    if (measure) {
      for (int e = 0; e < kEngineCount; ++e) {
        engines[e]->read(&poses[e]);
        read_joints(scene, poses[e], &readings[e]);
        probes[e] = c.id > 0 ? hard_case_probe(c.id) : moved_probe();
        probes[e]->begin(view(e, 0));
      }
    }
    // The engines take turns, `chunk` ticks each, starting with a different one each round.
    for (int t0 = 0, round = 0; t0 < run.ticks; t0 += o.chunk, ++round) {
      const int t1 = std::min(run.ticks, t0 + o.chunk);
      for (int k = 0; k < kEngineCount; ++k) {
        const int e = (k + round) % kEngineCount;
        Engine& engine = *engines[e];
        for (int t = t0; t < t1; ++t) {
          auto start = std::chrono::steady_clock::now();
          engine.step();
          auto stop = std::chrono::steady_clock::now();
          if (t >= 1) timed[e] += std::chrono::duration<double, std::milli>(stop - start).count();
          if (!measure) continue;
          engine.read(&poses[e]);
          const int tick = t + 1;
          if (applies(c, kMaxPenetration) && tick > 60) {
            pen[e] = std::max(pen[e], engine.max_penetration());
          }
          read_joints(scene, poses[e], &readings[e]);
          for (const JointReading& j : readings[e]) joint[e] = std::max(joint[e], j.separation);
          probes[e]->after_tick(view(e, tick));
        }
      }
    }
    for (int e = 0; e < kEngineCount; ++e) {
      times[e].push_back(timed[e] / (run.ticks - 1));
      if (!measure) continue;
      Measures& m = run.col[e].m;
      if (applies(c, kMaxPenetration)) m.set(kMaxPenetration, pen[e]);
      if (applies(c, kJointError)) m.set(kJointError, joint[e]);
      const PoseView end = view(e, run.ticks);
      m.check(all_finite(end), "NaN or infinity");
      probes[e]->finish(end, &m);
    }
  }
  for (int e = 0; e < kEngineCount; ++e) run.col[e].ms_per_step = median(times[e]);
  return run;
}

// --- Output ----------------------------------------------------------------------------------

std::string cell(const Measures& m, Measure k) {
  if (!m.value[k]) return "-";
  double v = *m.value[k];
  if (k == kBodiesOut) return std::to_string(static_cast<long long>(v));
  return num(v);
}

std::string verdict(const Measures& m) {
  if (!m.judged) return "-";
  return m.pass() ? "pass" : "**fail**";
}

std::string failures(const Measures& m) {
  std::string out;
  for (const std::string& f : m.failed) out += (out.empty() ? "" : "; ") + f;
  return out.empty() ? "-" : out;
}

std::string case_title(const Case& c) {
  return c.id > 0 ? std::to_string(c.id) : std::string("-");
}

// "2 large_pyramid", or the scene's name alone for a scene outside HARD_CASES.
std::string case_name(const Case& c) {
  return c.id > 0 ? std::to_string(c.id) + " " + c.name : c.name;
}

struct Header {
  std::string command, date, machine, load_before, load_after;
  double seconds = 0.0;
};

// The case-2 target of issue 6: Fulcrum's time per step at most 1.0x Box2D 2.4.1's on the large
// pyramid at 60 Hz, with penetration no larger.
void case2_target(std::ostringstream& o, const CaseRun& r) {
  const Column& b = r.col[kBox2D];
  double bp = b.m.value[kMaxPenetration].value_or(0.0);
  o << "\n## Case 2 target\n\nIssue 6: on the large pyramid at 60 Hz, Fulcrum's time per step at "
       "most 1.0x Box2D 2.4.1's (8 velocity + 3 position iterations), with penetration no "
       "larger. Penetration: the largest over every tick after the first second.\n\n"
       "| Fulcrum setting | ms/step | Box2D ms/step | ratio | time target | penetration (m) | "
       "Box2D penetration (m) | penetration target | stands (HARD_CASES 2) |\n"
       "|---|---|---|---|---|---|---|---|---|\n";
  for (EngineKind k : {kFulcrumClassic, kFulcrumSoft}) {
    const Column& f = r.col[k];
    double fp = f.m.value[kMaxPenetration].value_or(0.0);
    o << "| " << f.label << " | " << num(f.ms_per_step) << " | " << num(b.ms_per_step) << " | "
      << num(r.ratio(k)) << " | " << (r.ratio(k) <= 1.0 ? "met" : "**missed**") << " | " << num(fp)
      << " | " << num(bp) << " | " << (fp <= bp ? "met" : "**missed**") << " | " << verdict(f.m)
      << " |\n";
  }
  o << "\nBox2D itself: " << verdict(b.m) << " (" << failures(b.m) << ").\n";
}

std::string markdown(const std::vector<CaseRun>& runs, const Options& o, const Header& h) {
  std::ostringstream md;
  md << "# Fulcrum and Box2D 2.4.1 side by side\n\n";
  md << "Written by `" << h.command << "` on " << h.date << ", " << h.machine << " ("
     << std::thread::hardware_concurrency() << " hardware threads, load average " << h.load_before
     << " before, " << h.load_after << " after), in " << num(h.seconds, 3) << " s.\n\n";
  md << "- Box2D 2.4.1 (Debian `libbox2d-dev`; the library reports b2_version " << b2_version.major
     << "." << b2_version.minor << "." << b2_version.revision << "): float, " << o.b2_vel
     << " velocity and " << o.b2_pos
     << " position iterations, warm starting and continuous collision on (its defaults).\n";
  const WorldSettings d;
  md << "- Fulcrum " << soft_label(d) << " (the default): double, " << d.substeps << " substeps of "
     << d.velocity_iterations << " velocity + " << d.relax_iterations
     << " relax iterations, soft contacts at " << num(d.contact_hertz) << " Hz, joints at "
     << num(d.joint_hertz)
     << " Hz; with per-island budgets (docs/solver.md): an island whose "
        "joints or contacts need it runs up to "
     << d.max_substeps << " substeps, joints and contacts stiffer in proportion.\n";
  md << "- Fulcrum classic 8 (as `fulcrum_sweep`'s): 1 substep, 8 velocity iterations, no relax "
        "pass, rigid Baumgarte contacts with "
     << num(d.linear_slop)
     << " m slop (contact_hertz 0), split impulses off, no budgets; joints as in the default.\n";
  md << "- Both engines: the same scene (bodies, outlines, masses and inertias, friction 0.6 "
        "mixed as sqrt(a b), restitution mixed as max, restitution threshold 1 m/s, filters), "
        "gravity (0, -10), dt 1/60 s, sleeping as the scene says.\n";
  md << "- ms/step: mean over steps 1..N-1 of a run, median of "
     << (o.repeats > 0 ? std::to_string(o.repeats) + " run(s)"
                       : std::string("3 runs (1 for cases 2, 3 and 9, the largest)"))
     << "; the three engines step in turns of " << o.chunk
     << " ticks so that they share the machine's load; only the step call is timed. ratio = "
        "Fulcrum ms / Box2D ms (below 1: Fulcrum is faster).\n";
  md << "- Errors: from the first run, computed by the same code from each engine's body "
        "states (joint separation from both bodies' world anchor points, every tick; limits "
        "from the bodies' angles); penetration from each engine's own contact manifolds, every "
        "tick after the first second. pass = the HARD_CASES criterion, judged as "
        "`fulcrum_sweep` judges it.\n";

  md << "\n## Speed\n\n| # | case | dynamic bodies | joints | ticks | runs | Box2D ms/step | "
        "Fulcrum default ms/step | ratio | Fulcrum classic 8 ms/step | ratio |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const CaseRun& r : runs) {
    md << "| " << case_title(*r.c) << " | " << r.c->name << " | " << r.dynamic_bodies << " | "
       << r.joints << " | " << r.ticks << " | " << r.repeats << " | "
       << num(r.col[kBox2D].ms_per_step) << " | " << num(r.col[kFulcrumSoft].ms_per_step) << " | "
       << num(r.ratio(kFulcrumSoft)) << " | " << num(r.col[kFulcrumClassic].ms_per_step) << " | "
       << num(r.ratio(kFulcrumClassic)) << " |\n";
  }

  md << "\n## Error\n\n| # | case | measure | Box2D | Fulcrum default | Fulcrum classic 8 |\n"
        "|---|---|---|---|---|---|\n";
  for (const CaseRun& r : runs) {
    for (const auto& [k, label] : r.c->labels) {
      md << "| " << case_title(*r.c) << " | " << r.c->name << " | " << label;
      for (int e = 0; e < kEngineCount; ++e) md << " | " << cell(r.col[e].m, k);
      md << " |\n";
    }
    if (!r.c->criterion.empty()) {
      md << "| " << case_title(*r.c) << " | " << r.c->name << " | **pass:** " << r.c->criterion;
      for (int e = 0; e < kEngineCount; ++e) md << " | " << verdict(r.col[e].m);
      md << " |\n";
    }
  }
  bool any_failed = false;
  for (const CaseRun& r : runs) {
    for (const Column& col : r.col) any_failed = any_failed || !col.m.failed.empty();
  }
  if (any_failed) {
    md << "\nWhat failed:\n\n";
    for (const CaseRun& r : runs) {
      for (const Column& col : r.col) {
        if (col.m.failed.empty()) continue;
        md << "- " << case_name(*r.c) << ", " << col.label << ": " << failures(col.m) << "\n";
      }
    }
  }
  for (const CaseRun& r : runs) {
    if (r.c->id == 2) case2_target(md, r);
  }

  md << "\n## How the Box2D twin differs\n\n"
        "- Polygons: 2.4.1 grows every polygon by a 0.01 m skin (b2_polygonRadius). "
     << (o.twin.compensate_skin
             ? "The twin insets each polygon's core by the skin so that the outlines are "
               "Fulcrum's (the corners are rounded by 0.01 m); 2.4.1's world-manifold "
               "separation includes the skin, so both penetration columns measure overlap of "
               "the same outlines. A polygon thinner than 0.025 m (two skins and the 0.005 m "
               "core 2.4.1 needs at least) cannot be inset: its core is 0.005 m thick and its "
               "outline 0.025 m, so case 20's 2 mm planks start 2.3 cm overlapped in Box2D, "
               "and its figures there measure that.\n"
             : "Not compensated in this run (--b2-keep-skin): boxes that touch exactly start "
               "0.02 m overlapped in Box2D, and its penetration is skin overlap.\n")
     << "- Capsules: 2.4.1 has none; each is a box over the core segment (sides pulled in by "
        "the skin) plus a circle at each end, on the same body, and the body's mass, centre "
        "and inertia are set to Fulcrum's (b2Body::SetMassData). Every dynamic body gets "
        "Fulcrum's mass properties that way.\n"
        "- Particles (Fulcrum's translation-only bodies): dynamic bodies with fixedRotation and "
        "the same circle.\n"
        "- Joints: the same anchors, reference angles, limits, motors (joint friction is a "
        "motor with target speed 0 and a torque cap in both), distance ranges (rods min = max, "
        "ropes min = 0) and collideConnected. Box2D's joints are rigid (solved to its "
        "position iterations); Fulcrum's are soft at joint_hertz 60.\n"
        "- Friction and restitution need no adjustment: 2.4.1 mixes them as Fulcrum does "
        "(sqrt(a b), max(a, b)); Fulcrum's world restitution threshold is set on every "
        "fixture.\n"
        "- Filters: 2.4.1 keeps 16 bits of category and mask; every case fits.\n";
  bool any_notes = false;
  for (const CaseRun& r : runs) {
    if (r.twin_notes.empty()) continue;
    if (!any_notes) md << "\nPer case:\n\n";
    any_notes = true;
    md << "- " << case_name(*r.c) << ": ";
    for (size_t i = 0; i < r.twin_notes.size(); ++i) md << (i ? "; " : "") << r.twin_notes[i];
    md << "\n";
  }
  return md.str();
}

// The CSV's columns before the measures (kColumns) and after them.
const char* const kCsvHead = "case_id,case,engine,setting,ticks,repeats,ms_per_step,ratio_to_box2d";
const char* const kCsvTail = "pass,failed";

std::string csv(const std::vector<CaseRun>& runs) {
  std::string out = kCsvHead;
  for (const auto& column : kColumns) out += std::string(",") + column.second;
  out += std::string(",") + kCsvTail + "\n";
  for (const CaseRun& r : runs) {
    for (int e = 0; e < kEngineCount; ++e) {
      const Column& col = r.col[e];
      out += std::to_string(r.c->id) + "," + r.c->name + "," + kEngineKeys[e] + "," + col.label +
             "," + std::to_string(r.ticks) + "," + std::to_string(r.repeats) + "," +
             num(col.ms_per_step, 4) + "," + num(r.ratio(static_cast<EngineKind>(e)), 4);
      for (const auto& column : kColumns) {
        out += ",";
        if (col.m.value[column.first]) out += num(*col.m.value[column.first], 4);
      }
      std::string failed = col.m.judged ? failures(col.m) : "";
      std::replace(failed.begin(), failed.end(), ',', ' ');
      std::replace(failed.begin(), failed.end(), ';', '/');
      out += std::string(",") + (col.m.judged ? (col.m.pass() ? "1" : "0") : "") + "," +
             (failed == "-" ? "" : failed) + "\n";
    }
  }
  return out;
}

// Everything from this line on in an existing --markdown file is kept when it is rewritten.
const char* const kKeepMarker =
    "<!-- Written by hand from here on: fulcrum_box2d_compare keeps what follows. -->";

void write_markdown(const std::string& path, const std::string& generated) {
  std::string kept;
  {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    std::string old = ss.str();
    size_t at = old.find(kKeepMarker);
    if (at != std::string::npos) kept = old.substr(at);
  }
  std::ofstream out(path, std::ios::binary);
  out << generated << "\n" << (kept.empty() ? std::string(kKeepMarker) + "\n" : kept);
  if (!out) die("cannot write " + path);
}

void write_file(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) die("cannot write " + path);
}

int positive(const std::string& flag, const std::string& text, int min) {
  char* end = nullptr;
  long v = std::strtol(text.c_str(), &end, 10);
  if (end == text.c_str() || *end != '\0' || v < min || v > 1000000) {
    die(flag + ": expected an integer >= " + std::to_string(min) + ", got '" + text + "'");
  }
  return static_cast<int>(v);
}

void usage() {
  std::fprintf(stderr,
               "usage: fulcrum_box2d_compare [--cases NAME|NUMBER,...] [--repeats R] [--ticks N] "
               "[--chunk K] [--b2-vel N] [--b2-pos N] [--b2-keep-skin] [--markdown FILE] "
               "[--csv FILE]\n"
               "  --cases: HARD_CASES numbers or names (default 1,2,3,4,5,9,10,11,12,13), or "
               "any builtin scene\n");
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  std::vector<std::string> wanted;
  std::string markdown_path, csv_path;
  Header h;
  h.command = "fulcrum_box2d_compare";
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    h.command += " " + a;
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) die(a + " needs a value");
      h.command += " " + std::string(argv[i + 1]);
      return argv[++i];
    };
    if (a == "--cases" || a == "--scene") {
      for (const std::string& w : split_list(value())) wanted.push_back(w);
    } else if (a == "--repeats") {
      o.repeats = positive(a, value(), 1);
    } else if (a == "--ticks" || a == "--steps") {
      o.ticks = positive(a, value(), 2);
    } else if (a == "--chunk") {
      o.chunk = positive(a, value(), 1);
    } else if (a == "--b2-vel") {
      o.b2_vel = positive(a, value(), 1);
    } else if (a == "--b2-pos") {
      o.b2_pos = positive(a, value(), 0);
    } else if (a == "--b2-keep-skin") {
      o.twin.compensate_skin = false;
    } else if (a == "--markdown") {
      markdown_path = value();
    } else if (a == "--csv") {
      csv_path = value();
    } else {
      usage();
      return 2;
    }
  }

  const std::vector<Case> table = all_cases();
  std::vector<Case> cases;
  for (const std::string& w : wanted) {
    auto it = std::find_if(table.begin(), table.end(),
                           [&](const Case& c) { return c.name == w || std::to_string(c.id) == w; });
    cases.push_back(it != table.end() ? *it : generic_case(w));
  }
  if (cases.empty()) cases = table;

  std::time_t now = std::time(nullptr);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M", std::localtime(&now));
  h.date = date;
  utsname un{};
  h.machine = uname(&un) == 0 ? std::string(un.sysname) + " " + un.machine : "unknown";
  h.load_before = load_average();

  auto start = std::chrono::steady_clock::now();
  std::vector<CaseRun> runs;
  for (const Case& c : cases) {
    runs.push_back(run_case(c, o));
    const CaseRun& r = runs.back();
    double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::fprintf(stderr,
                 "[%6.1f s] %2d %-15s Box2D %8.3f  default %8.3f (x%.2f)  classic 8 %8.3f "
                 "(x%.2f) ms/step  pass %s/%s/%s\n",
                 elapsed, c.id, c.name.c_str(), r.col[kBox2D].ms_per_step,
                 r.col[kFulcrumSoft].ms_per_step, r.ratio(kFulcrumSoft),
                 r.col[kFulcrumClassic].ms_per_step, r.ratio(kFulcrumClassic),
                 verdict(r.col[kBox2D].m).c_str(), verdict(r.col[kFulcrumSoft].m).c_str(),
                 verdict(r.col[kFulcrumClassic].m).c_str());
  }
  h.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  h.load_after = load_average();

  const std::string md = markdown(runs, o, h);
  std::fputs(md.c_str(), stdout);
  if (!markdown_path.empty()) write_markdown(markdown_path, md);
  if (!csv_path.empty()) write_file(csv_path, csv(runs));
  return 0;
}
