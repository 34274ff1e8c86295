// The gRPC side of fulcrum_client: converts between the public types of fulcrum/client.h and
// the service's messages, and gRPC statuses into fulcrum::Status.
#include "fulcrum/client.h"

#include <google/protobuf/util/json_util.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <atomic>
#include <future>
#include <mutex>
#include <thread>

#include "frame_decode.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"

namespace fulcrum::client {

namespace {

const char* grpc_code_name(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::CANCELLED:
      return "CANCELLED";
    case grpc::StatusCode::UNKNOWN:
      return "UNKNOWN";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::ALREADY_EXISTS:
      return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED:
      return "PERMISSION_DENIED";
    case grpc::StatusCode::ABORTED:
      return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE:
      return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED:
      return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL:
      return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE:
      return "UNAVAILABLE";
    case grpc::StatusCode::UNAUTHENTICATED:
      return "UNAUTHENTICATED";
    default:
      return "ERROR";
  }
}

Status from_grpc(const grpc::Status& s) {
  switch (s.error_code()) {
    case grpc::StatusCode::OK:
      return {};
    case grpc::StatusCode::INVALID_ARGUMENT:
      return Status(StatusCode::kInvalidArgument, s.error_message());
    case grpc::StatusCode::NOT_FOUND:
      return Status(StatusCode::kNotFound, s.error_message());
    case grpc::StatusCode::FAILED_PRECONDITION:
      return Status(StatusCode::kFailedPrecondition, s.error_message());
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return Status(StatusCode::kResourceExhausted, s.error_message());
    case grpc::StatusCode::DATA_LOSS:
      return Status(StatusCode::kDataLoss, s.error_message());
    case grpc::StatusCode::PERMISSION_DENIED:
      return Status(StatusCode::kPermissionDenied, s.error_message());
    // Messages of these codes often come from gRPC itself ("failed to connect to all
    // addresses"), so they keep the code's name in front, as every other code does.
    case grpc::StatusCode::CANCELLED:
      return Status(StatusCode::kCancelled, "CANCELLED: " + s.error_message());
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return Status(StatusCode::kDeadlineExceeded, "DEADLINE_EXCEEDED: " + s.error_message());
    case grpc::StatusCode::UNAVAILABLE:
      return Status(StatusCode::kUnavailable, "UNAVAILABLE: " + s.error_message());
    default:
      return Status(StatusCode::kInternal,
                    std::string(grpc_code_name(s.error_code())) + ": " + s.error_message());
  }
}

RunMode run_mode_from(v1::RunMode m) {
  return m == v1::RUN_MODE_REAL_TIME ? RunMode::kRealTime : RunMode::kPaused;
}

WorldSummary summary_from(const v1::WorldInfo& w) {
  WorldSummary out;
  out.id = w.world_id();
  out.name = w.name();
  out.tick = w.tick();
  out.body_count = w.body_count();
  out.awake_body_count = w.awake_body_count();
  out.contact_count = w.contact_count();
  out.state_hash = w.state_hash();
  out.watchers = w.watchers();
  const v1::RealTimeInfo& r = w.run();
  out.run.mode = run_mode_from(r.mode());
  out.run.dt = r.dt();
  out.run.max_catch_up_ticks = r.max_catch_up_ticks();
  out.run.start_tick = r.start_tick();
  out.run.ticks_run = r.ticks_run();
  out.run.ticks_dropped = r.ticks_dropped();
  out.run.late_wakes = r.late_wakes();
  out.run.wakes = r.wakes();
  out.run.max_ticks_in_a_wake = r.max_ticks_in_a_wake();
  out.run.busy_retries = r.busy_retries();
  const v1::RecordingInfo& rec = w.recording();
  out.recording.active = rec.active();
  out.recording.name = rec.name();
  out.recording.start_tick = rec.start_tick();
  out.recording.ticks = rec.ticks();
  out.recording.bytes = rec.bytes();
  out.recording.error = rec.error();
  return out;
}

void filter_to(const QueryFilter& filter, v1::QueryRequest* request) {
  const QueryFilter defaults;
  if (filter.category_bits != defaults.category_bits) {
    request->mutable_filter()->set_category_bits(filter.category_bits);
  }
  if (filter.mask_bits != defaults.mask_bits) {
    request->mutable_filter()->set_mask_bits(filter.mask_bits);
  }
}

// FNV-1a 64, fed chunk by chunk (the checksum DownloadReplay sends).
// The pieces snapshots travel in (service.proto, SnapshotChunk).
constexpr size_t kSnapshotChunkBytes = 64 * 1024;

class Fnv1a64 {
 public:
  void update(std::string_view bytes) {
    for (unsigned char c : bytes) {
      h_ ^= c;
      h_ *= 0x100000001b3ULL;
    }
  }
  uint64_t value() const { return h_; }

 private:
  uint64_t h_ = 0xcbf29ce484222325ULL;
};

template <typename Id>
Id id_from(const v1::Handle& h) {
  Id id;
  id.index = h.index();
  id.generation = h.generation();
  return id;
}

void vec_to(const Vec2& v, v1::Vec2* out) {
  out->set_x(v.x());
  out->set_y(v.y());
}

// One server stream read on its own thread, each message handed to `on_message` in order.
template <typename Message>
class GrpcSubscription final : public Subscription {
 public:
  using Start = std::function<std::unique_ptr<grpc::ClientReader<Message>>(grpc::ClientContext*)>;
  GrpcSubscription(const std::string& token, const Start& start,
                   std::function<void(const Message&)> on_message)
      : on_message_(std::move(on_message)) {
    if (!token.empty()) context_.AddMetadata("authorization", "Bearer " + token);
    reader_ = start(&context_);
    thread_ = std::thread([this] { run(); });
  }
  ~GrpcSubscription() override {
    cancel();
    (void)wait();
  }

  void cancel() override {
    cancelled_ = true;
    context_.TryCancel();
    // The callback may be running on the reader thread: wait for it unless we are it.
    if (std::this_thread::get_id() != thread_.get_id()) {
      std::lock_guard<std::mutex> lock(callback_mu_);
    }
  }

  Status wait() override {
    std::lock_guard<std::mutex> lock(join_mu_);
    if (thread_.joinable() && std::this_thread::get_id() != thread_.get_id()) thread_.join();
    return final_;
  }

 private:
  void run() {
    Message message;
    while (reader_->Read(&message)) {
      std::lock_guard<std::mutex> lock(callback_mu_);
      if (cancelled_) continue;  // drain until the cancel takes effect
      on_message_(message);
    }
    grpc::Status status = reader_->Finish();
    final_ = cancelled_ ? Status() : from_grpc(status);
  }

  std::function<void(const Message&)> on_message_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<Message>> reader_;
  std::atomic<bool> cancelled_{false};
  std::mutex callback_mu_;
  std::mutex join_mu_;
  Status final_;
  std::thread thread_;
};

class GrpcClient final : public Client {
 public:
  explicit GrpcClient(const ClientOptions& options) : options_(options) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);  // the server enforces its own limit
    std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
    if (options.tls) {
      grpc::SslCredentialsOptions tls;
      tls.pem_root_certs = options.tls_ca_pem;
      credentials = grpc::SslCredentials(tls);
      if (!options.tls_target_name.empty()) {
        args.SetSslTargetNameOverride(options.tls_target_name);
      }
    }
    channel_ = grpc::CreateCustomChannel(options.address, credentials, args);
    stub_ = v1::Physics::NewStub(channel_);
  }

  Result<WorldSummary> create_world(const SceneDef& scene, std::string_view name) override {
    v1::CreateWorldRequest request;
    *request.mutable_scene() = scene_to_proto(scene, name);
    return create(request);
  }

  Result<WorldSummary> create_world_json(std::string_view json) override {
    v1::CreateWorldRequest request;
    google::protobuf::util::JsonParseOptions parse;
    parse.ignore_unknown_fields = false;
    auto st = google::protobuf::util::JsonStringToMessage(
        google::protobuf::StringPiece(json.data(), json.size()), request.mutable_scene(), parse);
    if (!st.ok()) return invalid_argument("scene JSON: " + std::string(st.message()));
    return create(request);
  }

  Result<std::vector<WorldSummary>> list_worlds() override {
    v1::ListWorldsReply reply;
    Status st = unary(&v1::Physics::Stub::ListWorlds, v1::ListWorldsRequest(), &reply);
    if (!st.ok()) return st;
    std::vector<WorldSummary> out;
    for (const v1::WorldInfo& w : reply.worlds()) out.push_back(summary_from(w));
    return out;
  }

  Result<WorldSummary> get_world(uint64_t world) override {
    v1::GetWorldRequest request;
    request.set_world_id(world);
    v1::WorldInfo reply;
    Status st = unary(&v1::Physics::Stub::GetWorld, request, &reply);
    if (!st.ok()) return st;
    return summary_from(reply);
  }

  Result<v1::DescribeWorldReply> describe_world(uint64_t world) override {
    v1::DescribeWorldRequest request;
    request.set_world_id(world);
    v1::DescribeWorldReply reply;
    Status st = unary(&v1::Physics::Stub::DescribeWorld, request, &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Status delete_world(uint64_t world) override {
    v1::DeleteWorldRequest request;
    request.set_world_id(world);
    v1::DeleteWorldReply reply;
    return unary(&v1::Physics::Stub::DeleteWorld, request, &reply);
  }

  Result<EditResult> apply_edits(uint64_t world, const v1::EditBatch& batch,
                                 std::optional<int64_t> expected_tick) override {
    v1::ApplyEditsRequest request;
    request.set_world_id(world);
    *request.mutable_batch() = batch;
    if (expected_tick) request.set_expected_tick(*expected_tick);
    v1::ApplyEditsReply reply;
    Status st = unary(&v1::Physics::Stub::ApplyEdits, request, &reply);
    if (!st.ok()) return st;
    EditResult out;
    out.tick = reply.tick();
    out.state_hash = reply.state_hash();
    for (const auto& h : reply.bodies()) out.bodies.push_back(id_from<BodyId>(h));
    for (const auto& h : reply.shapes()) out.shapes.push_back(id_from<ShapeId>(h));
    for (const auto& h : reply.joints()) out.joints.push_back(id_from<JointId>(h));
    return out;
  }

  Result<StepResult> step(uint64_t world, uint32_t ticks, std::optional<int64_t> expected_tick,
                          bool include_snapshot) override {
    v1::StepRequest request;
    request.set_world_id(world);
    request.set_ticks(ticks);
    if (expected_tick) request.set_expected_tick(*expected_tick);
    request.set_include_snapshot(include_snapshot);
    v1::StepReply reply;
    Status st = unary(&v1::Physics::Stub::Step, request, &reply);
    if (!st.ok()) return st;
    StepResult out;
    out.tick = reply.tick();
    out.state_hash = reply.state_hash();
    out.awake_body_count = reply.awake_body_count();
    out.step_ms = reply.step_ms();
    if (reply.has_snapshot()) reply.snapshot().SerializeToString(&out.snapshot);
    return out;
  }

  Result<StepResult> step_trajectory(
      uint64_t world, const TrajectoryOptions& options,
      const std::function<Status(const TrajectorySample&)>& on_sample) override {
    v1::StepTrajectoryRequest request;
    request.set_world_id(world);
    request.set_ticks(options.ticks);
    request.set_every_ticks(options.every_ticks);
    for (BodyId id : options.bodies) {
      request.add_bodies()->set_index(id.index);
      request.mutable_bodies()->rbegin()->set_generation(id.generation);
    }
    request.set_include_start(options.include_start);
    if (options.expected_tick) request.set_expected_tick(*options.expected_tick);
    auto context = make_context();
    std::unique_ptr<grpc::ClientReader<v1::TrajectoryChunk>> reader =
        stub_->StepTrajectory(context.get(), request);
    v1::TrajectoryChunk chunk;
    TrajectorySample sample;
    StepResult out;
    bool done = false;
    Status sink_error;
    while (sink_error.ok() && reader->Read(&chunk)) {
      for (const v1::TrajectorySample& s : chunk.samples()) {
        sample.tick = s.tick();
        sample.state_hash = s.state_hash();
        sample.bodies.clear();
        for (const v1::BodyFrame& b : s.bodies()) sample.bodies.push_back(body_frame_from(b));
        sink_error = on_sample(sample);
        if (!sink_error.ok()) break;
      }
      if (chunk.has_done()) {
        done = true;
        out.tick = chunk.done().tick();
        out.state_hash = chunk.done().state_hash();
        out.awake_body_count = chunk.done().awake_body_count();
        out.step_ms = chunk.done().step_ms();
      }
    }
    if (!sink_error.ok()) context->TryCancel();
    Status st = from_grpc(reader->Finish());
    if (!sink_error.ok()) return sink_error;
    if (!st.ok()) return st;
    if (!done) return data_loss("trajectory: the stream ended without the final step reply");
    return out;
  }

  Result<SnapshotResult> get_snapshot(uint64_t world) override {
    v1::GetSnapshotRequest request;
    request.set_world_id(world);
    auto context = make_context();
    std::unique_ptr<grpc::ClientReader<v1::SnapshotChunk>> reader =
        stub_->DownloadSnapshot(context.get(), request);
    SnapshotResult out;
    v1::SnapshotChunk chunk;
    uint64_t total = 0, checksum = 0;
    bool first = true, last = false;
    Status damaged;
    while (reader->Read(&chunk)) {
      if (first) {
        out.tick = chunk.tick();
        out.state_hash = chunk.state_hash();
        total = chunk.total_size();
        out.bytes.reserve(total);
        first = false;
      }
      if (damaged.ok() && chunk.offset() != out.bytes.size()) {
        damaged = data_loss("snapshot: chunk at offset " + std::to_string(chunk.offset()) +
                            ", expected " + std::to_string(out.bytes.size()));
      }
      out.bytes += chunk.data();
      if (chunk.last()) {
        last = true;
        checksum = chunk.checksum();
      }
    }
    Status st = from_grpc(reader->Finish());
    if (!st.ok()) return st;
    if (!damaged.ok()) return damaged;
    if (!last || out.bytes.size() != total) {
      return data_loss("snapshot: received " + std::to_string(out.bytes.size()) + " of " +
                       std::to_string(total) + " bytes");
    }
    Fnv1a64 sum;
    sum.update(out.bytes);
    if (sum.value() != checksum) {
      return data_loss("snapshot: checksum mismatch (the download is damaged)");
    }
    return out;
  }

  Result<RestoreResult> restore(uint64_t world, std::string_view snapshot_bytes,
                                std::string_view name) override {
    v1::SnapshotFile file;
    if (!file.ParseFromArray(snapshot_bytes.data(), static_cast<int>(snapshot_bytes.size()))) {
      return data_loss("snapshot: not a snapshot file, or truncated (" +
                       std::to_string(snapshot_bytes.size()) + " bytes)");
    }
    auto context = make_context();
    v1::RestoreSnapshotReply reply;
    std::unique_ptr<grpc::ClientWriter<v1::RestoreSnapshotChunk>> writer =
        stub_->RestoreSnapshotStream(context.get(), &reply);
    Fnv1a64 sum;
    sum.update(snapshot_bytes);
    size_t sent = 0;
    do {
      const size_t n = std::min(kSnapshotChunkBytes, snapshot_bytes.size() - sent);
      v1::RestoreSnapshotChunk message;
      if (sent == 0) {
        message.set_world_id(world);
        message.set_name(std::string(name));
        message.mutable_chunk()->set_total_size(snapshot_bytes.size());
      }
      v1::SnapshotChunk* chunk = message.mutable_chunk();
      chunk->set_offset(sent);
      chunk->set_data(std::string(snapshot_bytes.substr(sent, n)));
      sent += n;
      if (sent == snapshot_bytes.size()) {
        chunk->set_last(true);
        chunk->set_checksum(sum.value());
      }
      if (!writer->Write(message)) break;  // the server answered early: Finish says why
    } while (sent < snapshot_bytes.size());
    writer->WritesDone();
    Status st = from_grpc(writer->Finish());
    if (!st.ok()) return st;
    return RestoreResult{reply.world_id(), reply.tick(), reply.state_hash()};
  }

  Result<std::unique_ptr<Subscription>> subscribe(
      uint64_t world, const SubscribeOptions& options,
      std::function<void(const Frame&)> on_frame) override {
    if (options.every_ticks == 0) return invalid_argument("every_ticks: must be >= 1 (got 0)");
    v1::StreamFramesRequest request;
    request.set_world_id(world);
    request.set_every_ticks(options.every_ticks);
    request.set_bodies(options.bodies == FrameBodies::kAll       ? v1::FRAME_BODIES_ALL
                       : options.bodies == FrameBodies::kChanged ? v1::FRAME_BODIES_CHANGED
                                                                 : v1::FRAME_BODIES_NONE);
    request.set_quantized(options.quantized);
    v1::Physics::Stub* stub = stub_.get();
    return std::unique_ptr<Subscription>(new GrpcSubscription<v1::Frame>(
        options_.token,
        [stub, request](grpc::ClientContext* c) { return stub->StreamFrames(c, request); },
        [on_frame = std::move(on_frame)](const v1::Frame& f) { on_frame(frame_from(f)); }));
  }

  Result<std::optional<RayHit>> ray_cast_closest(uint64_t world, const Vec2& origin,
                                                 const Vec2& translation,
                                                 const QueryFilter& filter) override {
    v1::QueryRequest request;
    request.set_world_id(world);
    filter_to(filter, &request);
    vec_to(origin, request.mutable_ray_cast()->mutable_origin());
    vec_to(translation, request.mutable_ray_cast()->mutable_translation());
    v1::QueryReply reply;
    Status st = query(request, &reply);
    if (!st.ok()) return st;
    if (reply.hits_size() == 0) return std::optional<RayHit>();
    const v1::RayHit& h = reply.hits(0);
    RayHit hit;
    hit.shape = id_from<ShapeId>(h.shape());
    hit.point = Vec2(h.point().x(), h.point().y());
    hit.normal = Vec2(h.normal().x(), h.normal().y());
    hit.fraction = h.fraction();
    return std::optional<RayHit>(hit);
  }

  Result<std::vector<RayCastHit>> ray_cast_all(uint64_t world, const Vec2& origin,
                                               const Vec2& translation,
                                               const QueryFilter& filter) override {
    v1::QueryRequest request;
    request.set_world_id(world);
    filter_to(filter, &request);
    vec_to(origin, request.mutable_ray_cast()->mutable_origin());
    vec_to(translation, request.mutable_ray_cast()->mutable_translation());
    request.mutable_ray_cast()->set_all(true);
    v1::QueryReply reply;
    Status st = query(request, &reply);
    if (!st.ok()) return st;
    std::vector<RayCastHit> out;
    for (const v1::RayHit& h : reply.hits()) {
      RayCastHit hit;
      hit.shape = id_from<ShapeId>(h.shape());
      hit.body = id_from<BodyId>(h.body());
      hit.point = Vec2(h.point().x(), h.point().y());
      hit.normal = Vec2(h.normal().x(), h.normal().y());
      hit.fraction = h.fraction();
      out.push_back(hit);
    }
    return out;
  }

  Result<std::vector<ShapeHit>> overlap_aabb(uint64_t world, const AABB& box,
                                             const QueryFilter& filter) override {
    v1::QueryRequest request;
    request.set_world_id(world);
    filter_to(filter, &request);
    vec_to(box.lower, request.mutable_aabb()->mutable_lower());
    vec_to(box.upper, request.mutable_aabb()->mutable_upper());
    return shape_hits(request);
  }

  Result<std::vector<ShapeHit>> overlap_point(uint64_t world, const Vec2& point,
                                              const QueryFilter& filter) override {
    v1::QueryRequest request;
    request.set_world_id(world);
    filter_to(filter, &request);
    vec_to(point, request.mutable_point()->mutable_point());
    return shape_hits(request);
  }

  Result<RunModeResult> set_run_mode(uint64_t world, RunMode mode,
                                     std::optional<uint32_t> max_catch_up_ticks) override {
    v1::SetRunModeRequest request;
    request.set_world_id(world);
    request.set_mode(mode == RunMode::kRealTime ? v1::RUN_MODE_REAL_TIME : v1::RUN_MODE_PAUSED);
    if (max_catch_up_ticks) request.set_max_catch_up_ticks(*max_catch_up_ticks);
    v1::SetRunModeReply reply;
    Status st = unary(&v1::Physics::Stub::SetRunMode, request, &reply);
    if (!st.ok()) return st;
    return RunModeResult{run_mode_from(reply.mode()), reply.tick()};
  }

  Result<RecordingResult> start_recording(uint64_t world,
                                          std::optional<uint32_t> keyframe_interval) override {
    v1::StartRecordingRequest request;
    request.set_world_id(world);
    if (keyframe_interval) request.set_keyframe_interval(*keyframe_interval);
    v1::StartRecordingReply reply;
    Status st = unary(&v1::Physics::Stub::StartRecording, request, &reply);
    if (!st.ok()) return st;
    RecordingResult out;
    out.name = reply.name();
    out.tick = reply.tick();
    return out;
  }

  Result<RecordingResult> stop_recording(uint64_t world) override {
    v1::StopRecordingRequest request;
    request.set_world_id(world);
    v1::StopRecordingReply reply;
    Status st = unary(&v1::Physics::Stub::StopRecording, request, &reply);
    if (!st.ok()) return st;
    RecordingResult out;
    out.name = reply.name();
    out.ticks = reply.ticks();
    out.bytes = reply.bytes();
    return out;
  }

  Result<DownloadResult> download_replay(
      uint64_t world, std::string_view name,
      const std::function<Status(std::string_view chunk)>& sink) override {
    v1::DownloadReplayRequest request;
    request.set_world_id(world);
    request.set_name(std::string(name));
    auto context = make_context();
    std::unique_ptr<grpc::ClientReader<v1::ReplayChunk>> reader =
        stub_->DownloadReplay(context.get(), request);
    DownloadResult out;
    Fnv1a64 sum;
    uint64_t total = 0;
    bool first = true, last = false;
    uint64_t server_checksum = 0;
    Status sink_error;
    v1::ReplayChunk chunk;
    while (reader->Read(&chunk)) {
      if (first) {
        out.name = chunk.name();
        total = chunk.total_size();
        first = false;
      }
      if (chunk.offset() != out.bytes) {
        sink_error = data_loss("replay: chunk at offset " + std::to_string(chunk.offset()) +
                               ", expected " + std::to_string(out.bytes));
      }
      if (sink_error.ok()) sink_error = sink(chunk.data());
      if (!sink_error.ok()) {
        context->TryCancel();
        break;
      }
      sum.update(chunk.data());
      out.bytes += chunk.data().size();
      if (chunk.last()) {
        last = true;
        server_checksum = chunk.checksum();
      }
    }
    Status st = from_grpc(reader->Finish());
    if (!sink_error.ok()) return sink_error;
    if (!st.ok()) return st;
    out.checksum = sum.value();
    if (!last || out.bytes != total) {
      return data_loss("replay: received " + std::to_string(out.bytes) + " of " +
                       std::to_string(total) + " bytes");
    }
    if (out.checksum != server_checksum) {
      return data_loss("replay: checksum mismatch (the download is damaged)");
    }
    return out;
  }

  Result<v1::OpenSessionReply> open_session(uint64_t world,
                                            const v1::SessionOptions& options) override {
    v1::OpenSessionRequest request;
    request.set_world_id(world);
    *request.mutable_options() = options;
    v1::OpenSessionReply reply;
    Status st = unary(&v1::Physics::Stub::OpenSession, request, &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Result<v1::JoinSessionReply> join_session(const v1::JoinSessionRequest& request) override {
    v1::JoinSessionReply reply;
    Status st = unary(&v1::Physics::Stub::JoinSession, request, &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Result<v1::SetOwnershipReply> set_ownership(const v1::SetOwnershipRequest& request) override {
    v1::SetOwnershipReply reply;
    Status st = unary(&v1::Physics::Stub::SetOwnership, request, &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Result<v1::SendInputReply> send_input(uint64_t world, const v1::JoinSessionReply& player,
                                        int64_t tick, const v1::EditBatch& input) override {
    v1::SendInputRequest request;
    request.set_world_id(world);
    request.set_player_id(player.player_id());
    request.set_player_secret(player.player_secret());
    request.set_tick(tick);
    *request.mutable_input() = input;
    v1::SendInputReply reply;
    Status st = unary(&v1::Physics::Stub::SendInput, request, &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Result<v1::ReportHashReply> report_hash(uint64_t world, const v1::JoinSessionReply& player,
                                          v1::ReportHashRequest request) override {
    request.set_world_id(world);
    request.set_player_id(player.player_id());
    request.set_player_secret(player.player_secret());
    v1::ReportHashReply reply;
    Status st = unary(&v1::Physics::Stub::ReportHash, request, &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Result<std::unique_ptr<Subscription>> watch_session(
      uint64_t world, std::function<void(const v1::SessionEvent&)> on_event,
      const v1::JoinSessionReply* as_player) override {
    v1::WatchSessionRequest request;
    request.set_world_id(world);
    if (as_player) {
      request.set_player_id(as_player->player_id());
      request.set_player_secret(as_player->player_secret());
    }
    v1::Physics::Stub* stub = stub_.get();
    return std::unique_ptr<Subscription>(new GrpcSubscription<v1::SessionEvent>(
        options_.token,
        [stub, request](grpc::ClientContext* c) { return stub->WatchSession(c, request); },
        std::move(on_event)));
  }

  Result<v1::ServerStats> get_stats() override {
    v1::ServerStats reply;
    Status st = unary(&v1::Physics::Stub::GetStats, v1::GetStatsRequest(), &reply);
    if (!st.ok()) return st;
    return reply;
  }

  Result<bool> health(const std::string& service) override {
    // grpc.health.v1 is not among Debian's generated protos, and its two messages are one
    // field each: HealthCheckRequest{string service = 1} and HealthCheckResponse{ServingStatus
    // status = 1} (SERVING = 1), written and read here by hand through the generic stub.
    if (service.size() > 127) return invalid_argument("service: at most 127 characters");
    std::string request_bytes;
    if (!service.empty()) {
      request_bytes = std::string("\x0a", 1) + static_cast<char>(service.size()) + service;
    }
    grpc::Slice slice{request_bytes};
    grpc::ByteBuffer request(&slice, 1), response;
    grpc::GenericStub generic(channel_);
    auto context = make_context();
    std::promise<grpc::Status> done;
    generic.UnaryCall(context.get(), "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request,
                      &response, [&](grpc::Status s) { done.set_value(s); });
    Status st = from_grpc(done.get_future().get());
    if (!st.ok()) return st;
    std::vector<grpc::Slice> slices;
    std::string reply;
    if (response.Dump(&slices).ok()) {
      for (const grpc::Slice& s : slices)
        reply.append(reinterpret_cast<const char*>(s.begin()), s.size());
    }
    return reply == std::string("\x08\x01", 2);
  }

 private:
  std::unique_ptr<grpc::ClientContext> make_context() const {
    auto context = std::make_unique<grpc::ClientContext>();
    context->set_deadline(std::chrono::system_clock::now() + options_.deadline);
    if (!options_.token.empty()) context->AddMetadata("authorization", "Bearer " + options_.token);
    return context;
  }

  // One unary call with the deadline and token of make_context(); the server's status mapped.
  template <typename Request, typename Reply>
  Status unary(grpc::Status (v1::Physics::Stub::*method)(grpc::ClientContext*, const Request&,
                                                         Reply*),
               const Request& request, Reply* reply) {
    auto context = make_context();
    return from_grpc((stub_.get()->*method)(context.get(), request, reply));
  }

  Result<WorldSummary> create(const v1::CreateWorldRequest& request) {
    v1::CreateWorldReply reply;
    Status st = unary(&v1::Physics::Stub::CreateWorld, request, &reply);
    if (!st.ok()) return st;
    WorldSummary out = summary_from(reply.world());
    for (const v1::Handle& h : reply.bodies()) out.bodies.push_back(id_from<BodyId>(h));
    for (const v1::Handle& h : reply.joints()) out.joints.push_back(id_from<JointId>(h));
    return out;
  }

  Status query(const v1::QueryRequest& request, v1::QueryReply* reply) {
    return unary(&v1::Physics::Stub::Query, request, reply);
  }

  Result<std::vector<ShapeHit>> shape_hits(const v1::QueryRequest& request) {
    v1::QueryReply reply;
    Status st = query(request, &reply);
    if (!st.ok()) return st;
    std::vector<ShapeHit> out;
    for (const v1::ShapeHit& h : reply.shapes()) {
      out.push_back(ShapeHit{id_from<ShapeId>(h.shape()), id_from<BodyId>(h.body())});
    }
    return out;
  }

  ClientOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::Physics::Stub> stub_;
};

}  // namespace

std::unique_ptr<Client> Client::connect(const ClientOptions& options) {
  return std::make_unique<GrpcClient>(options);
}

}  // namespace fulcrum::client
