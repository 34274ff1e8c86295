// Predict/rollback: a player's client that plays ahead of a multiplayer session instead of
// waiting for it (lockstep.h waits). It keeps two worlds:
//
// - the confirmed world, stepped only by what the server confirms (a LockstepWorld: every
//   confirmed tick's state hash is checked against the server's);
// - the predicted world, some ticks ahead of it. The local player's input applies there at
//   once, at the predicted world's tick, and the application sends it to the server for that
//   same tick; the other players are assumed to do again what they last did.
//
// When the server confirms tick T, the batches it applied are compared with the ones the
// predicted world applied at T. The same batches: the prediction held, and the predicted
// world's hash after T is checked against the server's too. Different ones (a remote player
// changed its input, the world's owner edited, the local input arrived late): the predicted
// world is rolled back to the confirmed world, now at T + 1, and the ticks from T + 1 to the
// present are simulated again with the local inputs already played and the predictions made
// from the newly confirmed inputs.
//
// Not thread-safe: on_event() (from the watch's thread) and advance() (from the game loop)
// must not run at the same time; hold one mutex around both, and around reading the worlds.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "fulcrum/lockstep.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/edit.pb.h"
#include "fulcrum/v1/session.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::client {

// What another player is assumed to do at a tick the server has not confirmed yet.
enum class RemotePrediction {
  // Its last confirmed input again: a player mostly holds an input for many ticks, and a
  // session with MISSING_INPUT_REPEAT_LAST fills in an input that never arrived the same way.
  kRepeatLast,
  // Nothing (as MISSING_INPUT_NONE fills in a missing input).
  kNothing,
};

struct PredictedWorldOptions {
  // How many ticks the predicted world may run past the confirmed one, 1 to 600: advance()
  // refuses to go further (the client waits for the server). It bounds the deepest rollback:
  // at most max_lead - 1 ticks are simulated again.
  int max_lead = 32;
  RemotePrediction remote = RemotePrediction::kRepeatLast;
};

struct RollbackCounters {
  int64_t ticks_confirmed = 0;   // confirmed ticks stepped on the confirmed world, hash checked
  int64_t ticks_advanced = 0;    // advance() calls: local ticks played on the predicted world
  int64_t predictions_held = 0;  // confirmed ticks the predicted world had stepped with the same
                                 // batches; its hash after each was the server's
  // Confirmed ticks whose batches differed from what the predicted world applied at that tick:
  // each restored the predicted world from the confirmed one.
  int64_t rollbacks = 0;
  // Ticks the predicted world stepped again to return to the present. A rollback at confirmed
  // tick T with the predicted world at P steps P - T - 1 ticks again: the mispredicted tick T
  // itself is the one the confirmed world steps anyway.
  int64_t resimulated_ticks = 0;
  int deepest_rollback = 0;  // the most ticks one rollback stepped again
  // Confirmed ticks the predicted world had not reached (the game loop paused): the predicted
  // world was set to the confirmed one, without a rollback.
  int64_t caught_up = 0;
};

class PredictedWorld {
 public:
  // `me`: the local player's JoinSessionReply (its id and first input tick). INVALID_ARGUMENT
  // when max_lead is out of range or `me` has no player id.
  static Result<std::unique_ptr<PredictedWorld>> create(const v1::JoinSessionReply& me,
                                                        const PredictedWorldOptions& options = {});

  // Feed every SessionEvent of a watch as this player, in order. A SessionStart (re)starts
  // both worlds from its snapshot and moves the predicted world to the first tick this player
  // can still send an input for: input_delay ticks past the start on the clock
  // (SEAL_RULE_ON_STEP), and never before the player's first input tick. A ConfirmedTick steps
  // the confirmed world and checks its hash (DATA_LOSS naming the tick when it is not the
  // server's, as LockstepWorld; both worlds stop there until the next start), then confirms or
  // corrects the prediction. A predicted world whose hash differs from the server's after the
  // same batches is rolled back too, and DATA_LOSS says so (the engine or the game is not
  // deterministic).
  Status on_event(const v1::SessionEvent& event);

  // The local player's input for the predicted world's tick T = predicted_tick(): applied
  // there with the other players' predicted inputs, and the world stepped to T + 1. Returns T:
  // send the input to the server for tick T (Client::send_input), as it is, even when empty
  // (under SEAL_RULE_ALL_INPUTS the session waits for it). FAILED_PRECONDITION before a start,
  // after a desync, or when the predicted world is max_lead ticks past the confirmed one (wait
  // for the server); an input the engine refuses is returned as the engine words it, prefixed
  // "tick T: input.", and nothing changes.
  Result<int64_t> advance(const v1::EditBatch& input);

  // The world as the server confirmed it, at confirmed_tick().
  const World& confirmed_world() const { return confirmed_.world(); }
  // The world as this player sees it now, at predicted_tick() >= confirmed_tick().
  const World& predicted_world() const { return predicted_; }
  int64_t confirmed_tick() const { return confirmed_.world().tick(); }
  int64_t predicted_tick() const { return predicted_.tick(); }
  // predicted_tick() - confirmed_tick(): ticks played and not yet confirmed.
  int64_t lead() const { return predicted_tick() - confirmed_tick(); }
  bool started() const { return started_; }
  uint32_t player_id() const { return me_; }
  const RollbackCounters& counters() const { return counters_; }

 private:
  PredictedWorld(const v1::JoinSessionReply& me, const PredictedWorldOptions& options);

  Status start(const v1::SessionEvent& event);
  Status confirm(const v1::SessionEvent& event);
  // The batches the predicted world applies at `tick`, in the session's order (players by id).
  std::vector<const v1::EditBatch*> inputs_at(int64_t tick) const;
  // Applies inputs_at(predicted_tick()), steps and records the tick. A batch the world refuses
  // is left out, as the session leaves it out; with `strict`, the local input refused is an
  // error instead (advance()).
  Status predict_one(bool strict);
  // Sets the predicted world to the confirmed one and steps it again up to `present`.
  Status roll_back_to_confirmed(int64_t present);
  Status stop(Status status);

  // One tick the predicted world stepped and the server has not confirmed yet.
  struct Predicted {
    int64_t tick = 0;                  // the boundary before the step
    std::vector<std::string> batches;  // applied at it, encoded, in order
    uint64_t hash_after = 0;
  };

  const uint32_t me_;
  const int64_t first_input_tick_;
  const PredictedWorldOptions options_;
  v1::SessionOptions session_;
  LockstepWorld confirmed_;
  World predicted_;
  bool started_ = false;
  bool stopped_ = false;  // a desync: nothing moves until the next start
  uint32_t skip_ = 0;     // batches at the head of the next confirmed tick already in the start
  std::deque<Predicted> predictions_;             // ticks confirmed_tick() to predicted_tick() - 1
  std::map<int64_t, v1::EditBatch> local_;        // this player's inputs by tick, not confirmed yet
  std::map<uint32_t, v1::EditBatch> last_input_;  // every player's last confirmed input, by id
  RollbackCounters counters_;
};

}  // namespace fulcrum::client
