// Desync reports, resynchronisation and late join in multiplayer sessions (ReportHash,
// session.proto), in-process on loopback: a lockstep copy corrupted on purpose by one bit is
// reported at that tick with the body and field that differ, takes the fresh start the server
// sends and matches the server again; a player that joins a session at tick 5000 matches the
// server from its first tick; bad reports are refused naming the field and change nothing.
#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <set>

#include "confirmed_history.h"
#include "edit_convert.h"
#include "fulcrum/client.h"
#include "fulcrum/fingerprint.h"
#include "fulcrum/lockstep.h"
#include "fulcrum/scene.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"
#include "server.h"
#include "session_support.h"
#include "snapshot_convert.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using namespace std::chrono_literals;
using client::LockstepOptions;
using client::LockstepWorld;
using server::Server;
using server::ServerOptions;
using testing_support::handle;
using testing_support::impulse;
using testing_support::kBelow;
using testing_support::kTop;
using testing_support::pyramid_json;

class DesyncTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.listen = "127.0.0.1:0";
    auto started = Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    stub_ = v1::Physics::NewStub(
        grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()));
  }
  static std::unique_ptr<grpc::ClientContext> context() {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + 60s);
    return c;
  }
  uint64_t create_pyramid() {
    v1::CreateWorldRequest request;
    EXPECT_TRUE(
        google::protobuf::util::JsonStringToMessage(pyramid_json(), request.mutable_scene()).ok());
    v1::CreateWorldReply reply;
    auto c = context();
    EXPECT_TRUE(stub_->CreateWorld(c.get(), request, &reply).ok());
    return reply.world_id();
  }
  v1::ApplyEditsReply apply(uint64_t world, const v1::EditBatch& batch) {
    v1::ApplyEditsRequest request;
    request.set_world_id(world);
    *request.mutable_batch() = batch;
    v1::ApplyEditsReply reply;
    auto c = context();
    grpc::Status s = stub_->ApplyEdits(c.get(), request, &reply);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return reply;
  }
  void open(uint64_t world, const v1::SessionOptions& options) {
    v1::OpenSessionRequest request;
    request.set_world_id(world);
    *request.mutable_options() = options;
    v1::OpenSessionReply reply;
    auto c = context();
    grpc::Status s = stub_->OpenSession(c.get(), request, &reply);
    ASSERT_TRUE(s.ok()) << s.error_message();
  }
  v1::JoinSessionReply join(uint64_t world, int body) {
    v1::JoinSessionRequest request;
    request.set_world_id(world);
    request.set_fingerprint(kDeterminismFingerprint);
    *request.add_bodies() = handle(body);
    v1::JoinSessionReply reply;
    auto c = context();
    grpc::Status s = stub_->JoinSession(c.get(), request, &reply);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return reply;
  }
  grpc::Status send(uint64_t world, const v1::JoinSessionReply& player, int64_t tick,
                    const v1::EditBatch& input) {
    v1::SendInputRequest request;
    request.set_world_id(world);
    request.set_player_id(player.player_id());
    request.set_player_secret(player.player_secret());
    request.set_tick(tick);
    *request.mutable_input() = input;
    v1::SendInputReply reply;
    auto c = context();
    return stub_->SendInput(c.get(), request, &reply);
  }
  grpc::Status report(uint64_t world, const v1::JoinSessionReply& player,
                      v1::ReportHashRequest request, v1::ReportHashReply* reply) {
    request.set_world_id(world);
    request.set_player_id(player.player_id());
    request.set_player_secret(player.player_secret());
    auto c = context();
    return stub_->ReportHash(c.get(), request, reply);
  }
  v1::WorldInfo info(uint64_t world) {
    v1::GetWorldRequest request;
    request.set_world_id(world);
    v1::WorldInfo reply;
    auto c = context();
    EXPECT_TRUE(stub_->GetWorld(c.get(), request, &reply).ok());
    return reply;
  }
  void step(uint64_t world, uint32_t ticks) {
    v1::StepRequest request;
    request.set_world_id(world);
    request.set_ticks(ticks);
    v1::StepReply reply;
    auto c = context();
    grpc::Status s = stub_->Step(c.get(), request, &reply);
    ASSERT_TRUE(s.ok()) << s.error_message();
  }
  v1::ServerStats stats() {
    v1::ServerStats reply;
    auto c = context();
    EXPECT_TRUE(stub_->GetStats(c.get(), v1::GetStatsRequest(), &reply).ok());
    return reply;
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::Physics::Stub> stub_;
};

// A free body beside the pyramid: no gravity, no contact, moving at 0.25 m/s along x, so that
// nothing else in the world depends on it.
v1::EditBatch lone_body() {
  v1::EditBatch batch;
  v1::Body* body = batch.add_edits()->mutable_create_body();
  body->set_type(v1::BODY_TYPE_DYNAMIC);
  body->mutable_position()->set_x(100.0);
  body->mutable_position()->set_y(50.0);
  body->mutable_linear_velocity()->set_x(0.25);
  body->set_gravity_scale(0.0);
  body->set_enable_sleep(false);
  body->add_shapes()->mutable_circle()->set_radius(0.5);
  return batch;
}

TEST_F(DesyncTest, ACorruptedCopyIsReportedAtItsTickWithTheFieldAndResyncsBitForBit) {
  const uint64_t id = create_pyramid();
  const v1::Handle lone = apply(id, lone_body()).bodies(0);
  v1::SessionOptions options;
  options.set_seal(v1::SEAL_RULE_ALL_INPUTS);  // one player: each input runs its tick
  open(id, options);
  const v1::JoinSessionReply me = join(id, kTop);
  const v1::ServerStats before = stats();

  v1::WatchSessionRequest watch;
  watch.set_world_id(id);
  watch.set_player_id(me.player_id());
  watch.set_player_secret(me.player_secret());
  auto watch_context = context();
  auto reader = stub_->WatchSession(watch_context.get(), watch);

  // The copy reports every 16 ticks and resyncs on demand. After stepping tick 40 its lone
  // body's x velocity gets its lowest mantissa bit flipped: 0.25 becomes 0.25 + 2^-54.
  constexpr int64_t kCorruptTick = 40;
  constexpr int64_t kLastTick = 100;
  const double flipped = std::bit_cast<double>(std::bit_cast<uint64_t>(0.25) ^ 1u);
  LockstepWorld copy(LockstepOptions{.report_every = 16, .resync = true});
  copy.set_after_step_for_test([&](World* world) {
    if (world->tick() != kCorruptTick) return;
    ASSERT_TRUE(world->set_linear_velocity({lone.index(), lone.generation()}, {flipped, 0.0}).ok());
  });

  std::vector<v1::ReportHashReply> replies;
  std::vector<std::string> desyncs;
  // Reads events until the copy follows the server at `tick` again.
  auto follow = [&](int64_t tick) {
    v1::SessionEvent event;
    while (!(copy.started() && !copy.awaiting_resync() && copy.world().tick() >= tick)) {
      ASSERT_TRUE(reader->Read(&event)) << "the watch ended before tick " << tick;
      Status st = copy.on_event(event);
      if (st.code() == StatusCode::kDataLoss) {
        desyncs.push_back(st.message());
      } else {
        ASSERT_TRUE(st.ok()) << st.message();
      }
      if (auto r = copy.take_report()) {
        v1::ReportHashReply reply;
        grpc::Status s = report(id, me, *r, &reply);
        ASSERT_TRUE(s.ok()) << s.error_message();
        ASSERT_TRUE(copy.on_report_reply(reply).ok());
        replies.push_back(reply);
      }
    }
  };
  follow(0);
  for (int64_t t = 0; t < kLastTick; ++t) {
    ASSERT_TRUE(send(id, me, t, t % 9 == 0 ? impulse(kTop, 1.5) : v1::EditBatch()).ok());
    follow(t + 1);
    if (HasFatalFailure()) return;
  }

  // The copy saw its own desync at tick 40 (the server's hash came with the tick).
  ASSERT_EQ(desyncs.size(), 1u);
  EXPECT_EQ(desyncs[0].rfind("desync at tick 40: ", 0), 0u) << desyncs[0];
  // Reports: ticks 1-16 and 17-32 matched; 33-40 went at once at the desync, with the copy's
  // snapshot of tick 40; after the fresh start (at tick 40) 41-56, 57-72, 73-88 matched.
  ASSERT_EQ(replies.size(), 6u);
  for (int i : {0, 1, 3, 4, 5}) {
    EXPECT_EQ(replies[i].verdict(), v1::HASH_VERDICT_MATCH) << "report " << i;
  }
  EXPECT_EQ(replies[0].checked_from(), 1);
  EXPECT_EQ(replies[0].checked_through(), 16);
  EXPECT_EQ(replies[3].checked_from(), 41);
  EXPECT_EQ(replies[5].checked_through(), 88);
  const v1::ReportHashReply& d = replies[2];
  ASSERT_EQ(d.verdict(), v1::HASH_VERDICT_DESYNC);
  EXPECT_EQ(d.checked_from(), 33);
  EXPECT_EQ(d.divergent_tick(), kCorruptTick);
  EXPECT_NE(d.server_hash(), d.client_hash());
  EXPECT_EQ(d.note(), "");
  // The first field that differs is the flipped one, with the server's value and the copy's.
  const std::string field = "bodies[" + std::to_string(lone.index()) + "].linear_velocity.x";
  EXPECT_EQ(d.first_difference(), field + ": expected 0.25, got 0.25000000000000006");
  const std::string got = d.first_difference().substr(d.first_difference().rfind(' ') + 1);
  EXPECT_EQ(std::bit_cast<uint64_t>(std::strtod(got.c_str(), nullptr)),
            std::bit_cast<uint64_t>(flipped));
  EXPECT_EQ(d.body().index(), lone.index());
  EXPECT_EQ(d.body().generation(), lone.generation());
  EXPECT_TRUE(d.resynced());
  EXPECT_EQ(d.resync_tick(), kCorruptTick);
  EXPECT_EQ(d.resync_watches(), 1);

  // Resynchronised: the copy continued from the fresh start and every hash matched since.
  EXPECT_EQ(copy.resyncs(), 1);
  EXPECT_FALSE(copy.desynced());
  EXPECT_EQ(copy.ticks_skipped(), 0) << "the start came right after tick 40";
  EXPECT_EQ(copy.ticks_confirmed(), kLastTick - 1) << "every tick but the corrupted one";
  EXPECT_EQ(copy.world().tick(), kLastTick);
  EXPECT_EQ(copy.world().state_hash(), info(id).state_hash());

  const v1::ServerStats after = stats();
  EXPECT_EQ(after.hash_reports() - before.hash_reports(), 6u);
  EXPECT_EQ(after.desyncs() - before.desyncs(), 1u);
  EXPECT_EQ(after.resyncs() - before.resyncs(), 1u);
  watch_context->TryCancel();
}

TEST_F(DesyncTest, APlayerJoiningAtTick5000MatchesTheServerFromItsFirstTick) {
  const uint64_t id = create_pyramid();
  v1::SessionOptions options;
  options.set_input_delay(2);
  open(id, options);
  const v1::JoinSessionReply p1 = join(id, kTop);
  // A running session: player 1 pushes its box every 250 ticks, the owner edits between ticks,
  // and the world steps to tick 5000.
  for (int64_t t = 0; t < 5000; t += 250) {
    ASSERT_TRUE(send(id, p1, t + 2, impulse(kTop, t % 500 == 0 ? 2.0 : -2.0)).ok());
    if (t == 2500) apply(id, lone_body());
    step(id, 250);
  }
  ASSERT_EQ(info(id).tick(), 5000);
  // An edit after tick 5000: in the joiner's snapshot already, and again in tick 5001's batches.
  apply(id, impulse(5, 1.0));

  const v1::JoinSessionReply p2 = join(id, kBelow);
  EXPECT_EQ(p2.tick(), 5000);
  client::ClientOptions client_options;
  client_options.address = server_->address();
  auto c = client::Client::connect(client_options);
  std::mutex mu;
  LockstepWorld copy(LockstepOptions{.report_every = 10});
  int64_t start_tick = -1;
  uint32_t applied_batches = 0;
  int64_t first_confirmed = -1;
  std::vector<std::string> errors;
  std::vector<v1::ReportHashReply> replies;
  auto watch = c->watch_session(
      id,
      [&](const v1::SessionEvent& event) {
        std::lock_guard<std::mutex> lock(mu);
        if (event.has_start()) {
          start_tick = event.start().tick();
          applied_batches = event.start().applied_batches();
        } else if (first_confirmed < 0) {
          first_confirmed = event.confirmed().tick().tick();
        }
        if (Status st = copy.on_event(event); !st.ok()) errors.push_back(st.message());
        if (auto r = copy.take_report()) {
          auto reply = c->report_hash(id, p2, *r);
          if (!reply.ok()) {
            errors.push_back(reply.status().message());
          } else {
            replies.push_back(*reply);
          }
        }
      },
      &p2);
  ASSERT_TRUE(watch.ok()) << watch.status().message();
  ASSERT_TRUE(testing_support::eventually([&] {
    std::lock_guard<std::mutex> lock(mu);
    return copy.started();
  }));

  // Both play on for 200 ticks.
  for (int64_t t = 5000; t < 5200; ++t) {
    ASSERT_TRUE(send(id, p1, t + 2, t % 7 == 0 ? impulse(kTop, 1.0) : v1::EditBatch()).ok());
    ASSERT_TRUE(send(id, p2, t + 2, t % 5 == 0 ? impulse(kBelow, -1.0) : v1::EditBatch()).ok());
    step(id, 1);
  }
  ASSERT_TRUE(testing_support::eventually([&] {
    std::lock_guard<std::mutex> lock(mu);
    return copy.world().tick() >= 5200 || !errors.empty();
  }));
  (*watch)->cancel();

  std::lock_guard<std::mutex> lock(mu);
  ASSERT_TRUE(errors.empty()) << errors[0];
  EXPECT_EQ(start_tick, 5000) << "the joiner starts from a snapshot of the world as it is";
  EXPECT_EQ(applied_batches, 1u) << "the owner's edit after tick 5000 is in the snapshot";
  EXPECT_EQ(first_confirmed, 5001);
  EXPECT_EQ(copy.ticks_confirmed(), 200) << "every tick from 5001 matched the server's hash";
  EXPECT_EQ(copy.world().state_hash(), info(id).state_hash());
  // The server compared all of them too: 20 reports of 10 ticks, each a match.
  ASSERT_EQ(replies.size(), 20u);
  EXPECT_EQ(replies.front().checked_from(), 5001);
  EXPECT_EQ(replies.back().checked_through(), 5200);
  for (const v1::ReportHashReply& r : replies) {
    EXPECT_EQ(r.verdict(), v1::HASH_VERDICT_MATCH) << r.checked_from();
  }
}

TEST_F(DesyncTest, BadReportsAreRefusedNamingTheFieldAndChangeNothingForOthers) {
  const uint64_t id = create_pyramid();
  open(id, v1::SessionOptions());
  const v1::JoinSessionReply p1 = join(id, kTop);
  const v1::JoinSessionReply p2 = join(id, kBelow);
  step(id, 30);
  const v1::WorldInfo at30 = info(id);
  const v1::ServerStats before = stats();

  v1::ReportHashRequest good;
  good.set_first_tick(30);
  good.add_hashes(at30.state_hash());
  v1::ReportHashReply reply;
  auto refused = [&](const v1::JoinSessionReply& who, const v1::ReportHashRequest& r) {
    v1::ReportHashReply ignored;
    return report(id, who, r, &ignored);
  };

  v1::JoinSessionReply forged = p1;
  forged.set_player_secret(p2.player_secret());
  grpc::Status s = refused(forged, good);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(s.error_message(), "player_secret: not player 1's secret");
  v1::JoinSessionReply stranger = p1;
  stranger.set_player_id(9);
  s = refused(stranger, good);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(s.error_message(), "player_id: no player 9 in this session");

  v1::ReportHashRequest empty = good;
  empty.clear_hashes();
  s = refused(p1, empty);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "hashes: at least one (the state hash after first_tick)");
  v1::ReportHashRequest many = good;
  many.set_first_tick(1);
  for (int i = 0; i < 1024; ++i) many.add_hashes(0);
  s = refused(p1, many);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "hashes: at most 1024 per report (got 1025)");
  v1::ReportHashRequest zero = good;
  zero.set_first_tick(0);
  s = refused(p1, zero);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "first_tick: the world's tick after a step, at least 1 (got 0)");
  v1::ReportHashRequest ahead = good;
  ahead.add_hashes(0);
  s = refused(p1, ahead);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(),
            "first_tick: the hashes run to tick 31, past the last confirmed tick 30");

  // A snapshot with a NaN in it, one with a damaged payload, one of a tick not reported.
  v1::GetSnapshotRequest get;
  get.set_world_id(id);
  v1::GetSnapshotReply snap;
  {
    auto c = context();
    ASSERT_TRUE(stub_->GetSnapshot(c.get(), get, &snap).ok());
  }
  Result<v1::Snapshot> payload = unwrap_snapshot(snap.snapshot());
  ASSERT_TRUE(payload.ok());
  v1::Snapshot nan = *payload;
  nan.mutable_bodies(5)->mutable_position()->set_x(std::nan(""));
  v1::ReportHashRequest with_nan = good;
  *with_nan.mutable_snapshot() = wrap_snapshot(nan);
  s = refused(p1, with_nan);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "snapshot: body[5].position is not finite");
  v1::ReportHashRequest damaged = good;
  *damaged.mutable_snapshot() = snap.snapshot();
  damaged.mutable_snapshot()->mutable_payload()->back() ^= 1;
  s = refused(p1, damaged);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::DATA_LOSS);
  EXPECT_EQ(s.error_message().rfind("snapshot", 0), 0u) << s.error_message();
  v1::ReportHashRequest other_tick = good;
  other_tick.set_first_tick(20);
  other_tick.clear_hashes();
  other_tick.add_hashes(0);
  *other_tick.mutable_snapshot() = snap.snapshot();
  s = refused(p1, other_tick);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "snapshot: of tick 30, not one of the reported ticks 20 to 20");

  // Not a session at all.
  const uint64_t plain = create_pyramid();
  {
    v1::ReportHashRequest r = good;
    r.set_world_id(plain);
    auto c = context();
    s = stub_->ReportHash(c.get(), r, &reply);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  }

  // Nothing changed: the world, the counters, and player 2's report matches.
  EXPECT_EQ(info(id).tick(), 30);
  EXPECT_EQ(info(id).state_hash(), at30.state_hash());
  EXPECT_EQ(stats().hash_reports(), before.hash_reports());
  ASSERT_TRUE(report(id, p2, good, &reply).ok());
  EXPECT_EQ(reply.verdict(), v1::HASH_VERDICT_MATCH);
  EXPECT_EQ(reply.checked_from(), 30);
  EXPECT_EQ(reply.checked_through(), 30);

  // A wrong hash without a snapshot: the tick, no field, and no resync without a watch.
  v1::ReportHashRequest wrong = good;
  wrong.set_first_tick(29);
  wrong.clear_hashes();
  wrong.add_hashes(at30.state_hash());  // tick 30's hash given as tick 29's
  wrong.add_hashes(at30.state_hash());
  wrong.set_resync(true);
  ASSERT_TRUE(report(id, p1, wrong, &reply).ok());
  EXPECT_EQ(reply.verdict(), v1::HASH_VERDICT_DESYNC);
  EXPECT_EQ(reply.divergent_tick(), 29);
  EXPECT_EQ(reply.client_hash(), at30.state_hash());
  EXPECT_EQ(reply.first_difference(), "");
  EXPECT_EQ(reply.note(),
            "no snapshot sent: send this player's snapshot of tick 29 to learn the first field "
            "that differs");
  EXPECT_FALSE(reply.resynced());

  // Hashes the server no longer keeps are not compared.
  step(id, 1100);
  ASSERT_TRUE(report(id, p2, good, &reply).ok());
  EXPECT_EQ(reply.verdict(), v1::HASH_VERDICT_UNCHECKED);
  const v1::ServerStats after = stats();
  EXPECT_EQ(after.hash_reports() - before.hash_reports(), 3u);
  EXPECT_EQ(after.desyncs() - before.desyncs(), 1u);
  EXPECT_EQ(after.resyncs() - before.resyncs(), 0u);
}

// The server's memory of confirmed ticks: any tick in the hash window is rebuilt from its
// keyframe to the same snapshot the world had, across keyframe boundaries, and what fell out of
// the window is forgotten (at most a window's worth of hashes and a keyframe before it).
TEST(ConfirmedHistoryTest, RebuildsAnyTickInTheWindowBitForBit) {
  Result<SceneDef> scene = parse_scene_json(pyramid_json());
  ASSERT_TRUE(scene.ok());
  Result<World> built = build_world(*scene);
  ASSERT_TRUE(built.ok());
  World world = std::move(*built);
  server::ConfirmedHistory history;
  history.start(world);
  constexpr int64_t kTicks = 1500;
  std::map<int64_t, v1::Snapshot> kept;  // the world's own snapshots of a few ticks
  const std::set<int64_t> probes = {600, 767, 768, 769, 1000, 1023, 1024, 1025, 1300, 1500};
  for (int64_t t = 0; t < kTicks; ++t) {
    auto event = std::make_shared<v1::SessionEvent>();
    v1::ReplayTick* tick = event->mutable_confirmed()->mutable_tick();
    if (t % 37 == 0) {  // a player's push now and then, applied before the step as sealed
      *tick->add_edits() = impulse(kTop, t % 74 == 0 ? 3.0 : -3.0);
      ASSERT_TRUE(apply_edit_batch(&world, tick->edits(0)).ok());
    }
    world.step();
    tick->set_tick(world.tick());
    tick->set_state_hash(world.state_hash());
    history.add(world, event);
    if (probes.contains(world.tick())) kept[world.tick()] = snapshot_to_proto(world.snapshot());
  }
  // The window: the last 1024 confirmed ticks.
  EXPECT_EQ(history.newest_hash_tick(), kTicks);
  EXPECT_EQ(history.oldest_hash_tick(), kTicks - server::ConfirmedHistory::kHashWindow + 1);
  EXPECT_FALSE(history.hash_after(history.oldest_hash_tick() - 1).has_value());
  EXPECT_EQ(history.hash_after(kTicks), world.state_hash());
  // Keyframes at 0, 256, 512...: the oldest kept is the newest at or before tick 477 (256).
  EXPECT_TRUE(history.replay_to(256).has_value());
  EXPECT_FALSE(history.replay_to(255).has_value()) << "before the oldest keyframe kept";
  for (const auto& [t, expected] : kept) {
    std::optional<server::ConfirmedHistory::Replay> replay = history.replay_to(t);
    ASSERT_TRUE(replay.has_value()) << t;
    EXPECT_LT(t - replay->keyframe->tick, server::ConfirmedHistory::kKeyframeEvery) << t;
    Result<WorldSnapshot> rebuilt = server::rebuild(*replay);
    ASSERT_TRUE(rebuilt.ok()) << rebuilt.status().message();
    EXPECT_EQ(first_difference(expected, snapshot_to_proto(*rebuilt)), "") << "tick " << t;
  }
}

}  // namespace
}  // namespace fulcrum
