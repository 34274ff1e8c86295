// The Physics gRPC service (proto/fulcrum/v1/service.proto). Each handler checks the caller's
// token and the request, calls the world's Session, and maps the result to a grpc::Status in
// one place (to_grpc_status). Unary calls use the synchronous API: stepping a world is blocking
// work and belongs on the server's handler threads. StreamFrames uses the callback API, one
// reactor per stream, so that an idle or slow watcher holds no thread.
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "fulcrum/scene.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "session.h"

namespace fulcrum::server {

grpc::Status to_grpc_status(const Status& status);

class FrameSender;

class PhysicsService final
    : public v1::Physics::WithCallbackMethod_WatchSession<
          v1::Physics::WithCallbackMethod_DownloadReplay<
              v1::Physics::WithRawCallbackMethod_StreamFrames<v1::Physics::Service>>> {
 public:
  // An empty token turns authentication off.
  PhysicsService(Registry* registry, std::string token);
  ~PhysicsService() override;

  grpc::Status CreateWorld(grpc::ServerContext* context, const v1::CreateWorldRequest* request,
                           v1::CreateWorldReply* reply) override;
  grpc::Status ListWorlds(grpc::ServerContext* context, const v1::ListWorldsRequest* request,
                          v1::ListWorldsReply* reply) override;
  grpc::Status GetWorld(grpc::ServerContext* context, const v1::GetWorldRequest* request,
                        v1::WorldInfo* reply) override;
  grpc::Status DescribeWorld(grpc::ServerContext* context, const v1::DescribeWorldRequest* request,
                             v1::DescribeWorldReply* reply) override;
  grpc::Status DeleteWorld(grpc::ServerContext* context, const v1::DeleteWorldRequest* request,
                           v1::DeleteWorldReply* reply) override;
  grpc::Status ApplyEdits(grpc::ServerContext* context, const v1::ApplyEditsRequest* request,
                          v1::ApplyEditsReply* reply) override;
  grpc::Status Step(grpc::ServerContext* context, const v1::StepRequest* request,
                    v1::StepReply* reply) override;
  grpc::Status GetSnapshot(grpc::ServerContext* context, const v1::GetSnapshotRequest* request,
                           v1::GetSnapshotReply* reply) override;
  grpc::Status RestoreSnapshot(grpc::ServerContext* context,
                               const v1::RestoreSnapshotRequest* request,
                               v1::RestoreSnapshotReply* reply) override;
  grpc::Status Query(grpc::ServerContext* context, const v1::QueryRequest* request,
                     v1::QueryReply* reply) override;
  // Raw bytes out: frames are encoded once and shared by readers (frames.h).
  grpc::ServerWriteReactor<grpc::ByteBuffer>* StreamFrames(
      grpc::CallbackServerContext* context, const grpc::ByteBuffer* request) override;
  grpc::Status GetStats(grpc::ServerContext* context, const v1::GetStatsRequest* request,
                        v1::ServerStats* reply) override;

  // Real time and replays on the server (clock.h, recorder.h).
  grpc::Status SetRunMode(grpc::ServerContext* context, const v1::SetRunModeRequest* request,
                          v1::SetRunModeReply* reply) override;
  grpc::Status StartRecording(grpc::ServerContext* context,
                              const v1::StartRecordingRequest* request,
                              v1::StartRecordingReply* reply) override;
  grpc::Status StopRecording(grpc::ServerContext* context, const v1::StopRecordingRequest* request,
                             v1::StopRecordingReply* reply) override;
  grpc::ServerWriteReactor<v1::ReplayChunk>* DownloadReplay(
      grpc::CallbackServerContext* context, const v1::DownloadReplayRequest* request) override;

  // A Step that streams samples of the bodies named, in parts, each sent before the next is
  // stepped (flow control holds the stepping, never the world: session.h).
  grpc::Status StepTrajectory(grpc::ServerContext* context,
                              const v1::StepTrajectoryRequest* request,
                              grpc::ServerWriter<v1::TrajectoryChunk>* writer) override;
  // Snapshots in chunks, both ways.
  grpc::Status DownloadSnapshot(grpc::ServerContext* context, const v1::GetSnapshotRequest* request,
                                grpc::ServerWriter<v1::SnapshotChunk>* writer) override;
  grpc::Status RestoreSnapshotStream(grpc::ServerContext* context,
                                     grpc::ServerReader<v1::RestoreSnapshotChunk>* reader,
                                     v1::RestoreSnapshotReply* reply) override;

  // Multiplayer sessions (session.proto, game_session.h).
  grpc::Status OpenSession(grpc::ServerContext* context, const v1::OpenSessionRequest* request,
                           v1::OpenSessionReply* reply) override;
  grpc::Status JoinSession(grpc::ServerContext* context, const v1::JoinSessionRequest* request,
                           v1::JoinSessionReply* reply) override;
  grpc::Status SetOwnership(grpc::ServerContext* context, const v1::SetOwnershipRequest* request,
                            v1::SetOwnershipReply* reply) override;
  grpc::Status SendInput(grpc::ServerContext* context, const v1::SendInputRequest* request,
                         v1::SendInputReply* reply) override;
  grpc::Status ReportHash(grpc::ServerContext* context, const v1::ReportHashRequest* request,
                          v1::ReportHashReply* reply) override;
  grpc::ServerWriteReactor<v1::SessionEvent>* WatchSession(
      grpc::CallbackServerContext* context, const v1::WatchSessionRequest* request) override;

  // New streams are refused and open ones end with UNAVAILABLE.
  void begin_shutdown();
  // The grace period is over: calls still running stop at their next check (between ticks,
  // edits or scene bodies) with UNAVAILABLE.
  void abandon_calls() { abandoning_ = true; }

 private:
  grpc::Status check_token(const grpc::ServerContextBase& context) const;
  // What long calls ask between ticks and edits: whether to go on.
  std::function<Status()> keep_going(const grpc::ServerContext* context) const;
  // RestoreSnapshot and RestoreSnapshotStream once the snapshot is whole: rollback into
  // `world_id`, or a fork named `name` when it is 0.
  grpc::Status restore(uint64_t world_id, const std::string& name, const v1::SnapshotFile& file,
                       v1::RestoreSnapshotReply* reply);
  // Admits the call, finds its world (request.world_id()) and runs `method` on it.
  template <typename Request, typename Reply>
  grpc::Status on_world(grpc::ServerContext* context, const Request& request, Reply* reply,
                        Status (Session::*method)(const Request&, Reply*));
  // The limits the registry's worlds are built under.
  WorkLimits work_limits(const grpc::ServerContext* context) const;

  Registry* registry_;
  const std::string token_;
  std::unique_ptr<FrameSender> sender_;  // hands frames to readers off the stepping threads
  std::atomic<bool> shutting_down_{false};
  std::atomic<bool> abandoning_{false};
};

}  // namespace fulcrum::server
