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
