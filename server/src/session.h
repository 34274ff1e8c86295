// The engine side of the server: a registry of worlds, each in a Session that owns the World,
// serializes access to it (one thread steps or edits it at a time) and publishes frames to its
// watchers. No gRPC here: methods return fulcrum::Status and fill plain proto messages; the RPC
// layer (physics_service) checks requests, calls these, and maps the Status to a grpc::Status.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "clock.h"
#include "frames.h"
#include "fulcrum/state.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/frames.pb.h"
#include "fulcrum/v1/service.pb.h"
#include "fulcrum/world.h"
#include "game_session.h"
#include "recorder.h"

namespace fulcrum::server {

struct Limits {
  int max_worlds = 64;             // worlds alive at once
  int max_bodies = 100000;         // live bodies per world
  int max_shapes = 400000;         // live shapes per world, chain segments included
  int max_shapes_per_body = 1024;  // shapes on one dynamic or kinematic body
  // World::edit_work one edit batch (or one scene, when a world is created) may do: about one
  // unit per shape created and per broad-phase box its wake query visits. Overlapping shapes
  // make it grow with the square of their number.
  uint64_t max_batch_work = 10000000;
  int64_t max_contacts = 500000;      // live contacts per world (World::set_contact_limit)
  uint32_t max_step_ticks = 1000000;  // ticks per Step call
  size_t max_edits = 100000;          // edits per batch
  // A stream reader whose frame has been in flight (not taken by its connection) for longer
  // than this when a newer frame is published is ended with RESOURCE_EXHAUSTED.
  int64_t max_reader_stall_ms = 10000;
  // Threads each world's step may use (World::set_threads): the same results at any count.
  int world_threads = 1;
  // ServerOptions::max_message_bytes, set by the server: a trajectory sample must fit one.
  int max_message_bytes = 64 << 20;
  // Largest snapshot RestoreSnapshotStream accepts, bytes (it is held whole while it checks).
  int64_t max_snapshot_bytes = int64_t{1} << 30;
};

// A reader of frames (the StreamFrames reactor). offer() must not block: it is called by the
// thread stepping the world and keeps only the newest frame.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual uint32_t every_ticks() const = 0;
  virtual void offer(std::shared_ptr<const PublishedFrame> frame) = 0;
  // The stream ends with this status (world deleted, server stopping).
  virtual void close(const Status& status, bool shutting_down) = 0;
};

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(uint64_t id, std::string name, World world, const Limits& limits);

  uint64_t id() const { return id_; }
  // The world now, settings included (waits while the world is being stepped).
  void info(v1::WorldInfo* out);
  // The world as of the end of its last call, without waiting for a Step in progress
  // (ListWorlds); no settings.
  void summary(v1::WorldInfo* out);

  // Long calls ask `keep_going` between edits and between ticks; a non-OK status stops them
  // (a cancelled call, a passed deadline, a server shutting down). An edit batch stopped that
  // way leaves the world as it was. A Step keeps the ticks it completed, and its reply holds
  // the tick and hash reached even when the status is not OK.
  using KeepGoing = std::function<Status()>;
  Status apply_edits(const v1::EditBatch& batch, std::optional<int64_t> expected_tick,
                     const KeepGoing& keep_going, v1::ApplyEditsReply* reply);
  Status step(uint32_t ticks, std::optional<int64_t> expected_tick, bool include_snapshot,
              const KeepGoing& keep_going, v1::StepReply* reply);
  void snapshot(v1::GetSnapshotReply* reply);
  // Every body with its shapes and every joint (waits while the world is being stepped).
  void describe(v1::DescribeWorldReply* reply);

  // StepTrajectory (trajectory.cpp): a Step in parts, so that the caller can send each part's
  // samples with the world free. The first part checks the request; each part holds the world
  // until it has gathered about `chunk_bytes` of samples, run about `part_time` of ticks, or
  // run them all, and fills `chunk` (plus chunk->done after the last tick). `progress` carries
  // the call from part to part. On an error the chunk still holds the samples of the ticks
  // that ran, and progress->reply says where the world is.
  struct TrajectoryProgress {
    bool started = false;                            // the request has been checked
    uint32_t total = 0;                              // ticks to run
    uint32_t every = 1;                              // a sample every this many ticks
    uint32_t done = 0;                               // ticks run so far
    std::vector<BodyId> bodies;                      // sampled, in the request's order
    std::chrono::steady_clock::duration stepping{};  // wall time of the ticks so far
    v1::StepReply reply;                             // the world after the last tick run
    bool finished() const { return started && done == total; }
  };
  Status step_trajectory(const v1::StepTrajectoryRequest& request, size_t chunk_bytes,
                         std::chrono::steady_clock::duration part_time, const KeepGoing& keep_going,
                         TrajectoryProgress* progress, v1::TrajectoryChunk* chunk);
  // Rollback: replaces the world with the snapshot (checked whole; unchanged on error).
  Status restore(const WorldSnapshot& records, v1::RestoreSnapshotReply* reply);
  Status query(const v1::QueryRequest& request, v1::QueryReply* reply);

  // Watchers. subscribe() never waits for the world: the first frame is delivered by whoever
  // holds the world next (at once when it is idle).
  void subscribe(std::shared_ptr<FrameSink> sink);
  void unsubscribe(const FrameSink* sink);
  // Ends every stream (world deleted or server stopping), and every stream that subscribes or
  // watches later, at once: a stream whose handler was between its checks and subscribe() while
  // this ran would otherwise wait for the shutdown's grace period to run out.
  void close_streams(const Status& status, bool shutting_down);

  // --- Real time (clock.cpp) ---
  // Sets the run mode and puts the world on the pool's clock (REAL_TIME, the schedule starting
  // now) or takes it off (PAUSED: no tick runs after the call returns).
  Status set_run_mode(RealTimePool* pool, v1::RunMode mode, std::optional<uint32_t> max_catch_up,
                      v1::SetRunModeReply* reply);
  // Marks a deleted world: off the clock for good, and SetRunMode / StartRecording calls that
  // found it before it was deleted are refused with NOT_FOUND.
  void retire();
  // One wake of the clock, on a pool thread: steps the ticks due by `now` (at most the cap,
  // dropping the rest) unless an RPC holds the world. Returns when to wake next, or nullopt
  // when the world no longer runs.
  std::optional<SteadyClock::time_point> run_due_ticks(SteadyClock::time_point now);

  // --- Multiplayer sessions (game_session.cpp) ---
  Status open_session(const v1::OpenSessionRequest& request, v1::OpenSessionReply* reply);
  Status join_session(const v1::JoinSessionRequest& request, v1::JoinSessionReply* reply);
  // What the world's scene gave each player id (Body.player, Joint.player), for a session
  // opened later.
  void set_scene_owners(std::map<uint32_t, GameSession::SceneOwned> owners);
  Status set_ownership(const v1::SetOwnershipRequest& request, v1::SetOwnershipReply* reply);
  // Holds the input for its tick; with SEAL_RULE_ALL_INPUTS and the world paused, then steps
  // every tick whose inputs are all in.
  Status send_input(const v1::SendInputRequest& request, v1::SendInputReply* reply);
  // The watcher gets the world now, then every confirmed tick (FAILED_PRECONDITION when the
  // world is not a session). As a player (id and secret checked) it marks the player present
  // until unwatch_session.
  Status watch_session(std::shared_ptr<SessionWatcher> watcher, uint32_t player_id,
                       const std::string& secret);
  void unwatch_session(const SessionWatcher* watcher, uint32_t player_id);
  // A player's state hashes for recent confirmed ticks (ReportHash): the verdict, and on a
  // desync the first tick that differs, the first field (given the player's snapshot of that
  // tick) and, when asked, a fresh start on the player's watches. Counted and logged.
  Status report_hash(const v1::ReportHashRequest& request, v1::ReportHashReply* reply);

  // --- Replays on the server (recorder.cpp) ---
  Status start_recording(ReplayStore* store, std::optional<uint32_t> keyframe_interval,
                         v1::StartRecordingReply* reply);
  // FAILED_PRECONDITION when the world is not recording.
  Status stop_recording(v1::StopRecordingReply* reply);
  // The current recording (up to its last complete tick) or the last one; NOT_FOUND if none.
  Result<ReplayFileRef> replay_file();
  // Closes an open recording (world deleted, server stopping).
  void close_recording();

 private:
  struct Watcher {
    std::weak_ptr<FrameSink> sink;
    const FrameSink* key = nullptr;
    uint32_t every = 1;
    bool needs_first = true;  // has not received any frame yet
  };

  // Holds the world; on release, delivers first frames that arrived meanwhile (see
  // deliver_first_frames). Every holder of mu_ but deliver_first_frames goes through it.
  class Hold {
   public:
    explicit Hold(Session* s) : s_(s) { s_->mu_.lock(); }
    ~Hold() {
      s_->mu_.unlock();
      s_->deliver_first_frames();
    }
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

   private:
    Session* s_;
  };

  // Called with mu_ held, after a tick: offers a frame to watchers due at this tick.
  void publish_tick_locked();
  // Called with mu_ held after a change that is not a step (edit, restore), or at the end of a
  // Step: every watcher gets the world as it now is.
  void publish_all_locked();
  // Gives waiting watchers their first frame if the world is free; see subscribe().
  void deliver_first_frames();

  // Copies tick, hash and counts into summary_; called with mu_ held at the end of every change.
  void refresh_summary_locked(uint64_t state_hash);
  // One tick with mu_ held: step, record, publish. A tick the contact limit refuses does not
  // run (RESOURCE_EXHAUSTED, the world unchanged).
  Status tick_locked();
  // The run mode, clock counters and recording state (WorldInfo.run, .recording).
  void runtime_to_proto_locked(v1::WorldInfo* out) const;
  // Closes the recording after a failed write, keeping the error for WorldInfo.
  void end_recording_locked(const std::string& error);
  // A session's part of a tick, with mu_ held: seals the tick's inputs and applies the
  // players' batches (one the world refuses is dropped and its player counted missing).
  GameSession::Sealed seal_inputs_locked();
  // SEAL_RULE_ALL_INPUTS on a paused world: steps every tick whose inputs are all in.
  void step_complete_ticks_locked();
  // Offers a fresh start (resync) to every watch open as the player; fills reply's resync.
  void resync_player_locked(uint32_t player_id, v1::ReportHashReply* reply);

  const uint64_t id_;
  const std::string name_;
  const Limits limits_;

  std::mutex mu_;  // guards world_, epoch_, frame_seq_, clock_ and the recording; held for a
                   // whole Step
  World world_;
  uint64_t epoch_ = 0;
  uint64_t frame_seq_ = 0;  // the last PublishedFrame::seq issued
  RealTimeClock clock_;
  bool retired_ = false;                // deleted from the registry
  std::unique_ptr<Recorder> recorder_;  // open recording, or null
  ReplayFileRef last_replay_;           // the last closed recording (name empty: none)
  int64_t last_replay_start_tick_ = 0;
  int64_t last_replay_ticks_ = 0;
  std::string recording_error_;
  std::unique_ptr<GameSession> game_;  // set once by OpenSession; guarded by mu_
  std::map<uint32_t, GameSession::SceneOwned> scene_owners_;  // from the scene; guarded by mu_
  std::mutex run_mode_mu_;                        // one SetRunMode at a time (taken before mu_)
  std::atomic<int64_t> busy_retries_pending_{0};  // wakes that found the world held

  std::mutex summary_mu_;  // guards summary_ (never held with another lock taken after it)
  v1::WorldInfo summary_;  // without settings or watchers

  std::mutex watchers_mu_;  // guards watchers_ and closed_; taken after mu_ when both are held
  std::vector<Watcher> watchers_;
  struct Closed {
    Status status;
    bool shutting_down = false;
  };
  std::optional<Closed> closed_;  // set by close_streams
  std::atomic<bool> any_need_first_{false};

  // WatchSession streams; taken after mu_ when both are held.
  std::mutex session_watchers_mu_;
  std::vector<std::weak_ptr<SessionWatcher>> session_watchers_;
  std::optional<Status> session_watchers_closed_;  // set by close_streams
};

// FAILED_PRECONDITION naming the world's tick when `expected` is set and differs from it.
Status check_expected_tick(std::optional<int64_t> expected, int64_t tick);

// Unwraps and checks a snapshot file and the body limit, before any world is touched.
Result<WorldSnapshot> decode_snapshot(const v1::SnapshotFile& file, const Limits& limits);

class Registry {
 public:
  explicit Registry(const Limits& limits) : limits_(limits) {}

  const Limits& limits() const { return limits_; }
  // The real-time pool and the replay directory (server.cpp sets them before serving).
  void attach(RealTimePool* pool, ReplayStore* replays) {
    pool_ = pool;
    replays_ = replays;
  }
  RealTimePool* pool() const { return pool_; }
  ReplayStore* replays() const { return replays_; }
  // Checks the body limit, then adds the world (RESOURCE_EXHAUSTED when full).
  Result<std::shared_ptr<Session>> create(std::string name, World world);
  // NOT_FOUND naming `field` when there is no such world.
  Result<std::shared_ptr<Session>> find(uint64_t id, const char* field = "world_id") const;
  Status remove(uint64_t id);
  std::vector<std::shared_ptr<Session>> list() const;
  // Ends every stream of every world (shutdown).
  void close_all_streams(const Status& status);
  // Closes every open recording (shutdown).
  void close_all_recordings();

 private:
  const Limits limits_;
  RealTimePool* pool_ = nullptr;
  ReplayStore* replays_ = nullptr;
  mutable std::mutex mu_;
  std::map<uint64_t, std::shared_ptr<Session>> worlds_;
  uint64_t next_id_ = 1;
};

}  // namespace fulcrum::server
