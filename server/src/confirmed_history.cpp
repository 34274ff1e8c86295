#include "confirmed_history.h"

#include <utility>

#include "edit_convert.h"

namespace fulcrum::server {

void ConfirmedHistory::start(const World& world) {
  hashes_.clear();
  ticks_.clear();
  keyframes_.clear();
  first_hash_tick_ = world.tick() + 1;
  keyframes_.push_back(std::make_shared<const WorldSnapshot>(world.snapshot()));
}

void ConfirmedHistory::add(const World& world, std::shared_ptr<const v1::SessionEvent> confirmed) {
  const int64_t tick = confirmed->confirmed().tick().tick();
  if (hashes_.empty()) first_hash_tick_ = tick;
  hashes_.push_back(confirmed->confirmed().tick().state_hash());  // hashed once, by confirm
  while (static_cast<int64_t>(hashes_.size()) > kHashWindow) {
    hashes_.pop_front();
    ++first_hash_tick_;
  }
  ticks_.push_back(std::move(confirmed));
  if (tick - keyframes_.back()->tick >= kKeyframeEvery) {
    keyframes_.push_back(std::make_shared<const WorldSnapshot>(world.snapshot()));
  }
  // Keep the newest keyframe at or before the oldest hash, so every tick in the window can be
  // rebuilt, and the confirmed ticks after it.
  while (keyframes_.size() > 1 && keyframes_[1]->tick <= first_hash_tick_) {
    keyframes_.pop_front();
  }
  while (!ticks_.empty() && ticks_.front()->confirmed().tick().tick() <= keyframes_[0]->tick) {
    ticks_.pop_front();
  }
}

std::optional<uint64_t> ConfirmedHistory::hash_after(int64_t tick) const {
  if (tick < first_hash_tick_ || tick > newest_hash_tick()) return std::nullopt;
  return hashes_[static_cast<size_t>(tick - first_hash_tick_)];
}

int64_t ConfirmedHistory::newest_hash_tick() const {
  return first_hash_tick_ + static_cast<int64_t>(hashes_.size()) - 1;
}

std::optional<ConfirmedHistory::Replay> ConfirmedHistory::replay_to(int64_t tick) const {
  if (keyframes_.empty() || tick < keyframes_.front()->tick || tick > newest_hash_tick()) {
    return std::nullopt;
  }
  Replay out;
  for (const auto& k : keyframes_) {
    if (k->tick <= tick) out.keyframe = k;
  }
  for (const auto& t : ticks_) {
    const int64_t at = t->confirmed().tick().tick();
    if (at > out.keyframe->tick && at <= tick) out.ticks.push_back(t);
  }
  return out;
}

Result<WorldSnapshot> rebuild(const ConfirmedHistory::Replay& replay) {
  World world;
  FULCRUM_RETURN_IF_ERROR(world.restore(*replay.keyframe));
  for (const auto& event : replay.ticks) {
    const v1::ReplayTick& tick = event->confirmed().tick();
    for (const v1::EditBatch& batch : tick.edits()) {
      Result<EditOutcome> applied = apply_edit_batch(&world, batch);
      if (!applied.ok()) {
        return Status(StatusCode::kInternal,
                      "rebuilding tick " + std::to_string(tick.tick()) +
                          ": a confirmed batch was refused: " + applied.status().message());
      }
    }
    FULCRUM_RETURN_IF_ERROR(world.try_step());
    if (world.tick() != tick.tick() || world.state_hash() != tick.state_hash()) {
      return Status(StatusCode::kInternal,
                    "rebuilding tick " + std::to_string(tick.tick()) + " gave state hash " +
                        World::hash_text(world.state_hash()) + ", the confirmed one is " +
                        World::hash_text(tick.state_hash()));
    }
  }
  return world.snapshot();
}

}  // namespace fulcrum::server
