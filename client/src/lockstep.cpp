#include "fulcrum/lockstep.h"

#include "edit_convert.h"
#include "fulcrum/fingerprint.h"
#include "snapshot_convert.h"

namespace fulcrum::client {

Status LockstepWorld::on_event(const v1::SessionEvent& event) {
  if (event.has_start()) {
    const v1::SessionStart& start = event.start();
    if (start.fingerprint() != kDeterminismFingerprint) {
      return failed_precondition("fingerprint: the server's engine gives the results of " +
                                 start.fingerprint() + ", this build's those of " +
                                 kDeterminismFingerprint + ": the copies would differ");
    }
    World fresh;
    FULCRUM_RETURN_IF_ERROR(restore_encoded(&fresh, start.snapshot().SerializeAsString()));
    world_ = std::move(fresh);
    started_ = true;
    desynced_ = false;
    skip_ = start.applied_batches();
    return {};
  }
  if (!event.has_confirmed()) return invalid_argument("event: neither start nor confirmed");
  if (!started_) return failed_precondition("confirmed tick before the session's start");
  if (desynced_) return failed_precondition("the copy desynchronised: watch again to restart");
  const v1::ReplayTick& tick = event.confirmed().tick();
  for (int i = 0; i < tick.edits_size(); ++i) {
    if (skip_ > 0) {
      --skip_;
      continue;
    }
    Result<EditOutcome> applied = apply_edit_batch(&world_, tick.edits(i));
    if (!applied.ok()) {
      desynced_ = true;
      return Status(StatusCode::kDataLoss,
                    "tick " + std::to_string(tick.tick()) + ": the server applied batch " +
                        std::to_string(i) +
                        " but this copy refuses it: " + applied.status().message());
    }
  }
  FULCRUM_RETURN_IF_ERROR(world_.try_step());
  if (world_.tick() != tick.tick() || world_.state_hash() != tick.state_hash()) {
    desynced_ = true;
    return Status(StatusCode::kDataLoss,
                  "desync at tick " + std::to_string(tick.tick()) + ": the server's state hash " +
                      World::hash_text(tick.state_hash()) + ", this copy's " +
                      World::hash_text(world_.state_hash()) + " (at tick " +
                      std::to_string(world_.tick()) + ")");
  }
  ++ticks_confirmed_;
  return {};
}

}  // namespace fulcrum::client
