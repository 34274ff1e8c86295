// Replays recorded on the server (--replay-dir): where the files live and how they are named
// (ReplayStore), and the open recording of one world (Recorder). File names are chosen here,
// never by clients: "world<ID>-<N>.replay", N counting up past any file already in the
// directory; a name a client sends is checked against that alphabet before it touches a path.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "fulcrum/status.h"
#include "fulcrum/v1/edit.pb.h"
#include "fulcrum/world.h"
#include "replay.h"

namespace fulcrum::server {

class ReplayStore {
 public:
  // An empty dir turns recording off (StartRecording is FAILED_PRECONDITION).
  explicit ReplayStore(std::string dir) : dir_(std::move(dir)) {}

  bool enabled() const { return !dir_.empty(); }
  const std::string& dir() const { return dir_; }
  // A name no file in the directory has yet, and its path.
  Result<std::string> new_name(uint64_t world_id);
  std::string path_of(const std::string& name) const { return dir_ + "/" + name; }
  // INVALID_ARGUMENT unless `name` is letters, digits, '.', '-', '_', not starting with '.',
  // at most 128 characters: nothing a client sends can leave the directory.
  static Status check_name(const std::string& name);

 private:
  const std::string dir_;
  std::mutex mu_;
  uint64_t next_ = 1;
};

// A finished or growing replay file: what DownloadReplay sends.
struct ReplayFileRef {
  std::string name;
  std::string path;
  uint64_t bytes = 0;  // up to the last complete tick
};

// One world's open replay. Used with the world's lock held: note_batch() after each ApplyEdits
// batch, after_tick() after each step.
class Recorder {
 public:
  static Result<std::unique_ptr<Recorder>> start(ReplayStore* store, uint64_t world_id,
                                                 const World& world, uint32_t keyframe_interval,
                                                 const std::string& scene);

  void note_batch(const v1::EditBatch& batch) { batches_.push_back(batch); }
  // Writes the tick's record (the batches noted since the last one, the hash, a keyframe when
  // due) and flushes it.
  Status after_tick(const World& world);
  // Closes the file. Batches noted after the last tick are not in it: a replay ends at a tick.
  Status stop();

  const std::string& name() const { return name_; }
  int64_t start_tick() const { return start_tick_; }
  int64_t ticks() const { return writer_->ticks_written(); }
  ReplayFileRef file() const { return {name_, writer_->path(), writer_->bytes_written()}; }

 private:
  Recorder() = default;

  std::string name_;
  int64_t start_tick_ = 0;
  std::unique_ptr<ReplayWriter> writer_;
  std::vector<v1::EditBatch> batches_;
};

}  // namespace fulcrum::server
