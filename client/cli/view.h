// fulcrum view: a page in the browser that draws a world. view.cpp serves it over HTTP
// (cpp-httplib) and speaks to a fulcrum-server; view_replay.cpp plays a replay file locally.
// Both hand the page the same JSON: a description (shapes, from DescribeWorld) and frames
// (body poses).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "fulcrum/client.h"
#include "fulcrum/state.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/describe.pb.h"
#include "fulcrum/world.h"
#include "replay.h"

namespace fulcrum::cli {

// Protobuf JSON of the description (every field, lowerCamelCase names).
std::string description_json(const v1::DescribeWorldReply& reply);

// One frame as the page reads it:
//   {"tick":N,"hash":"16 hex","bodies":B,"awake":A,"full":true|false,
//    "destroyed":[[index,generation],...],
//    "b":[[index,generation,x,y,angle,awake 0|1],...], ...extra}
// `extra` is appended inside the object as written (",\"k\":v" pairs) when not empty.
struct FrameJson {
  int64_t tick = 0;
  uint64_t hash = 0;
  int body_count = 0;
  int awake_count = 0;
  bool full = false;
  std::vector<BodyId> destroyed;
  std::vector<client::BodyFrame> bodies;
  std::string extra;
};
std::string frame_json(const FrameJson& frame);
// A JSON string literal.
std::string json_string(const std::string& text);
// A double in the shortest form that parses back to the same bits (null when not finite).
std::string json_number(double value);

// A replay file stepped locally: the page seeks to any tick. The world is re-stepped from the
// replay's initial snapshot once when the file is opened, keeping a snapshot every
// kCheckpointTicks ticks and every tick's re-stepped hash; a seek restores the nearest
// checkpoint at or before the tick and steps forward from there (or steps on from the current
// tick when that is nearer). Calls are serialized by the player's own lock.
class ReplayPlayer {
 public:
  static constexpr int64_t kCheckpointTicks = 60;

  static Result<std::unique_ptr<ReplayPlayer>> open(const std::string& path);

  // {"path":..,"scene":..,"startTick":..,"endTick":..,"ticks":..,"ok":bool,
  //  "firstDivergentTick":N|null,"detail":".."}
  std::string info_json() const;
  // The world at `tick` (clamped to the replay's range): every body, plus "recordedHash" (the
  // file's hash of that tick, "" at the start) and "diverged" (the re-stepped hash differs).
  std::string frame_json_at(int64_t tick);
  // The description of the world at the tick of the last frame.
  std::string describe_json();

 private:
  ReplayPlayer() = default;
  // Moves world_ to `tick` within [start_tick_, end_tick_].
  void seek(int64_t tick);
  // Applies the edits recorded before tick world_.tick() + 1, then steps.
  void step_once();

  std::string path_;
  ReplayContents replay_;
  int64_t start_tick_ = 0;
  int64_t end_tick_ = 0;
  std::vector<WorldSnapshot> checkpoints_;  // checkpoints_[k]: tick start + k * kCheckpointTicks
  std::vector<uint64_t> restepped_hashes_;  // [t - start]: the hash of tick t, re-stepped
  int64_t first_divergent_tick_ = -1;
  std::string detail_;

  std::mutex mu_;
  World world_;
};

}  // namespace fulcrum::cli
