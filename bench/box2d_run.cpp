// Box2D 2.4.1 and Fulcrum behind one interface (box2d_run.h).
#include "box2d_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <variant>

namespace fulcrum::bench {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

bool is_dynamic(const SceneBody& b) {
  return b.def.type == BodyType::kDynamic || b.def.type == BodyType::kParticle;
}

// Energy over the dynamic bodies, with Fulcrum's masses (which the Box2D twin carries too):
// kinetic, plus gravitational when `potential`.
double energy(const SceneDef& scene, const std::vector<BodyMass>& masses,
              const std::vector<Pose>& poses, bool potential) {
  const Vec2 g = scene.settings.gravity;
  double e = 0.0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const BodyMass& m = masses[i];
    if (!is_dynamic(scene.bodies[i]) || m.mass <= 0.0) continue;
    const Pose& p = poses[i];
    e += 0.5 * m.mass * fulcrum::length_squared(p.velocity) + 0.5 * m.inertia * p.spin * p.spin;
    if (potential) e -= m.mass * scene.bodies[i].def.gravity_scale * fulcrum::dot(g, p.center);
  }
  return e;
}

// The joint's wrapped relative angle, in (-pi, pi].
double relative_angle(double a, double b, double reference) {
  double r = std::remainder(b - a - reference, 2.0 * kPi);
  return r <= -kPi ? r + 2.0 * kPi : r;
}

// How far one joint is from satisfied, from the world anchor points of both bodies, as
// Fulcrum's JointState reports it: the anchor separation for revolute and weld joints, how far
// the length is outside [min, max] for distance joints, the distance off the axis for prismatic
// and wheel joints; motor joints (a target, not a constraint) give 0 (and no length). The limit
// error is the angle past a revolute limit; the length, the anchors' distance.
JointReading read_joint(const SceneJoint& sj, const std::vector<Pose>& poses) {
  const Pose& a = poses[sj.body_a];
  const Pose& b = poses[sj.body_b];
  JointReading out;
  std::visit(
      [&](const auto& def) {
        using Def = std::decay_t<decltype(def)>;
        if constexpr (!std::is_same_v<Def, fulcrum::MotorJointDef>) {
          Vec2 pa = a.world_point(def.local_anchor_a), pb = b.world_point(def.local_anchor_b);
          Vec2 d = pb - pa;
          out.length = fulcrum::length(d);
          if constexpr (std::is_same_v<Def, fulcrum::DistanceJointDef>) {
            out.separation =
                std::max({0.0, def.min_length - out.length, out.length - def.max_length});
          } else if constexpr (std::is_same_v<Def, fulcrum::PrismaticJointDef> ||
                               std::is_same_v<Def, fulcrum::WheelJointDef>) {
            Vec2 axis = a.world_point(def.local_axis_a) - a.world_point(Vec2::Zero());
            out.separation = std::abs(fulcrum::cross(fulcrum::normalize_or_zero(axis), d));
          } else {
            if constexpr (std::is_same_v<Def, fulcrum::RevoluteJointDef>) {
              if (def.enable_limit) {
                double r = relative_angle(a.angle, b.angle, def.reference_angle);
                out.limit_error = std::max({0.0, def.lower_angle - r, r - def.upper_angle});
              }
            }
            out.separation = out.length;
          }
        }
      },
      sj.def);
  return out;
}

// Every joint's reading, in scene order.
void read_joints(const SceneDef& scene, const std::vector<Pose>& poses,
                 std::vector<JointReading>* out) {
  out->resize(scene.joints.size());
  for (size_t k = 0; k < scene.joints.size(); ++k) (*out)[k] = read_joint(scene.joints[k], poses);
}

Box2DRun run_box2d(const SceneDef& scene, std::unique_ptr<Probe> probe, bool penetration,
                   bool joints, int ticks, int timing_ticks, int vel_iters, int pos_iters) {
  Box2DRun out;
  const std::vector<BodyMass> masses = fulcrum_masses(scene);
  TwinNotes notes;
  Box2DEngine engine(scene, masses, TwinOptions{}, vel_iters, pos_iters, &notes);
  out.notes = notes.lines();
  std::vector<Pose> poses;
  std::vector<JointReading> readings;
  engine.read(&poses);
  read_joints(scene, poses, &readings);
  probe->begin(PoseView(scene, masses, poses, readings, engine, 0, ticks));
  double timed = 0.0, pen = 0.0, joint = 0.0;
  for (int t = 0; t < ticks; ++t) {
    auto start = std::chrono::steady_clock::now();
    engine.step();
    auto stop = std::chrono::steady_clock::now();
    if (t >= 1 && t < timing_ticks) {
      timed += std::chrono::duration<double, std::milli>(stop - start).count();
    }
    engine.read(&poses);
    read_joints(scene, poses, &readings);
    const int tick = t + 1;
    if (penetration && tick > 60) pen = std::max(pen, engine.max_penetration());
    for (const JointReading& j : readings) joint = std::max(joint, j.separation);
    probe->after_tick(PoseView(scene, masses, poses, readings, engine, tick, ticks));
  }
  out.ms_per_step = timed / std::max(1, timing_ticks - 1);
  if (penetration) out.m.set(kMaxPenetration, pen);
  if (joints) out.m.set(kJointError, joint);
  const PoseView end(scene, masses, poses, readings, engine, ticks, ticks);
  out.m.check(all_finite(end), "NaN or infinity");
  probe->finish(end, &out.m);
  return out;
}

}  // namespace fulcrum::bench
