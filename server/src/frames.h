// Frames for StreamFrames: the world's motion state at one tick, captured once by the thread
// that steps the world and shared read-only by every reader, and turned into a v1::Frame per
// reader (all bodies, or only those that changed since that reader's previous frame, at full
// precision or quantized).
//
// Encoding once: a frame's bytes depend on the reader only through its skipped counts (a few
// bytes, encoded per reader and sent ahead of the shared part: protobuf merges concatenated
// messages) and, in CHANGED mode, through the frame the reader had before. Readers that keep up
// all had the same previous frame, so encode_shared() memoizes each distinct encoding on the
// frame: one encoding per (kind, precision) for readers in step, and at most one more per
// reader that fell behind (it then gets fewer frames: coalescing bounds that cost).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
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

// The encodings of one frame built so far, shared by its readers.
struct FrameMemo {
  struct Entry {
    int kind = 0;           // 0 every body, 1 changes since base_seq, 2 no bodies
    uint64_t base_seq = 0;  // kind 1
    bool quantized = false;
    bool restored = false;
    std::shared_ptr<const std::string> bytes;
  };
  std::mutex mu;
  std::vector<Entry> entries;
};

// Immutable once published (but for the memo of its encodings).
struct PublishedFrame {
  uint64_t world_id = 0;
  int64_t tick = 0;
  uint64_t state_hash = 0;
  int awake_body_count = 0;
  World::Budgets budgets;
  uint64_t epoch = 0;  // bumped by every restore: frames of different epochs are not diffed
  std::vector<BodyMotion> bodies;  // every live body, in index order
  uint64_t seq = 0;  // unique per session and increasing (0: not published; never memoized)
  std::shared_ptr<FrameMemo> memo = std::make_shared<FrameMemo>();
};

BodyMotion motion_of(BodyId id, const BodyState& state);
void motion_to_proto(const BodyMotion& m, v1::BodyFrame* out);

std::shared_ptr<const PublishedFrame> capture_frame(const World& world, uint64_t world_id,
                                                    uint64_t epoch, uint64_t seq = 0);

// What one reader is sent: `next` in full, or as the changes since `previous` (the frame this
// reader last received; null for its first frame).
void frame_to_proto(const PublishedFrame& next, const PublishedFrame* previous,
                    v1::FrameBodies mode, uint64_t skipped_frames, uint32_t every_ticks,
                    v1::Frame* out, bool quantized = false);

// The serialized frame_to_proto(next, previous, mode, 0, 1, &frame, quantized), memoized on
// `next`. *built says whether this call encoded it (false: another reader's copy was reused).
std::shared_ptr<const std::string> encode_shared(const PublishedFrame& next,
                                                 const PublishedFrame* previous,
                                                 v1::FrameBodies mode, bool quantized,
                                                 bool* built = nullptr);

// The reader's own fields of a frame, to send ahead of encode_shared()'s bytes.
std::string encode_reader_part(uint64_t skipped_frames, uint32_t every_ticks);

}  // namespace fulcrum::server
