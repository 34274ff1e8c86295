#include "physics_service.h"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <filesystem>

#include "call_guard.h"
#include "fulcrum/scene.h"
#include "fulcrum/state.h"
#include "replay_download.h"
#include "scene_convert.h"
#include "snapshot_convert.h"
#include "stats.h"

namespace fulcrum::server {

grpc::Status to_grpc_status(const Status& status) {
  switch (status.code()) {
    case StatusCode::kOk:
      return grpc::Status::OK;
    case StatusCode::kInvalidArgument:
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, status.message());
    case StatusCode::kNotFound:
      return grpc::Status(grpc::StatusCode::NOT_FOUND, status.message());
    case StatusCode::kFailedPrecondition:
      return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, status.message());
    case StatusCode::kResourceExhausted:
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, status.message());
    case StatusCode::kDataLoss:
      return grpc::Status(grpc::StatusCode::DATA_LOSS, status.message());
    case StatusCode::kCancelled:
      return grpc::Status(grpc::StatusCode::CANCELLED, status.message());
    case StatusCode::kDeadlineExceeded:
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, status.message());
    case StatusCode::kUnavailable:
      return grpc::Status(grpc::StatusCode::UNAVAILABLE, status.message());
    case StatusCode::kPermissionDenied:
      return grpc::Status(grpc::StatusCode::PERMISSION_DENIED, status.message());
    case StatusCode::kInternal:
      break;
  }
  return grpc::Status(grpc::StatusCode::INTERNAL, status.message());
}

namespace {
class FrameStream;

// The pieces DownloadSnapshot sends and RestoreSnapshotStream takes, as replays are sent.
constexpr size_t kSnapshotChunkBytes = 64 * 1024;
}  // namespace

// One thread that starts the writes of frames offered to idle readers, so that the thread
// stepping a world only stores a pointer per reader (offer) and never does a reader's encoding
// or socket work. Writes that complete start the next one on gRPC's own threads (OnWriteDone).
class FrameSender {
 public:
  FrameSender() : thread_([this] { run(); }) {}
  ~FrameSender() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      stop_ = true;
    }
    cv_.notify_one();
    thread_.join();
  }
  void post(std::shared_ptr<FrameStream> stream) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      queue_.push_back(std::move(stream));
    }
    cv_.notify_one();
  }

 private:
  void run();

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<FrameStream>> queue_;
  bool stop_ = false;
  std::thread thread_;  // last: starts after the members above exist
};

namespace {

std::optional<int64_t> optional_tick(bool has, int64_t value) {
  return has ? std::optional<int64_t>(value) : std::nullopt;
}

// A stream that ends at once with an error (bad request, unknown world).
// Counted and logged like any refused request.
template <typename Message>
class Refused final : public grpc::ServerWriteReactor<Message> {
 public:
  Refused(const char* rpc, grpc::Status status) {
    counters().add_refused(status.error_code());
    log_event("refused", {{"rpc", rpc},
                          {"code", status_code_name(status.error_code())},
                          {"field", field_of(status.error_message())},
                          {"message", status.error_message()}});
    this->Finish(std::move(status));
  }
  void OnDone() override { delete this; }
};

// One StreamFrames call. The world's thread offers frames; the newest unread one waits in
// pending_ (a mailbox of one: a newer frame replaces it and counts as skipped), so a reader
// that falls behind costs the world nothing and holds at most two frames (one in flight).
// offer() only stores the frame and, when no write is in flight, posts the stream to the
// FrameSender, whose thread encodes (encode_shared) and starts the write. The
// object keeps itself alive (self_) until gRPC calls OnDone; the Session holds a weak_ptr.
// A write in flight for longer than the stall limit when a newer frame arrives ends the stream
// with RESOURCE_EXHAUSTED (its client stopped reading). Messages are a reader part (skipped
// counts) followed by the frame's shared encoding (encode_shared), two slices, no copy.
class FrameStream final : public grpc::ServerWriteReactor<grpc::ByteBuffer>,
                          public FrameSink,
                          public std::enable_shared_from_this<FrameStream> {
 public:
  FrameStream(std::shared_ptr<Session> session, const v1::StreamFramesRequest& request,
              std::chrono::milliseconds max_stall, FrameSender* sender)
      : session_(std::move(session)),
        sender_(sender),
        every_(request.every_ticks() == 0 ? 1 : request.every_ticks()),
        mode_(request.bodies()),
        quantized_(request.quantized()),
        max_stall_(max_stall) {}

  static FrameStream* start(std::shared_ptr<Session> session,
                            const v1::StreamFramesRequest& request,
                            std::chrono::milliseconds max_stall, FrameSender* sender) {
    auto stream = std::make_shared<FrameStream>(session, request, max_stall, sender);
    stream->self_ = stream;
    ++counters().streams_opened;
    ++counters().streams_open;
    log_event("stream_opened", {{"world", session->id()},
                                {"every_ticks", stream->every_},
                                {"bodies", v1::FrameBodies_Name(stream->mode_)},
                                {"quantized", stream->quantized_ ? "true" : "false"}});
    session->subscribe(stream);
    return stream.get();
  }

  uint32_t every_ticks() const override { return every_; }

  void offer(std::shared_ptr<const PublishedFrame> frame) override {
    std::unique_lock<std::mutex> lock(mu_);
    if (closing_) return;
    if (writing_ && std::chrono::steady_clock::now() - write_started_ > max_stall_) {
      ++counters().readers_too_slow;
      lock.unlock();
      end(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                       "frames: this reader took no frame for more than " +
                           std::to_string(max_stall_.count()) +
                           " ms (--max-reader-stall-ms) while the world moved on"));
      return;
    }
    if (pending_) {
      ++skipped_;
      ++counters().frames_coalesced;
    }
    pending_ = std::move(frame);
    if (writing_ || queued_) return;  // OnWriteDone or the sender picks it up
    queued_ = true;
    lock.unlock();
    sender_->post(shared_from_this());
  }

  // On the sender's thread: starts a write of the pending frame if none is in flight.
  void send_pending() {
    std::unique_lock<std::mutex> lock(mu_);
    queued_ = false;
    if (closing_ || writing_ || !pending_) return;
    prepare_write_locked();
    lock.unlock();
    StartWrite(&message_);
  }

  void close(const Status& status, bool shutting_down) override {
    end(shutting_down ? grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is stopping")
                      : to_grpc_status(status));
  }

  void OnWriteDone(bool ok) override {
    std::unique_lock<std::mutex> lock(mu_);
    writing_ = false;
    if (!ok && !closing_) {
      closing_ = true;
      final_ = grpc::Status(grpc::StatusCode::CANCELLED, "the stream was broken");
    }
    if (closing_) {
      if (finished_) return;
      finished_ = true;
      lock.unlock();
      Finish(final_);
      return;
    }
    if (!pending_) return;
    prepare_write_locked();
    lock.unlock();
    StartWrite(&message_);
  }

  void OnCancel() override {
    end(grpc::Status(grpc::StatusCode::CANCELLED, "the client cancelled the stream"));
  }

  void OnDone() override {
    --counters().streams_open;
    log_event("stream_closed", {{"world", session_->id()},
                                {"code", status_code_name(final_.error_code())},
                                {"frames", frames_sent_},
                                {"coalesced", coalesced_total_}});
    session_->unsubscribe(this);
    std::shared_ptr<FrameStream> last = std::move(self_);  // may destroy this on return
  }

 private:
  void end(grpc::Status status) {
    std::unique_lock<std::mutex> lock(mu_);
    if (closing_) return;
    closing_ = true;
    final_ = std::move(status);
    if (writing_ || finished_) return;  // OnWriteDone finishes
    finished_ = true;
    lock.unlock();
    Finish(final_);
  }

  void prepare_write_locked() {
    bool built = false;
    std::shared_ptr<const std::string> shared =
        encode_shared(*pending_, last_sent_.get(), mode_, quantized_, &built);
    if (built) ++counters().frames_encoded;
    // The slice holds a reference to the shared bytes until gRPC has sent them.
    auto* keep = new std::shared_ptr<const std::string>(shared);
    grpc::Slice slices[2] = {
        grpc::Slice(encode_reader_part(skipped_, every_)),
        grpc::Slice(
            const_cast<char*>(shared->data()), shared->size(),
            [](void* p) { delete static_cast<std::shared_ptr<const std::string>*>(p); }, keep)};
    message_ = grpc::ByteBuffer(slices, 2);
    coalesced_total_ += skipped_;
    ++frames_sent_;
    ++counters().frames_sent;
    last_sent_ = std::move(pending_);
    pending_.reset();
    skipped_ = 0;
    writing_ = true;
    write_started_ = std::chrono::steady_clock::now();
  }

  const std::shared_ptr<Session> session_;
  FrameSender* const sender_;
  const uint32_t every_;
  const v1::FrameBodies mode_;
  const bool quantized_;
  const std::chrono::milliseconds max_stall_;
  std::shared_ptr<FrameStream> self_;

  std::mutex mu_;
  std::shared_ptr<const PublishedFrame> pending_;    // newest frame not yet sent
  std::shared_ptr<const PublishedFrame> last_sent_;  // what the reader has (CHANGED diffs)
  uint64_t skipped_ = 0;
  grpc::ByteBuffer message_;  // the write in flight; untouched while writing_
  std::chrono::steady_clock::time_point write_started_;
  uint64_t frames_sent_ = 0;
  uint64_t coalesced_total_ = 0;
  bool writing_ = false;
  bool queued_ = false;  // posted to the sender, not yet picked up
  bool closing_ = false;
  bool finished_ = false;
  grpc::Status final_;
};

}  // namespace

void FrameSender::run() {
  for (;;) {
    std::shared_ptr<FrameStream> stream;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;
      stream = std::move(queue_.front());
      queue_.pop_front();
    }
    stream->send_pending();
  }
}

PhysicsService::PhysicsService(Registry* registry, std::string token)
    : registry_(registry), token_(std::move(token)), sender_(std::make_unique<FrameSender>()) {}

PhysicsService::~PhysicsService() = default;

void PhysicsService::begin_shutdown() {
  shutting_down_ = true;
  registry_->close_all_streams(Status(StatusCode::kInternal, "the server is stopping"));
}

grpc::Status PhysicsService::check_token(const grpc::ServerContextBase& context) const {
  if (token_.empty()) return grpc::Status::OK;
  switch (check_bearer(context, token_)) {
    case BearerCheck::kMissing:
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          "authorization: missing (expected \"Bearer <token>\")");
    case BearerCheck::kWrong:
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "authorization: wrong token");
    case BearerCheck::kMatches:
      break;
  }
  return grpc::Status::OK;
}

// Every unary handler starts here: the token, then a server that is stopping refuses new work
// (calls already running finish within the shutdown's grace period).
#define FULCRUM_ADMIT_CALL(context)                                                 \
  do {                                                                              \
    grpc::Status auth_ = check_token(*(context));                                   \
    if (!auth_.ok()) return auth_;                                                  \
    if (shutting_down_) {                                                           \
      return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is stopping"); \
    }                                                                               \
  } while (false)

grpc::Status PhysicsService::CreateWorld(grpc::ServerContext* context,
                                         const v1::CreateWorldRequest* request,
                                         v1::CreateWorldReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  if (!request->has_scene()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "scene: required");
  }
  Result<SceneDef> scene = scene_from_proto(request->scene());
  if (!scene.ok()) return to_grpc_status(scene.status().with_prefix("scene."));
  // Counts are checked before building: a scene over a limit is refused without allocating it.
  Result<World> world = build_world(*scene, work_limits(context));
  if (!world.ok()) return to_grpc_status(world.status().with_prefix("scene."));
  for (BodyId id : world->bodies()) {
    v1::Handle* h = reply->add_bodies();
    h->set_index(id.index);
    h->set_generation(id.generation);
  }
  for (JointId id : world->joints()) {
    v1::Handle* h = reply->add_joints();
    h->set_index(id.index);
    h->set_generation(id.generation);
  }
  // Ownership the scene declares for multiplayer sessions: explicit bodies and joints come
  // last in the world, in the scene's order.
  std::map<uint32_t, GameSession::SceneOwned> owners;
  const v1::Scene& sp = request->scene();
  const int first_body = reply->bodies_size() - sp.bodies_size();
  for (int i = 0; i < sp.bodies_size(); ++i) {
    const uint32_t player = sp.bodies(i).player();
    if (player == 0) continue;
    const std::string field = "scene.bodies[" + std::to_string(i) + "].player";
    if (player > GameSession::kMaxPlayers) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          field + ": at most " + std::to_string(GameSession::kMaxPlayers) +
                              " (got " + std::to_string(player) + ")");
    }
    if (sp.bodies(i).type() == v1::BODY_TYPE_STATIC) {
      return grpc::Status(
          grpc::StatusCode::INVALID_ARGUMENT,
          field + ": a static body cannot be a player's (inputs could not move it)");
    }
    const v1::Handle& h = reply->bodies(first_body + i);
    owners[player].bodies.push_back(BodyId{h.index(), h.generation()});
  }
  const int first_joint = reply->joints_size() - sp.joints_size();
  for (int i = 0; i < sp.joints_size(); ++i) {
    const uint32_t player = sp.joints(i).player();
    if (player == 0) continue;
    if (player > GameSession::kMaxPlayers) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "scene.joints[" + std::to_string(i) + "].player: at most " +
                              std::to_string(GameSession::kMaxPlayers) + " (got " +
                              std::to_string(player) + ")");
    }
    const v1::Handle& h = reply->joints(first_joint + i);
    owners[player].joints.push_back(JointId{h.index(), h.generation()});
  }
  Result<std::shared_ptr<Session>> session =
      registry_->create(request->scene().name(), std::move(world).value());
  if (!session.ok()) return to_grpc_status(session.status());
  if (!owners.empty()) (*session)->set_scene_owners(std::move(owners));
  reply->set_world_id((*session)->id());
  (*session)->info(reply->mutable_world());
  return grpc::Status::OK;
}

grpc::Status PhysicsService::ListWorlds(grpc::ServerContext* context,
                                        const v1::ListWorldsRequest* request,
                                        v1::ListWorldsReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  for (const auto& session : registry_->list()) session->summary(reply->add_worlds());
  return grpc::Status::OK;
}

grpc::Status PhysicsService::GetWorld(grpc::ServerContext* context,
                                      const v1::GetWorldRequest* request, v1::WorldInfo* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  (*session)->info(reply);
  return grpc::Status::OK;
}

grpc::Status PhysicsService::DescribeWorld(grpc::ServerContext* context,
                                           const v1::DescribeWorldRequest* request,
                                           v1::DescribeWorldReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  (*session)->describe(reply);
  return grpc::Status::OK;
}

grpc::Status PhysicsService::DeleteWorld(grpc::ServerContext* context,
                                         const v1::DeleteWorldRequest* request,
                                         v1::DeleteWorldReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  return to_grpc_status(registry_->remove(request->world_id()));
}

grpc::Status PhysicsService::ApplyEdits(grpc::ServerContext* context,
                                        const v1::ApplyEditsRequest* request,
                                        v1::ApplyEditsReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  return to_grpc_status((*session)->apply_edits(
      request->batch(), optional_tick(request->has_expected_tick(), request->expected_tick()),
      keep_going(context), reply));
}

grpc::Status PhysicsService::Step(grpc::ServerContext* context, const v1::StepRequest* request,
                                  v1::StepReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  const Status status = (*session)->step(
      request->ticks(), optional_tick(request->has_expected_tick(), request->expected_tick()),
      request->include_snapshot(), keep_going(context), reply);
  if (!status.ok() && reply->state_hash() != 0) {
    // Stopped part way: the ticks run are kept, and the trailers say where the world is.
    context->AddTrailingMetadata("fulcrum-tick", std::to_string(reply->tick()));
    context->AddTrailingMetadata("fulcrum-state-hash", World::hash_text(reply->state_hash()));
  }
  return to_grpc_status(status);
}

std::function<Status()> PhysicsService::keep_going(const grpc::ServerContext* context) const {
  // IsCancelled is a call into gRPC's core that costs about 20 us here, more than a small
  // world's tick, so it is asked at most once a millisecond; the flag and the clock are cheap.
  const auto deadline = context->deadline();
  return [this, context, deadline,
          last_asked = std::chrono::steady_clock::time_point()]() mutable -> Status {
    if (abandoning_.load(std::memory_order_relaxed)) {
      return Status(StatusCode::kUnavailable,
                    "the server is shutting down and the call's grace period is over");
    }
    if (deadline <= std::chrono::system_clock::now()) {
      return Status(StatusCode::kDeadlineExceeded, "the call's deadline passed");
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - last_asked >= std::chrono::milliseconds(1)) {
      last_asked = now;
      if (context->IsCancelled()) return Status(StatusCode::kCancelled, "the call was cancelled");
    }
    return {};
  };
}

WorkLimits PhysicsService::work_limits(const grpc::ServerContext* context) const {
  const Limits& limits = registry_->limits();
  WorkLimits out;
  out.max_bodies = limits.max_bodies;
  out.max_shapes = limits.max_shapes;
  out.max_shapes_per_body = limits.max_shapes_per_body;
  out.max_work = limits.max_batch_work;
  out.keep_going = keep_going(context);
  return out;
}

grpc::Status PhysicsService::GetSnapshot(grpc::ServerContext* context,
                                         const v1::GetSnapshotRequest* request,
                                         v1::GetSnapshotReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  (*session)->snapshot(reply);
  return grpc::Status::OK;
}

grpc::Status PhysicsService::RestoreSnapshot(grpc::ServerContext* context,
                                             const v1::RestoreSnapshotRequest* request,
                                             v1::RestoreSnapshotReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  if (!request->has_snapshot()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "snapshot: required");
  }
  return restore(request->world_id(), request->name(), request->snapshot(), reply);
}

grpc::Status PhysicsService::restore(uint64_t world_id, const std::string& name,
                                     const v1::SnapshotFile& file,
                                     v1::RestoreSnapshotReply* reply) {
  std::shared_ptr<Session> target;
  if (world_id != 0) {
    auto found = registry_->find(world_id);
    if (!found.ok()) return to_grpc_status(found.status());
    target = *found;
  }
  Result<WorldSnapshot> records = decode_snapshot(file, registry_->limits());
  if (!records.ok()) return to_grpc_status(records.status());
  if (target) return to_grpc_status(target->restore(*records, reply));

  // Fork: a new world continuing from the snapshot.
  World world;
  Status restored = world.restore(*records);
  if (!restored.ok()) return to_grpc_status(restored);  // "snapshot: ..." already
  auto created = registry_->create(name.empty() ? "fork" : name, std::move(world));
  if (!created.ok()) return to_grpc_status(created.status());
  v1::WorldInfo info;
  (*created)->summary(&info);
  reply->set_world_id(info.world_id());
  reply->set_tick(info.tick());
  reply->set_state_hash(info.state_hash());
  return grpc::Status::OK;
}

grpc::Status PhysicsService::Query(grpc::ServerContext* context, const v1::QueryRequest* request,
                                   v1::QueryReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  return to_grpc_status((*session)->query(*request, reply));
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* PhysicsService::StreamFrames(
    grpc::CallbackServerContext* context, const grpc::ByteBuffer* raw_request) {
  v1::StreamFramesRequest parsed;
  grpc::ByteBuffer copy(*raw_request);  // Deserialize consumes its buffer
  if (!grpc::SerializationTraits<v1::StreamFramesRequest>::Deserialize(&copy, &parsed).ok()) {
    return new Refused<grpc::ByteBuffer>(
        "StreamFrames",
        grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "request: not a StreamFramesRequest"));
  }
  const v1::StreamFramesRequest* request = &parsed;
  grpc::Status auth = check_token(*context);
  if (!auth.ok()) return new Refused<grpc::ByteBuffer>("StreamFrames", auth);
  if (shutting_down_) {
    return new Refused<grpc::ByteBuffer>(
        "StreamFrames", grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is stopping"));
  }
  if (!v1::FrameBodies_IsValid(request->bodies())) {
    return new Refused<grpc::ByteBuffer>(
        "StreamFrames",
        grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                     "bodies: unknown FrameBodies value " + std::to_string(request->bodies())));
  }
  auto session = registry_->find(request->world_id());
  if (!session.ok())
    return new Refused<grpc::ByteBuffer>("StreamFrames", to_grpc_status(session.status()));
  return FrameStream::start(*session, *request,
                            std::chrono::milliseconds(registry_->limits().max_reader_stall_ms),
                            sender_.get());
}

grpc::Status PhysicsService::GetStats(grpc::ServerContext* context,
                                      const v1::GetStatsRequest* request, v1::ServerStats* reply) {
  FULCRUM_ADMIT_CALL(context);
  counters().to_proto(static_cast<uint32_t>(registry_->list().size()), reply);
  return grpc::Status::OK;
}

// --- Real time and replays on the server ------------------------------------------------------

grpc::Status PhysicsService::SetRunMode(grpc::ServerContext* context,
                                        const v1::SetRunModeRequest* request,
                                        v1::SetRunModeReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  std::optional<uint32_t> cap;
  if (request->has_max_catch_up_ticks()) cap = request->max_catch_up_ticks();
  return to_grpc_status((*session)->set_run_mode(registry_->pool(), request->mode(), cap, reply));
}

grpc::Status PhysicsService::StartRecording(grpc::ServerContext* context,
                                            const v1::StartRecordingRequest* request,
                                            v1::StartRecordingReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  std::optional<uint32_t> keyframes;
  if (request->has_keyframe_interval()) keyframes = request->keyframe_interval();
  return to_grpc_status((*session)->start_recording(registry_->replays(), keyframes, reply));
}

grpc::Status PhysicsService::StopRecording(grpc::ServerContext* context,
                                           const v1::StopRecordingRequest* request,
                                           v1::StopRecordingReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  return to_grpc_status((*session)->stop_recording(reply));
}

// --- Streams that step or carry snapshots -----------------------------------------------------

grpc::Status PhysicsService::StepTrajectory(grpc::ServerContext* context,
                                            const v1::StepTrajectoryRequest* request,
                                            grpc::ServerWriter<v1::TrajectoryChunk>* writer) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  // A part gathers about 256 KiB of samples (at most half a message) or runs for 20 ms,
  // whichever comes first, so that a reader sees progress and other calls get the world
  // between parts.
  const size_t chunk_bytes =
      std::min<size_t>(256 * 1024, registry_->limits().max_message_bytes / 2);
  constexpr auto kPartTime = std::chrono::milliseconds(20);
  Session::TrajectoryProgress progress;
  const std::function<Status()> go_on = keep_going(context);
  v1::TrajectoryChunk chunk;
  for (;;) {
    Status status =
        (*session)->step_trajectory(*request, chunk_bytes, kPartTime, go_on, &progress, &chunk);
    // What a part ran is sent even when it stopped part way: nothing stepped is lost.
    if ((chunk.samples_size() > 0 || chunk.has_done()) && !writer->Write(chunk)) {
      status = Status(StatusCode::kCancelled, "the trajectory's reader went away after " +
                                                  std::to_string(progress.done) + " of " +
                                                  std::to_string(progress.total) + " ticks");
    }
    if (!status.ok()) {
      if (progress.started) {
        context->AddTrailingMetadata("fulcrum-tick", std::to_string(progress.reply.tick()));
        context->AddTrailingMetadata("fulcrum-state-hash",
                                     World::hash_text(progress.reply.state_hash()));
      }
      return to_grpc_status(status);
    }
    if (progress.finished()) return grpc::Status::OK;
    // Between parts, as between ticks: a cancelled call or a server past its grace stops here.
    if (Status stop = go_on(); !stop.ok()) {
      context->AddTrailingMetadata("fulcrum-tick", std::to_string(progress.reply.tick()));
      context->AddTrailingMetadata("fulcrum-state-hash",
                                   World::hash_text(progress.reply.state_hash()));
      return to_grpc_status(
          Status(stop.code(), "ticks: stopped after " + std::to_string(progress.done) + " of " +
                                  std::to_string(progress.total) + " ticks: " + stop.message()));
    }
  }
}

grpc::Status PhysicsService::DownloadSnapshot(grpc::ServerContext* context,
                                              const v1::GetSnapshotRequest* request,
                                              grpc::ServerWriter<v1::SnapshotChunk>* writer) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request->world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  v1::GetSnapshotReply taken;
  (*session)->snapshot(&taken);
  const std::string bytes = taken.snapshot().SerializeAsString();
  v1::SnapshotChunk chunk;
  size_t sent = 0;
  do {
    const size_t n = std::min(kSnapshotChunkBytes, bytes.size() - sent);
    chunk.Clear();
    if (sent == 0) {
      chunk.set_tick(taken.tick());
      chunk.set_state_hash(taken.state_hash());
      chunk.set_total_size(bytes.size());
    }
    chunk.set_offset(sent);
    chunk.set_data(bytes.substr(sent, n));
    sent += n;
    if (sent == bytes.size()) {
      chunk.set_last(true);
      chunk.set_checksum(fnv1a64(bytes));
    }
    if (!writer->Write(chunk)) {
      return grpc::Status(grpc::StatusCode::CANCELLED, "the download was broken off");
    }
  } while (sent < bytes.size());
  return grpc::Status::OK;
}

grpc::Status PhysicsService::RestoreSnapshotStream(
    grpc::ServerContext* context, grpc::ServerReader<v1::RestoreSnapshotChunk>* reader,
    v1::RestoreSnapshotReply* reply) {
  FULCRUM_ADMIT_CALL(context);
  const int64_t max_bytes = registry_->limits().max_snapshot_bytes;
  auto refuse = [](grpc::StatusCode code, std::string message) {
    return grpc::Status(code, message + "; nothing was restored");
  };
  v1::RestoreSnapshotChunk message;
  uint64_t world_id = 0;
  std::string name;
  std::string bytes;
  uint64_t total = 0;
  bool last = false;
  uint64_t checksum = 0;
  for (int64_t i = 0; reader->Read(&message); ++i) {
    const std::string field = "chunks[" + std::to_string(i) + "]";
    if (last) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT, field + ": arrived after the last chunk");
    }
    if (!message.has_chunk()) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT, field + ".chunk: required");
    }
    const v1::SnapshotChunk& chunk = message.chunk();
    if (i == 0) {
      world_id = message.world_id();
      name = message.name();
      total = chunk.total_size();
      if (total == 0) {
        return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                      field + ".chunk.total_size: required in the first chunk (got 0)");
      }
      if (total > static_cast<uint64_t>(max_bytes)) {
        return refuse(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      field + ".chunk.total_size: " + std::to_string(total) +
                          " bytes; this server takes at most " + std::to_string(max_bytes) +
                          " (--max-snapshot-bytes)");
      }
      bytes.reserve(total);
    } else if (message.world_id() != 0 || !message.name().empty() || chunk.total_size() != 0) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    field + ": world_id, name and total_size belong in the first chunk only");
    }
    if (chunk.offset() != bytes.size()) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    field + ".chunk.offset: expected " + std::to_string(bytes.size()) +
                        " (the bytes received so far), got " + std::to_string(chunk.offset()));
    }
    if (chunk.data().size() > kSnapshotChunkBytes) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    field + ".chunk.data: " + std::to_string(chunk.data().size()) +
                        " bytes; at most " + std::to_string(kSnapshotChunkBytes) + " per chunk");
    }
    if (bytes.size() + chunk.data().size() > total) {
      return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                    field + ".chunk.data: runs past total_size " + std::to_string(total));
    }
    bytes += chunk.data();
    last = chunk.last();
    checksum = chunk.checksum();
  }
  if (context->IsCancelled()) {
    return grpc::Status(grpc::StatusCode::CANCELLED, "the upload was broken off");
  }
  if (bytes.empty() && !last) {
    return refuse(grpc::StatusCode::INVALID_ARGUMENT, "chunks: none arrived");
  }
  if (!last || bytes.size() != total) {
    return refuse(grpc::StatusCode::INVALID_ARGUMENT,
                  "chunks: the stream ended after " + std::to_string(bytes.size()) + " of " +
                      std::to_string(total) + " bytes without a chunk marked last");
  }
  if (fnv1a64(bytes) != checksum) {
    return refuse(grpc::StatusCode::DATA_LOSS,
                  "chunks: the last chunk's checksum does not match the bytes received");
  }
  v1::SnapshotFile file;
  if (!file.ParseFromString(bytes)) {
    return refuse(grpc::StatusCode::DATA_LOSS, "snapshot: the bytes are not a SnapshotFile");
  }
  return restore(world_id, name, file, reply);
}

// --- Multiplayer sessions ---------------------------------------------------------------------

template <typename Request, typename Reply>
grpc::Status PhysicsService::on_world(grpc::ServerContext* context, const Request& request,
                                      Reply* reply,
                                      Status (Session::*method)(const Request&, Reply*)) {
  FULCRUM_ADMIT_CALL(context);
  auto session = registry_->find(request.world_id());
  if (!session.ok()) return to_grpc_status(session.status());
  return to_grpc_status(((**session).*method)(request, reply));
}

grpc::Status PhysicsService::OpenSession(grpc::ServerContext* context,
                                         const v1::OpenSessionRequest* request,
                                         v1::OpenSessionReply* reply) {
  return on_world(context, *request, reply, &Session::open_session);
}

grpc::Status PhysicsService::JoinSession(grpc::ServerContext* context,
                                         const v1::JoinSessionRequest* request,
                                         v1::JoinSessionReply* reply) {
  return on_world(context, *request, reply, &Session::join_session);
}

grpc::Status PhysicsService::SetOwnership(grpc::ServerContext* context,
                                          const v1::SetOwnershipRequest* request,
                                          v1::SetOwnershipReply* reply) {
  return on_world(context, *request, reply, &Session::set_ownership);
}

grpc::Status PhysicsService::SendInput(grpc::ServerContext* context,
                                       const v1::SendInputRequest* request,
                                       v1::SendInputReply* reply) {
  return on_world(context, *request, reply, &Session::send_input);
}

grpc::Status PhysicsService::ReportHash(grpc::ServerContext* context,
                                        const v1::ReportHashRequest* request,
                                        v1::ReportHashReply* reply) {
  return on_world(context, *request, reply, &Session::report_hash);
}

namespace {

// One WatchSession call: every event in order, none skipped. Events queue while a write is in
// flight; a watcher more than SessionWatcher::kMaxBehind events behind is ended with
// RESOURCE_EXHAUSTED (it watches again, from a new start). Alive until gRPC calls OnDone.
class SessionStream final : public grpc::ServerWriteReactor<v1::SessionEvent>,
                            public SessionWatcher,
                            public std::enable_shared_from_this<SessionStream> {
 public:
  SessionStream(std::shared_ptr<Session> session, uint32_t player_id)
      : session_(std::move(session)), player_id_(player_id) {}

  static SessionStream* start(std::shared_ptr<Session> session,
                              const v1::WatchSessionRequest& request) {
    auto stream = std::make_shared<SessionStream>(session, request.player_id());
    stream->self_ = stream;
    Status watching = session->watch_session(stream, request.player_id(), request.player_secret());
    if (!watching.ok()) {
      stream->player_id_ = 0;  // not counted present
      stream->end(to_grpc_status(watching));
    }
    return stream.get();
  }

  void offer(std::shared_ptr<const v1::SessionEvent> event) override {
    std::unique_lock<std::mutex> lock(mu_);
    if (closing_) return;
    if (queue_.size() >= kMaxBehind) {
      lock.unlock();
      end(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                       "this watcher fell more than " + std::to_string(kMaxBehind) +
                           " confirmed ticks behind: watch again to start from the world as it "
                           "is then"));
      return;
    }
    queue_.push_back(std::move(event));
    if (writing_) return;
    writing_ = true;
    const v1::SessionEvent* next = queue_.front().get();
    lock.unlock();
    StartWrite(next);
  }

  void close(const Status& status) override { end(to_grpc_status(status)); }
  uint32_t player_id() const override { return player_id_; }

  void OnWriteDone(bool ok) override {
    std::unique_lock<std::mutex> lock(mu_);
    queue_.pop_front();
    if (!ok && !closing_) {
      closing_ = true;
      final_ = grpc::Status(grpc::StatusCode::CANCELLED, "the stream was broken");
    }
    if (closing_ || queue_.empty()) {
      writing_ = false;
      if (closing_ && !finished_) {
        finished_ = true;
        lock.unlock();
        Finish(final_);
      }
      return;
    }
    const v1::SessionEvent* next = queue_.front().get();
    lock.unlock();
    StartWrite(next);
  }

  void OnCancel() override {
    end(grpc::Status(grpc::StatusCode::CANCELLED, "the client cancelled the watch"));
  }

  void OnDone() override {
    session_->unwatch_session(this, player_id_);
    std::shared_ptr<SessionStream> last = std::move(self_);  // may destroy this on return
  }

 private:
  void end(grpc::Status status) {
    std::unique_lock<std::mutex> lock(mu_);
    if (closing_) return;
    closing_ = true;
    final_ = std::move(status);
    if (writing_ || finished_) return;  // OnWriteDone finishes
    finished_ = true;
    lock.unlock();
    Finish(final_);
  }

  const std::shared_ptr<Session> session_;
  uint32_t player_id_ = 0;  // watching as this player (0: a spectator)
  std::shared_ptr<SessionStream> self_;
  std::mutex mu_;
  std::deque<std::shared_ptr<const v1::SessionEvent>> queue_;  // front: in flight when writing_
  bool writing_ = false;
  bool closing_ = false;
  bool finished_ = false;
  grpc::Status final_;
};

}  // namespace

grpc::ServerWriteReactor<v1::SessionEvent>* PhysicsService::WatchSession(
    grpc::CallbackServerContext* context, const v1::WatchSessionRequest* request) {
  grpc::Status auth = check_token(*context);
  if (!auth.ok()) return new Refused<v1::SessionEvent>("WatchSession", auth);
  if (shutting_down_) {
    return new Refused<v1::SessionEvent>(
        "WatchSession", grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is stopping"));
  }
  auto session = registry_->find(request->world_id());
  if (!session.ok()) {
    return new Refused<v1::SessionEvent>("WatchSession", to_grpc_status(session.status()));
  }
  return SessionStream::start(*session, *request);
}

namespace {

// The file a DownloadReplay request names: a world's current or last recording, or a name in
// the replay directory (a recording in progress is cut at its last complete tick).
Result<ReplayFileRef> find_replay(Registry* registry, const v1::DownloadReplayRequest& request) {
  if (request.name().empty()) {
    if (request.world_id() == 0) return invalid_argument("world_id or name: one is required");
    auto session = registry->find(request.world_id());
    if (!session.ok()) return session.status();
    return (*session)->replay_file();
  }
  FULCRUM_RETURN_IF_ERROR(ReplayStore::check_name(request.name()));
  ReplayStore* store = registry->replays();
  if (store == nullptr || !store->enabled()) {
    return not_found("name: no replay " + request.name() + " (recording is off on this server)");
  }
  for (const auto& session : registry->list()) {
    Result<ReplayFileRef> file = session->replay_file();
    if (file.ok() && file->name == request.name()) return file;
  }
  ReplayFileRef file{request.name(), store->path_of(request.name()), 0};
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file.path, ec)) {
    return not_found("name: no replay " + request.name());
  }
  file.bytes = std::filesystem::file_size(file.path, ec);
  if (ec) return not_found("name: replay " + request.name() + " cannot be read");
  return file;
}

}  // namespace

grpc::ServerWriteReactor<v1::ReplayChunk>* PhysicsService::DownloadReplay(
    grpc::CallbackServerContext* context, const v1::DownloadReplayRequest* request) {
  grpc::Status auth = check_token(*context);
  if (!auth.ok()) return new Refused<v1::ReplayChunk>("DownloadReplay", auth);
  if (shutting_down_) {
    return new Refused<v1::ReplayChunk>(
        "DownloadReplay", grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is stopping"));
  }
  Result<ReplayFileRef> file = find_replay(registry_, *request);
  if (!file.ok())
    return new Refused<v1::ReplayChunk>("DownloadReplay", to_grpc_status(file.status()));
  return start_replay_download(*file);
}

}  // namespace fulcrum::server
