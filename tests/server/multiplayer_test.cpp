// Multiplayer sessions on the server in-process (session.proto): players' inputs confirmed per
// tick in player order, a watcher that replays the confirmed ticks on its own copy of the world
// with the server's hash at every tick, authority and tick checks, the missing-input rule, the
// owner's edits in the stream, late watchers, and a recorded session that verifies.
#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>

#include "edit_convert.h"
#include "fulcrum/fingerprint.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "replay.h"
#include "scene_convert.h"
#include "server.h"
#include "session_support.h"
#include "snapshot_convert.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using namespace std::chrono_literals;
using server::Server;
using server::ServerOptions;
using testing_support::handle;
using testing_support::impulse;
using testing_support::kBelow;
using testing_support::kTop;
using testing_support::pyramid_json;

// A client's own copy of the world, stepped only by what the session stream confirms.
class Follower {
 public:
  // From the first event of a watch.
  void start(const v1::SessionEvent& event) {
    ASSERT_TRUE(event.has_start());
    ASSERT_TRUE(restore_encoded(&world_, event.start().snapshot().SerializeAsString()).ok());
    ASSERT_EQ(world_.state_hash(), event.start().state_hash());
    skip_ = event.start().applied_batches();
  }
  // Applies the tick's batches and steps; the hash must be the server's.
  void confirm(const v1::ConfirmedTick& c) {
    for (int i = 0; i < c.tick().edits_size(); ++i) {
      if (skip_ > 0) {
        --skip_;
        continue;
      }
      ASSERT_TRUE(apply_edit_batch(&world_, c.tick().edits(i)).ok()) << c.tick().tick();
    }
    world_.step();
    ASSERT_EQ(world_.tick(), c.tick().tick());
    ASSERT_EQ(world_.state_hash(), c.tick().state_hash()) << "tick " << c.tick().tick();
    ++confirmed_;
  }
  const World& world() const { return world_; }
  int confirmed() const { return confirmed_; }

 private:
  World world_;
  uint32_t skip_ = 0;
  int confirmed_ = 0;
};

class MultiplayerTest : public ::testing::Test {
 protected:
  void start(ServerOptions options = {}) {
    options.listen = "127.0.0.1:0";
    auto started = Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    stub_ = v1::Physics::NewStub(
        grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()));
  }
  static std::unique_ptr<grpc::ClientContext> context() {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + 30s);
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
  grpc::Status open(uint64_t world, v1::SessionOptions options) {
    v1::OpenSessionRequest request;
    request.set_world_id(world);
    *request.mutable_options() = options;
    v1::OpenSessionReply reply;
    auto c = context();
    return stub_->OpenSession(c.get(), request, &reply);
  }
  // Joins with the bodies; last_ holds the call's status.
  v1::JoinSessionReply join(uint64_t world, std::vector<int> bodies,
                            std::string fingerprint = kDeterminismFingerprint) {
    v1::JoinSessionRequest request;
    request.set_world_id(world);
    request.set_fingerprint(fingerprint);
    for (int b : bodies) *request.add_bodies() = handle(b);
    v1::JoinSessionReply reply;
    auto c = context();
    last_ = stub_->JoinSession(c.get(), request, &reply);
    return reply;
  }
  grpc::Status send(uint64_t world, const v1::JoinSessionReply& player, int64_t tick,
                    const v1::EditBatch& input, v1::SendInputReply* reply = nullptr) {
    v1::SendInputRequest request;
    request.set_world_id(world);
    request.set_player_id(player.player_id());
    request.set_player_secret(player.player_secret());
    request.set_tick(tick);
    *request.mutable_input() = input;
    v1::SendInputReply ignored;
    auto c = context();
    return stub_->SendInput(c.get(), request, reply ? reply : &ignored);
  }
  v1::WorldInfo info(uint64_t world) {
    v1::GetWorldRequest request;
    request.set_world_id(world);
    v1::WorldInfo reply;
    auto c = context();
    EXPECT_TRUE(stub_->GetWorld(c.get(), request, &reply).ok());
    return reply;
  }
  grpc::Status step(uint64_t world, uint32_t ticks) {
    v1::StepRequest request;
    request.set_world_id(world);
    request.set_ticks(ticks);
    v1::StepReply reply;
    auto c = context();
    return stub_->Step(c.get(), request, &reply);
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::Physics::Stub> stub_;
  grpc::Status last_;
};

// Reads events until the confirmed tick `until` (at most 10 s).
void follow(grpc::ClientReader<v1::SessionEvent>* reader, Follower* follower, int64_t until,
            std::vector<v1::ConfirmedTick>* seen = nullptr) {
  v1::SessionEvent event;
  while (follower->world().tick() < until && reader->Read(&event)) {
    if (event.has_start()) {
      follower->start(event);
    } else {
      follower->confirm(event.confirmed());
      if (seen) seen->push_back(event.confirmed());
    }
    if (::testing::Test::HasFatalFailure()) return;
  }
}

// The watch's first event, the start, read before anything else is done: once it has
// arrived the server has registered the watcher, so every tick stepped after this reaches it.
void read_start(grpc::ClientReader<v1::SessionEvent>* reader, Follower* follower) {
  v1::SessionEvent event;
  ASSERT_TRUE(reader->Read(&event));
  ASSERT_TRUE(event.has_start());
  follower->start(event);
}

TEST_F(MultiplayerTest, TwoPlayersTakeTurnsAndAWatcherFollowsBitForBit) {
  start();
  const uint64_t id = create_pyramid();
  v1::SessionOptions options;
  options.set_max_players(2);
  options.set_input_delay(2);
  options.set_seal(v1::SEAL_RULE_ALL_INPUTS);
  ASSERT_TRUE(open(id, options).ok());

  auto watch_context = context();
  v1::WatchSessionRequest watch;
  watch.set_world_id(id);
  auto reader = stub_->WatchSession(watch_context.get(), watch);
  Follower follower;
  read_start(reader.get(), &follower);

  v1::JoinSessionReply p1 = join(id, {kTop});
  ASSERT_TRUE(last_.ok()) << last_.error_message();
  v1::JoinSessionReply p2 = join(id, {kBelow});
  ASSERT_TRUE(last_.ok()) << last_.error_message();
  EXPECT_EQ(p1.player_id(), 1u);
  EXPECT_EQ(p2.player_id(), 2u);
  EXPECT_EQ(p1.first_input_tick(), 2);
  EXPECT_NE(p1.player_secret(), p2.player_secret());

  // Ticks 2 to 31: player 1 pushes every 5th tick, player 2 every 7th, otherwise they send an
  // empty input ("nothing this tick"). Each tick runs when the second input for it arrives.
  for (int64_t t = 2; t < 32; ++t) {
    ASSERT_TRUE(send(id, p1, t, t % 5 == 0 ? impulse(kTop, 2.0) : v1::EditBatch()).ok());
    EXPECT_EQ(info(id).tick(), t) << "one input of two: tick " << t << " must wait";
    ASSERT_TRUE(send(id, p2, t, t % 7 == 0 ? impulse(kBelow, -3.0) : v1::EditBatch()).ok());
    EXPECT_EQ(info(id).tick(), t + 1);
  }

  std::vector<v1::ConfirmedTick> seen;
  follow(reader.get(), &follower, 32, &seen);
  ASSERT_EQ(follower.world().tick(), 32);
  EXPECT_EQ(follower.world().state_hash(), info(id).state_hash());
  ASSERT_EQ(seen.size(), 32u);
  // Within ticks 2..31, player 1 pushed at 10, 15, 20, 25 and 30, player 2 at 14, 21 and 28;
  // empty inputs add no batch.
  const v1::ConfirmedTick& at10 = seen[10];  // the step from tick 10 to 11
  EXPECT_EQ(at10.tick().tick(), 11);
  ASSERT_EQ(at10.batch_players_size(), 1);
  EXPECT_EQ(at10.batch_players(0), 1u);
  EXPECT_EQ(seen[14].batch_players(0), 2u);
  EXPECT_EQ(seen[0].missing_players_size(), 0) << "before their first input tick nobody is missing";
  watch_context->TryCancel();
}

TEST_F(MultiplayerTest, InputsAreCheckedForAuthorityTicksAndValues) {
  start();
  const uint64_t id = create_pyramid();
  v1::SessionOptions options;
  options.set_input_delay(3);
  ASSERT_TRUE(open(id, options).ok());
  EXPECT_EQ(open(id, options).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  v1::JoinSessionReply p1 = join(id, {kTop});
  ASSERT_TRUE(last_.ok()) << last_.error_message();
  v1::JoinSessionReply p2 = join(id, {kBelow});
  ASSERT_TRUE(last_.ok()) << last_.error_message();

  grpc::Status s = send(id, p1, 5, impulse(kBelow, 1.0));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(s.error_message(),
            "input.edits[0].apply_impulse.body: body {209, 1} is player 2's, not player 1's");
  v1::JoinSessionReply forged = p2;
  forged.set_player_secret(p1.player_secret());
  s = send(id, forged, 5, impulse(kBelow, 1.0));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(s.error_message(), "player_secret: not player 2's secret");

  s = send(id, p1, 2, impulse(kTop, 1.0));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(s.error_message(),
            "tick: 2 is less than input_delay (3) past the world's tick 0; the earliest tick "
            "open to inputs is 3");
  s = send(id, p1, 100000, impulse(kTop, 1.0));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  v1::EditBatch bad = impulse(kTop, std::nan(""));
  s = send(id, p1, 5, bad);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message().rfind("input.edits[0].apply_impulse.impulse.x: must be finite", 0),
            0u)
      << s.error_message();
  v1::EditBatch teleport;
  v1::SetTransform* t = teleport.add_edits()->mutable_set_transform();
  *t->mutable_body() = handle(kTop);
  s = send(id, p1, 5, teleport);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("input.edits[0].set_transform: not an input edit"),
            std::string::npos);

  // A body someone owns cannot be taken again; another engine's client is told so at once.
  v1::JoinSessionRequest taken;
  taken.set_world_id(id);
  *taken.add_bodies() = handle(kTop);
  v1::JoinSessionReply ignored;
  auto c = context();
  s = stub_->JoinSession(c.get(), taken, &ignored);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(s.error_message(), "bodies[0]: body {210, 1} is player 1's");
  join(id, {}, "fulcrum-results-0");
  EXPECT_EQ(last_.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(last_.error_message().find("fulcrum-results-0"), std::string::npos);

  // Accepted once; the same tick again is a duplicate, ignored; after the tick is sealed it is
  // refused with the tick it missed.
  v1::SendInputReply reply;
  ASSERT_TRUE(send(id, p1, 3, impulse(kTop, 1.0), &reply).ok());
  EXPECT_FALSE(reply.duplicate());
  ASSERT_TRUE(send(id, p1, 3, impulse(kTop, 50.0), &reply).ok());
  EXPECT_TRUE(reply.duplicate());
  ASSERT_TRUE(step(id, 4).ok());
  s = send(id, p1, 3, impulse(kTop, 1.0));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(s.error_message(), "tick: 3 is sealed already; the earliest tick open to inputs is 7");
  EXPECT_EQ(info(id).tick(), 4);

  // A session's world is not rolled back under its players.
  v1::GetSnapshotRequest get;
  get.set_world_id(id);
  v1::GetSnapshotReply snap;
  auto g = context();
  ASSERT_TRUE(stub_->GetSnapshot(g.get(), get, &snap).ok());
  v1::RestoreSnapshotRequest restore;
  restore.set_world_id(id);
  *restore.mutable_snapshot() = snap.snapshot();
  v1::RestoreSnapshotReply restored;
  auto r = context();
  EXPECT_EQ(stub_->RestoreSnapshot(r.get(), restore, &restored).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
}

TEST_F(MultiplayerTest, MissingInputsRepeatTheLastAndTheOwnersEditsComeFirst) {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("fulcrum_mp_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  ServerOptions server_options;
  server_options.replay_dir = dir.string();
  start(server_options);
  const uint64_t id = create_pyramid();
  v1::SessionOptions options;
  options.set_missing_input(v1::MISSING_INPUT_REPEAT_LAST);
  ASSERT_TRUE(open(id, options).ok());
  v1::StartRecordingRequest record;
  record.set_world_id(id);
  v1::StartRecordingReply recording;
  {
    auto c = context();
    ASSERT_TRUE(stub_->StartRecording(c.get(), record, &recording).ok());
  }
  auto watch_context = context();
  v1::WatchSessionRequest watch;
  watch.set_world_id(id);
  auto reader = stub_->WatchSession(watch_context.get(), watch);
  Follower follower;
  read_start(reader.get(), &follower);
  v1::JoinSessionReply p1 = join(id, {kTop});
  ASSERT_TRUE(last_.ok()) << last_.error_message();
  v1::EditBatch lift;
  v1::SetVelocity* v = lift.add_edits()->mutable_set_velocity();
  *v->mutable_body() = handle(kTop);
  v->mutable_linear()->set_y(0.5);
  ASSERT_TRUE(send(id, p1, 1, lift).ok());
  // The owner's own edit between ticks.
  v1::ApplyEditsRequest edit;
  edit.set_world_id(id);
  *edit.mutable_batch() = impulse(5, 1.0);
  v1::ApplyEditsReply edited;
  {
    auto c = context();
    ASSERT_TRUE(stub_->ApplyEdits(c.get(), edit, &edited).ok());
  }
  ASSERT_TRUE(step(id, 4).ok());

  std::vector<v1::ConfirmedTick> seen;
  follow(reader.get(), &follower, 4, &seen);
  ASSERT_EQ(seen.size(), 4u);
  // Tick 0 -> 1: the owner's batch only (player 1's first input tick is 0, and it sent none
  // for tick 0: missing, with nothing to repeat yet).
  ASSERT_EQ(seen[0].batch_players_size(), 1);
  EXPECT_EQ(seen[0].batch_players(0), 0u);
  ASSERT_EQ(seen[0].missing_players_size(), 1);
  // Tick 1 -> 2: player 1's input; ticks 2 and 3: repeated, and player 1 counted missing.
  ASSERT_EQ(seen[1].batch_players_size(), 1);
  EXPECT_EQ(seen[1].batch_players(0), 1u);
  EXPECT_EQ(seen[1].missing_players_size(), 0);
  for (int i : {2, 3}) {
    ASSERT_EQ(seen[i].batch_players_size(), 1) << i;
    EXPECT_EQ(seen[i].batch_players(0), 1u);
    ASSERT_EQ(seen[i].missing_players_size(), 1);
    EXPECT_EQ(seen[i].tick().edits(0).SerializeAsString(), lift.SerializeAsString());
  }

  // A watcher that starts now begins from the world as it is and follows from there.
  auto late_context = context();
  auto late = stub_->WatchSession(late_context.get(), watch);
  Follower late_follower;
  read_start(late.get(), &late_follower);
  ASSERT_TRUE(step(id, 3).ok());
  follow(late.get(), &late_follower, 7);
  EXPECT_EQ(late_follower.confirmed(), 3);
  EXPECT_EQ(late_follower.world().state_hash(), info(id).state_hash());

  // The session's replay holds the same batches: it verifies tick for tick.
  v1::StopRecordingRequest stop;
  stop.set_world_id(id);
  v1::StopRecordingReply stopped;
  {
    auto c = context();
    ASSERT_TRUE(stub_->StopRecording(c.get(), stop, &stopped).ok());
  }
  Result<ReplayContents> replay = read_replay((dir / recording.name()).string());
  ASSERT_TRUE(replay.ok()) << replay.status().message();
  Result<ReplayReport> report = verify_replay(*replay);
  ASSERT_TRUE(report.ok());
  EXPECT_TRUE(report->ok) << report->detail;
  EXPECT_EQ(report->final_tick, 7);
  watch_context->TryCancel();
  late_context->TryCancel();
  std::filesystem::remove_all(dir);
}

TEST_F(MultiplayerTest, APlayerWhoseWatchEndsNoLongerHoldsUpTheTurn) {
  start();
  const uint64_t id = create_pyramid();
  v1::SessionOptions options;
  options.set_seal(v1::SEAL_RULE_ALL_INPUTS);
  ASSERT_TRUE(open(id, options).ok());
  v1::JoinSessionReply p1 = join(id, {kTop});
  ASSERT_TRUE(last_.ok());
  v1::JoinSessionReply p2 = join(id, {kBelow});
  ASSERT_TRUE(last_.ok());

  v1::WatchSessionRequest as_p1;
  as_p1.set_world_id(id);
  as_p1.set_player_id(p1.player_id());
  as_p1.set_player_secret(p2.player_secret());
  {
    auto c = context();
    auto refused = stub_->WatchSession(c.get(), as_p1);
    v1::SessionEvent event;
    EXPECT_FALSE(refused->Read(&event));
    EXPECT_EQ(refused->Finish().error_code(), grpc::StatusCode::PERMISSION_DENIED);
  }
  as_p1.set_player_secret(p1.player_secret());
  auto watch_context = context();
  auto watch = stub_->WatchSession(watch_context.get(), as_p1);
  v1::SessionEvent event;
  ASSERT_TRUE(watch->Read(&event));  // the start: player 1 is present from here
  ASSERT_TRUE(event.has_start());

  ASSERT_TRUE(send(id, p1, 0, v1::EditBatch()).ok());
  ASSERT_TRUE(send(id, p2, 0, v1::EditBatch()).ok());
  EXPECT_EQ(info(id).tick(), 1);
  ASSERT_TRUE(send(id, p2, 1, impulse(kBelow, 1.0)).ok());
  EXPECT_EQ(info(id).tick(), 1) << "player 1 is present: the turn waits for it";
  // Player 1's watch ends: it has left, and the turn goes on without it.
  watch_context->TryCancel();
  (void)watch->Finish();
  EXPECT_TRUE(testing_support::eventually([&] { return info(id).tick() == 2; }, 5s));
}

}  // namespace
}  // namespace fulcrum

namespace fulcrum {
namespace {

// A scene gives bodies and joints to player ids (Body.player, Joint.player): a player joining
// with that id owns them with what it asked for, and the reply lists all it owns. A chain of 4
// links (a builder's bodies and joints first), then two explicit boxes and a joint between
// them: box 0 and the joint are player 2's, box 1 player 1's.
TEST_F(MultiplayerTest, TheSceneGivesBodiesAndJointsToPlayerIds) {
  start();
  v1::CreateWorldRequest request;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(
                  R"({"builders": [{"jointChain": {"links": 4}}],
                      "bodies": [
                        {"type": "BODY_TYPE_DYNAMIC", "position": {"x": -3, "y": 5}, "player": 2,
                         "shapes": [{"box": {"halfWidth": 0.5, "halfHeight": 0.5}}]},
                        {"type": "BODY_TYPE_DYNAMIC", "position": {"x": 3, "y": 5}, "player": 1,
                         "shapes": [{"box": {"halfWidth": 0.5, "halfHeight": 0.5}}]}],
                      "joints": [{"bodyA": 5, "bodyB": 6, "player": 2,
                                  "distance": {"length": 6}}]})",
                  request.mutable_scene())
                  .ok());
  v1::CreateWorldReply created;
  auto c = context();
  grpc::Status s = stub_->CreateWorld(c.get(), request, &created);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_EQ(created.bodies_size(), 7);  // the chain's anchor and 4 links, the two boxes
  ASSERT_EQ(created.joints_size(), 5);  // 4 of the chain, the explicit one
  const uint64_t id = created.world_id();
  ASSERT_TRUE(open(id, v1::SessionOptions()).ok());
  v1::JoinSessionReply one = join(id, {});
  ASSERT_TRUE(last_.ok()) << last_.error_message();
  ASSERT_EQ(one.bodies_size(), 1);
  EXPECT_EQ(one.bodies(0).index(), created.bodies(6).index());
  EXPECT_EQ(one.joints_size(), 0);
  v1::JoinSessionReply two = join(id, {1});  // a link asked for, then the scene's box 0
  ASSERT_TRUE(last_.ok()) << last_.error_message();
  ASSERT_EQ(two.bodies_size(), 2);
  EXPECT_EQ(two.bodies(0).index(), 1u);
  EXPECT_EQ(two.bodies(1).index(), created.bodies(5).index());
  ASSERT_EQ(two.joints_size(), 1);
  EXPECT_EQ(two.joints(0).index(), created.joints(4).index());
  // Player 1 cannot push player 2's box.
  s = send(id, one, 0, impulse(static_cast<int>(created.bodies(5).index()), 1.0));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_TRUE(send(id, two, 0, impulse(static_cast<int>(created.bodies(5).index()), 1.0)).ok());

  // Refused whole, naming the field: a static body given to a player, a player past 64.
  request.mutable_scene()->mutable_bodies(0)->set_type(v1::BODY_TYPE_STATIC);
  auto c2 = context();
  s = stub_->CreateWorld(c2.get(), request, &created);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message().rfind("scene.bodies[0].player: a static body", 0), 0u)
      << s.error_message();
  request.mutable_scene()->mutable_bodies(0)->set_type(v1::BODY_TYPE_DYNAMIC);
  request.mutable_scene()->mutable_joints(0)->set_player(65);
  auto c3 = context();
  s = stub_->CreateWorld(c3.get(), request, &created);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "scene.joints[0].player: at most 64 (got 65)");
}

}  // namespace
}  // namespace fulcrum
