#include "quantize.h"

#include <cmath>

#include "frames.h"

namespace fulcrum::server {

namespace {

// Rounds value / step to the nearest integer (std::round: ties away from zero) if it fits an
// int32; the error is then at most step / 2 (plus the rounding of the division, ~1e-16 of it).
bool to_units(double value, double step, int32_t* out) {
  if (!std::isfinite(value)) return false;
  const double units = std::round(value / step);
  if (units < -2147483647.0 || units > 2147483647.0) return false;
  *out = static_cast<int32_t>(units);
  return true;
}

}  // namespace

bool quantize(const BodyMotion& m, QuantizedMotion* out) {
  QuantizedMotion q;
  if (!to_units(m.position.x(), kPositionStep, &q.x) ||
      !to_units(m.position.y(), kPositionStep, &q.y) || !to_units(m.angle, kAngleStep, &q.angle) ||
      !to_units(m.linear_velocity.x(), kLinearVelocityStep, &q.vx) ||
      !to_units(m.linear_velocity.y(), kLinearVelocityStep, &q.vy) ||
      !to_units(m.angular_velocity, kAngularVelocityStep, &q.w)) {
    return false;
  }
  q.awake = m.awake;
  *out = q;
  return true;
}

void quantized_to_proto(const BodyMotion& m, const QuantizedMotion& q,
                        v1::QuantizedBodyFrame* out) {
  out->set_index(m.id.index);
  out->set_generation(m.id.generation);
  out->set_x(q.x);
  out->set_y(q.y);
  out->set_angle(q.angle);
  out->set_vx(q.vx);
  out->set_vy(q.vy);
  out->set_angular_velocity(q.w);
  out->set_awake(q.awake);
}

}  // namespace fulcrum::server
