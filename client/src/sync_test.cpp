#include "fulcrum/sync_test.h"

#include <utility>

#include "edit_convert.h"
#include "snapshot_convert.h"

namespace fulcrum::client {

namespace {

constexpr int kMaxCheckDistance = 128;

}  // namespace

SyncTest::SyncTest(World world, const SyncTestOptions& options, GameTick game)
    : world_(std::move(world)), options_(options), game_(std::move(game)) {}

Result<std::unique_ptr<SyncTest>> SyncTest::start(World world, const SyncTestOptions& options,
                                                  GameTick game) {
  if (options.check_distance < 1 || options.check_distance > kMaxCheckDistance) {
    return invalid_argument("check_distance: must be 1 to " + std::to_string(kMaxCheckDistance) +
                            " (got " + std::to_string(options.check_distance) + ")");
  }
  if (!game) return invalid_argument("game: required");
  return std::unique_ptr<SyncTest>(new SyncTest(std::move(world), options, std::move(game)));
}

Status SyncTest::tick_once(std::string* encoded) {
  const int64_t tick = world_.tick();
  v1::EditBatch inputs;
  Status played = game_(tick, world_, &inputs);
  if (!played.ok()) return played.with_prefix("tick " + std::to_string(tick) + ": game: ");
  // Serialized twice from equal messages (no maps in an EditBatch), the bytes are equal.
  encoded->clear();
  inputs.SerializeToString(encoded);
  if (inputs.edits_size() > 0) {
    Result<EditOutcome> applied = apply_edit_batch(&world_, inputs);
    if (!applied.ok()) {
      return applied.status().with_prefix("tick " + std::to_string(tick) + ": inputs.");
    }
  }
  return world_.try_step();
}

Status SyncTest::advance() {
  Kept kept;
  kept.tick = world_.tick();
  kept.before = world_.snapshot();
  if (hook_) hook_(&kept.before);
  FULCRUM_RETURN_IF_ERROR(tick_once(&kept.inputs));
  kept.hash_after = world_.state_hash();
  kept_.push_back(std::move(kept));
  if (static_cast<int>(kept_.size()) > options_.check_distance) kept_.pop_front();
  ++counters_.ticks;
  return rollback_and_compare(static_cast<int>(kept_.size()));
}

Status SyncTest::run(int64_t ticks) {
  for (int64_t i = 0; i < ticks; ++i) FULCRUM_RETURN_IF_ERROR(advance());
  return {};
}

Status SyncTest::rollback_and_compare(int distance) {
  // The first pass's world: kept to compare with, and to go back to when the check fails.
  const WorldSnapshot present = world_.snapshot();
  const size_t first = kept_.size() - static_cast<size_t>(distance);
  const int64_t now = world_.tick();
  auto fail = [&](const std::string& what) {
    (void)world_.restore(present);  // taken from this world a moment ago: cannot be refused
    return Status(StatusCode::kDataLoss, "sync test at tick " + std::to_string(now) + ": " + what);
  };
  Status restored = world_.restore(kept_[first].before);
  if (!restored.ok()) {
    return fail("rolling back " + std::to_string(distance) + " ticks to tick " +
                std::to_string(kept_[first].tick) + " failed: " + restored.message());
  }
  ++counters_.rollbacks;
  if (distance > counters_.deepest_rollback) counters_.deepest_rollback = distance;
  for (size_t i = first; i < kept_.size(); ++i) {
    const Kept& k = kept_[i];
    std::string inputs;
    Status ticked = tick_once(&inputs);
    ++counters_.resimulated_ticks;
    if (!ticked.ok()) {
      return fail("re-simulating after a rollback of " + std::to_string(distance) +
                  " ticks: " + ticked.message());
    }
    if (world_.state_hash() == k.hash_after) continue;
    const WorldSnapshot& expected = i + 1 < kept_.size() ? kept_[i + 1].before : present;
    const std::string difference =
        first_difference(snapshot_to_proto(expected), snapshot_to_proto(world_.snapshot()));
    return fail("tick " + std::to_string(k.tick + 1) + " re-simulated after a rollback of " +
                std::to_string(distance) + " ticks has state hash " +
                World::hash_text(world_.state_hash()) + ", the first pass had " +
                World::hash_text(k.hash_after) + "; " +
                (inputs == k.inputs
                     ? std::string("the game's inputs for tick ") + std::to_string(k.tick) +
                           " were the same"
                     : std::string("the game's inputs for tick ") + std::to_string(k.tick) +
                           " differ from the first pass's (they depend on something "
                           "other than the world and the tick)") +
                (difference.empty() ? "" : "; first difference: " + difference));
  }
  return {};
}

}  // namespace fulcrum::client
