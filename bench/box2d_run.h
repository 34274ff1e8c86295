// One hard case's scene run in Box2D 2.4.1 and in Fulcrum through one interface, read as the
// same poses, so that fulcrum_box2d_compare and fulcrum_sweep judge both engines with the same
// probes (hard_case_probes.h). Box2D's world is the scene's twin (box2d_twin.h).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "box2d_twin.h"
#include "fulcrum/scene.h"
#include "fulcrum/world.h"
#include "hard_case_probes.h"

namespace fulcrum::bench {

// One body as both engines report it, in double.
struct Pose {
  Vec2 origin = Vec2::Zero();  // body origin, m
  double angle = 0.0;          // rad (Fulcrum: in (-pi, pi]; Box2D: unwrapped)
  Vec2 center = Vec2::Zero();  // centre of mass, m
  Vec2 velocity = Vec2::Zero();
  double spin = 0.0;

  Vec2 world_point(const Vec2& local) const {
    double c = std::cos(angle), s = std::sin(angle);
    return origin + Vec2(c * local.x() - s * local.y(), s * local.x() + c * local.y());
  }
};

class Engine {
 public:
  virtual ~Engine() = default;
  virtual void step() = 0;
  // Every body, in scene order.
  virtual void read(std::vector<Pose>* out) = 0;
  // The largest overlap over the current contact points, m (each engine's own manifolds).
  virtual double max_penetration() = 0;
};

class FulcrumEngine final : public Engine {
 public:
  explicit FulcrumEngine(const SceneDef& scene)
      : world_(std::move(fulcrum::build_world(scene).value())), ids_(world_.bodies()) {}
  void step() override { world_.step(); }
  void read(std::vector<Pose>* out) override {
    out->resize(ids_.size());
    for (size_t i = 0; i < ids_.size(); ++i) {
      BodyState s = world_.body_state(ids_[i]).value();
      (*out)[i] = {s.transform.p, s.transform.q.angle(), s.center, s.linear_velocity,
                   s.angular_velocity};
    }
  }
  double max_penetration() override { return world_.metrics().max_penetration; }

 private:
  World world_;
  std::vector<BodyId> ids_;
};

class Box2DEngine final : public Engine {
 public:
  Box2DEngine(const SceneDef& scene, const std::vector<BodyMass>& masses,
              const fulcrum::bench::TwinOptions& options, int vel_iters, int pos_iters,
              fulcrum::bench::TwinNotes* notes)
      : twin_(fulcrum::bench::build_box2d_twin(scene, masses, options, notes)),
        dt_(static_cast<float>(scene.settings.dt)),
        vel_(vel_iters),
        pos_(pos_iters) {}
  void step() override { twin_.world->Step(dt_, vel_, pos_); }
  void read(std::vector<Pose>* out) override {
    out->resize(twin_.bodies.size());
    for (size_t i = 0; i < twin_.bodies.size(); ++i) {
      const b2Body* b = twin_.bodies[i];
      b2Vec2 p = b->GetPosition(), c = b->GetWorldCenter(), v = b->GetLinearVelocity();
      (*out)[i] = {Vec2(p.x, p.y), b->GetAngle(), Vec2(c.x, c.y), Vec2(v.x, v.y),
                   b->GetAngularVelocity()};
    }
  }
  double max_penetration() override { return fulcrum::bench::box2d_max_penetration(*twin_.world); }

 private:
  fulcrum::bench::Twin twin_;
  float dt_;
  int vel_, pos_;
};

bool is_dynamic(const SceneBody& b);

// Energy over the dynamic bodies, with Fulcrum's masses (which the Box2D twin carries too):
// kinetic, plus gravitational when `potential`.
double energy(const SceneDef& scene, const std::vector<BodyMass>& masses,
              const std::vector<Pose>& poses, bool potential);

// How far one joint is from satisfied, from the world anchor points of both bodies, as
// Fulcrum's JointState reports it (box2d_run.cpp).
JointReading read_joint(const SceneJoint& sj, const std::vector<Pose>& poses);

// Every joint's reading, in scene order.
void read_joints(const SceneDef& scene, const std::vector<Pose>& poses,
                 std::vector<JointReading>* out);

// A probe's view of one engine's run: the poses and joint readings the runner took after the
// tick; penetration from the engine's own contacts, read on demand.
class PoseView final : public View {
 public:
  PoseView(const SceneDef& scene, const std::vector<BodyMass>& masses,
           const std::vector<Pose>& poses, const std::vector<JointReading>& joints, Engine& engine,
           int tick, int ticks)
      : View(scene, tick, ticks),
        masses_(masses),
        poses_(poses),
        joints_(joints),
        engine_(&engine) {}

  BodyPose body(size_t i) const override {
    const Pose& p = poses_[i];
    // The rotation as Pose::world_point applies it.
    fulcrum::Transform xf{p.origin, fulcrum::Rot{std::cos(p.angle), std::sin(p.angle)}};
    return {xf, p.center, p.velocity, p.spin};
  }
  JointReading joint(size_t k) const override { return joints_[k]; }
  double max_penetration() const override { return engine_->max_penetration(); }
  double kinetic_energy() const override { return energy(scene(), masses_, poses_, false); }
  double mechanical_energy() const override { return energy(scene(), masses_, poses_, true); }

 private:
  const std::vector<BodyMass>& masses_;
  const std::vector<Pose>& poses_;
  const std::vector<JointReading>& joints_;
  Engine* engine_;
};

// One run of a scene in Box2D 2.4.1 (vel + pos iterations), judged as fulcrum_sweep judges
// Fulcrum: `probe` after every tick, the largest penetration after the first second when
// `penetration`, the largest joint separation when `joints`. ms per step: the mean over steps
// 1..timing_ticks-1.
struct Box2DRun {
  double ms_per_step = 0.0;
  Measures m;
  std::vector<std::string> notes;  // what the twin could not carry over
};
Box2DRun run_box2d(const SceneDef& scene, std::unique_ptr<Probe> probe, bool penetration,
                   bool joints, int ticks, int timing_ticks, int vel_iters = 8, int pos_iters = 3);

}  // namespace fulcrum::bench
