// Frames for StreamFrames: the world's motion state at one tick, captured once by the thread
// that steps the world and shared read-only by every reader, and turned into a v1::Frame per
// reader (all bodies, or only those that changed since that reader's previous frame).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "fulcrum/v1/frames.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::server {

struct BodyMotion {
  BodyId id;
  Vec2 position = Vec2::Zero();         // body origin, m
  double angle = 0.0;                   // rad
  Vec2 linear_velocity = Vec2::Zero();  // m/s
  double angular_velocity = 0.0;        // rad/s
  bool awake = false;
};

// Immutable once published.
struct PublishedFrame {
  uint64_t world_id = 0;
  int64_t tick = 0;
  uint64_t state_hash = 0;
  int awake_body_count = 0;
  uint64_t epoch = 0;  // bumped by every restore: frames of different epochs are not diffed
  std::vector<BodyMotion> bodies;  // every live body, in index order
};

std::shared_ptr<const PublishedFrame> capture_frame(const World& world, uint64_t world_id,
                                                    uint64_t epoch);

// What one reader is sent: `next` in full, or as the changes since `previous` (the frame this
// reader last received; null for its first frame).
void frame_to_proto(const PublishedFrame& next, const PublishedFrame* previous,
                    v1::FrameBodies mode, uint64_t skipped_frames, uint32_t every_ticks,
                    v1::Frame* out);

}  // namespace fulcrum::server
