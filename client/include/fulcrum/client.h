// fulcrum_client: a C++ client of the Physics service (proto/fulcrum/v1/service.proto) that
// shows no gRPC types. Every call returns a Result or Status; a server error keeps the
// server's code and message (e.g. NOT_FOUND "world_id: no world 7"). Unary calls carry a
// deadline (ClientOptions::deadline).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/describe.pb.h"
#include "fulcrum/v1/edit.pb.h"
#include "fulcrum/v1/session.pb.h"
#include "fulcrum/v1/stats.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::client {

struct ClientOptions {
  std::string address = "127.0.0.1:50051";    // HOST:PORT
  std::string token;                          // bearer token; empty: none sent
  std::chrono::milliseconds deadline{30000};  // per unary call
  // TLS (a server started with --tls-cert). tls_ca_pem: PEM root certificate(s) that signed the
  // server's certificate; empty: the system's roots. tls_target_name: the name to check the
  // certificate against instead of the host in `address` (e.g. "localhost").
  bool tls = false;
  std::string tls_ca_pem;
  std::string tls_target_name;
};

// Server errors keep their code where the engine's StatusCode has it; others (UNAUTHENTICATED,
// UNAVAILABLE, DEADLINE_EXCEEDED, ...) come back as kInternal with the gRPC code name leading
// the message ("UNAVAILABLE: failed to connect to all addresses").

enum class RunMode { kPaused, kRealTime };

// A world's real-time clock (fulcrum.v1.RealTimeInfo): counters of the current run.
struct RealTimeInfo {
  RunMode mode = RunMode::kPaused;
  double dt = 0.0;                   // s: the clock's period (the world's tick length)
  uint32_t max_catch_up_ticks = 0;   // ticks per wake, at most
  int64_t start_tick = 0;            // the tick the run started from
  int64_t ticks_run = 0;             // ticks stepped by the clock in this run
  int64_t ticks_dropped = 0;         // due ticks skipped because the server fell behind
  int64_t late_wakes = 0;            // wakes with more ticks due than the cap
  int64_t wakes = 0;                 // wakes that stepped at least one tick
  uint32_t max_ticks_in_a_wake = 0;  // <= max_catch_up_ticks
  int64_t busy_retries = 0;          // wakes put off while an RPC held the world
};

// A world's replay recording on the server (fulcrum.v1.RecordingInfo).
struct RecordingInfo {
  bool active = false;  // recording now
  std::string name;     // the current or last recording; empty: none
  int64_t start_tick = 0;
  int64_t ticks = 0;   // ticks recorded
  uint64_t bytes = 0;  // file size up to the last complete tick
  std::string error;   // why a recording stopped early
};

struct WorldSummary {
  uint64_t id = 0;
  std::string name;
  int64_t tick = 0;
  int body_count = 0;
  int awake_body_count = 0;
  int contact_count = 0;
  uint64_t state_hash = 0;
  uint32_t watchers = 0;
  RealTimeInfo run;
  RecordingInfo recording;
  // From create_world and create_world_json only: the scene's bodies and joints in its order
  // (bodies[i] is the scene's i-th body). Empty in every other summary.
  std::vector<BodyId> bodies;
  std::vector<JointId> joints;
};

struct RunModeResult {
  RunMode mode = RunMode::kPaused;
  // Real time: the tick the clock starts from; paused: the tick the world stopped at.
  int64_t tick = 0;
};

struct RecordingResult {
  std::string name;    // the replay's name on the server
  int64_t tick = 0;    // start: the tick of the header snapshot
  int64_t ticks = 0;   // stop: ticks in the file
  uint64_t bytes = 0;  // stop: file size
};

struct DownloadResult {
  std::string name;
  uint64_t bytes = 0;     // received, equal to the server's total_size
  uint64_t checksum = 0;  // FNV-1a 64 of the bytes, checked against the server's
};

struct StepResult {
  int64_t tick = 0;
  uint64_t state_hash = 0;
  int awake_body_count = 0;
  double step_ms = 0.0;  // server wall time of the steps
  std::string snapshot;  // serialized SnapshotFile when asked for; else empty
};

struct EditResult {
  int64_t tick = 0;  // the tick boundary the batch applied at
  uint64_t state_hash = 0;
  std::vector<BodyId> bodies;
  std::vector<ShapeId> shapes;
  std::vector<JointId> joints;
};

struct SnapshotResult {
  int64_t tick = 0;
  uint64_t state_hash = 0;
  std::string bytes;  // serialized SnapshotFile (restore_encoded and `snapshot restore` read it)
};

struct RestoreResult {
  uint64_t world_id = 0;
  int64_t tick = 0;
  uint64_t state_hash = 0;
};

struct BodyFrame {
  BodyId id;
  Vec2 position = Vec2::Zero();  // m
  double angle = 0.0;            // rad
  Vec2 linear_velocity = Vec2::Zero();
  double angular_velocity = 0.0;
  bool awake = false;
  // Decoded from a quantized frame: within frames.proto's bounds of the exact state (position
  // 1/8192 m, angle pi/65536 rad, velocities 1/2048 m/s and rad/s). False: exact.
  bool quantized = false;
};

struct Frame {
  uint64_t world_id = 0;
  int64_t tick = 0;
  uint64_t state_hash = 0;
  uint64_t skipped_frames = 0;  // coalesced away since the previous frame
  int64_t skipped_ticks = 0;
  int body_count = 0;
  int awake_body_count = 0;
  bool full = false;      // `bodies` lists every live body
  bool restored = false;  // the world was restored since the previous frame
  std::vector<BodyFrame> bodies;
  std::vector<BodyId> destroyed;
  size_t message_bytes = 0;  // the frame's protobuf encoding as received (gRPC framing aside)
};

// StepTrajectory: a Step that streams every sample of the bodies named (service.proto).
struct TrajectoryOptions {
  uint32_t ticks = 1;
  uint32_t every_ticks = 1;              // a sample after ticks k, 2k, 3k ... of the call
  std::vector<BodyId> bodies;            // sampled in this order; empty: every live body
  bool include_start = false;            // also a sample before the first tick
  std::optional<int64_t> expected_tick;  // as for step()
};

struct TrajectorySample {
  int64_t tick = 0;
  uint64_t state_hash = 0;
  std::vector<BodyFrame> bodies;  // exact states, in the order the options name the bodies
};

enum class FrameBodies { kAll, kChanged, kNone };

struct SubscribeOptions {
  uint32_t every_ticks = 1;
  FrameBodies bodies = FrameBodies::kChanged;
  bool quantized = false;  // fixed-point body states (frames.proto, QuantizedBodyFrame)
};

// An open StreamFrames call. The callback runs on the subscription's own thread, one frame at
// a time; while it runs, newer frames are coalesced on the server.
class Subscription {
 public:
  virtual ~Subscription() = default;
  // Ends the stream (the callback is not called after cancel returns).
  virtual void cancel() = 0;
  // Blocks until the stream ends; returns how (OK, NOT_FOUND when the world was deleted, ...).
  virtual Status wait() = 0;
};

struct ShapeHit {
  ShapeId shape;
  BodyId body;
};

struct RayCastHit {
  ShapeId shape;
  BodyId body;
  Vec2 point = Vec2::Zero();   // world, m
  Vec2 normal = Vec2::Zero();  // world unit surface normal
  double fraction = 0.0;       // along the translation, [0, 1]
};

class Client {
 public:
  // Opens a channel (lazily: a server that is down shows up on the first call).
  static std::unique_ptr<Client> connect(const ClientOptions& options);
  virtual ~Client() = default;

  virtual Result<WorldSummary> create_world(const SceneDef& scene, std::string_view name = {}) = 0;
  // A scene file's text (Protobuf JSON of fulcrum.v1.Scene), sent as written: builders stay
  // builders. JSON errors are reported without calling the server.
  virtual Result<WorldSummary> create_world_json(std::string_view json) = 0;
  virtual Result<std::vector<WorldSummary>> list_worlds() = 0;
  virtual Result<WorldSummary> get_world(uint64_t world) = 0;
  // Every live body with its shapes (in the body frame) and every joint, at the world's tick
  // (describe.proto); NOT_FOUND for an unknown world.
  virtual Result<v1::DescribeWorldReply> describe_world(uint64_t world) = 0;
  virtual Status delete_world(uint64_t world) = 0;

  virtual Result<EditResult> apply_edits(uint64_t world, const v1::EditBatch& batch,
                                         std::optional<int64_t> expected_tick = {}) = 0;
  virtual Result<StepResult> step(uint64_t world, uint32_t ticks,
                                  std::optional<int64_t> expected_tick = {},
                                  bool include_snapshot = false) = 0;

  // Steps `options.ticks` ticks and calls `on_sample` for every sample, in tick order, on the
  // calling thread; the server steps no further ahead than the connection's buffers while
  // on_sample runs, so nothing is skipped. A non-OK status from on_sample cancels the call
  // (the world keeps the ticks it ran) and is returned.
  virtual Result<StepResult> step_trajectory(
      uint64_t world, const TrajectoryOptions& options,
      const std::function<Status(const TrajectorySample&)>& on_sample) = 0;

  // Snapshots travel in chunks (DownloadSnapshot, RestoreSnapshotStream): any size the server
  // allows, whatever the message limits.
  virtual Result<SnapshotResult> get_snapshot(uint64_t world) = 0;
  // Rollback into `world`, or, with world 0, a new world (fork) named `name`.
  virtual Result<RestoreResult> restore(uint64_t world, std::string_view snapshot_bytes,
                                        std::string_view name = {}) = 0;

  virtual Result<std::unique_ptr<Subscription>> subscribe(
      uint64_t world, const SubscribeOptions& options,
      std::function<void(const Frame&)> on_frame) = 0;

  // Queries see the world at its current tick; `filter` is the query's own category and mask
  // (a shape is seen when each side's category meets the other's mask).
  virtual Result<std::optional<RayHit>> ray_cast_closest(uint64_t world, const Vec2& origin,
                                                         const Vec2& translation,
                                                         const QueryFilter& filter = {}) = 0;
  // Every hit along the ray, by fraction then shape.
  virtual Result<std::vector<RayCastHit>> ray_cast_all(uint64_t world, const Vec2& origin,
                                                       const Vec2& translation,
                                                       const QueryFilter& filter = {}) = 0;
  virtual Result<std::vector<ShapeHit>> overlap_aabb(uint64_t world, const AABB& box,
                                                     const QueryFilter& filter = {}) = 0;
  virtual Result<std::vector<ShapeHit>> overlap_point(uint64_t world, const Vec2& point,
                                                      const QueryFilter& filter = {}) = 0;

  // Real time: the server steps the world at its dt until paused. While it runs, step() is
  // refused (FAILED_PRECONDITION) and edits apply between two ticks. `max_catch_up_ticks`
  // caps the ticks one wake may step when the server falls behind (default 5).
  virtual Result<RunModeResult> set_run_mode(uint64_t world, RunMode mode,
                                             std::optional<uint32_t> max_catch_up_ticks = {}) = 0;

  // Replays on the server (needs fulcrum-server --replay-dir). A keyframe every
  // `keyframe_interval` ticks (default 60, 0: none).
  virtual Result<RecordingResult> start_recording(
      uint64_t world, std::optional<uint32_t> keyframe_interval = {}) = 0;
  virtual Result<RecordingResult> stop_recording(uint64_t world) = 0;
  // Downloads a replay: by `name` when not empty, else the world's current or last recording.
  // Chunks go to `sink` in order (a sink error ends the download with that error); the size
  // and checksum are checked at the end (DATA_LOSS when they differ).
  virtual Result<DownloadResult> download_replay(
      uint64_t world, std::string_view name,
      const std::function<Status(std::string_view chunk)>& sink) = 0;

  // The server's counters (stats.proto).
  virtual Result<v1::ServerStats> get_stats() = 0;

  // Multiplayer sessions (session.proto; LockstepWorld in fulcrum/lockstep.h follows one).
  virtual Result<v1::OpenSessionReply> open_session(uint64_t world,
                                                    const v1::SessionOptions& options) = 0;
  // request.fingerprint: fulcrum::kDeterminismFingerprint for a client that simulates.
  virtual Result<v1::JoinSessionReply> join_session(const v1::JoinSessionRequest& request) = 0;
  // The world owner gives bodies and joints to a player (0: to none); all of them or none.
  virtual Result<v1::SetOwnershipReply> set_ownership(const v1::SetOwnershipRequest& request) = 0;
  virtual Result<v1::SendInputReply> send_input(uint64_t world, const v1::JoinSessionReply& player,
                                                int64_t tick, const v1::EditBatch& input) = 0;
  // A desync report (LockstepWorld::take_report): world_id, player_id and player_secret are
  // filled in from `world` and `player`.
  virtual Result<v1::ReportHashReply> report_hash(uint64_t world,
                                                  const v1::JoinSessionReply& player,
                                                  v1::ReportHashRequest request) = 0;
  // The world at the start, then every confirmed tick, on the subscription's thread. With
  // `as_player` (a join's reply) the player counts as present while the watch is open.
  virtual Result<std::unique_ptr<Subscription>> watch_session(
      uint64_t world, std::function<void(const v1::SessionEvent&)> on_event,
      const v1::JoinSessionReply* as_player = nullptr) = 0;

  // The standard gRPC health check (grpc.health.v1.Health/Check) for `service` ("" for the
  // whole server, or "fulcrum.v1.Physics"): true when SERVING, false when NOT_SERVING (a
  // server shutting down); UNAVAILABLE when nothing answers, NOT_FOUND for an unknown service.
  // Needs no token.
  virtual Result<bool> health(const std::string& service = "") = 0;
};

}  // namespace fulcrum::client
