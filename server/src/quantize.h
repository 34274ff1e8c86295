// Fixed-point body states for quantized frames (frames.proto, QuantizedBodyFrame): positions in
// steps of 1/4096 m, angles in steps of 2 pi/65536 rad, velocities in steps of 1/1024 m/s and
// rad/s, each rounded to the nearest step. A body with a value that does not fit a sint32 after
// rounding (or that is not finite) is not quantized; the frame sends it at full precision.
#pragma once

#include <cstdint>

#include "fulcrum/v1/frames.pb.h"

namespace fulcrum::server {

struct BodyMotion;

inline constexpr double kPositionStep = 1.0 / 4096.0;                             // m
inline constexpr double kAngleStep = 6.283185307179586476925286766559 / 65536.0;  // rad
inline constexpr double kLinearVelocityStep = 1.0 / 1024.0;                       // m/s
inline constexpr double kAngularVelocityStep = 1.0 / 1024.0;                      // rad/s

struct QuantizedMotion {
  int32_t x = 0, y = 0;    // kPositionStep
  int32_t angle = 0;       // kAngleStep
  int32_t vx = 0, vy = 0;  // kLinearVelocityStep
  int32_t w = 0;           // kAngularVelocityStep
  bool awake = false;

  bool operator==(const QuantizedMotion&) const = default;
};

// False (and *out untouched) when some value is out of range or not finite.
bool quantize(const BodyMotion& m, QuantizedMotion* out);

void quantized_to_proto(const BodyMotion& m, const QuantizedMotion& q, v1::QuantizedBodyFrame* out);

}  // namespace fulcrum::server
