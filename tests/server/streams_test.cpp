// The calls that stream what Step and GetSnapshot return in one message: StepTrajectory (every
// sample, the stepping held by a slow reader but never the world) and snapshots in chunks both
// ways (any size the server allows, refused whole when a piece is wrong).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "fulcrum/client.h"
#include "fulcrum/scene.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"
#include "server.h"
#include "snapshot_convert.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using namespace std::chrono_literals;
using server::Server;
using server::ServerOptions;
using testing_support::pyramid_json;

// The pyramid scene stepped locally: hashes[t] is the state hash at tick t, and bodies[t] the
// state of every body at tick t.
struct LocalRun {
  std::vector<uint64_t> hashes;
  std::vector<std::vector<BodyState>> bodies;
};
const LocalRun& local_pyramid(int ticks) {
  static LocalRun run;
  if (static_cast<int>(run.hashes.size()) <= ticks) {
    Result<SceneDef> scene = parse_scene_json(pyramid_json());
    EXPECT_TRUE(scene.ok());
    Result<World> world = build_world(*scene);
    EXPECT_TRUE(world.ok());
    run = {};
    for (int t = 0; t <= ticks; ++t) {
      if (t > 0) world->step();
      run.hashes.push_back(world->state_hash());
      std::vector<BodyState> states;
      for (BodyId id : world->bodies()) states.push_back(*world->body_state(id));
      run.bodies.push_back(std::move(states));
    }
  }
  return run;
}

class StreamsTest : public ::testing::Test {
 protected:
  void start(ServerOptions options = {}) {
    options.listen = "127.0.0.1:0";
    auto started = Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    stub_ = v1::Physics::NewStub(
        grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()));
    client::ClientOptions copts;
    copts.address = server_->address();
    client_ = client::Client::connect(copts);
  }

  uint64_t create_pyramid() {
    Result<client::WorldSummary> w = client_->create_world_json(pyramid_json());
    EXPECT_TRUE(w.ok()) << w.status().message();
    return w.ok() ? w->id : 0;
  }

  static std::unique_ptr<grpc::ClientContext> context() {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + 30s);
    return c;
  }

  int64_t tick_of(uint64_t world) {
    Result<client::WorldSummary> w = client_->get_world(world);
    EXPECT_TRUE(w.ok());
    return w.ok() ? w->tick : -1;
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::Physics::Stub> stub_;
  std::unique_ptr<client::Client> client_;
};

TEST_F(StreamsTest, ATrajectoryHoldsEverySampleOfTheBodiesNamedInTheirOrder) {
  start();
  const uint64_t id = create_pyramid();
  const LocalRun& local = local_pyramid(100);
  client::TrajectoryOptions options;
  options.ticks = 100;
  options.every_ticks = 3;
  options.include_start = true;
  options.bodies = {BodyId{5, 1}, BodyId{1, 1}};  // not in index order: kept as asked
  std::vector<client::TrajectorySample> samples;
  Result<client::StepResult> done =
      client_->step_trajectory(id, options, [&](const client::TrajectorySample& s) {
        samples.push_back(s);
        return Status();
      });
  ASSERT_TRUE(done.ok()) << done.status().message();
  EXPECT_EQ(done->tick, 100);
  EXPECT_EQ(done->state_hash, local.hashes[100]);

  // The start, then ticks 3, 6, ... 99: 34 samples, each the world exactly as stepped locally.
  ASSERT_EQ(samples.size(), 34u);
  for (size_t i = 0; i < samples.size(); ++i) {
    const client::TrajectorySample& s = samples[i];
    ASSERT_EQ(s.tick, static_cast<int64_t>(3 * i)) << i;
    EXPECT_EQ(s.state_hash, local.hashes[s.tick]) << s.tick;
    ASSERT_EQ(s.bodies.size(), 2u);
    for (int k = 0; k < 2; ++k) {
      const BodyId want = options.bodies[k];
      EXPECT_EQ(s.bodies[k].id, want);
      const BodyState& exact = local.bodies[s.tick][want.index];
      EXPECT_EQ(s.bodies[k].position.x(), exact.transform.p.x());
      EXPECT_EQ(s.bodies[k].position.y(), exact.transform.p.y());
      EXPECT_EQ(s.bodies[k].angular_velocity, exact.angular_velocity);
      EXPECT_FALSE(s.bodies[k].quantized);
    }
  }
  EXPECT_EQ(tick_of(id), 100);

  // No bodies named: every live body, in index order.
  options = {};
  options.ticks = 1;
  std::vector<client::TrajectorySample> every;
  ASSERT_TRUE(client_
                  ->step_trajectory(id, options,
                                    [&](const client::TrajectorySample& s) {
                                      every.push_back(s);
                                      return Status();
                                    })
                  .ok());
  ASSERT_EQ(every.size(), 1u);
  ASSERT_EQ(every[0].bodies.size(), local.bodies[0].size());
  for (size_t i = 1; i < every[0].bodies.size(); ++i) {
    EXPECT_LT(every[0].bodies[i - 1].id.index, every[0].bodies[i].id.index);
  }
}

TEST_F(StreamsTest, AStoppedTrajectoryReaderHoldsTheSteppingButNotTheWorld) {
  start();
  const uint64_t id = create_pyramid();
  // Every body every tick: about 4 KB a tick, far more than the connection's buffers hold.
  v1::StepTrajectoryRequest request;
  request.set_world_id(id);
  request.set_ticks(200000);
  auto ctx = context();
  auto reader = stub_->StepTrajectory(ctx.get(), request);
  v1::TrajectoryChunk chunk;
  ASSERT_TRUE(reader->Read(&chunk));
  ASSERT_GT(chunk.samples_size(), 0);
  const int64_t first_tick = chunk.samples(0).tick();
  EXPECT_EQ(first_tick, 1);

  // The reader takes nothing more: the stepping stops once the buffers are full ...
  int64_t held = -1;
  ASSERT_TRUE(testing_support::eventually(
      [&] {
        const int64_t before = tick_of(id);
        std::this_thread::sleep_for(300ms);
        const int64_t after = tick_of(id);
        held = after;
        return before == after;
      },
      20s));
  EXPECT_LT(held, 200000);
  // ... while the world answers other calls at once (it is not held while the server waits).
  const auto asked = std::chrono::steady_clock::now();
  v1::GetSnapshotReply snapshot;
  {
    auto c = context();
    v1::GetSnapshotRequest get;
    get.set_world_id(id);
    ASSERT_TRUE(stub_->GetSnapshot(c.get(), get, &snapshot).ok());
  }
  EXPECT_LT(std::chrono::steady_clock::now() - asked, 2s);
  EXPECT_EQ(snapshot.tick(), held);

  // Reading again resumes the stepping, with no tick missing in between.
  int64_t last = chunk.samples(chunk.samples_size() - 1).tick();
  for (int i = 0; i < 50 && reader->Read(&chunk); ++i) {
    for (const v1::TrajectorySample& s : chunk.samples()) {
      ASSERT_EQ(s.tick(), last + 1);
      last = s.tick();
    }
  }
  EXPECT_GT(last, first_tick);
  ctx->TryCancel();
  grpc::Status finished = reader->Finish();
  EXPECT_EQ(finished.error_code(), grpc::StatusCode::CANCELLED) << finished.error_message();
  // The world keeps the ticks it ran and goes on answering.
  EXPECT_TRUE(testing_support::eventually([&] { return tick_of(id) >= last; }, 5s));
  EXPECT_TRUE(client_->step(id, 1).ok());
}

TEST_F(StreamsTest, ABadTrajectoryRequestIsRefusedBeforeAnyTick) {
  start();
  const uint64_t id = create_pyramid();
  auto refused = [&](v1::StepTrajectoryRequest request) {
    request.set_world_id(id);
    auto ctx = context();
    auto reader = stub_->StepTrajectory(ctx.get(), request);
    v1::TrajectoryChunk chunk;
    EXPECT_FALSE(reader->Read(&chunk));
    return reader->Finish();
  };
  v1::StepTrajectoryRequest r;
  r.set_ticks(10);
  v1::Handle* h = r.add_bodies();
  h->set_index(1);
  h->set_generation(1);
  h = r.add_bodies();
  h->set_index(999);
  h->set_generation(1);
  grpc::Status s = refused(r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(s.error_message(), "bodies[1]: no live body {999, 1}");

  r.mutable_bodies(1)->set_index(1);
  s = refused(r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "bodies[1]: body {1, 1} is listed twice (also bodies[0])");

  r.clear_bodies();
  r.set_ticks(0);
  s = refused(r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("ticks"), std::string::npos);

  r.set_ticks(5);
  r.set_expected_tick(7);
  s = refused(r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(tick_of(id), 0) << "a refused trajectory runs no tick";

  r.set_world_id(12345);
  auto ctx = context();
  v1::StepTrajectoryRequest unknown = r;
  unknown.set_world_id(12345);
  auto reader = stub_->StepTrajectory(ctx.get(), unknown);
  v1::TrajectoryChunk chunk;
  EXPECT_FALSE(reader->Read(&chunk));
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST_F(StreamsTest, SnapshotsLargerThanAMessageTravelInChunksBothWays) {
  ServerOptions options;
  options.max_message_bytes = ServerOptions::kMinMessageBytes;  // 128 KiB
  start(options);
  // 5051 bodies: a snapshot of about a megabyte.
  Result<client::WorldSummary> w = client_->create_world_json(R"({"builtin": "large_pyramid"})");
  ASSERT_TRUE(w.ok()) << w.status().message();
  const uint64_t id = w->id;
  ASSERT_TRUE(client_->step(id, 30).ok());

  // In one message the snapshot cannot leave the server ...
  {
    auto c = context();
    v1::GetSnapshotRequest get;
    get.set_world_id(id);
    v1::GetSnapshotReply reply;
    EXPECT_EQ(stub_->GetSnapshot(c.get(), get, &reply).error_code(),
              grpc::StatusCode::RESOURCE_EXHAUSTED);
  }
  // A trajectory of every body could not send one sample in a message either: refused.
  client::TrajectoryOptions all;
  Result<client::StepResult> too_wide =
      client_->step_trajectory(id, all, [](const client::TrajectorySample&) { return Status(); });
  EXPECT_EQ(too_wide.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(too_wide.status().message().find("--max-message-bytes 131072"), std::string::npos)
      << too_wide.status().message();
  // ... in chunks it does, and goes back in: a rollback and a fork continue bit for bit.
  Result<client::SnapshotResult> snap = client_->get_snapshot(id);
  ASSERT_TRUE(snap.ok()) << snap.status().message();
  EXPECT_GT(snap->bytes.size(), 2u * ServerOptions::kMinMessageBytes);
  EXPECT_EQ(snap->tick, 30);
  Result<client::StepResult> ahead = client_->step(id, 30);
  ASSERT_TRUE(ahead.ok());
  Result<client::RestoreResult> back = client_->restore(id, snap->bytes);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->tick, 30);
  EXPECT_EQ(back->state_hash, snap->state_hash);
  Result<client::RestoreResult> fork = client_->restore(0, snap->bytes, "fork");
  ASSERT_TRUE(fork.ok()) << fork.status().message();
  for (uint64_t world : {id, fork->world_id}) {
    Result<client::StepResult> on = client_->step(world, 30);
    ASSERT_TRUE(on.ok());
    EXPECT_EQ(on->state_hash, ahead->state_hash) << world;
  }
}

TEST_F(StreamsTest, ABrokenSnapshotUploadChangesNothing) {
  ServerOptions options;
  options.limits.max_snapshot_bytes = 1 << 20;
  start(options);
  const uint64_t id = create_pyramid();
  Result<client::SnapshotResult> snap = client_->get_snapshot(id);
  ASSERT_TRUE(snap.ok());
  ASSERT_TRUE(client_->step(id, 20).ok());
  const uint64_t hash_before = client_->get_world(id)->state_hash;
  const std::string& bytes = snap->bytes;
  const size_t half = bytes.size() / 2;

  // Sends the messages in order; the server's answer.
  auto upload = [&](std::vector<v1::RestoreSnapshotChunk> messages) {
    auto ctx = context();
    v1::RestoreSnapshotReply reply;
    auto writer = stub_->RestoreSnapshotStream(ctx.get(), &reply);
    for (const auto& m : messages) {
      if (!writer->Write(m)) break;
    }
    writer->WritesDone();
    return writer->Finish();
  };
  auto piece = [&](uint64_t offset, size_t size, bool first, bool last, uint64_t checksum) {
    v1::RestoreSnapshotChunk m;
    if (first) {
      m.set_world_id(id);
      m.mutable_chunk()->set_total_size(bytes.size());
    }
    m.mutable_chunk()->set_offset(offset);
    m.mutable_chunk()->set_data(bytes.substr(offset, size));
    m.mutable_chunk()->set_last(last);
    m.mutable_chunk()->set_checksum(checksum);
    return m;
  };
  const uint64_t sum = fnv1a64(bytes);

  grpc::Status s = upload({piece(0, half, true, false, 0), piece(half + 1, 10, false, true, sum)});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "chunks[1].chunk.offset: expected " + std::to_string(half) +
                                   " (the bytes received so far), got " + std::to_string(half + 1) +
                                   "; nothing was restored");

  s = upload({piece(0, half, true, false, 0)});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("without a chunk marked last"), std::string::npos);

  s = upload(
      {piece(0, half, true, false, 0), piece(half, bytes.size() - half, false, true, sum ^ 1)});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::DATA_LOSS);

  v1::RestoreSnapshotChunk big = piece(0, 10, true, false, 0);
  big.mutable_chunk()->set_total_size(2 << 20);
  s = upload({big});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(s.error_message().find("--max-snapshot-bytes"), std::string::npos);

  EXPECT_EQ(client_->get_world(id)->state_hash, hash_before);
  EXPECT_EQ(client_->get_world(id)->tick, 20);

  // The same pieces, right: the world is back at tick 0.
  s = upload({piece(0, half, true, false, 0), piece(half, bytes.size() - half, false, true, sum)});
  EXPECT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(client_->get_world(id)->tick, 0);
  EXPECT_EQ(client_->get_world(id)->state_hash, snap->state_hash);
}

}  // namespace
}  // namespace fulcrum
