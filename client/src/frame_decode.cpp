#include "frame_decode.h"

#include <algorithm>

namespace fulcrum::client {

namespace {

BodyId body_id(const v1::Handle& h) {
  BodyId id;
  id.index = h.index();
  id.generation = h.generation();
  return id;
}

// frames.proto, QuantizedBodyFrame.
constexpr double kPositionStep = 1.0 / 4096.0;                             // m
constexpr double kAngleStep = 6.283185307179586476925286766559 / 65536.0;  // rad
constexpr double kVelocityStep = 1.0 / 1024.0;                             // m/s and rad/s

}  // namespace

BodyFrame body_frame_from(const v1::BodyFrame& b) {
  BodyFrame m;
  m.id = body_id(b.body());
  m.position = Vec2(b.position().x(), b.position().y());
  m.angle = b.angle();
  m.linear_velocity = Vec2(b.linear_velocity().x(), b.linear_velocity().y());
  m.angular_velocity = b.angular_velocity();
  m.awake = b.awake();
  return m;
}

Frame frame_from(const v1::Frame& f) {
  Frame out;
  out.world_id = f.world_id();
  out.tick = f.tick();
  out.state_hash = f.state_hash();
  out.skipped_frames = f.skipped_frames();
  out.skipped_ticks = f.skipped_ticks();
  out.body_count = f.body_count();
  out.awake_body_count = f.awake_body_count();
  out.full = f.full();
  out.restored = f.restored();
  out.bodies.reserve(f.bodies_size() + f.quantized_bodies_size());
  for (const v1::QuantizedBodyFrame& q : f.quantized_bodies()) {
    BodyFrame m;
    m.id.index = q.index();
    m.id.generation = q.generation();
    m.position = Vec2(q.x() * kPositionStep, q.y() * kPositionStep);
    m.angle = q.angle() * kAngleStep;
    m.linear_velocity = Vec2(q.vx() * kVelocityStep, q.vy() * kVelocityStep);
    m.angular_velocity = q.angular_velocity() * kVelocityStep;
    m.awake = q.awake();
    m.quantized = true;
    out.bodies.push_back(m);
  }
  for (const v1::BodyFrame& b : f.bodies()) out.bodies.push_back(body_frame_from(b));
  // Quantized bodies and full-precision fallbacks come in two lists: one index order.
  if (f.quantized_bodies_size() > 0 && f.bodies_size() > 0) {
    std::stable_sort(
        out.bodies.begin(), out.bodies.end(),
        [](const BodyFrame& a, const BodyFrame& b) { return a.id.index < b.id.index; });
  }
  for (const v1::Handle& h : f.destroyed()) out.destroyed.push_back(body_id(h));
  out.message_bytes = f.ByteSizeLong();
  return out;
}

}  // namespace fulcrum::client
