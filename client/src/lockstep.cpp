#include "fulcrum/lockstep.h"

#include <utility>

#include "edit_convert.h"
#include "fulcrum/fingerprint.h"
#include "snapshot_convert.h"

namespace fulcrum::client {

namespace {

constexpr size_t kMaxReportHashes = 1024;  // ReportHashRequest.hashes

}  // namespace

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
    if (started_ && start.resync()) {
      ++resyncs_;
      resync_tick_ = start.tick();
    }
    started_ = true;
    desynced_ = false;
    awaiting_resync_ = false;
    skip_ = start.applied_batches();
    first_unreported_ = start.tick() + 1;
    unreported_.clear();
    report_.reset();
    return {};
  }
  if (!event.has_confirmed()) return invalid_argument("event: neither start nor confirmed");
  if (!started_) return failed_precondition("confirmed tick before the session's start");
  if (awaiting_resync_) {
    ++ticks_skipped_;
    return {};
  }
  if (desynced_) return failed_precondition("the copy desynchronised: watch again to restart");
  const v1::ReplayTick& tick = event.confirmed().tick();
  std::string refused;  // a batch the server applied and this copy refuses: a desync too
  for (int i = 0; i < tick.edits_size(); ++i) {
    if (skip_ > 0) {
      --skip_;
      continue;
    }
    Result<EditOutcome> applied = apply_edit_batch(&world_, tick.edits(i));
    if (!applied.ok() && refused.empty()) {
      refused = "; the server applied batch " + std::to_string(i) +
                " but this copy refuses it: " + applied.status().message();
    }
  }
  FULCRUM_RETURN_IF_ERROR(world_.try_step());
  if (after_step_) after_step_(&world_);
  unreported_.push_back(world_.state_hash());
  if (unreported_.size() > kMaxReportHashes) {
    unreported_.pop_front();
    ++first_unreported_;
  }
  if (world_.tick() != tick.tick() || world_.state_hash() != tick.state_hash() ||
      !refused.empty()) {
    desynced_ = true;
    queue_report(/*with_snapshot=*/true);
    return Status(StatusCode::kDataLoss,
                  "desync at tick " + std::to_string(tick.tick()) + ": the server's state hash " +
                      World::hash_text(tick.state_hash()) + ", this copy's " +
                      World::hash_text(world_.state_hash()) + " (at tick " +
                      std::to_string(world_.tick()) + ")" + refused);
  }
  ++ticks_confirmed_;
  if (options_.report_every > 0 &&
      unreported_.size() >= static_cast<size_t>(options_.report_every)) {
    queue_report(/*with_snapshot=*/false);
  }
  return {};
}

void LockstepWorld::queue_report(bool with_snapshot) {
  if (unreported_.empty()) return;
  v1::ReportHashRequest r;
  r.set_first_tick(first_unreported_);
  for (uint64_t h : unreported_) r.add_hashes(h);
  if (with_snapshot) {
    (void)r.mutable_snapshot()->ParseFromString(encode_snapshot(world_));
    r.set_resync(options_.resync);
    awaiting_resync_ = options_.resync;
  }
  first_unreported_ += static_cast<int64_t>(unreported_.size());
  unreported_.clear();
  report_ = std::move(r);
}

std::optional<v1::ReportHashRequest> LockstepWorld::take_report() {
  std::optional<v1::ReportHashRequest> out = std::move(report_);
  report_.reset();
  return out;
}

Status LockstepWorld::on_report_reply(const v1::ReportHashReply& reply) {
  if (reply.verdict() != v1::HASH_VERDICT_DESYNC) return {};
  last_desync_ = reply;
  if (!reply.resynced()) {
    desynced_ = true;
    if (!awaiting_resync_) return {};
    awaiting_resync_ = false;
    return failed_precondition("desync at tick " + std::to_string(reply.divergent_tick()) +
                               ": the server sent no fresh start (no watch is open as this "
                               "player): watch again to restart");
  }
  // The fresh start is on its way, unless the watch delivered it before this reply came.
  if (resync_tick_ >= reply.resync_tick()) return {};
  desynced_ = true;
  awaiting_resync_ = true;
  return {};
}

}  // namespace fulcrum::client
