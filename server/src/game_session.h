// A world opened as a multiplayer session (session.proto): its players, their objects, and
// their inputs waiting for their ticks. The Session that owns the world owns its GameSession
// and calls it with the world held (Session::mu_); the Session also keeps the watchers.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "confirmed_history.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/session.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::server {

// One WatchSession stream. offer() never blocks: events queue in order, and a watcher more than
// kMaxBehind events behind is ended (it watches again from a new start).
class SessionWatcher {
 public:
  static constexpr size_t kMaxBehind = 1024;
  virtual ~SessionWatcher() = default;
  virtual void offer(std::shared_ptr<const v1::SessionEvent> event) = 0;
  virtual void close(const Status& status) = 0;
  // The player this stream watches as (0: a spectator); fixed while the stream is registered.
  virtual uint32_t player_id() const = 0;
};

class GameSession {
 public:
  // `options` checked by check_options(); the world when it was opened.
  GameSession(const v1::SessionOptions& options, const World& world);

  // INVALID_ARGUMENT naming the field when an option is out of range; fills in the defaults.
  static Status check_options(v1::SessionOptions* options);
  static constexpr uint32_t kMaxPlayers = 64;  // SessionOptions.max_players at most

  const v1::SessionOptions& options() const { return options_; }

  Status join(const v1::JoinSessionRequest& request, const World& world,
              v1::JoinSessionReply* reply);
  // What the scene gave each player (Body.player, Joint.player): a player joining takes the
  // ones still alive and no player's.
  struct SceneOwned {
    std::vector<BodyId> bodies;
    std::vector<JointId> joints;
  };
  void set_scene_owners(std::map<uint32_t, SceneOwned> owners) {
    scene_owners_ = std::move(owners);
  }
  // The world owner's SetOwnership: all of it or none.
  Status set_ownership(const v1::SetOwnershipRequest& request, const World& world);
  // Checks the player, the tick and the input (the edit kinds an input may hold, on the
  // player's own objects, finite values), then holds it for its tick.
  Status send_input(const v1::SendInputRequest& request, const World& world,
                    v1::SendInputReply* reply);
  // Every player has sent its input for `tick`, or could not have (the tick is before its
  // first input tick); false when there are no players.
  bool complete(int64_t tick) const;

  // A batch the world's owner applied (ApplyEdits): it goes first in the next confirmed tick.
  void note_owner_batch(const v1::EditBatch& batch) { pending_.push_back({0, batch, true}); }

  // What to apply before stepping `tick`, in order: pending batches (the owner's, and inputs
  // carried from a tick whose step the world refused), then each player's input in player-id
  // order, the missing-input rule standing in for inputs that did not arrive. The tick is
  // sealed: later inputs for it are refused.
  struct Batch {
    uint32_t player = 0;  // 0: the owner
    v1::EditBatch edits;
    bool applied = false;  // in the world already (the owner's, and carried inputs)
  };
  struct Sealed {
    std::vector<Batch> batches;
    std::vector<uint32_t> missing;
  };
  Sealed seal(int64_t tick);
  // The world refused to step the tick (a server limit): what was applied stays applied and
  // goes out with the next tick that runs.
  void carry(Sealed sealed);
  // After the step: the event for every watcher (batches the world refused were taken out of
  // `applied` by the caller, and their players put in `missing`).
  std::shared_ptr<const v1::SessionEvent> confirm(const Sealed& applied, const World& world);

  // The first event of a watch: the world now, the options and the players. `resync`: sent
  // again mid-watch to a desynchronised player (ReportHash).
  std::shared_ptr<const v1::SessionEvent> start_event(const World& world,
                                                      bool resync = false) const;

  // A desync report (ReportHash) with the world held: checks the player's secret and the ticks
  // (INVALID_ARGUMENT naming first_tick for ticks not confirmed yet), then compares the hashes
  // still in the history and fills reply's verdict, checked range and, on a desync, the first
  // tick that differs with both hashes.
  Status compare_hashes(const v1::ReportHashRequest& request, const World& world,
                        v1::ReportHashReply* reply) const;
  const ConfirmedHistory& history() const { return history_; }

  int players() const { return static_cast<int>(players_.size()); }

  // A watch as `player_id` opened (+1) or ended (-1). Opening checks the secret
  // (PERMISSION_DENIED); a player whose last watch ended has left (see session.proto).
  Status check_player(uint32_t player_id, const std::string& secret) const;
  void presence(uint32_t player_id, int change);

 private:
  struct Player {
    uint32_t id = 0;
    std::string name;
    std::string secret;
    std::vector<BodyId> bodies;
    std::vector<JointId> joints;
    int64_t first_input_tick = 0;  // the world's tick at join + input_delay
    int watches = 0;               // WatchSession streams open as this player
    bool left = false;             // its last watch ended
    v1::EditBatch last_input;      // the last confirmed input (MISSING_INPUT_REPEAT_LAST)
  };
  void player_to_proto(const Player& p, v1::PlayerInfo* out) const;
  // Checks listed bodies and joints (live, bodies not static, none twice and, with
  // `refuse_owned`, none a player's already) and returns their ids.
  Status check_objects(const google::protobuf::RepeatedPtrField<v1::Handle>& bodies,
                       const google::protobuf::RepeatedPtrField<v1::Handle>& joints,
                       const World& world, bool refuse_owned, std::vector<BodyId>* body_ids,
                       std::vector<JointId>* joint_ids) const;
  Status check_input(const Player& player, const v1::EditBatch& input) const;

  v1::SessionOptions options_;
  int64_t open_tick_ = 0;
  int64_t sealed_through_ = -1;  // the last tick sealed
  std::map<uint32_t, Player> players_;
  std::map<uint64_t, uint32_t> body_owner_;  // by handle (generation << 32 | index)
  std::map<uint64_t, uint32_t> joint_owner_;
  std::map<int64_t, std::map<uint32_t, v1::EditBatch>> inputs_;  // by tick, then player
  std::vector<Batch> pending_;
  std::vector<uint32_t> joined_;                 // players joined since the last confirmed tick
  std::set<uint32_t> owners_changed_;            // players SetOwnership changed since then
  std::map<uint32_t, SceneOwned> scene_owners_;  // by player id
  ConfirmedHistory history_;  // confirmed hashes and keyframes, for desync reports
};

}  // namespace fulcrum::server
