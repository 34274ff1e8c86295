// Multiplayer sessions on the engine side of the server (game_session.cpp), without gRPC: the
// rules the `sessions` fuzz target found broken (tests/fuzz/findings/sessions/), one test each.
#include <gtest/gtest.h>

#include <deque>
#include <memory>
#include <optional>
#include <string>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "session.h"

namespace fulcrum::server {
namespace {

std::shared_ptr<Session> bounce_session() {
  Result<SceneDef> scene = scenes::builtin("bounce");
  EXPECT_TRUE(scene.ok());
  Result<World> world = build_world(*scene);
  EXPECT_TRUE(world.ok()) << world.status().message();
  return std::make_shared<Session>(1, "bounce", std::move(world).value(), Limits{});
}

v1::Handle dynamic_body(const World& w) {
  v1::Handle h;
  for (BodyId id : w.bodies()) {
    if (w.body_state(id)->type == BodyType::kDynamic) {
      h.set_index(id.index);
      h.set_generation(id.generation);
      break;
    }
  }
  return h;
}

class Events final : public SessionWatcher {
 public:
  void offer(std::shared_ptr<const v1::SessionEvent> event) override {
    if (event->has_confirmed()) confirmed.push_back(event->confirmed());
  }
  void close(const Status&) override {}
  uint32_t player_id() const override { return 0; }  // a spectator
  std::deque<v1::ConfirmedTick> confirmed;
};

// A session watcher arriving after the world's streams were closed (the server stopping while
// its WatchSession call was on its way) is closed at once with UNAVAILABLE, as those before it.
TEST(GameSession, WatchersArrivingAfterTheStreamsClosedAreClosedAtOnce) {
  struct Probe final : SessionWatcher {
    void offer(std::shared_ptr<const v1::SessionEvent>) override { ++events; }
    void close(const Status& status) override { closed.push_back(status.code()); }
    uint32_t player_id() const override { return 0; }
    int events = 0;
    std::vector<StatusCode> closed;
  };
  std::shared_ptr<Session> session = bounce_session();
  v1::OpenSessionReply opened;
  ASSERT_TRUE(session->open_session(v1::OpenSessionRequest(), &opened).ok());
  auto before = std::make_shared<Probe>();
  ASSERT_TRUE(session->watch_session(before, 0, "").ok());
  session->close_streams(Status(StatusCode::kInternal, "the server is stopping"), true);
  auto after = std::make_shared<Probe>();
  ASSERT_TRUE(session->watch_session(after, 0, "").ok());
  EXPECT_EQ(before->closed, std::vector<StatusCode>{StatusCode::kUnavailable});
  EXPECT_EQ(after->closed, std::vector<StatusCode>{StatusCode::kUnavailable});
}

// With MISSING_INPUT_REPEAT_LAST, a player's last input stands in for a missing one; when the
// world refuses it (the owner destroyed the player's body) the stand-in is dropped and its
// player counted missing, once: the fuzz target found it listed twice.
TEST(GameSession, AStandInTheWorldRefusesListsItsPlayerMissingOnce) {
  std::shared_ptr<Session> session = bounce_session();
  v1::OpenSessionRequest open;
  open.mutable_options()->set_missing_input(v1::MISSING_INPUT_REPEAT_LAST);
  v1::OpenSessionReply opened;
  ASSERT_TRUE(session->open_session(open, &opened).ok());
  auto events = std::make_shared<Events>();
  ASSERT_TRUE(session->watch_session(events, 0, "").ok());

  v1::WorldInfo info;
  session->info(&info);
  Result<SceneDef> scene = scenes::builtin("bounce");
  ASSERT_TRUE(scene.ok());
  const v1::Handle ball = dynamic_body(*build_world(*scene));
  v1::JoinSessionRequest join;
  *join.add_bodies() = ball;
  v1::JoinSessionReply player;
  ASSERT_TRUE(session->join_session(join, &player).ok());

  // An input for the first tick, applied; the owner then destroys the ball.
  v1::SendInputRequest send;
  send.set_player_id(player.player_id());
  send.set_player_secret(player.player_secret());
  send.set_tick(info.tick());
  v1::SetVelocity* push = send.mutable_input()->add_edits()->mutable_set_velocity();
  *push->mutable_body() = ball;
  push->mutable_linear()->set_x(1.0);
  v1::SendInputReply sent;
  ASSERT_TRUE(session->send_input(send, &sent).ok());
  v1::StepReply stepped;
  ASSERT_TRUE(session->step(1, std::nullopt, false, nullptr, &stepped).ok());
  v1::EditBatch destroy;
  *destroy.add_edits()->mutable_destroy_body() = ball;
  v1::ApplyEditsReply edited;
  ASSERT_TRUE(session->apply_edits(destroy, std::nullopt, nullptr, &edited).ok());
  ASSERT_TRUE(session->step(1, std::nullopt, false, nullptr, &stepped).ok());

  ASSERT_EQ(events->confirmed.size(), 2u);
  EXPECT_EQ(events->confirmed[0].missing_players_size(), 0);
  // The owner's batch only: the stand-in was refused, and its player is missing once.
  const v1::ConfirmedTick& second = events->confirmed[1];
  ASSERT_EQ(second.batch_players_size(), 1);
  EXPECT_EQ(second.batch_players(0), 0u);
  ASSERT_EQ(second.missing_players_size(), 1) << second.ShortDebugString();
  EXPECT_EQ(second.missing_players(0), player.player_id());
}

// Every refusal names the field at fault: calls on a world that is not a session (or already
// is one) name world_id, as the fuzz target checks.
TEST(GameSession, RefusalsForTheWrongKindOfWorldNameWorldId) {
  std::shared_ptr<Session> session = bounce_session();
  v1::JoinSessionReply joined;
  Status s = session->join_session(v1::JoinSessionRequest(), &joined);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(s.message(), "world_id: world 1 is not a multiplayer session (OpenSession first)");
  v1::SendInputReply sent;
  s = session->send_input(v1::SendInputRequest(), &sent);
  EXPECT_EQ(s.message(), "world_id: world 1 is not a multiplayer session (OpenSession first)");
  s = session->watch_session(std::make_shared<Events>(), 0, "");
  EXPECT_EQ(s.message(), "world_id: world 1 is not a multiplayer session (OpenSession first)");

  v1::OpenSessionReply opened;
  ASSERT_TRUE(session->open_session(v1::OpenSessionRequest(), &opened).ok());
  s = session->open_session(v1::OpenSessionRequest(), &opened);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(s.message(), "world_id: world 1 is a session already");
}

}  // namespace
}  // namespace fulcrum::server

namespace fulcrum::server {
namespace {

v1::Handle handle_of(BodyId id) {
  v1::Handle h;
  h.set_index(id.index);
  h.set_generation(id.generation);
  return h;
}

// The world owner's SetOwnership moves bodies between players, all of a request or none of
// it: inputs are checked against the ownership of the moment they arrive, and watchers learn
// each change in the next confirmed tick.
TEST(GameSession, TheOwnerMovesBodiesBetweenPlayersAllOrNothing) {
  Result<SceneDef> scene = scenes::builtin("vertical_stack");
  ASSERT_TRUE(scene.ok());
  Result<World> world = build_world(*scene);
  ASSERT_TRUE(world.ok());
  // The ground first, then the boxes.
  const std::vector<BodyId> ids = world->bodies();
  const v1::Handle ground = handle_of(ids[0]), a = handle_of(ids[1]), b = handle_of(ids[2]);
  ASSERT_EQ(world->body_state(ids[0])->type, BodyType::kStatic);
  auto session = std::make_shared<Session>(1, "stack", std::move(world).value(), Limits{});
  v1::OpenSessionReply opened;
  ASSERT_TRUE(session->open_session(v1::OpenSessionRequest(), &opened).ok());
  auto events = std::make_shared<Events>();
  ASSERT_TRUE(session->watch_session(events, 0, "").ok());

  v1::JoinSessionRequest join;
  *join.add_bodies() = a;
  v1::JoinSessionReply one, two;
  ASSERT_TRUE(session->join_session(join, &one).ok());
  ASSERT_TRUE(session->join_session(v1::JoinSessionRequest(), &two).ok());
  v1::StepReply stepped;
  ASSERT_TRUE(session->step(1, std::nullopt, false, nullptr, &stepped).ok());

  int64_t tick = stepped.tick() + 1;
  // Player `p` pushes `body` at a tick not sealed yet.
  auto push = [&](const v1::JoinSessionReply& p, const v1::Handle& body) {
    v1::SendInputRequest send;
    send.set_player_id(p.player_id());
    send.set_player_secret(p.player_secret());
    send.set_tick(tick);
    v1::SetVelocity* v = send.mutable_input()->add_edits()->mutable_set_velocity();
    *v->mutable_body() = body;
    v->mutable_linear()->set_x(1.0);
    v1::SendInputReply sent;
    return session->send_input(send, &sent);
  };
  EXPECT_EQ(push(two, a).code(), StatusCode::kPermissionDenied);

  v1::SetOwnershipRequest give;
  give.set_player_id(two.player_id());
  *give.add_bodies() = a;
  v1::SetOwnershipReply given;
  ASSERT_TRUE(session->set_ownership(give, &given).ok());
  EXPECT_EQ(given.tick(), stepped.tick());
  EXPECT_EQ(push(one, a).code(), StatusCode::kPermissionDenied);
  EXPECT_TRUE(push(two, a).ok());
  ASSERT_TRUE(session->step(1, std::nullopt, false, nullptr, &stepped).ok());
  ASSERT_EQ(events->confirmed.size(), 2u);
  const v1::ConfirmedTick& changed = events->confirmed.back();
  ASSERT_EQ(changed.owners_changed_size(), 2) << changed.ShortDebugString();
  EXPECT_EQ(changed.owners_changed(0).player_id(), one.player_id());
  EXPECT_EQ(changed.owners_changed(0).bodies_size(), 0);
  EXPECT_EQ(changed.owners_changed(1).player_id(), two.player_id());
  ASSERT_EQ(changed.owners_changed(1).bodies_size(), 1);
  EXPECT_EQ(changed.owners_changed(1).bodies(0).index(), a.index());

  // Refused whole: an unknown player, a static body, a body listed twice. b stays no one's.
  tick = stepped.tick() + 1;
  v1::SetOwnershipRequest bad;
  bad.set_player_id(9);
  *bad.add_bodies() = b;
  Status s = session->set_ownership(bad, &given);
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("player_id: no player 9"), std::string::npos) << s.message();
  bad.set_player_id(one.player_id());
  *bad.add_bodies() = ground;
  s = session->set_ownership(bad, &given);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("bodies[1]"), std::string::npos) << s.message();
  bad.mutable_bodies(1)->CopyFrom(b);
  s = session->set_ownership(bad, &given);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("listed twice"), std::string::npos) << s.message();
  EXPECT_EQ(push(one, b).code(), StatusCode::kPermissionDenied);

  // Player 0 takes a body back from everyone.
  v1::SetOwnershipRequest take;
  *take.add_bodies() = a;
  ASSERT_TRUE(session->set_ownership(take, &given).ok());
  EXPECT_EQ(push(two, a).code(), StatusCode::kPermissionDenied);
  ASSERT_TRUE(session->step(1, std::nullopt, false, nullptr, &stepped).ok());
  const v1::ConfirmedTick& taken = events->confirmed.back();
  ASSERT_EQ(taken.owners_changed_size(), 1);
  EXPECT_EQ(taken.owners_changed(0).player_id(), two.player_id());
  EXPECT_EQ(taken.owners_changed(0).bodies_size(), 0);
}

}  // namespace
}  // namespace fulcrum::server
