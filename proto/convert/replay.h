// Replay files (proto/fulcrum/v1/replay.proto): the initial snapshot, every edit batch with the
// tick it applied at, the state hash of every tick and a keyframe snapshot every few ticks.
// Records are length-delimited and checksummed, so a file can be read while it is written and
// a file cut off mid-write reads up to its last complete tick.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "fulcrum/status.h"
#include "fulcrum/v1/replay.pb.h"
#include "fulcrum/world.h"

namespace fulcrum {

inline constexpr uint32_t kReplayVersion = 1;
inline constexpr char kReplayFormat[] = "fulcrum.replay";

struct ReplayOptions {
  uint32_t keyframe_interval = 60;  // a full snapshot every this many ticks (0: none)
  std::string scene;                // where the world came from, for people
};

class ReplayWriter {
 public:
  // Creates (or truncates) the file and writes the header with the world as it is now.
  static Result<std::unique_ptr<ReplayWriter>> open(const std::string& path, const World& world,
                                                    const ReplayOptions& options = {});
  ~ReplayWriter();
  ReplayWriter(const ReplayWriter&) = delete;
  ReplayWriter& operator=(const ReplayWriter&) = delete;

  // Records one step: the batches applied at the boundary before it, then the world after it
  // (its hash, and a keyframe when the tick is a multiple of the interval). Flushed at once.
  Status record_tick(const World& world, const std::vector<v1::EditBatch>& batches);
  Status close();
  int64_t ticks_written() const { return ticks_; }
  // Bytes written and flushed so far: the file up to its last complete record.
  uint64_t bytes_written() const { return bytes_; }
  const std::string& path() const { return path_; }

 private:
  ReplayWriter(std::FILE* file, std::string path, uint32_t keyframe_interval);
  Status write_record(const v1::ReplayRecord& record);

  std::FILE* file_;
  std::string path_;
  uint32_t keyframe_interval_;
  int64_t ticks_ = 0;
  uint64_t bytes_ = 0;
};

struct ReplayContents {
  v1::ReplayHeader header;
  std::vector<v1::ReplayTick> ticks;
  bool truncated = false;  // the file ended inside a record (cut off mid-write)
};

// Reads a whole replay. DATA_LOSS for a damaged record (checksum, parse) or a missing header;
// FAILED_PRECONDITION for another format or version; a cut-off tail is not an error.
Result<ReplayContents> read_replay(const std::string& path);
// The same from a replay file's bytes; `path` names it in errors.
Result<ReplayContents> parse_replay(std::string_view data, const std::string& path);
// Writes contents as a replay file (used to rewrite or trim replays, and by tests).
Status write_replay(const std::string& path, const ReplayContents& contents);

struct ReplayReport {
  bool ok = false;
  int64_t ticks_checked = 0;
  int64_t final_tick = 0;
  uint64_t final_hash = 0;
  int64_t first_divergent_tick = -1;  // -1: none
  std::string detail;                 // what differs, and where
};

// Re-simulates the replay from its initial snapshot with its edits and compares every tick's
// hash and every keyframe. At the first divergence it names the tick and, from the keyframe of
// that tick (or the next one), the first record and field that differ.
Result<ReplayReport> verify_replay(const ReplayContents& replay);

}  // namespace fulcrum
