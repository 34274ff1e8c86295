// Four players in one multiplayer session on the real fulcrum-server process, each connected
// through its own loopback relay (relay.h) that holds every chunk of bytes for a random 0 to
// 150 ms each way: the players' inputs reach the server, and the confirmed ticks reach the
// players, out of order relative to each other. The world holds 1000 boxes in 200 stacks; each
// player owns 250 and pushes only those, with seeded random forces. Two players predict and
// roll back (PredictedWorld), two follow in lockstep (LockstepWorld). Every client's confirmed
// world must have the server's hash at every tick, the predicting players must have rolled
// back, and once the inputs stop changing every prediction must hold with the server's hash.
//
// Turn by turn (SEAL_RULE_ALL_INPUTS): the server seals a tick as soon as the four inputs for
// it are in, so the run is as fast as the relays and the two cores allow, and the world's
// every tick, and so its final hash, depends on the seeds only. The tick count is kDefaultTicks
// in CI (about 25 s); FULCRUM_RELAY_TICKS=10000 runs the full length by hand.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <mutex>
#include <random>
#include <thread>

#include "fulcrum/client.h"
#include "fulcrum/fingerprint.h"
#include "fulcrum/lockstep.h"
#include "fulcrum/rollback.h"
#include "fulcrum/scenes.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "relay.h"
#include "server_process.h"

namespace fulcrum {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using client::LockstepWorld;
using client::PredictedWorld;
using testing_support::Relay;
using testing_support::ServerProcess;

constexpr int kPlayers = 4;
constexpr int kStacks = 200;
constexpr int kStackHeight = 5;
constexpr int kOwned = kStacks * kStackHeight / kPlayers;  // boxes per player
constexpr auto kMaxDelay = 150ms;                          // each way, per chunk
// Ticks a player plays past its confirmed world: the inputs in flight. Through the relays a
// round trip is up to 300 ms, so this bounds the rate at about kLead / 0.3 s ticks.
constexpr int64_t kLead = 24;
constexpr int64_t kDefaultTicks = 1800;  // half a minute of play at 60 Hz
constexpr int64_t kQuietTicks = 120;     // the inputs are empty for the last ticks

// FULCRUM_RELAY_TICKS, or kDefaultTicks.
int64_t ticks_to_run() {
  const char* env = std::getenv("FULCRUM_RELAY_TICKS");
  const int64_t n = env ? std::atoll(env) : 0;
  return n > 2 * kQuietTicks ? n : kDefaultTicks;
}

// A ground 420 m wide and 200 stacks of five 0.5 m boxes (0.25 kg), 2 m apart: scene body 0 is
// the ground, bodies 1 to 1000 the boxes, stack by stack from the left. Player p owns the p-th
// quarter (50 stacks), so each player's pushes stay mostly among its own stacks.
SceneDef stacks_scene() {
  SceneDef scene;
  scenes::add_ground(&scene, 210.0);
  for (int i = 0; i < kStacks; ++i) {
    scenes::StackOptions stack;
    stack.count = kStackHeight;
    stack.box_size = 0.5;
    stack.offset = 0.0;
    stack.origin = Vec2(-199.0 + 2.0 * i, 0.0);
    scenes::add_stack(&scene, stack);
  }
  return scene;
}

int first_box(int slot) {
  return 1 + slot * kOwned;
}

// Player `slot`'s input for `tick`: one draw held for 6, 9, 12 or 15 ticks (by player), then
// the next. A draw is nothing (one in four) or a force on one to three of the player's own
// boxes, up to 4 N sideways and -1 to 3 N up (the weight of a box is 2.45 N). From `quiet` on,
// nothing.
v1::EditBatch input_for(int slot, int64_t tick, int64_t quiet) {
  v1::EditBatch batch;
  if (tick >= quiet) return batch;
  const int64_t hold = 6 + 3 * slot;
  std::mt19937_64 random(static_cast<uint64_t>(tick / hold) * 0x9E3779B97F4A7C15ULL +
                         static_cast<uint64_t>(slot) * 7919ULL + 1);
  auto unit = [&] { return static_cast<double>(random() >> 11) * 0x1.0p-53; };  // [0, 1)
  if (random() % 4 == 0) return batch;
  const int pushes = 1 + static_cast<int>(random() % 3);
  for (int i = 0; i < pushes; ++i) {
    v1::ApplyForce* force = batch.add_edits()->mutable_apply_force();
    force->mutable_body()->set_index(first_box(slot) + static_cast<int>(random() % kOwned));
    force->mutable_body()->set_generation(1);
    force->mutable_force()->set_x(8.0 * unit() - 4.0);
    force->mutable_force()->set_y(4.0 * unit() - 1.0);
  }
  return batch;
}

// SendInput without waiting for the reply (the client library's send_input waits a round trip,
// up to 300 ms here): a player keeps kLead inputs in flight. Its own channel through the
// player's relay.
class InputSender {
 public:
  InputSender(const std::string& address, uint64_t world, const v1::JoinSessionReply& me)
      : stub_(
            v1::Physics::NewStub(grpc::CreateChannel(address, grpc::InsecureChannelCredentials()))),
        world_(world),
        me_(me) {}

  void send(int64_t tick, const v1::EditBatch& input) {
    auto call = std::make_shared<Call>();
    call->context.set_deadline(std::chrono::system_clock::now() + 60s);
    call->request.set_world_id(world_);
    call->request.set_player_id(me_.player_id());
    call->request.set_player_secret(me_.player_secret());
    call->request.set_tick(tick);
    *call->request.mutable_input() = input;
    {
      std::lock_guard<std::mutex> lock(mu_);
      ++in_flight_;
    }
    Call* raw = call.get();
    stub_->async()->SendInput(
        &raw->context, &raw->request, &raw->reply,
        [this, call = std::move(call)](grpc::Status status) mutable {
          std::string error;
          if (!status.ok()) {
            error = "tick " + std::to_string(call->request.tick()) + ": " + status.error_message();
          } else if (call->reply.duplicate()) {
            error = "tick " + std::to_string(call->request.tick()) + ": duplicate";
          }
          call.reset();  // the call's state goes before finish() can return
          std::lock_guard<std::mutex> lock(mu_);
          if (!error.empty()) errors_.push_back(error);
          --in_flight_;
          cv_.notify_all();
        });
  }

  // Waits for every reply; the errors (refusals, duplicates), if any.
  std::vector<std::string> finish() {
    std::unique_lock<std::mutex> lock(mu_);
    if (!cv_.wait_for(lock, 60s, [&] { return in_flight_ == 0; })) {
      errors_.push_back(std::to_string(in_flight_) + " inputs unanswered after 60 s");
    }
    return errors_;
  }

  ~InputSender() { finish(); }

 private:
  struct Call {
    grpc::ClientContext context;
    v1::SendInputRequest request;
    v1::SendInputReply reply;
  };

  std::unique_ptr<v1::Physics::Stub> stub_;
  const uint64_t world_;
  const v1::JoinSessionReply me_;
  std::mutex mu_;
  std::condition_variable cv_;
  int64_t in_flight_ = 0;
  std::vector<std::string> errors_;
};

// What every player has: its relay, its client through it, its sender, its watch.
struct Player {
  int slot = 0;
  v1::JoinSessionReply me;
  std::unique_ptr<Relay> relay;
  std::unique_ptr<client::Client> client;
  std::unique_ptr<InputSender> sender;
  std::unique_ptr<client::Subscription> watch;
  std::mutex mu;
  std::condition_variable cv;
  std::vector<std::string> errors;

  // The confirmed tick, under mu.
  virtual int64_t confirmed_tick() const = 0;
  virtual bool started() const = 0;
  virtual ~Player() = default;
};

// Follows in lockstep and keeps its inputs kLead ticks past its confirmed world, sent from the
// watch's thread as each tick is confirmed.
struct LockstepPlayer : Player {
  LockstepWorld world;
  int64_t next = 0;  // the next tick to send an input for
  int64_t end = 0;
  int64_t quiet = 0;

  ~LockstepPlayer() override { watch.reset(); }  // before `world`, which its thread feeds

  int64_t confirmed_tick() const override { return world.world().tick(); }
  bool started() const override { return world.started(); }

  void on_event(const v1::SessionEvent& event) {
    std::lock_guard<std::mutex> lock(mu);
    Status st = world.on_event(event);
    if (!st.ok()) errors.push_back(st.message());
    for (; st.ok() && next <= std::min(world.world().tick() + kLead, end - 1); ++next) {
      sender->send(next, input_for(slot, next, quiet));
    }
    cv.notify_all();
  }
};

// Plays up to kLead ticks ahead of its confirmed world on its own thread (play()); rollbacks
// happen on the watch's thread.
struct PredictingPlayer : Player {
  std::unique_ptr<PredictedWorld> world;
  int64_t quiet = -1;
  bool quiet_seen = false;
  client::RollbackCounters at_quiet;  // once tick `quiet` was confirmed

  ~PredictingPlayer() override { watch.reset(); }

  int64_t confirmed_tick() const override { return world->confirmed_tick(); }
  bool started() const override { return world->started(); }

  void on_event(const v1::SessionEvent& event) {
    std::lock_guard<std::mutex> lock(mu);
    Status st = world->on_event(event);
    if (!st.ok()) errors.push_back(st.message());
    if (!quiet_seen && world->confirmed_tick() == quiet + 1) {
      at_quiet = world->counters();
      quiet_seen = true;
    }
    cv.notify_all();
  }

  void play(int64_t end) {
    for (;;) {
      std::unique_lock<std::mutex> lock(mu);
      if (!cv.wait_for(lock, 30s, [&] {
            return !errors.empty() || world->predicted_tick() >= end ||
                   (world->started() && world->lead() < kLead);
          })) {
        errors.push_back("no confirmed tick for 30 s at tick " +
                         std::to_string(world->confirmed_tick()));
        return;
      }
      if (!errors.empty() || world->predicted_tick() >= end) return;
      const int64_t tick = world->predicted_tick();
      const v1::EditBatch input = input_for(slot, tick, quiet);
      Result<int64_t> played = world->advance(input);
      if (!played.ok() || *played != tick) {
        errors.push_back("advance: " + played.status().message());
        return;
      }
      lock.unlock();
      sender->send(tick, input);
    }
  }
};

TEST(RelayTest, FourPlayersThroughJitteryRelaysStayOnTheServersHashes) {
  const int64_t end = ticks_to_run();
  const int64_t quiet = end - kQuietTicks;
  ServerProcess server({});
  ASSERT_FALSE(server.address().empty()) << server.log();
  auto owner = testing_support::connect(server);
  Result<client::WorldSummary> created = owner->create_world(stacks_scene());
  ASSERT_TRUE(created.ok()) << created.status().message();
  ASSERT_EQ(created->body_count, 1 + kStacks * kStackHeight);
  const uint64_t world = created->id;
  v1::SessionOptions options;
  options.set_max_players(kPlayers);
  options.set_input_delay(2);
  options.set_seal(v1::SEAL_RULE_ALL_INPUTS);
  ASSERT_TRUE(owner->open_session(world, options).ok());

  // Players 1 and 3 predict, 2 and 4 follow in lockstep.
  PredictingPlayer predicting[2];
  LockstepPlayer lockstep[2];
  Player* players[kPlayers] = {&predicting[0], &lockstep[0], &predicting[1], &lockstep[1]};
  for (int slot = 0; slot < kPlayers; ++slot) {
    Player& p = *players[slot];
    p.slot = slot;
    v1::JoinSessionRequest join;
    join.set_world_id(world);
    join.set_fingerprint(kDeterminismFingerprint);
    for (int i = 0; i < kOwned; ++i) {
      v1::Handle* box = join.add_bodies();
      box->set_index(first_box(slot) + i);
      box->set_generation(1);
    }
    Result<v1::JoinSessionReply> joined = owner->join_session(join);
    ASSERT_TRUE(joined.ok()) << joined.status().message();
    p.me = *joined;
    p.relay = std::make_unique<Relay>(Relay::port_of(server.address()), 101 + slot, kMaxDelay);
    ASSERT_FALSE(p.relay->address().empty());
    client::ClientOptions through;
    through.address = p.relay->address();
    p.client = client::Client::connect(through);
    p.sender = std::make_unique<InputSender>(p.relay->address(), world, p.me);
  }
  for (PredictingPlayer& p : predicting) {
    p.quiet = quiet;
    p.world = std::move(PredictedWorld::create(p.me).value());  // max_lead 32 > kLead
    auto watch = p.client->watch_session(
        world, [&p](const v1::SessionEvent& e) { p.on_event(e); }, &p.me);
    ASSERT_TRUE(watch.ok()) << watch.status().message();
    p.watch = std::move(watch).value();
  }
  for (LockstepPlayer& p : lockstep) {
    p.quiet = quiet;
    p.end = end;
    p.next = p.me.first_input_tick();
    auto watch = p.client->watch_session(
        world, [&p](const v1::SessionEvent& e) { p.on_event(e); }, &p.me);
    ASSERT_TRUE(watch.ok()) << watch.status().message();
    p.watch = std::move(watch).value();
  }
  int64_t start_tick[kPlayers];
  for (int slot = 0; slot < kPlayers; ++slot) {
    Player& p = *players[slot];
    std::unique_lock<std::mutex> lock(p.mu);
    ASSERT_TRUE(p.cv.wait_for(lock, 20s, [&] { return p.started(); })) << "player " << slot + 1;
    start_tick[slot] = p.confirmed_tick();
  }

  const auto began = Clock::now();
  std::thread loops[] = {std::thread([&] { predicting[0].play(end); }),
                         std::thread([&] { predicting[1].play(end); })};
  for (std::thread& t : loops) t.join();
  for (int slot = 0; slot < kPlayers; ++slot) {
    Player& p = *players[slot];
    std::unique_lock<std::mutex> lock(p.mu);
    ASSERT_TRUE(
        p.cv.wait_for(lock, 60s, [&] { return !p.errors.empty() || p.confirmed_tick() >= end; }))
        << "player " << slot + 1 << " confirmed through " << p.confirmed_tick();
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - began).count();

  Result<client::WorldSummary> at_end = owner->get_world(world);
  ASSERT_TRUE(at_end.ok());
  EXPECT_EQ(at_end->tick, end);
  for (int slot = 0; slot < kPlayers; ++slot) {
    Player& p = *players[slot];
    SCOPED_TRACE("player " + std::to_string(slot + 1));
    std::lock_guard<std::mutex> lock(p.mu);
    // A confirmed tick whose hash is not the server's is an error here (DATA_LOSS).
    EXPECT_TRUE(p.errors.empty()) << p.errors.front();
    std::vector<std::string> refused = p.sender->finish();
    EXPECT_TRUE(refused.empty()) << refused.front();
    EXPECT_EQ(p.confirmed_tick(), end);
    EXPECT_GT(p.relay->chunks(), 0);
  }
  for (LockstepPlayer& p : lockstep) {
    std::lock_guard<std::mutex> lock(p.mu);
    EXPECT_EQ(p.world.ticks_confirmed(), end - start_tick[p.slot]);
    EXPECT_EQ(p.world.world().state_hash(), at_end->state_hash);
  }
  for (PredictingPlayer& p : predicting) {
    SCOPED_TRACE("player " + std::to_string(p.slot + 1));
    std::lock_guard<std::mutex> lock(p.mu);
    const client::RollbackCounters& n = p.world->counters();
    EXPECT_EQ(n.ticks_confirmed, end - start_tick[p.slot]);
    EXPECT_EQ(p.world->confirmed_world().state_hash(), at_end->state_hash);
    // The three others change their inputs every 6 to 15 ticks while this one plays up to
    // kLead ticks ahead: it mispredicts, and each rollback steps at most kLead - 1 ticks again.
    EXPECT_GT(n.rollbacks, 0);
    EXPECT_LE(n.deepest_rollback, kLead - 1);
    // Turn by turn nothing is sealed before this player's input is in: every confirmed tick was
    // predicted, rightly or not.
    EXPECT_EQ(n.caught_up, 0);
    EXPECT_EQ(n.rollbacks + n.predictions_held, n.ticks_confirmed);
    // From tick `quiet` every input is empty; once that tick is confirmed every prediction
    // holds, each with the server's hash, and the predicted world ends on the confirmed one.
    ASSERT_TRUE(p.quiet_seen);
    EXPECT_EQ(n.rollbacks, p.at_quiet.rollbacks);
    EXPECT_EQ(n.predictions_held - p.at_quiet.predictions_held, end - quiet - 1);
    EXPECT_EQ(p.world->predicted_tick(), end);
    EXPECT_EQ(p.world->predicted_world().state_hash(), p.world->confirmed_world().state_hash());
    std::printf(
        "player %d: %lld ticks confirmed, %lld rollbacks, %lld ticks stepped again, deepest %d\n",
        p.slot + 1, static_cast<long long>(n.ticks_confirmed), static_cast<long long>(n.rollbacks),
        static_cast<long long>(n.resimulated_ticks), n.deepest_rollback);
  }
  int64_t chunks = 0;
  for (Player* p : players) chunks += p->relay->chunks();
  std::printf("%lld ticks in %.1f s (%.0f ticks/s), final hash %016llx, %lld chunks relayed\n",
              static_cast<long long>(end), seconds, end / seconds,
              static_cast<unsigned long long>(at_end->state_hash), static_cast<long long>(chunks));
  for (Player* p : players) p->watch->cancel();
}

}  // namespace
}  // namespace fulcrum
