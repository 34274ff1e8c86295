// The server in-process on an ephemeral loopback port: determinism across the wire, refused
// requests that leave the world untouched, rollback and fork, many stream readers, slow
// readers, limits, authentication and shutdown.
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <limits>
#include <mutex>
#include <sstream>
#include <thread>

#include "fulcrum/client.h"
#include "fulcrum/scene.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"
#include "server.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using server::Server;
using server::ServerOptions;

using testing_support::eventually;
using testing_support::pyramid_json;
using testing_support::read_text;

// State hashes of a local pyramid world after each tick: hashes[t] is the hash at tick t.
const std::vector<uint64_t>& local_pyramid_hashes(int ticks) {
  static std::vector<uint64_t> hashes;
  if (static_cast<int>(hashes.size()) <= ticks) {
    Result<SceneDef> scene = parse_scene_json(pyramid_json());
    EXPECT_TRUE(scene.ok());
    Result<World> world = build_world(*scene);
    EXPECT_TRUE(world.ok());
    hashes.assign(1, world->state_hash());
    for (int t = 1; t <= ticks; ++t) {
      world->step();
      hashes.push_back(world->state_hash());
    }
  }
  return hashes;
}

class ServerTest : public ::testing::Test {
 protected:
  void start(ServerOptions options = {}) {
    options.listen = "127.0.0.1:0";
    auto started = Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    token_ = options.token;
    channel_ = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
    stub_ = v1::Physics::NewStub(channel_);
    client::ClientOptions copts;
    copts.address = server_->address();
    copts.token = options.token;
    client_ = client::Client::connect(copts);
  }

  std::unique_ptr<grpc::ClientContext> context(const std::string& token = "<default>") {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    const std::string t = token == "<default>" ? token_ : token;
    if (!t.empty()) c->AddMetadata("authorization", "Bearer " + t);
    return c;
  }

  uint64_t create_pyramid() {
    Result<client::WorldSummary> w = client_->create_world_json(pyramid_json());
    EXPECT_TRUE(w.ok()) << w.status().message();
    return w.ok() ? w->id : 0;
  }

  // A reader's copy of a world kept from a CHANGED stream: bodies by index as the frames left
  // them, and the tick and state hash of the last frame.
  struct Mirror {
    std::map<int32_t, client::BodyFrame> bodies;
    int64_t tick = -1;
    uint64_t hash = 0;
  };
  // Follows world `id` through 12 Steps of 5 ticks with a CHANGED stream until the frame of
  // tick 60 arrives (at most 20 s), then cancels the stream.
  void mirror_changed_stream(uint64_t id, bool quantized, Mirror* out) {
    std::mutex mu;
    Mirror m;
    client::SubscribeOptions options;
    options.bodies = client::FrameBodies::kChanged;
    options.quantized = quantized;
    auto sub = client_->subscribe(id, options, [&](const client::Frame& f) {
      std::lock_guard<std::mutex> lock(mu);
      if (f.full) m.bodies.clear();
      for (const BodyId& gone : f.destroyed) m.bodies.erase(gone.index);
      for (const client::BodyFrame& b : f.bodies) m.bodies[b.id.index] = b;
      m.tick = f.tick;
      m.hash = f.state_hash;
    });
    ASSERT_TRUE(sub.ok());
    for (int i = 0; i < 12; ++i) ASSERT_TRUE(client_->step(id, 5).ok());
    const bool reached = eventually([&] {
      std::lock_guard<std::mutex> lock(mu);
      return m.tick == 60;
    });
    (*sub)->cancel();
    ASSERT_TRUE(reached) << "the frame of tick 60 never arrived";
    std::lock_guard<std::mutex> lock(mu);
    *out = std::move(m);
  }

  v1::WorldInfo info(uint64_t world) {
    v1::GetWorldRequest request;
    request.set_world_id(world);
    v1::WorldInfo reply;
    auto c = context();
    EXPECT_TRUE(stub_->GetWorld(c.get(), request, &reply).ok());
    return reply;
  }

  grpc::Status apply(uint64_t world, const v1::EditBatch& batch,
                     std::optional<int64_t> expected_tick = {}) {
    v1::ApplyEditsRequest request;
    request.set_world_id(world);
    *request.mutable_batch() = batch;
    if (expected_tick) request.set_expected_tick(*expected_tick);
    v1::ApplyEditsReply reply;
    auto c = context();
    return stub_->ApplyEdits(c.get(), request, &reply);
  }

  std::unique_ptr<Server> server_;
  std::string token_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::Physics::Stub> stub_;
  std::unique_ptr<client::Client> client_;
};

v1::Edit set_velocity(int index, uint32_t generation, double vx, double vy) {
  v1::Edit e;
  e.mutable_set_velocity()->mutable_body()->set_index(index);
  e.mutable_set_velocity()->mutable_body()->set_generation(generation);
  e.mutable_set_velocity()->mutable_linear()->set_x(vx);
  e.mutable_set_velocity()->mutable_linear()->set_y(vy);
  return e;
}

// CreateWorld answers with the scene's handles in the scene's order: the builders' bodies,
// then the explicit ones; joints as listed.
TEST_F(ServerTest, CreateWorldAnswersTheScenesHandlesInOrder) {
  start();
  Result<client::WorldSummary> made = client_->create_world_json(R"({
    "builders": [{"ground": {"half_width": 10}}],
    "bodies": [{"type": "BODY_TYPE_DYNAMIC", "position": {"x": 5, "y": 7},
                "shapes": [{"circle": {"radius": 0.25}}]},
               {"type": "BODY_TYPE_DYNAMIC", "position": {"x": 6, "y": 7},
                "shapes": [{"circle": {"radius": 0.25}}]}],
    "joints": [{"body_a": 1, "body_b": 2, "distance": {"length": 1}}]})");
  ASSERT_TRUE(made.ok()) << made.status().message();
  ASSERT_EQ(made->bodies.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(made->bodies[i].index, i);
    EXPECT_EQ(made->bodies[i].generation, 1u);
  }
  ASSERT_EQ(made->joints.size(), 1u);
  EXPECT_EQ(made->joints[0].index, 0);
  // The handle names the body the scene put there.
  v1::QueryRequest query;
  query.set_world_id(made->id);
  query.mutable_point()->mutable_point()->set_x(5);
  query.mutable_point()->mutable_point()->set_y(7);
  v1::QueryReply hits;
  ASSERT_TRUE(stub_->Query(context().get(), query, &hits).ok());
  ASSERT_EQ(hits.shapes_size(), 1);
  EXPECT_EQ(hits.shapes(0).body().index(), made->bodies[1].index);
  Result<client::WorldSummary> info = client_->get_world(made->id);
  ASSERT_TRUE(info.ok());
  EXPECT_TRUE(info->bodies.empty() && info->joints.empty());
}

TEST_F(ServerTest, StepsMatchALocalWorldBitForBit) {
  start();
  const uint64_t id = create_pyramid();
  const auto& expected = local_pyramid_hashes(240);
  EXPECT_EQ(info(id).state_hash(), expected[0]);
  EXPECT_EQ(info(id).body_count(), 211);
  int64_t tick = 0;
  for (uint32_t n : {1u, 59u, 100u, 80u}) {
    Result<client::StepResult> r = client_->step(id, n);
    ASSERT_TRUE(r.ok()) << r.status().message();
    tick += n;
    EXPECT_EQ(r->tick, tick);
    EXPECT_EQ(r->state_hash, expected[tick]) << "tick " << tick;
  }
}

// --world-threads: every world steps on three threads, bit for bit as one local thread does.
TEST_F(ServerTest, WorldThreadsStepBitForBitAsOneThread) {
  ServerOptions options;
  options.limits.world_threads = 3;
  start(options);
  const uint64_t id = create_pyramid();
  const auto& expected = local_pyramid_hashes(240);
  int64_t tick = 0;
  for (uint32_t n : {1u, 59u, 60u}) {
    Result<client::StepResult> r = client_->step(id, n);
    ASSERT_TRUE(r.ok()) << r.status().message();
    tick += n;
    EXPECT_EQ(r->state_hash, expected[tick]) << "tick " << tick;
  }
}

TEST_F(ServerTest, RefusedRequestsLeaveTheWorldUnchanged) {
  start();
  const uint64_t id = create_pyramid();
  ASSERT_TRUE(client_->step(id, 10).ok());
  const uint64_t hash = info(id).state_hash();

  {  // NaN in an edit, after a valid one: the batch is refused whole.
    v1::EditBatch batch;
    *batch.add_edits() = set_velocity(5, 1, 1.0, 0.0);
    *batch.add_edits() = set_velocity(6, 1, std::numeric_limits<double>::quiet_NaN(), 0.0);
    grpc::Status st = apply(id, batch);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("batch.edits[1].set_velocity"), std::string::npos)
        << st.error_message();
  }
  {  // Unknown world.
    v1::EditBatch batch;
    *batch.add_edits() = set_velocity(5, 1, 1.0, 0.0);
    grpc::Status st = apply(9999, batch);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND);
    EXPECT_NE(st.error_message().find("world_id"), std::string::npos) << st.error_message();
  }
  {  // Empty batch.
    grpc::Status st = apply(id, v1::EditBatch());
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("batch.edits"), std::string::npos) << st.error_message();
  }
  {  // expected_tick mismatch, on edits and on steps.
    v1::EditBatch batch;
    *batch.add_edits() = set_velocity(5, 1, 1.0, 0.0);
    grpc::Status st = apply(id, batch, 3);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(st.error_message().find("expected_tick"), std::string::npos);
    Result<client::StepResult> r = client_->step(id, 1, 9);
    EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  }
  {  // Zero ticks.
    Result<client::StepResult> r = client_->step(id, 0);
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("ticks"), std::string::npos);
  }
  EXPECT_EQ(info(id).state_hash(), hash);
  EXPECT_EQ(info(id).tick(), 10);

  {  // A stale handle: create a body, destroy it, then address the old handle.
    v1::EditBatch create;
    v1::Body* body = create.add_edits()->mutable_create_body();
    body->set_type(v1::BODY_TYPE_DYNAMIC);
    body->mutable_position()->set_y(40);
    body->add_shapes()->mutable_circle()->set_radius(0.5);
    Result<client::EditResult> made = client_->apply_edits(id, create, 10);
    ASSERT_TRUE(made.ok()) << made.status().message();
    ASSERT_EQ(made->bodies.size(), 1u);
    const BodyId stale = made->bodies[0];
    v1::EditBatch destroy;
    v1::Handle* h = destroy.add_edits()->mutable_destroy_body();
    h->set_index(stale.index);
    h->set_generation(stale.generation);
    ASSERT_TRUE(client_->apply_edits(id, destroy).ok());
    const uint64_t after = info(id).state_hash();
    v1::EditBatch poke;
    *poke.add_edits() = set_velocity(stale.index, stale.generation, 1.0, 0.0);
    grpc::Status st = apply(id, poke);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << st.error_message();
    EXPECT_EQ(info(id).state_hash(), after);
  }
}

TEST_F(ServerTest, RollbackAndForkContinueBitForBit) {
  start();
  const uint64_t id = create_pyramid();
  const auto& expected = local_pyramid_hashes(120);
  ASSERT_TRUE(client_->step(id, 60).ok());
  Result<client::SnapshotResult> snap = client_->get_snapshot(id);
  ASSERT_TRUE(snap.ok());
  EXPECT_EQ(snap->tick, 60);
  EXPECT_EQ(snap->state_hash, expected[60]);
  ASSERT_TRUE(client_->step(id, 60).ok());

  Result<client::RestoreResult> back = client_->restore(id, snap->bytes);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->world_id, id);
  EXPECT_EQ(back->tick, 60);
  Result<client::StepResult> again = client_->step(id, 60);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->state_hash, expected[120]);

  Result<client::RestoreResult> fork = client_->restore(0, snap->bytes, "fork");
  ASSERT_TRUE(fork.ok()) << fork.status().message();
  EXPECT_NE(fork->world_id, id);
  Result<client::StepResult> forked = client_->step(fork->world_id, 60);
  ASSERT_TRUE(forked.ok());
  EXPECT_EQ(forked->state_hash, expected[120]);

  // A damaged snapshot is refused and the world keeps its state.
  std::string damaged = snap->bytes;
  damaged[damaged.size() / 2] ^= 0x5a;
  Result<client::RestoreResult> bad = client_->restore(id, damaged);
  EXPECT_FALSE(bad.ok());
  EXPECT_EQ(info(id).state_hash(), expected[120]);
}

TEST_F(ServerTest, TenReadersSeeIncreasingTicksAndMatchingHashes) {
  start();
  const uint64_t id = create_pyramid();
  const int kTicks = 180;
  const auto& expected = local_pyramid_hashes(kTicks);

  struct Reader {
    std::mutex mu;
    std::vector<int64_t> ticks;
    int mismatches = 0;
    std::unique_ptr<client::Subscription> sub;
  };
  std::vector<std::unique_ptr<Reader>> readers;
  for (int i = 0; i < 10; ++i) {
    auto reader = std::make_unique<Reader>();
    Reader* r = reader.get();
    client::SubscribeOptions options;
    options.every_ticks = 1 + i % 3;
    options.bodies = i % 2 == 0 ? client::FrameBodies::kChanged : client::FrameBodies::kAll;
    auto sub = client_->subscribe(id, options, [r, &expected](const client::Frame& f) {
      std::lock_guard<std::mutex> lock(r->mu);
      r->ticks.push_back(f.tick);
      if (f.tick < 0 || f.tick >= static_cast<int64_t>(expected.size()) ||
          f.state_hash != expected[f.tick]) {
        ++r->mismatches;
      }
    });
    ASSERT_TRUE(sub.ok());
    r->sub = std::move(sub).value();
    readers.push_back(std::move(reader));
  }
  for (int t = 0; t < kTicks; t += 10) ASSERT_TRUE(client_->step(id, 10).ok());

  // Every reader eventually sees the last tick (or the last tick due at its interval).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  for (auto& r : readers) {
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(r->mu);
        if (!r->ticks.empty() && r->ticks.back() >= kTicks - 2) break;
      }
      ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "a reader never caught up";
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  for (auto& r : readers) {
    r->sub->cancel();
    std::lock_guard<std::mutex> lock(r->mu);
    EXPECT_EQ(r->mismatches, 0);
    for (size_t i = 1; i < r->ticks.size(); ++i) EXPECT_LT(r->ticks[i - 1], r->ticks[i]);
  }
}

TEST_F(ServerTest, ChangedFramesRebuildTheWorld) {
  start();
  Mirror mirror;
  ASSERT_NO_FATAL_FAILURE(mirror_changed_stream(create_pyramid(), false, &mirror));
  const auto& bodies = mirror.bodies;

  Result<SceneDef> scene = parse_scene_json(pyramid_json());
  Result<World> local = build_world(*scene);
  for (int t = 0; t < 60; ++t) local->step();
  ASSERT_EQ(bodies.size(), static_cast<size_t>(local->body_count()));
  for (BodyId id_local : local->bodies()) {
    const BodyState s = *local->body_state(id_local);
    const client::BodyFrame& b = bodies.at(id_local.index);
    EXPECT_EQ(b.position.x(), s.transform.p.x());
    EXPECT_EQ(b.position.y(), s.transform.p.y());
    EXPECT_EQ(b.linear_velocity.x(), s.linear_velocity.x());
    EXPECT_EQ(b.awake, s.awake);
  }
}

// A reader that takes nothing until the world has stepped 400 ticks: the steps must finish
// anyway (the world never waits for a reader), and once the gRPC transport's flow-control
// window is full the frames it could not take are coalesced into the newest one. Frames of a
// 1830-body pyramid are about 130 kB, so 400 of them overflow any window gRPC grants.
TEST_F(ServerTest, AStalledReaderIsCoalescedAndDoesNotHoldTheWorld) {
  // The reader stalls for as long as the 400 ticks take, which under a sanitizer on a busy
  // machine can pass the default 10 s after which a stalled reader is ended: this test is about
  // coalescing, so it gives the reader the largest stall allowed.
  ServerOptions server;
  server.limits.max_reader_stall_ms = 86400000;
  start(server);
  Result<client::WorldSummary> big = client_->create_world_json(
      R"({"name": "big", "settings": {"gravity": {"x": 0, "y": -10}},
          "builders": [{"ground": {"halfWidth": 100}}, {"pyramid": {"base": 60}}]})");
  ASSERT_TRUE(big.ok()) << big.status().message();
  const uint64_t id = big->id;
  std::promise<void> stepped;
  std::shared_future<void> released = stepped.get_future().share();
  std::atomic<int64_t> last_tick{-1};
  std::atomic<uint64_t> skipped{0};
  std::atomic<int> frames{0};
  client::SubscribeOptions options;
  options.bodies = client::FrameBodies::kAll;
  auto sub = client_->subscribe(id, options, [&](const client::Frame& f) {
    released.wait();
    last_tick = f.tick;
    skipped += f.skipped_frames;
    ++frames;
  });
  ASSERT_TRUE(sub.ok());
  const int kTicks = 400;
  for (int i = 0; i < kTicks; ++i) ASSERT_TRUE(client_->step(id, 1).ok());
  stepped.set_value();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (last_tick.load() != kTicks) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "the last frame never arrived";
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::printf("stalled reader: %d frames delivered for %d ticks, %llu coalesced\n", frames.load(),
              kTicks, static_cast<unsigned long long>(skipped.load()));
  EXPECT_GT(skipped.load(), 0u);
  EXPECT_LT(frames.load(), kTicks);
  (*sub)->cancel();
}

TEST_F(ServerTest, DeletingAWorldEndsItsStreams) {
  start();
  const uint64_t id = create_pyramid();
  auto sub = client_->subscribe(id, {}, [](const client::Frame&) {});
  ASSERT_TRUE(sub.ok());
  ASSERT_TRUE(client_->step(id, 2).ok());
  ASSERT_TRUE(client_->delete_world(id).ok());
  Status end = (*sub)->wait();
  EXPECT_EQ(end.code(), StatusCode::kNotFound) << end.message();
  EXPECT_EQ(client_->get_world(id).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(client_->delete_world(id).code(), StatusCode::kNotFound);
}

TEST_F(ServerTest, LimitsAreEnforced) {
  ServerOptions options;
  options.limits.max_worlds = 2;
  options.limits.max_bodies = 250;
  options.limits.max_step_ticks = 100;
  start(options);
  const uint64_t a = create_pyramid();
  create_pyramid();
  Result<client::WorldSummary> third = client_->create_world_json(pyramid_json());
  EXPECT_EQ(third.status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(client_->step(a, 101).status().code(), StatusCode::kResourceExhausted);
  v1::EditBatch many;
  for (int i = 0; i < 40; ++i) {
    v1::Body* b = many.add_edits()->mutable_create_body();
    b->set_type(v1::BODY_TYPE_DYNAMIC);
    b->add_shapes()->mutable_circle()->set_radius(0.5);
  }
  EXPECT_EQ(client_->apply_edits(a, many).status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(info(a).body_count(), 211);
}

TEST_F(ServerTest, QueriesSeeTheWorld) {
  start();
  const uint64_t id = create_pyramid();
  Result<std::optional<RayHit>> hit = client_->ray_cast_closest(id, Vec2(0, 50), Vec2(0, -100));
  ASSERT_TRUE(hit.ok()) << hit.status().message();
  ASSERT_TRUE(hit->has_value());
  EXPECT_NEAR((*hit)->point.y(), 20.0, 0.1);  // the top box of a 20-row pyramid of 1 m boxes
  Result<std::vector<client::ShapeHit>> boxes =
      client_->overlap_aabb(id, AABB{Vec2(-0.2, 0.2), Vec2(0.2, 0.4)});
  ASSERT_TRUE(boxes.ok());
  EXPECT_FALSE(boxes->empty());
  Result<std::vector<client::ShapeHit>> nothing = client_->overlap_point(id, Vec2(0, 100));
  ASSERT_TRUE(nothing.ok());
  EXPECT_TRUE(nothing->empty());
  Result<std::optional<RayHit>> bad = client_->ray_cast_closest(id, Vec2(0, 50), Vec2(0, 0));
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
}

TEST_F(ServerTest, TokenIsRequiredWhenSet) {
  ServerOptions options;
  options.token = "s3cret";
  start(options);
  v1::ListWorldsReply reply;
  auto none = context("");
  EXPECT_EQ(stub_->ListWorlds(none.get(), {}, &reply).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  auto wrong = context("guess");
  EXPECT_EQ(stub_->ListWorlds(wrong.get(), {}, &reply).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  auto right = context("s3cret");
  EXPECT_TRUE(stub_->ListWorlds(right.get(), {}, &reply).ok());
  EXPECT_NE(create_pyramid(), 0u);  // the client library sends the token

  // Streams check it too.
  client::ClientOptions anonymous;
  anonymous.address = server_->address();
  auto stranger = client::Client::connect(anonymous);
  auto sub = stranger->subscribe(1, {}, [](const client::Frame&) {});
  ASSERT_TRUE(sub.ok());
  Status end = (*sub)->wait();
  EXPECT_NE(end.message().find("UNAUTHENTICATED"), std::string::npos) << end.message();

  // Health checks need no token: HealthCheckRequest{} is empty bytes; SERVING is 08 01.
  grpc::GenericStub generic(channel_);
  grpc::ClientContext health_context;
  grpc::Slice empty{std::string()};
  grpc::ByteBuffer request(&empty, 1), response;
  std::promise<grpc::Status> done;
  generic.UnaryCall(&health_context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request,
                    &response, [&](grpc::Status s) { done.set_value(s); });
  grpc::Status health = done.get_future().get();
  ASSERT_TRUE(health.ok()) << health.error_message();
  std::vector<grpc::Slice> slices;
  ASSERT_TRUE(response.Dump(&slices).ok());
  std::string bytes;
  for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  EXPECT_EQ(bytes, std::string("\x08\x01", 2));
}

// Lists services through server reflection with the given token ("" for none): the status and
// the reply bytes. ServerReflectionRequest{list_services: ""} is the bytes 3a 00; the reply
// names each service.
std::pair<grpc::Status, std::string> list_services(const std::shared_ptr<grpc::Channel>& channel,
                                                   const std::string& token) {
  class Lister : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
   public:
    void start() {
      StartWrite(&request_, grpc::WriteOptions().set_last_message());
      StartRead(&response_);
      StartCall();
    }
    void OnReadDone(bool ok) override {
      if (!ok) return;
      std::vector<grpc::Slice> slices;
      if (response_.Dump(&slices).ok()) {
        for (const auto& s : slices)
          text_.append(reinterpret_cast<const char*>(s.begin()), s.size());
      }
      StartRead(&response_);
    }
    void OnDone(const grpc::Status& status) override { done_.set_value(status); }
    grpc::Slice slice_{std::string("\x3a\x00", 2)};
    grpc::ByteBuffer request_{&slice_, 1};
    grpc::ByteBuffer response_;
    std::string text_;
    std::promise<grpc::Status> done_;
  } lister;
  grpc::GenericStub generic(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
  generic.PrepareBidiStreamingCall(&context,
                                   "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                                   grpc::StubOptions(), &lister);
  lister.start();
  grpc::Status status = lister.done_.get_future().get();
  return {status, lister.text_};
}

// Server reflection lists the Physics service and the health service.
TEST_F(ServerTest, ReflectionListsThePhysicsService) {
  start();
  auto [status, text] = list_services(channel_, "");
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_NE(text.find("fulcrum.v1.Physics"), std::string::npos);
  EXPECT_NE(text.find("grpc.health.v1.Health"), std::string::npos);
}

TEST_F(ServerTest, ShutdownEndsStreams) {
  start();
  const uint64_t id = create_pyramid();
  auto sub = client_->subscribe(id, {}, [](const client::Frame&) {});
  ASSERT_TRUE(sub.ok());
  ASSERT_TRUE(client_->step(id, 1).ok());
  const auto t0 = std::chrono::steady_clock::now();
  server_->shutdown(std::chrono::milliseconds(2000));
  Status end = (*sub)->wait();
  EXPECT_NE(end.message().find("UNAVAILABLE"), std::string::npos) << end.message();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(2));
}

// A call running when the shutdown begins finishes within the grace period with its full
// result, and a call that arrives after the shutdown began is refused. The world does not sleep,
// so 1000 ticks of the 211-body pyramid keep the Step busy for a while (about 0.5 s here);
// the shutdown starts once the server counts the Step, the only call then, in flight.
TEST_F(ServerTest, ShutdownLetsARunningCallFinish) {
  start();
  std::string json = pyramid_json();
  const std::string settings = "\"settings\": {";
  ASSERT_NE(json.find(settings), std::string::npos);
  json.insert(json.find(settings) + settings.size(), "\"enableSleep\": false, ");
  Result<client::WorldSummary> w = client_->create_world_json(json);
  ASSERT_TRUE(w.ok()) << w.status().message();
  // CreateWorld's call ends on the server just after its reply reaches the client.
  ASSERT_TRUE(eventually([&] { return server_->calls_in_flight() == 0; }));
  std::future<Result<client::StepResult>> step =
      std::async(std::launch::async, [&] { return client_->step(w->id, 1000); });
  ASSERT_TRUE(eventually([&] { return server_->calls_in_flight() > 0; }, std::chrono::seconds(10)));
  std::thread stopper([&] { server_->shutdown(std::chrono::milliseconds(30000)); });
  Result<client::StepResult> stepped = step.get();
  stopper.join();
  ASSERT_TRUE(stepped.ok()) << stepped.status().message();
  EXPECT_EQ(stepped->tick, 1000);
  Result<std::vector<client::WorldSummary>> late = client_->list_worlds();
  EXPECT_FALSE(late.ok());
  EXPECT_NE(late.status().message().find("UNAVAILABLE"), std::string::npos)
      << late.status().message();
}

// A self-signed certificate for localhost and 127.0.0.1, made with openssl (tools/setup.sh
// installs it) in a fresh directory; returns the directory, or empty when openssl failed.
std::string make_certificate(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "fulcrum_tls_" + name;
  const std::string command =
      "mkdir -p " + dir +
      " && openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 "
      "-nodes -days 2 -subj /CN=localhost -addext subjectAltName=DNS:localhost,IP:127.0.0.1 "
      "-keyout " +
      dir + "/key.pem -out " + dir + "/cert.pem >/dev/null 2>&1";
  return std::system(command.c_str()) == 0 ? dir : std::string();
}

TEST_F(ServerTest, TlsServesOnlyClientsThatTrustItsCertificate) {
  const std::string dir = make_certificate("server");
  const std::string other = make_certificate("other");
  ASSERT_FALSE(dir.empty()) << "openssl could not make a certificate";
  ASSERT_FALSE(other.empty());
  ServerOptions options;
  options.tls_cert_pem = read_text(dir + "/cert.pem");
  options.tls_key_pem = read_text(dir + "/key.pem");
  start(options);

  client::ClientOptions tls;
  tls.address = server_->address();
  tls.tls = true;
  tls.tls_ca_pem = options.tls_cert_pem;
  tls.deadline = std::chrono::milliseconds(10000);
  auto trusted = client::Client::connect(tls);
  Result<client::WorldSummary> w = trusted->create_world_json(pyramid_json());
  ASSERT_TRUE(w.ok()) << w.status().message();
  ASSERT_TRUE(trusted->step(w->id, 3).ok());

  // The target name override: the certificate names localhost, the address is an IP.
  client::ClientOptions named = tls;
  named.tls_target_name = "localhost";
  EXPECT_TRUE(client::Client::connect(named)->list_worlds().ok());

  // A plaintext client and a client that trusts another certificate are both refused.
  client::ClientOptions plain;
  plain.address = server_->address();
  plain.deadline = std::chrono::milliseconds(3000);
  Result<std::vector<client::WorldSummary>> refused = client::Client::connect(plain)->list_worlds();
  EXPECT_FALSE(refused.ok());
  client::ClientOptions wrong_ca = tls;
  wrong_ca.tls_ca_pem = read_text(other + "/cert.pem");
  wrong_ca.deadline = std::chrono::milliseconds(3000);
  Result<std::vector<client::WorldSummary>> untrusted =
      client::Client::connect(wrong_ca)->list_worlds();
  EXPECT_FALSE(untrusted.ok());
  EXPECT_NE(untrusted.status().message().find("UNAVAILABLE"), std::string::npos)
      << untrusted.status().message();

  // A key without its certificate is refused before listening.
  ServerOptions half;
  half.listen = "127.0.0.1:0";
  half.tls_key_pem = options.tls_key_pem;
  auto bad = Server::start(half);
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("tls_cert"), std::string::npos);
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(other);
}

TEST_F(ServerTest, ReflectionNeedsTheTokenWhenOneIsSet) {
  ServerOptions options;
  options.token = "s3cret";
  start(options);
  for (const std::string token : {"", "guess"}) {
    auto [status, text] = list_services(channel_, token);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << "token '" << token << "'";
    EXPECT_EQ(text.find("fulcrum.v1.Physics"), std::string::npos) << "the service list leaked";
  }
  auto [status, text] = list_services(channel_, "s3cret");
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_NE(text.find("fulcrum.v1.Physics"), std::string::npos);
}

TEST_F(ServerTest, CountersFollowWhatTheServerDid) {
  start();
  Result<v1::ServerStats> before = client_->get_stats();
  ASSERT_TRUE(before.ok()) << before.status().message();
  auto refused = [](const v1::ServerStats& s, const std::string& code) {
    for (const v1::CodeCount& c : s.refused()) {
      if (c.code() == code) return c.count();
    }
    return uint64_t{0};
  };
  const uint64_t id = create_pyramid();
  std::atomic<int> frames{0};
  auto sub = client_->subscribe(id, {}, [&](const client::Frame&) { ++frames; });
  ASSERT_TRUE(sub.ok());
  ASSERT_TRUE(client_->step(id, 30).ok());
  EXPECT_EQ(client_->step(id, 0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(client_->step(999, 1).status().code(), StatusCode::kNotFound);
  Result<client::SnapshotResult> snap = client_->get_snapshot(id);
  ASSERT_TRUE(snap.ok());
  ASSERT_TRUE(client_->restore(id, snap->bytes).ok());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (frames.load() == 0) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  (*sub)->cancel();
  (void)(*sub)->wait();
  ASSERT_TRUE(client_->delete_world(id).ok());

  Result<v1::ServerStats> after = client_->get_stats();
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(after->worlds_created() - before->worlds_created(), 1u);
  EXPECT_EQ(after->worlds_deleted() - before->worlds_deleted(), 1u);
  EXPECT_EQ(after->worlds_restored() - before->worlds_restored(), 1u);
  EXPECT_EQ(after->ticks_stepped() - before->ticks_stepped(), 30u);
  EXPECT_GT(after->step_ms_total(), before->step_ms_total());
  EXPECT_GT(after->step_ms_max(), 0.0);
  EXPECT_EQ(after->streams_opened() - before->streams_opened(), 1u);
  EXPECT_GE(after->frames_sent() - before->frames_sent(), static_cast<uint64_t>(frames.load()));
  EXPECT_GE(after->frames_encoded(), 1u);
  EXPECT_EQ(refused(*after, "INVALID_ARGUMENT") - refused(*before, "INVALID_ARGUMENT"), 1u);
  EXPECT_EQ(refused(*after, "NOT_FOUND") - refused(*before, "NOT_FOUND"), 1u);
  EXPECT_EQ(after->worlds(), 0u);
}

// Quantized frames over the wire rebuild the world within the stated bounds (frames.proto):
// position 1/8192 m, angle pi/65536 rad, velocities 1/2048 m/s, plus nothing else.
TEST_F(ServerTest, QuantizedFramesRebuildTheWorldWithinTheBounds) {
  start();
  Mirror mirror;
  ASSERT_NO_FATAL_FAILURE(mirror_changed_stream(create_pyramid(), true, &mirror));
  const auto& bodies = mirror.bodies;
  EXPECT_EQ(mirror.hash, local_pyramid_hashes(60)[60]);  // the exact hash
  Result<SceneDef> scene = parse_scene_json(pyramid_json());
  Result<World> local = build_world(*scene);
  for (int t = 0; t < 60; ++t) local->step();
  ASSERT_EQ(bodies.size(), static_cast<size_t>(local->body_count()));
  int quantized = 0;
  for (BodyId id_local : local->bodies()) {
    const BodyState s = *local->body_state(id_local);
    const client::BodyFrame& b = bodies.at(id_local.index);
    quantized += b.quantized ? 1 : 0;
    EXPECT_LE(std::abs(b.position.x() - s.transform.p.x()), 1.0 / 8192);
    EXPECT_LE(std::abs(b.position.y() - s.transform.p.y()), 1.0 / 8192);
    EXPECT_LE(std::abs(std::remainder(b.angle - s.transform.q.angle(), 2 * M_PI)),
              M_PI / 65536 + 1e-15);
    EXPECT_LE(std::abs(b.linear_velocity.x() - s.linear_velocity.x()), 1.0 / 2048);
    EXPECT_LE(std::abs(b.linear_velocity.y() - s.linear_velocity.y()), 1.0 / 2048);
    EXPECT_LE(std::abs(b.angular_velocity - s.angular_velocity), 1.0 / 2048);
    EXPECT_EQ(b.awake, s.awake);
  }
  EXPECT_EQ(quantized, local->body_count());  // the pyramid is well inside the ranges
}

// The malformed values RefusedRequestsLeaveTheWorldUnchanged does not cover, on every RPC:
// infinities, negative densities, oversized batches, unknown world ids, a snapshot of another
// version, a bad query. Each gets its code and a message naming the field; the hash stays.
TEST_F(ServerTest, MalformedValuesOnEveryRpcAreRefusedByField) {
  ServerOptions options;
  options.limits.max_edits = 50;
  start(options);
  const uint64_t id = create_pyramid();
  ASSERT_TRUE(client_->step(id, 5).ok());
  const uint64_t hash = info(id).state_hash();
  const double inf = std::numeric_limits<double>::infinity();
  auto expect = [&](grpc::Status st, grpc::StatusCode code, const std::string& field) {
    EXPECT_EQ(st.error_code(), code) << st.error_message();
    EXPECT_NE(st.error_message().find(field), std::string::npos)
        << "'" << st.error_message() << "' does not name " << field;
    EXPECT_EQ(info(id).state_hash(), hash) << field;
  };
  auto body_edit = [](double density, double x) {
    v1::Edit e;
    v1::Body* b = e.mutable_create_body();
    b->set_type(v1::BODY_TYPE_DYNAMIC);
    b->mutable_position()->set_x(x);
    v1::Shape* shape = b->add_shapes();
    shape->mutable_circle()->set_radius(0.5);
    shape->set_density(density);
    return e;
  };
  {  // An infinite velocity, a negative density, an infinite position.
    v1::EditBatch batch;
    *batch.add_edits() = set_velocity(5, 1, -inf, 0.0);
    expect(apply(id, batch), grpc::StatusCode::INVALID_ARGUMENT, "batch.edits[0].set_velocity");
    v1::EditBatch negative;
    *negative.add_edits() = body_edit(1.0, 0.0);
    *negative.add_edits() = body_edit(-2.0, 0.0);
    expect(apply(id, negative), grpc::StatusCode::INVALID_ARGUMENT, "density");
    v1::EditBatch far;
    *far.add_edits() = body_edit(1.0, inf);
    expect(apply(id, far), grpc::StatusCode::INVALID_ARGUMENT, "batch.edits[0].create_body");
  }
  {  // More edits than --max-edits.
    v1::EditBatch big;
    for (int i = 0; i < 51; ++i) *big.add_edits() = set_velocity(5, 1, 1.0, 0.0);
    expect(apply(id, big), grpc::StatusCode::RESOURCE_EXHAUSTED, "batch.edits");
  }
  {  // A scene with a negative density or a NaN gravity creates no world.
    v1::CreateWorldRequest request;
    v1::Body* b = request.mutable_scene()->add_bodies();
    b->set_type(v1::BODY_TYPE_DYNAMIC);
    v1::Shape* shape = b->add_shapes();
    shape->mutable_circle()->set_radius(1.0);
    shape->set_density(-1.0);
    v1::CreateWorldReply reply;
    auto c = context();
    expect(stub_->CreateWorld(c.get(), request, &reply), grpc::StatusCode::INVALID_ARGUMENT,
           "scene.bodies[0].shapes[0].density");
    shape->set_density(1.0);
    request.mutable_scene()->mutable_settings()->mutable_gravity()->set_y(
        std::numeric_limits<double>::quiet_NaN());
    auto c2 = context();
    expect(stub_->CreateWorld(c2.get(), request, &reply), grpc::StatusCode::INVALID_ARGUMENT,
           "scene.settings.gravity");
    auto c3 = context();
    expect(stub_->CreateWorld(c3.get(), v1::CreateWorldRequest(), &reply),
           grpc::StatusCode::INVALID_ARGUMENT, "scene");
    EXPECT_EQ(client_->list_worlds()->size(), 1u);
  }
  {  // Unknown world ids on every RPC that takes one.
    const uint64_t unknown = 4242;
    v1::WorldInfo world_info;
    v1::GetWorldRequest get;
    get.set_world_id(unknown);
    auto c1 = context();
    expect(stub_->GetWorld(c1.get(), get, &world_info), grpc::StatusCode::NOT_FOUND, "world_id");
    v1::DeleteWorldRequest del;
    del.set_world_id(unknown);
    v1::DeleteWorldReply del_reply;
    auto c2 = context();
    expect(stub_->DeleteWorld(c2.get(), del, &del_reply), grpc::StatusCode::NOT_FOUND, "world_id");
    v1::StepRequest step;
    step.set_world_id(unknown);
    step.set_ticks(1);
    v1::StepReply step_reply;
    auto c3 = context();
    expect(stub_->Step(c3.get(), step, &step_reply), grpc::StatusCode::NOT_FOUND, "world_id");
    v1::GetSnapshotRequest snap;
    snap.set_world_id(unknown);
    v1::GetSnapshotReply snap_reply;
    auto c4 = context();
    expect(stub_->GetSnapshot(c4.get(), snap, &snap_reply), grpc::StatusCode::NOT_FOUND,
           "world_id");
    v1::QueryRequest query;
    query.set_world_id(unknown);
    query.mutable_point()->mutable_point()->set_x(0);
    v1::QueryReply query_reply;
    auto c5 = context();
    expect(stub_->Query(c5.get(), query, &query_reply), grpc::StatusCode::NOT_FOUND, "world_id");
    auto sub = client_->subscribe(unknown, {}, [](const client::Frame&) {});
    ASSERT_TRUE(sub.ok());
    Status end = (*sub)->wait();
    EXPECT_EQ(end.code(), StatusCode::kNotFound);
    EXPECT_NE(end.message().find("world_id"), std::string::npos) << end.message();
  }
  {  // A snapshot of another format version, into the world and as a fork.
    Result<client::SnapshotResult> snap = client_->get_snapshot(id);
    ASSERT_TRUE(snap.ok());
    v1::RestoreSnapshotRequest request;
    ASSERT_TRUE(request.mutable_snapshot()->ParseFromString(snap->bytes));
    request.mutable_snapshot()->set_version(request.snapshot().version() + 1);
    v1::RestoreSnapshotReply reply;
    for (uint64_t target : {id, uint64_t{0}}) {
      request.set_world_id(target);
      auto c = context();
      expect(stub_->RestoreSnapshot(c.get(), request, &reply),
             grpc::StatusCode::FAILED_PRECONDITION, "snapshot");
    }
    request.set_world_id(4242);
    auto c = context();
    expect(stub_->RestoreSnapshot(c.get(), request, &reply), grpc::StatusCode::NOT_FOUND,
           "world_id");
    EXPECT_EQ(client_->list_worlds()->size(), 1u);
  }
  {  // Queries: an infinite ray, an inverted box, no kind.
    v1::QueryRequest query;
    query.set_world_id(id);
    query.mutable_ray_cast()->mutable_origin()->set_x(inf);
    query.mutable_ray_cast()->mutable_translation()->set_y(-1);
    v1::QueryReply reply;
    auto c1 = context();
    expect(stub_->Query(c1.get(), query, &reply), grpc::StatusCode::INVALID_ARGUMENT,
           "ray_cast.origin");
    query.mutable_aabb()->mutable_lower()->set_x(1);
    auto c2 = context();
    expect(stub_->Query(c2.get(), query, &reply), grpc::StatusCode::INVALID_ARGUMENT, "aabb.upper");
    query.clear_aabb();
    auto c3 = context();
    expect(stub_->Query(c3.get(), query, &reply), grpc::StatusCode::INVALID_ARGUMENT, "kind");
  }
  {  // A stream with an unknown FrameBodies value.
    v1::StreamFramesRequest request;
    request.set_world_id(id);
    request.set_bodies(static_cast<v1::FrameBodies>(7));
    auto c = context();
    auto reader = stub_->StreamFrames(c.get(), request);
    v1::Frame frame;
    EXPECT_FALSE(reader->Read(&frame));
    expect(reader->Finish(), grpc::StatusCode::INVALID_ARGUMENT, "bodies");
  }
}

}  // namespace
}  // namespace fulcrum
