#include "recorder.h"

#include <filesystem>

#include "session.h"
#include "stats.h"

namespace fulcrum::server {

Result<std::string> ReplayStore::new_name(uint64_t world_id) {
  if (!enabled()) {
    return Status(StatusCode::kFailedPrecondition,
                  "recording is off on this server: start fulcrum-server with --replay-dir DIR");
  }
  std::lock_guard<std::mutex> lock(mu_);
  for (;; ++next_) {
    std::string name = "world" + std::to_string(world_id) + "-" + std::to_string(next_) + ".replay";
    std::error_code ec;
    if (!std::filesystem::exists(path_of(name), ec)) {
      ++next_;
      return name;
    }
  }
}

Status ReplayStore::check_name(const std::string& name) {
  if (name.empty() || name.size() > 128 || name[0] == '.') {
    return invalid_argument("name: a replay name from StartRecording (got '" + name + "')");
  }
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '-' || c == '_';
    if (!ok) {
      return invalid_argument("name: only letters, digits, '.', '-' and '_' (got '" + name + "')");
    }
  }
  return {};
}

Result<std::unique_ptr<Recorder>> Recorder::start(ReplayStore* store, uint64_t world_id,
                                                  const World& world, uint32_t keyframe_interval,
                                                  const std::string& scene) {
  Result<std::string> name = store->new_name(world_id);
  if (!name.ok()) return name.status();
  ReplayOptions options;
  options.keyframe_interval = keyframe_interval;
  options.scene = scene;
  auto writer = ReplayWriter::open(store->path_of(*name), world, options);
  if (!writer.ok()) {
    return Status(writer.status().code(),
                  "the recording could not start: " + writer.status().message());
  }
  std::unique_ptr<Recorder> r(new Recorder());
  r->name_ = std::move(name).value();
  r->start_tick_ = world.tick();
  r->writer_ = std::move(writer).value();
  return r;
}

Status Recorder::after_tick(const World& world) {
  Status st = writer_->record_tick(world, batches_);
  batches_.clear();
  return st;
}

Status Recorder::stop() {
  batches_.clear();
  return writer_->close();
}

// --- Session: recording ----------------------------------------------------------------------

Status Session::start_recording(ReplayStore* store, std::optional<uint32_t> keyframe_interval,
                                v1::StartRecordingReply* reply) {
  if (store == nullptr || !store->enabled()) {
    return Status(StatusCode::kFailedPrecondition,
                  "recording is off on this server: start fulcrum-server with --replay-dir DIR");
  }
  Hold hold(this);
  if (recorder_) {
    return Status(StatusCode::kFailedPrecondition,
                  "world " + std::to_string(id_) + " is already recording " + recorder_->name());
  }
  auto recorder = Recorder::start(store, id_, world_, keyframe_interval.value_or(60),
                                  "server world " + std::to_string(id_) + " (" + name_ + ")");
  if (!recorder.ok()) {
    // The server's disk, not the request: reported where a failed recording is (the log,
    // recordings_failed, WorldInfo.recording.error) as well as to the caller.
    recording_error_ = recorder.status().message();
    ++counters().recordings_failed;
    log_event("recording_failed", {{"world", id_}, {"error", recording_error_}});
    refresh_summary_locked(world_.state_hash());
    return recorder.status();
  }
  recorder_ = std::move(recorder).value();
  recording_error_.clear();
  ++counters().recordings_started;
  log_event("recording_started",
            {{"world", id_}, {"replay", recorder_->name()}, {"tick", world_.tick()}});
  reply->set_name(recorder_->name());
  reply->set_tick(world_.tick());
  refresh_summary_locked(world_.state_hash());
  return {};
}

void Session::end_recording_locked(const std::string& error) {
  if (!recorder_) return;
  last_replay_ = recorder_->file();
  last_replay_start_tick_ = recorder_->start_tick();
  last_replay_ticks_ = recorder_->ticks();
  Status closed = recorder_->stop();
  recorder_.reset();
  recording_error_ = !error.empty() ? error : closed.ok() ? std::string() : closed.message();
  if (!recording_error_.empty()) ++counters().recordings_failed;
  log_event("recording_closed", {{"world", id_},
                                 {"replay", last_replay_.name},
                                 {"ticks", last_replay_ticks_},
                                 {"bytes", last_replay_.bytes},
                                 {"error", recording_error_}});
}

Status Session::stop_recording(v1::StopRecordingReply* reply) {
  Hold hold(this);
  if (!recorder_) {
    return Status(StatusCode::kFailedPrecondition,
                  "world " + std::to_string(id_) + " is not recording");
  }
  end_recording_locked("");
  reply->set_name(last_replay_.name);
  reply->set_ticks(last_replay_ticks_);
  reply->set_bytes(last_replay_.bytes);
  refresh_summary_locked(world_.state_hash());
  if (!recording_error_.empty()) return Status(StatusCode::kInternal, recording_error_);
  return {};
}

Result<ReplayFileRef> Session::replay_file() {
  Hold hold(this);
  if (recorder_) return recorder_->file();
  if (last_replay_.name.empty()) {
    return not_found("world_id: world " + std::to_string(id_) + " has no recording");
  }
  return last_replay_;
}

void Session::close_recording() {
  Hold hold(this);
  end_recording_locked("");
}

}  // namespace fulcrum::server
