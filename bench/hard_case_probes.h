// The HARD_CASES pass criteria (../shared/HARD_CASES.md), written once for every benchmark that
// judges them: fulcrum_sweep (Fulcrum over a grid of solver settings) and
// fulcrum_box2d_compare (Fulcrum and Box2D 2.4.1 side by side). A probe watches one run of a
// case through an engine-neutral View and fills the case's error measures and the criteria it
// missed. What only an engine can say about itself (its own contact overlap, its joints'
// separation, its energy) comes through the View too, from whatever the runner reads it from.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bench_text.h"
#include "fulcrum/math.h"
#include "fulcrum/scene.h"

namespace fulcrum::bench {

// Every error measure a probe or a runner fills; a case fills those that apply to it.
enum Measure {
  kMaxPenetration,   // m: largest contact overlap, sampled every tick after the first second
  kMeanPenetration,  // m: mean over those ticks of the mean overlap of overlapping points
  kDisplacement,     // m: the case's "left its region" distance (what it is: each case's labels)
  kBodiesOut,        // bodies beyond the case's bound
  kJointError,       // m: largest joint separation at any tick (JointReading::separation)
  kStretch,          // fraction: largest (length - rest) / rest of a distance joint
  kLimitError,       // rad: largest JointReading::limit_error (angle past a limit)
  kEnergyDrift,      // fraction: energy gain where energy must not rise (see each case)
  kMaxSpeed,         // m/s: largest body speed at any tick (explosions)
  kAnalytic,         // fraction: relative error against the case's closed form
  kRefVelocity,      // m/s: largest |v - v_ref| over the bodies after one tick (reference.h)
  kRefAngular,       // rad/s: largest |w - w_ref| over the bodies after the same tick
  kMeasureCount
};

struct Measures {
  std::array<std::optional<double>, kMeasureCount> value;
  std::vector<std::string> failed;  // the criteria missed, with the figures
  bool judged = true;               // false for scenes without a HARD_CASES criterion

  void set(Measure m, double v) { value[m] = v; }
  // Records a criterion; `what` says what was missed, with the figure and the limit.
  void check(bool ok, const std::string& what) {
    if (!ok) failed.push_back(what);
  }
  bool pass() const { return failed.empty(); }
};

// One body as an engine reports it, in double.
struct BodyPose {
  Transform transform;         // body origin and rotation
  Vec2 center = Vec2::Zero();  // centre of mass, m
  Vec2 velocity = Vec2::Zero();
  double spin = 0.0;  // rad/s
};

// One joint as an engine reports it (or as a runner measures it from the bodies' anchors).
struct JointReading {
  double separation = 0.0;   // m: how far from satisfied (Fulcrum's JointState::linear_error)
  double limit_error = 0.0;  // rad: angle past a revolute limit (JointState::angular_error)
  double length = 0.0;       // m: distance between the world anchors
};

// What a probe sees of one engine's run: before the first tick (tick 0), after each tick and
// at the end (tick == ticks). Bodies and joints are indexed as in the scene. Each runner
// implements it over its engine; the accessors are read on demand, so a probe pays only for
// what it reads, and runners read nothing inside their step clocks.
class View {
 public:
  View(const SceneDef& scene, int tick, int ticks) : scene_(scene), tick_(tick), ticks_(ticks) {}
  virtual ~View() = default;

  // The scene the engine was built from, with the settings it runs at.
  const SceneDef& scene() const { return scene_; }
  int tick() const { return tick_; }    // ticks stepped so far
  int ticks() const { return ticks_; }  // ticks in this run
  size_t body_count() const { return scene_.bodies.size(); }
  size_t joint_count() const { return scene_.joints.size(); }

  virtual BodyPose body(size_t i) const = 0;
  virtual JointReading joint(size_t k) const = 0;
  // The largest overlap over the engine's current contact points, m.
  virtual double max_penetration() const = 0;
  // J, over the dynamic bodies.
  virtual double kinetic_energy() const = 0;
  // Kinetic plus gravitational (m g . x, relative to the origin), J.
  virtual double mechanical_energy() const = 0;

  Vec2 center(size_t i) const { return body(i).center; }

 private:
  const SceneDef& scene_;
  int tick_, ticks_;
};

// Every body centre, in scene order.
std::vector<Vec2> centers(const View& v);
// No NaN or infinity in any body's centre, velocity or spin.
bool all_finite(const View& v);

// Per-case measurement: begin() before the first tick, after_tick() after each, finish() at the
// end fills the case's own measures and criteria. The runner fills the common measures first
// (penetration, joint error, speed: whichever its case lists) and checks for NaN.
class Probe {
 public:
  virtual ~Probe() = default;
  virtual void begin(const View&) {}
  virtual void after_tick(const View&) {}
  virtual void finish(const View&, Measures*) = 0;
};

// The probe that judges HARD_CASES case `id` (what each checks: hard_case_probes.cpp, above
// each class), with the scene layout of the scene table's builtin (and, for the pendulum (16),
// of the scene its test builds). Null for the bullet (17): its criterion needs worlds of its
// own (fulcrum_sweep runs them), and for ids outside 1..20.
std::unique_ptr<Probe> hard_case_probe(int id);

// Any other scene: how far the bodies moved (displacement, bodies moved > 0.5 m), no criterion.
std::unique_ptr<Probe> moved_probe();

}  // namespace fulcrum::bench
