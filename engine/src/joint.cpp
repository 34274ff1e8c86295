// Joint lifetimes, validation, reporting, and the solver stages that visit every awake joint
// (each type's math is in its own file).
#include <algorithm>
#include <cmath>
#include <string>

#include "fulcrum/trig.h"
#include "joint_solver.h"
#include "validation.h"
#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

// The angle of b relative to a, less the reference, in (-pi, pi].
double relative_angle(const Rot& qa, const Rot& qb, double reference) {
  double angle = inv_mul(qa, qb).angle() - reference;
  if (angle > kPi) angle -= 2.0 * kPi;
  if (angle <= -kPi) angle += 2.0 * kPi;
  return angle;
}

}  // namespace

const char* joint_type_name(JointType type) {
  switch (type) {
    case JointType::kDistance:
      return "distance";
    case JointType::kRevolute:
      return "revolute";
    case JointType::kWeld:
      return "weld";
    case JointType::kTarget:
      return "target";
    case JointType::kPrismatic:
      return "prismatic";
    case JointType::kWheel:
      return "wheel";
    case JointType::kMotor:
      return "motor";
    case JointType::kCurve:
      return "curve";
    case JointType::kSpring:
      return "spring";
  }
  return "unknown";
}

Status validate_distance_joint_def(const DistanceJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_a", d.local_anchor_a));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  if (!(d.length > 0.0) || !std::isfinite(d.length)) {
    return invalid_argument("joint.length: must be finite and > 0 (got " + format_number(d.length) +
                            ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.min_length", d.min_length));
  if (!(d.min_length <= d.length)) {
    return invalid_argument("joint.min_length: must be <= length (got " +
                            format_number(d.min_length) + " > " + format_number(d.length) + ")");
  }
  if (!(d.max_length >= d.length) || !std::isfinite(d.max_length)) {
    return invalid_argument("joint.max_length: must be finite and >= length (got " +
                            format_number(d.max_length) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.hertz", d.hertz));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.damping_ratio", d.damping_ratio));
  return {};
}

Status validate_weld_joint_def(const WeldJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_a", d.local_anchor_a));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.reference_angle", d.reference_angle));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.linear_hertz", d.linear_hertz));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.linear_damping_ratio", d.linear_damping_ratio));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.angular_hertz", d.angular_hertz));
  FULCRUM_RETURN_IF_ERROR(
      check_non_negative("joint.angular_damping_ratio", d.angular_damping_ratio));
  return {};
}

Status validate_target_joint_def(const TargetJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.target", d.target));
  FULCRUM_RETURN_IF_ERROR(check_cap("joint.max_force", d.max_force));
  FULCRUM_RETURN_IF_ERROR(check_above("joint.hertz", d.hertz, 0.0));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.damping_ratio", d.damping_ratio));
  return {};
}

Status validate_prismatic_joint_def(const PrismaticJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_a", d.local_anchor_a));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_axis_a", d.local_axis_a));
  if (length(d.local_axis_a) < 1e-9)
    return invalid_argument("joint.local_axis_a: must not be zero");
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.reference_angle", d.reference_angle));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.lower_translation", d.lower_translation));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.upper_translation", d.upper_translation));
  if (d.lower_translation > d.upper_translation) {
    return invalid_argument("joint.lower_translation: must be <= upper_translation (got " +
                            format_number(d.lower_translation) + " > " +
                            format_number(d.upper_translation) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.motor_speed", d.motor_speed));
  FULCRUM_RETURN_IF_ERROR(check_cap("joint.max_motor_force", d.max_motor_force));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.hertz", d.hertz));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.damping_ratio", d.damping_ratio));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.target_translation", d.target_translation));
  return {};
}

Status validate_revolute_joint_def(const RevoluteJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_a", d.local_anchor_a));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.reference_angle", d.reference_angle));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.lower_angle", d.lower_angle));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.upper_angle", d.upper_angle));
  if (d.lower_angle > d.upper_angle) {
    return invalid_argument("joint.lower_angle: must be <= upper_angle (got " +
                            format_number(d.lower_angle) + " > " + format_number(d.upper_angle) +
                            ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.motor_speed", d.motor_speed));
  FULCRUM_RETURN_IF_ERROR(check_cap("joint.max_motor_torque", d.max_motor_torque));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.hertz", d.hertz));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.damping_ratio", d.damping_ratio));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.target_angle", d.target_angle));
  return {};
}

// --- WorldImpl ---------------------------------------------------------------------------------

int WorldImpl::joint_index(JointId id) const {
  if (id.index < 0 || id.index >= static_cast<int>(joints.size())) return kNullIndex;
  const Joint& j = joints[id.index];
  return j.alive && j.generation == id.generation ? id.index : kNullIndex;
}

bool WorldImpl::joint_blocks_contact(int body_a, int body_b) const {
  const Body& a = bodies[body_a];
  const Body& b = bodies[body_b];
  const std::vector<int>& list = a.joints.size() <= b.joints.size() ? a.joints : b.joints;
  for (int ji : list) {
    const Joint& j = joints[ji];
    bool pair =
        (j.body_a == body_a && j.body_b == body_b) || (j.body_a == body_b && j.body_b == body_a);
    if (pair && !j.collide_connected) return true;
  }
  return false;
}

void WorldImpl::destroy_joint_at(int ji) {
  Joint& j = joints[ji];
  for (int bi : {j.body_a, j.body_b}) {
    auto& list = bodies[bi].joints;
    list.erase(std::find(list.begin(), list.end(), ji));
  }
  j.alive = false;
  note_joint(ji);
  free_joints.push_back(ji);
}

// Joint rows per chunk when prepare_joints shares them among threads.
constexpr size_t kJointsPerChunk = 256;

namespace {

// A plain pin (solved in lanes, joint_lanes.h): a revolute joint with no limit, motor or spring
// and no impulse left on those rows.
bool plain_pin(const Joint& j) {
  return j.type == JointType::kRevolute && !j.enable_limit && !j.enable_motor && !j.enable_spring &&
         j.spring_impulse == 0.0 && j.motor_impulse == 0.0 && j.lower_impulse == 0.0 &&
         j.upper_impulse == 0.0;
}

}  // namespace

void WorldImpl::prepare_joints(const std::vector<int>& awake, double h, bool every_row) {
  SolverScratch& s = solver_scratch;
  // Awake joints in id order, each once (from its lower-indexed awake body).
  s.joints.clear();
  size_t springs = 0;
  const bool all_awake = awake.size() == awake_bodies.size();
  if (all_awake && tick_joints.stamp == step_stamp) {
    // The budgets' walk over the joint pool listed them this tick (budget.cpp).
    s.joints.assign(tick_joints.joints.begin(), tick_joints.joints.end());
    springs = tick_joints.springs;
  } else if (all_awake && 2 * awake.size() >= static_cast<size_t>(body_count)) {
    // All awake bodies (not one budget group), most bodies in all: one pass over the joint pool
    // finds the same joints, already in id order.
    for (size_t ji = 0; ji < joints.size(); ++ji) {
      if (ji + kFetchAhead < joints.size()) fetch_joint(joints[ji + kFetchAhead]);
      const Joint& j = joints[ji];
      if (j.alive && (bodies[j.body_a].awake || bodies[j.body_b].awake)) {
        s.joints.push_back(static_cast<int>(ji));
        springs += j.type == JointType::kSpring;
      }
    }
  } else {
    for (int bi : awake) {
      for (int ji : bodies[bi].joints) {
        const Joint& j = joints[ji];
        int other = j.body_a == bi ? j.body_b : j.body_a;
        if (bodies[other].awake && other < bi) continue;
        s.joints.push_back(ji);
      }
    }
    std::sort(s.joints.begin(), s.joints.end());
    s.joints.erase(std::unique(s.joints.begin(), s.joints.end()), s.joints.end());
    for (int ji : s.joints) springs += joints[ji].type == JointType::kSpring;
  }

  const Softness soft = make_softness(settings.joint_hertz, settings.joint_damping_ratio, h);
  // Joint k's row, in `r`.
  auto fill_row = [&](size_t k, JointRow& r) {
    Joint& j = joints[s.joints[k]];
    if (!settings.warm_starting) {
      j.linear_impulse = Vec2::Zero();
      j.axial_impulse = j.lower_impulse = j.upper_impulse = 0.0;
      j.motor_impulse = j.spring_impulse = 0.0;
    }
    const Body& ba = bodies[j.body_a];
    const Body& bb = bodies[j.body_b];
    // A plain pin (solved in lanes) has no angle row: it needs no springs and no joint angle
    // (which skips the arctangent), and its row reads nothing past the joint's first two
    // cache lines. Its row is written up to `soft` only (JointRow); any other row in full.
    const bool plain = plain_pin(j);
    if (!plain) r = JointRow{};
    r.joint = s.joints[k];
    r.type = j.type;
    r.plain_point = plain;
    r.ia = ba.awake ? s.body_slot[j.body_a] : 0;
    r.ib = bb.awake ? s.body_slot[j.body_b] : 0;
    Vec2 ra = ba.xf.q.rotate(j.local_a - ba.local_center);
    Vec2 rb = bb.xf.q.rotate(j.local_b - bb.local_center);
    r.rax = ra.x();
    r.ray = ra.y();
    r.rbx = rb.x();
    r.rby = rb.y();
    r.dcx = bb.center.x() - ba.center.x();
    r.dcy = bb.center.y() - ba.center.y();
    r.soft = soft;
    if (j.type == JointType::kRevolute) {  // its point impulse, pin or not
      r.ix = j.linear_impulse.x();
      r.iy = j.linear_impulse.y();
    }
    if (plain) return;
    r.spring = make_softness(j.hertz, j.damping_ratio, h);
    r.angular_spring = make_softness(j.angular_hertz, j.angular_damping_ratio, h);
    const ScalarBody a = scalar_body(s, r.ia);
    const ScalarBody b = scalar_body(s, r.ib);
    if (j.type == JointType::kTarget) {
      r.dcx = bb.center.x() - j.target.x();
      r.dcy = bb.center.y() - j.target.y();
    } else if (j.type == JointType::kCurve) {
      r.dcx = bb.center.x();  // the curve is in world coordinates
      r.dcy = bb.center.y();
    } else if (j.type == JointType::kPrismatic || j.type == JointType::kWheel) {
      Vec2 axis = ba.xf.q.rotate(j.local_axis);
      r.axis_x = axis.x();
      r.axis_y = axis.y();
      r.angle = relative_angle(ba.xf.q, bb.xf.q, j.reference_angle);
      if (j.type == JointType::kWheel) prepare_revolute_joint(j, r, a, b);  // the motor's mass
    } else if (j.type == JointType::kDistance) {
      prepare_distance_joint(j, r, a, b);
    } else if (j.type != JointType::kSpring) {
      // Revolute (not a plain pin), weld and motor: the angle row's mass and the joint angle at
      // tick start.
      r.angle = relative_angle(ba.xf.q, bb.xf.q, j.reference_angle);
      prepare_revolute_joint(j, r, a, b);
      if (j.type == JointType::kRevolute) {
        RevoluteRow& v = r.revolute;
        v.spring = j.enable_spring;
        v.motor = j.enable_motor;
        v.limit = j.enable_limit;
        v.target_angle = j.target_angle;
        v.motor_speed = j.motor_speed;
        v.max_motor_torque = j.max_motor_torque;
        v.lower_angle = j.lower_angle;
        v.upper_angle = j.upper_angle;
        v.spring_impulse = j.spring_impulse;
        v.motor_impulse = j.motor_impulse;
        v.lower_impulse = j.lower_impulse;
        v.upper_impulse = j.upper_impulse;
      }
    }
  };
  s.joint_rows.resize(s.joints.size());
  s.joint_row_slots.resize(s.joints.size());
  // A row's slots and kind (revolute joints go to lanes, joint_lanes.h).
  auto slots_of = [](const JointRow& r) {
    return SolverScratch::RowSlots{r.ia, r.ib, r.plain_point,
                                   r.type == JointType::kRevolute && !r.plain_point};
  };
  auto note_slots = [&](size_t k) { s.joint_row_slots[k] = slots_of(s.joint_rows[k]); };
  s.spring_rows.clear();
  size_t n_rows = 0;
  ColouredPoints& cp = coloured_points;
  if (springs == 0) {
    // Row k is joint k's: rows in chunks, each written by one thread. When the rows may be last
    // tick's (the same joints with the same slots and kinds: the same layout), each revolute
    // joint is written straight into its lane from a row of the chunk's own (place_point), and
    // only the other rows are kept; a row that differs is kept too and the tick colours its rows
    // anew.
    n_rows = s.joints.size();
    const int chunks = static_cast<int>((n_rows + kJointsPerChunk - 1) / kJointsPerChunk);
    const bool placing = !every_row && layout_fits(cp, s.joints, pool != nullptr);
    cp.chunk_differs.assign(chunks, 0);
    auto chunk = [&](int c) {
      const size_t lo = static_cast<size_t>(c) * kJointsPerChunk;
      const size_t hi = std::min(lo + kJointsPerChunk, n_rows);
      JointRow pin;  // revolute rows; those of plain pins are written up to `soft` only
      for (size_t k = lo; k < hi; ++k) {
        if (k + kFetchAhead < hi) fetch_joint(joints[s.joints[k + kFetchAhead]]);
        if (!placing) {
          fill_row(k, s.joint_rows[k]);
          note_slots(k);
          continue;
        }
        const bool to_lane = joints[s.joints[k]].type == JointType::kRevolute;
        JointRow& r = to_lane ? pin : s.joint_rows[k];
        fill_row(k, r);
        s.joint_row_slots[k] = slots_of(r);
        if (place_point(&cp, k, r, s.bodies, s.body_extras)) continue;
        cp.chunk_differs[c] = 1;
        if (to_lane) s.joint_rows[k] = pin;
      }
    };
    run_chunks(chunks > 1 ? pool : nullptr, chunks, chunk, true);
    const bool placed = placing && std::find(cp.chunk_differs.begin(), cp.chunk_differs.end(), 1) ==
                                       cp.chunk_differs.end();
    if (placed) {
      s.track_angles = !cp.other_rows.empty() || cp.revolutes.joints > 0;
      return;
    }
    if (placing) {
      // Some revolute joints went straight to lanes that are about to be laid out anew: their
      // rows too.
      for (size_t k = 0; k < n_rows; ++k) {
        const SolverScratch::RowSlots& slots = s.joint_row_slots[k];
        if (slots.plain_point || slots.revolute) fill_row(k, s.joint_rows[k]);
      }
    }
  } else {
    // Spring force elements have rows of their own; constraints fill joint_rows in id order.
    for (size_t k = 0; k < s.joints.size(); ++k) {
      const bool spring = joints[s.joints[k]].type == JointType::kSpring;
      if (spring) {
        fill_row(k, s.spring_rows.emplace_back());
      } else {
        fill_row(k, s.joint_rows[n_rows]);
        note_slots(n_rows++);
      }
    }
  }
  s.joint_rows.resize(n_rows);
  s.joint_row_slots.resize(n_rows);
  colour_points(s.joint_rows, s.joint_row_slots, s.bodies, s.body_extras, pool, &cp);
  // Only the rows that are not plain points read the angles the bodies turn.
  s.track_angles = !cp.other_rows.empty() || cp.revolutes.joints > 0;
}

void WorldImpl::warm_start_joints(WorkerPool* workers, bool lanes) {
  SolverScratch& s = solver_scratch;
  if (lanes) warm_start_points(coloured_points, s.bodies.data(), workers);
  each_other_row(coloured_points, workers, [&](int k) {
    const JointRow& r = s.joint_rows[k];
    ScalarBody a = scalar_body(s, r.ia);
    ScalarBody b = scalar_body(s, r.ib);
    Joint& j = joints[r.joint];
    switch (r.type) {
      case JointType::kDistance:
        warm_start_distance_joint(j, r, a, b);
        break;
      case JointType::kRevolute:
        break;  // in lanes (joint_lanes.h)
      case JointType::kWeld:
        warm_start_weld_joint(j, r, a, b);
        break;
      case JointType::kTarget:
        warm_start_target_joint(j, r, b);
        break;
      case JointType::kPrismatic:
        warm_start_prismatic_joint(j, r, a, b);
        break;
      case JointType::kWheel:
        warm_start_wheel_joint(j, r, a, b);
        break;
      case JointType::kMotor:
        warm_start_motor_joint(j, r, a, b);
        break;
      case JointType::kCurve:
        warm_start_curve_joint(j, r, b);
        break;
      case JointType::kSpring:
        break;  // a force, applied with the velocities (apply_spring_forces)
    }
    store_velocity(a, s.bodies[r.ia]);
    store_velocity(b, s.bodies[r.ib]);
  });
}

void WorldImpl::solve_joints(bool use_bias, WorkerPool* workers, VelocityBefore* warm_next,
                             PointMassUse mass) {
  SolverScratch& s = solver_scratch;
  JointStep st;
  st.h = settings.dt / settings.substeps;
  st.inv_h = 1.0 / st.h;
  st.use_bias = use_bias;
  st.rigid = settings.joint_hertz == 0.0;
  st.baumgarte = settings.baumgarte;
  st.max_speed = settings.max_correction_speed;
  // The feedback of the revolute joints' lanes: their rows' softness (prepare_joints') and
  // limit_bias's rule, for all of them at once.
  const Softness soft = make_softness(settings.joint_hertz, settings.joint_damping_ratio, st.h);
  PointRule rule;
  rule.use_bias = use_bias;
  rule.rate = st.rigid ? st.baumgarte * st.inv_h : soft.bias_rate;
  rule.mass_scale = st.rigid ? 1.0 : soft.mass_scale;
  rule.impulse_scale = st.rigid ? 0.0 : soft.impulse_scale;
  rule.max_speed = st.max_speed;
  rule.warm_next = warm_next;
  rule.h = st.h;
  rule.inv_h = st.inv_h;
  rule.mass = mass;
  solve_points(coloured_points, s.bodies.data(), s.body_extras.data(), rule, workers);
  each_other_row(coloured_points, workers, [&](int k) {
    JointRow& r = s.joint_rows[k];
    ScalarBody a = scalar_body(s, r.ia);
    ScalarBody b = scalar_body(s, r.ib);
    Joint& j = joints[r.joint];
    switch (r.type) {
      case JointType::kDistance:
        solve_distance_joint(j, r, st, a, b);
        break;
      case JointType::kRevolute:
        break;  // in lanes (joint_lanes.h)
      case JointType::kWeld:
        solve_weld_joint(j, r, st, a, b);
        break;
      case JointType::kTarget:
        solve_target_joint(j, r, st, b);
        break;
      case JointType::kPrismatic:
        solve_prismatic_joint(j, r, st, a, b);
        break;
      case JointType::kWheel:
        solve_wheel_joint(j, r, st, a, b);
        break;
      case JointType::kMotor:
        solve_motor_joint(j, r, st, a, b);
        break;
      case JointType::kCurve:
        solve_curve_joint(j, r, st, b);
        break;
      case JointType::kSpring:
        break;
    }
    store_velocity(a, s.bodies[r.ia]);
    store_velocity(b, s.bodies[r.ib]);
  });
}

void WorldImpl::store_joint_impulses(WorkerPool* workers) {
  unpack_points(coloured_points, &joints, workers);
}

namespace {

// The force (N) and torque (N m) a joint applied to body B over the last tick.
void joint_reaction(const Joint& j, double inv_h, const Vec2& axis, Vec2* force, double* torque) {
  if (j.type == JointType::kDistance) {
    *force =
        inv_h * (j.axial_impulse + j.spring_impulse + j.lower_impulse - j.upper_impulse) * axis;
    *torque = 0.0;
  } else if (j.type == JointType::kPrismatic) {
    // axis: the slide axis; linear_impulse holds the line row (along its perpendicular) and
    // the angle row.
    double axial = j.motor_impulse + j.lower_impulse - j.upper_impulse;
    if (j.enable_spring) axial += j.spring_impulse;
    *force = inv_h * (axial * axis + j.linear_impulse.x() * left_perp(axis));
    *torque = inv_h * j.linear_impulse.y();
  } else if (j.type == JointType::kWheel) {
    // axis: the suspension axis; the line row pushes along its perpendicular, the motor turns.
    double axial = j.spring_impulse + j.lower_impulse - j.upper_impulse;
    *force = inv_h * (axial * axis + j.linear_impulse.x() * left_perp(axis));
    *torque = inv_h * j.motor_impulse;
  } else if (j.type == JointType::kCurve) {
    *force = inv_h * j.axial_impulse * axis;  // axis: the curve normal
    *torque = 0.0;
  } else if (j.type == JointType::kSpring) {
    *force = inv_h * j.spring_impulse * axis;  // axis: anchor A -> anchor B
    *torque = 0.0;
  } else if (j.type == JointType::kRevolute) {
    *force = inv_h * j.linear_impulse;
    *torque = inv_h * (j.spring_impulse + j.motor_impulse + j.lower_impulse - j.upper_impulse);
  } else {
    *force = inv_h * j.linear_impulse;
    *torque = inv_h * j.axial_impulse;
  }
}

}  // namespace

void WorldImpl::break_joints() {
  if (!breakable_joints) return;
  const double inv_h = settings.substeps / settings.dt;
  const std::vector<int>& list = solver_scratch.joints;
  for (size_t k = 0; k < list.size(); ++k) {
    if (k + kFetchAhead < list.size()) fetch_joint(joints[list[k + kFetchAhead]]);
    const int ji = list[k];
    Joint& j = joints[ji];
    if (!j.alive || !may_break(j)) continue;
    Vec2 force;
    double torque;
    // Any unit axis gives the right size of force (a distance joint's, a curve joint's and a
    // spring's lie along their axis, a prismatic or wheel joint's rows are orthogonal).
    joint_reaction(j, inv_h, Vec2(1.0, 0.0), &force, &torque);
    if (length(force) > j.break_force || std::abs(torque) > j.break_torque) {
      events.joints_broken.push_back(joint_id(ji));
      wake_island(j.body_a);
      wake_island(j.body_b);
      destroy_joint_at(ji);
    }
  }
}

// --- World -------------------------------------------------------------------------------------

Result<int> WorldImpl::add_joint(JointType type, BodyId body_a, BodyId body_b,
                                 bool collide_connected) {
  WorldImpl& w = *this;
  int a = w.body_index(body_a);
  if (a == kNullIndex) {
    return not_found("joint.body_a: unknown or destroyed body {" + std::to_string(body_a.index) +
                     ", " + std::to_string(body_a.generation) + "}");
  }
  int b = w.body_index(body_b);
  if (b == kNullIndex) {
    return not_found("joint.body_b: unknown or destroyed body {" + std::to_string(body_b.index) +
                     ", " + std::to_string(body_b.generation) + "}");
  }
  if (a == b) return invalid_argument("joint.body_b: must differ from body_a (same body)");
  int ji;
  if (!w.free_joints.empty()) {
    ji = w.free_joints.back();
    w.free_joints.pop_back();
  } else {
    ji = static_cast<int>(w.joints.size());
    w.joints.emplace_back();
  }
  Joint& j = w.joints[ji];
  uint32_t generation = j.generation + 1;
  j = Joint{};
  j.type = type;
  j.generation = generation;
  j.alive = true;
  j.body_a = a;
  j.body_b = b;
  j.collide_connected = collide_connected;
  w.note_joint(ji);
  w.bodies[a].joints.push_back(ji);
  w.bodies[b].joints.push_back(ji);
  if (!collide_connected) {
    // Jointed bodies stop colliding: drop their contacts now.
    for (int e = w.bodies[a].contact_list; e != kNullIndex;) {
      int ci = edge_contact(e);
      int next = w.contacts[ci].edges[edge_side(e)].next;
      const Contact& c = w.contacts[ci];
      if ((c.body_a == a && c.body_b == b) || (c.body_a == b && c.body_b == a)) {
        w.destroy_contact(ci, true);
      }
      e = next;
    }
  }
  w.wake_island(a);
  w.wake_island(b);
  return ji;
}

namespace {

// The common start of create_*_joint: the definition's own check, then a joint between its
// two bodies with its anchors.
template <typename Def>
Result<int> start_joint(WorldImpl& w, const Def& def, const Status& valid, JointType type) {
  if (!valid.ok()) return valid;
  Result<int> ji = w.add_joint(type, def.body_a, def.body_b, def.collide_connected);
  if (!ji.ok()) return ji;
  Joint& j = w.joints[*ji];
  j.local_a = def.local_anchor_a;
  j.local_b = def.local_anchor_b;
  return ji;
}

}  // namespace

Result<JointId> World::create_distance_joint(const DistanceJointDef& def) {
  Result<int> ji = start_joint(*impl_, def, validate_distance_joint_def(def), JointType::kDistance);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.length = def.length;
  j.min_length = def.min_length;
  j.max_length = def.max_length;
  j.hertz = def.hertz;
  j.damping_ratio = def.damping_ratio;
  return impl_->joint_id(*ji);
}

Result<JointId> World::create_revolute_joint(const RevoluteJointDef& def) {
  Result<int> ji = start_joint(*impl_, def, validate_revolute_joint_def(def), JointType::kRevolute);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.reference_angle = def.reference_angle;
  j.enable_limit = def.enable_limit;
  j.lower_angle = def.lower_angle;
  j.upper_angle = def.upper_angle;
  j.enable_motor = def.enable_motor;
  j.motor_speed = def.motor_speed;
  j.max_motor_torque = def.max_motor_torque;
  j.enable_spring = def.enable_spring;
  j.hertz = def.enable_spring ? def.hertz : 0.0;
  j.damping_ratio = def.damping_ratio;
  j.target_angle = def.target_angle;
  return impl_->joint_id(*ji);
}

Result<JointId> World::create_weld_joint(const WeldJointDef& def) {
  Result<int> ji = start_joint(*impl_, def, validate_weld_joint_def(def), JointType::kWeld);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.reference_angle = def.reference_angle;
  j.hertz = def.linear_hertz;
  j.damping_ratio = def.linear_damping_ratio;
  j.angular_hertz = def.angular_hertz;
  j.angular_damping_ratio = def.angular_damping_ratio;
  return impl_->joint_id(*ji);
}

Result<JointId> World::create_prismatic_joint(const PrismaticJointDef& def) {
  Result<int> ji =
      start_joint(*impl_, def, validate_prismatic_joint_def(def), JointType::kPrismatic);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.local_axis = normalize_or_zero(def.local_axis_a);
  j.reference_angle = def.reference_angle;
  j.enable_limit = def.enable_limit;
  j.lower_angle = def.lower_translation;  // translations, in the limit fields
  j.upper_angle = def.upper_translation;
  j.enable_motor = def.enable_motor;
  j.motor_speed = def.motor_speed;
  j.max_motor_force = def.max_motor_force;
  j.enable_spring = def.enable_spring;
  j.hertz = def.enable_spring ? def.hertz : 0.0;
  j.damping_ratio = def.damping_ratio;
  j.target_translation = def.target_translation;
  return impl_->joint_id(*ji);
}

Result<JointId> World::create_target_joint(const TargetJointDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_target_joint_def(def));
  int a = impl_->body_index(def.body_a);
  if (a != kNullIndex && impl_->bodies[a].type != BodyType::kStatic) {
    return invalid_argument("joint.body_a: must be a static body (the target's frame)");
  }
  Result<int> ji = impl_->add_joint(JointType::kTarget, def.body_a, def.body_b, true);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.local_b = def.local_anchor_b;
  j.target = def.target;
  j.max_force = def.max_force;
  j.hertz = def.hertz;
  j.damping_ratio = def.damping_ratio;
  return impl_->joint_id(*ji);
}

Status World::set_joint_target(JointId id, const Vec2& target) {
  int ji = impl_->joint_index(id);
  if (ji == kNullIndex) return not_found("joint: unknown or destroyed joint handle");
  if (impl_->joints[ji].type != JointType::kTarget) {
    return invalid_argument("joint: not a target joint");
  }
  FULCRUM_RETURN_IF_ERROR(check_finite("target", target));
  impl_->joints[ji].target = target;
  impl_->wake_island(impl_->joints[ji].body_b);
  return {};
}

Status World::set_joint_break_limits(JointId id, double force, double torque) {
  int ji = impl_->joint_index(id);
  if (ji == kNullIndex) return not_found("joint: unknown or destroyed joint handle");
  if (!(force >= 0.0)) return invalid_argument("break_force: must be >= 0 (infinity: never)");
  if (!(torque >= 0.0)) return invalid_argument("break_torque: must be >= 0 (infinity: never)");
  impl_->joints[ji].break_force = force;
  impl_->joints[ji].break_torque = torque;
  if (may_break(impl_->joints[ji])) impl_->breakable_joints = true;
  return {};
}

Status World::destroy_joint(JointId id) {
  int ji = impl_->joint_index(id);
  if (ji == kNullIndex) {
    return not_found("joint {" + std::to_string(id.index) + ", " + std::to_string(id.generation) +
                     "}: unknown or destroyed joint handle");
  }
  impl_->wake_island(impl_->joints[ji].body_a);
  impl_->wake_island(impl_->joints[ji].body_b);
  impl_->destroy_joint_at(ji);
  return {};
}

bool World::is_valid(JointId id) const {
  return impl_->joint_index(id) != kNullIndex;
}

Status World::set_motor_speed(JointId id, double speed) {
  int ji = impl_->joint_index(id);
  if (ji == kNullIndex) return not_found("joint: unknown or destroyed joint handle");
  if (!std::isfinite(speed)) return invalid_argument("motor_speed: must be finite");
  impl_->joints[ji].motor_speed = speed;
  impl_->wake_island(impl_->joints[ji].body_a);
  impl_->wake_island(impl_->joints[ji].body_b);
  return {};
}

Result<JointState> World::joint_state(JointId id) const {
  const WorldImpl& w = *impl_;
  int ji = w.joint_index(id);
  if (ji == kNullIndex) return not_found("joint: unknown or destroyed joint handle");
  const Joint& j = w.joints[ji];
  const Body& a = w.bodies[j.body_a];
  const Body& b = w.bodies[j.body_b];
  JointState s;
  s.type = j.type;
  s.body_a = w.body_id(j.body_a);
  s.body_b = w.body_id(j.body_b);
  s.anchor_a = a.xf.apply(j.local_a);
  s.anchor_b = b.xf.apply(j.local_b);
  Vec2 d = s.anchor_b - s.anchor_a;
  s.length = length(d);
  // Impulses are per substep: force = impulse / substep.
  const double inv_h = w.settings.substeps / w.settings.dt;
  const bool line = j.type == JointType::kPrismatic || j.type == JointType::kWheel;
  Vec2 axis = line ? a.xf.q.rotate(j.local_axis) : normalize_or_zero(d);
  if (j.type == JointType::kCurve) {
    CurvePoint cp = closest_on_curve(j, s.anchor_b);
    axis = cp.normal;
    s.anchor_a = cp.closest;
    s.length = s.linear_error = std::abs(dot(cp.normal, s.anchor_b - cp.closest));
  }
  joint_reaction(j, inv_h, axis, &s.reaction_force, &s.reaction_torque);
  if (j.type == JointType::kDistance) {
    s.linear_error = std::max({0.0, j.min_length - s.length, s.length - j.max_length});
  } else if (j.type == JointType::kCurve || j.type == JointType::kSpring) {
    // Curve: set above. Spring: a force element has no error (its extension is its state).
  } else {
    s.motor_torque = inv_h * j.motor_impulse;
    s.angle = relative_angle(a.xf.q, b.xf.q, j.reference_angle);
    s.linear_error = s.length;
    if (line) {
      // length: the translation along the axis; linear error: off the line. A wheel turns
      // freely: its angle is the wheel's rotation, not an error.
      s.length = dot(axis, d);
      s.linear_error = std::abs(cross(axis, d));
      if (j.type == JointType::kPrismatic) s.angular_error = std::abs(s.angle);
      if (j.enable_limit) {
        s.linear_error =
            std::max({s.linear_error, j.lower_angle - s.length, s.length - j.upper_angle});
      }
    } else if (j.type == JointType::kTarget) {
      s.anchor_a = j.target;
      s.linear_error = length(s.anchor_b - j.target);
      s.length = s.linear_error;
      s.angle = 0.0;
    } else if (j.type == JointType::kWeld || j.type == JointType::kMotor) {
      // Motor: anchor_a is the target point (A's frame at the offset), anchor_b B's origin;
      // the errors are how far the pose lags the target.
      s.angular_error = std::abs(s.angle);
    } else if (j.enable_limit) {
      s.angular_error = std::max({0.0, j.lower_angle - s.angle, s.angle - j.upper_angle});
    }
  }
  return s;
}

}  // namespace fulcrum
