#include "fulcrum/types.h"

#include <string>

#include "validation.h"

namespace fulcrum {

const char* body_type_name(BodyType type) {
  switch (type) {
    case BodyType::kStatic:
      return "static";
    case BodyType::kKinematic:
      return "kinematic";
    case BodyType::kDynamic:
      return "dynamic";
    case BodyType::kParticle:
      return "particle";
  }
  return "unknown";
}

Status validate_settings(const WorldSettings& s) {
  FULCRUM_RETURN_IF_ERROR(check_finite("settings.gravity", s.gravity));
  FULCRUM_RETURN_IF_ERROR(check_above("settings.dt", s.dt, 0.0));
  if (s.substeps < 1 || s.substeps > 1000) {
    return invalid_argument("settings.substeps: must be in [1, 1000] (got " +
                            std::to_string(s.substeps) + ")");
  }
  if (s.relax_iterations < 0 || s.relax_iterations > 1000) {
    return invalid_argument("settings.relax_iterations: must be in [0, 1000] (got " +
                            std::to_string(s.relax_iterations) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_in_range("settings.contact_hertz", s.contact_hertz, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.contact_damping_ratio", s.contact_damping_ratio, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(check_in_range("settings.joint_hertz", s.joint_hertz, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.joint_damping_ratio", s.joint_damping_ratio, 0.0, 1e6));
  if (s.max_substeps < 1 || s.max_substeps > 1000) {
    return invalid_argument("settings.max_substeps: must be in [1, 1000] (got " +
                            std::to_string(s.max_substeps) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(
      check_above("settings.joint_give_tolerance", s.joint_give_tolerance, 0.0));
  FULCRUM_RETURN_IF_ERROR(
      check_above("settings.contact_give_tolerance", s.contact_give_tolerance, 0.0));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.one_pass_give_tolerance", s.one_pass_give_tolerance, 0.0, 1e6));
  if (s.velocity_iterations < 1 || s.velocity_iterations > 1000) {
    return invalid_argument("settings.velocity_iterations: must be in [1, 1000] (got " +
                            std::to_string(s.velocity_iterations) + ")");
  }
  if (s.position_iterations < 0 || s.position_iterations > 1000) {
    return invalid_argument("settings.position_iterations: must be in [0, 1000] (got " +
                            std::to_string(s.position_iterations) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_in_range("settings.baumgarte", s.baumgarte, 0.0, 1.0));
  FULCRUM_RETURN_IF_ERROR(check_in_range("settings.linear_slop", s.linear_slop, 0.0, 1.0));
  FULCRUM_RETURN_IF_ERROR(
      check_above("settings.max_correction_speed", s.max_correction_speed, 0.0));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.restitution_threshold", s.restitution_threshold, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.early_exit_tolerance", s.early_exit_tolerance, 0.0, 1e30));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.speculative_distance", s.speculative_distance, 0.0, 10.0));
  FULCRUM_RETURN_IF_ERROR(check_in_range("settings.aabb_margin", s.aabb_margin, 0.0, 100.0));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.manifold_reuse_distance", s.manifold_reuse_distance, 0.0, 1.0));
  FULCRUM_RETURN_IF_ERROR(check_above("settings.max_linear_speed", s.max_linear_speed, 0.0));
  FULCRUM_RETURN_IF_ERROR(check_above("settings.time_to_sleep", s.time_to_sleep, 0.0));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.linear_sleep_tolerance", s.linear_sleep_tolerance, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(
      check_in_range("settings.angular_sleep_tolerance", s.angular_sleep_tolerance, 0.0, 1e6));
  return {};
}

Status validate_body_def(const BodyDef& d) {
  if (static_cast<int>(d.type) > 3) {
    return invalid_argument("body.type: unknown body type " +
                            std::to_string(static_cast<int>(d.type)));
  }
  FULCRUM_RETURN_IF_ERROR(check_finite("body.position", d.position));
  FULCRUM_RETURN_IF_ERROR(check_finite("body.angle", d.angle));
  FULCRUM_RETURN_IF_ERROR(check_finite("body.linear_velocity", d.linear_velocity));
  FULCRUM_RETURN_IF_ERROR(check_finite("body.angular_velocity", d.angular_velocity));
  FULCRUM_RETURN_IF_ERROR(check_in_range("body.linear_damping", d.linear_damping, 0.0, 1e9));
  FULCRUM_RETURN_IF_ERROR(check_in_range("body.angular_damping", d.angular_damping, 0.0, 1e9));
  FULCRUM_RETURN_IF_ERROR(check_finite("body.gravity_scale", d.gravity_scale));
  FULCRUM_RETURN_IF_ERROR(check_in_range("body.drag", d.drag, 0.0, 1e12));
  FULCRUM_RETURN_IF_ERROR(check_finite("body.constant_force", d.constant_force));
  FULCRUM_RETURN_IF_ERROR(check_finite("body.constant_torque", d.constant_torque));
  return {};
}

Status validate_attractor(const AttractorDef& d, const std::string& field) {
  FULCRUM_RETURN_IF_ERROR(check_finite(field + ".point", d.point));
  FULCRUM_RETURN_IF_ERROR(check_finite(field + ".strength", d.strength));
  if (static_cast<int>(d.falloff) < 0 || static_cast<int>(d.falloff) > 1) {
    return invalid_argument(field + ".falloff: unknown falloff " +
                            std::to_string(static_cast<int>(d.falloff)));
  }
  FULCRUM_RETURN_IF_ERROR(check_finite(field + ".min_distance", d.min_distance));
  FULCRUM_RETURN_IF_ERROR(check_above(field + ".min_distance", d.min_distance, 0.0));
  return {};
}

Status validate_shape_def(const ShapeDef& d) {
  FULCRUM_RETURN_IF_ERROR(validate_geometry(d.geometry, "shape"));
  FULCRUM_RETURN_IF_ERROR(check_in_range("shape.density", d.density, 0.0, 1e12));
  // 0 is a massless shape; a positive density below 1e-12 gives masses whose inverses overflow
  // (a density of 5e-322 made a body's inverse mass infinite; found by fuzzing).
  if (d.density != 0.0 && d.density < 1e-12) {
    return invalid_argument("shape.density: must be 0 or at least 1e-12 (got " +
                            format_number(d.density) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_in_range("shape.friction", d.friction, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(check_in_range("shape.restitution", d.restitution, 0.0, 1e3));
  return {};
}

Status validate_chain_def(const ChainDef& d) {
  size_t min_points = d.loop ? 3 : 2;
  if (d.points.size() < min_points) {
    return invalid_argument("chain.points: needs at least " + std::to_string(min_points) +
                            " points (got " + std::to_string(d.points.size()) + ")");
  }
  for (size_t i = 0; i < d.points.size(); ++i) {
    std::string field = "chain.points[" + std::to_string(i) + "]";
    FULCRUM_RETURN_IF_ERROR(check_finite(field, d.points[i]));
    size_t j = i + 1 < d.points.size() ? i + 1 : 0;
    if (j == 0 && !d.loop) break;
    if (distance(d.points[i], d.points[j]) <= kGeometryTolerance) {
      return invalid_argument(field +
                              ": coincides with the next point (segments must be longer than " +
                              format_number(kGeometryTolerance) + " m)");
    }
  }
  FULCRUM_RETURN_IF_ERROR(check_in_range("chain.friction", d.friction, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(check_in_range("chain.restitution", d.restitution, 0.0, 1e3));
  return {};
}

}  // namespace fulcrum
