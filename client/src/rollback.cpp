#include "fulcrum/rollback.h"

#include <algorithm>
#include <set>
#include <utility>

#include "edit_convert.h"
#include "fulcrum/state.h"

namespace fulcrum::client {

namespace {

constexpr int kMaxLead = 600;  // the session's own bound on input_delay

}  // namespace

PredictedWorld::PredictedWorld(const v1::JoinSessionReply& me, const PredictedWorldOptions& options)
    : me_(me.player_id()), first_input_tick_(me.first_input_tick()), options_(options) {}

Result<std::unique_ptr<PredictedWorld>> PredictedWorld::create(
    const v1::JoinSessionReply& me, const PredictedWorldOptions& options) {
  if (options.max_lead < 1 || options.max_lead > kMaxLead) {
    return invalid_argument("max_lead: must be 1 to " + std::to_string(kMaxLead) + " ticks (got " +
                            std::to_string(options.max_lead) + ")");
  }
  if (me.player_id() == 0) {
    return invalid_argument("me.player_id: required (the local player's JoinSessionReply)");
  }
  return std::unique_ptr<PredictedWorld>(new PredictedWorld(me, options));
}

Status PredictedWorld::on_event(const v1::SessionEvent& event) {
  if (event.has_start()) return start(event);
  return confirm(event);
}

Status PredictedWorld::stop(Status status) {
  stopped_ = true;
  return status;
}

Status PredictedWorld::start(const v1::SessionEvent& event) {
  FULCRUM_RETURN_IF_ERROR(confirmed_.on_event(event));
  const v1::SessionStart& s = event.start();
  session_ = s.options();
  // Taken from a world that was just checked against the start's hash: cannot be refused.
  FULCRUM_RETURN_IF_ERROR(predicted_.restore(confirmed_.world().snapshot()));
  started_ = true;
  stopped_ = false;
  skip_ = s.applied_batches();
  predictions_.clear();
  // What the players did before the start is not in it: their next inputs are predicted from
  // the first ones confirmed from here.
  last_input_.clear();
  for (const v1::PlayerInfo& p : s.players()) last_input_.emplace(p.player_id(), v1::EditBatch());
  last_input_.emplace(me_, v1::EditBatch());
  local_.erase(local_.begin(), local_.lower_bound(s.tick()));

  // Ticks this player can no longer send an input for: on the clock, the first input_delay
  // ticks past the world's (turn by turn any tick not sealed); never before its first input
  // tick. The session fills them in (inputs sent before the start, or the missing-input rule),
  // and so does the prediction.
  const int64_t delay =
      session_.seal() == v1::SEAL_RULE_ALL_INPUTS ? 0 : int64_t{session_.input_delay()};
  const int64_t first = std::max(s.tick() + delay, first_input_tick_);
  if (first - s.tick() > options_.max_lead) {
    return stop(failed_precondition("max_lead: " + std::to_string(options_.max_lead) +
                                    " ticks, but this player's first " + "input is for tick " +
                                    std::to_string(first) + ", " +
                                    std::to_string(first - s.tick()) + " ticks past the start"));
  }
  while (predicted_.tick() < first) FULCRUM_RETURN_IF_ERROR(predict_one(false));
  return {};
}

std::vector<const v1::EditBatch*> PredictedWorld::inputs_at(int64_t tick) const {
  std::vector<const v1::EditBatch*> out;
  for (const auto& [id, last] : last_input_) {  // by player id, as the session applies them
    const v1::EditBatch* input = nullptr;
    if (id == me_) {
      if (auto played = local_.find(tick); played != local_.end()) {
        input = &played->second;
      } else if (tick >= first_input_tick_ &&
                 session_.missing_input() == v1::MISSING_INPUT_REPEAT_LAST) {
        input = &last;  // not sent: the session repeats the last one
      }
    } else if (options_.remote == RemotePrediction::kRepeatLast) {
      input = &last;
    }
    // An empty input is sent but adds no batch to the confirmed tick.
    if (input != nullptr && input->edits_size() > 0) out.push_back(input);
  }
  return out;
}

Status PredictedWorld::predict_one(bool strict) {
  Predicted p;
  p.tick = predicted_.tick();
  const auto local = local_.find(p.tick);
  for (const v1::EditBatch* input : inputs_at(p.tick)) {
    Result<EditOutcome> applied = apply_edit_batch(&predicted_, *input);
    if (!applied.ok()) {
      if (strict && local != local_.end() && input == &local->second) {
        return applied.status().with_prefix("input.");
      }
      // The session drops an input the world refuses when it seals the tick; so does the
      // prediction (the batch is all or nothing: the world is as it was).
      continue;
    }
    p.batches.push_back(input->SerializeAsString());
  }
  FULCRUM_RETURN_IF_ERROR(predicted_.try_step());
  p.hash_after = predicted_.state_hash();
  predictions_.push_back(std::move(p));
  return {};
}

Status PredictedWorld::roll_back_to_confirmed(int64_t present) {
  FULCRUM_RETURN_IF_ERROR(predicted_.restore(confirmed_.world().snapshot()));
  predictions_.clear();
  while (predicted_.tick() < present) FULCRUM_RETURN_IF_ERROR(predict_one(false));
  return {};
}

Result<int64_t> PredictedWorld::advance(const v1::EditBatch& input) {
  if (!started_) {
    return failed_precondition("advance before the session's start: feed the watch's events");
  }
  if (stopped_) return failed_precondition("the session desynchronised: watch again to restart");
  if (lead() >= options_.max_lead) {
    return failed_precondition("the predicted world is " + std::to_string(lead()) +
                               " ticks past the confirmed one (max_lead): wait for the server");
  }
  const int64_t tick = predicted_tick();
  local_[tick] = input;
  Status played = predict_one(true);
  if (!played.ok()) {
    // Batches before the local one may be applied already: the world is put back by stepping
    // the unconfirmed ticks again, which gives the same bits.
    local_.erase(tick);
    Status back = roll_back_to_confirmed(tick);
    if (!back.ok()) return stop(back);
    return played.with_prefix("tick " + std::to_string(tick) + ": ");
  }
  ++counters_.ticks_advanced;
  return tick;
}

Status PredictedWorld::confirm(const v1::SessionEvent& event) {
  Status checked = confirmed_.on_event(event);
  if (!checked.ok()) return started_ ? stop(checked) : checked;
  ++counters_.ticks_confirmed;
  const v1::ConfirmedTick& c = event.confirmed();
  const v1::ReplayTick& tick = c.tick();

  // What the server applied before the step, less what the start's snapshot held already.
  std::vector<std::string> applied;
  for (int i = static_cast<int>(std::min<uint32_t>(skip_, tick.edits_size()));
       i < tick.edits_size(); ++i) {
    applied.push_back(tick.edits(i).SerializeAsString());
  }
  skip_ = 0;

  // Each player's last input as the session keeps it: what arrived (a batch, or nothing for
  // an empty input); unchanged when the missing-input rule stood in for it.
  for (const v1::PlayerInfo& p : c.joined()) last_input_.emplace(p.player_id(), v1::EditBatch());
  const std::set<uint32_t> missing(c.missing_players().begin(), c.missing_players().end());
  for (auto& [id, last] : last_input_) {
    if (missing.contains(id)) continue;
    last.Clear();
    for (int i = 0; i < c.batch_players_size() && i < tick.edits_size(); ++i) {
      if (c.batch_players(i) == id) last = tick.edits(i);
    }
  }
  const int64_t now = confirmed_tick();
  local_.erase(local_.begin(), local_.lower_bound(now));

  if (predictions_.empty()) {
    // The predicted world was not ahead: it becomes the confirmed one.
    ++counters_.caught_up;
    Status set = predicted_.restore(confirmed_.world().snapshot());
    return set.ok() ? set : stop(set);
  }
  const Predicted held = std::move(predictions_.front());
  predictions_.pop_front();
  const int64_t present = predicted_tick();
  const bool same_inputs = held.batches == applied;
  if (same_inputs && held.hash_after == tick.state_hash()) {
    ++counters_.predictions_held;
    return {};
  }
  ++counters_.rollbacks;
  const int depth = static_cast<int>(present - now);
  counters_.resimulated_ticks += depth;
  counters_.deepest_rollback = std::max(counters_.deepest_rollback, depth);
  Status back = roll_back_to_confirmed(present);
  if (!back.ok()) return stop(back);
  if (same_inputs) {
    return data_loss("tick " + std::to_string(now) + ": the predicted world applied the " +
                     "server's batches but its state hash was " +
                     World::hash_text(held.hash_after) + ", the server's " +
                     World::hash_text(tick.state_hash()) + "; rolled back to the confirmed world");
  }
  return {};
}

}  // namespace fulcrum::client
