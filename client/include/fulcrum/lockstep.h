// A client's own copy of a multiplayer session's world, stepped only by what the server
// confirms (Client::watch_session): lockstep. Every confirmed tick's batches are applied and the
// world stepped, and its state hash must be the server's; a difference is a desync, reported at
// its tick with the server's hash and the local one.
//
// Desync reports (ReportHash, session.proto): the copy keeps its own hash of every tick it
// stepped and hands out a report every `report_every` ticks (take_report, sent with
// Client::report_hash), so that the server sees a player drift even when the player does not
// look. At a desync it hands out a report at once, through the tick that differs and with its
// snapshot of that tick, so the server names the first field that differs; with `resync` it
// asks for a fresh start and skips confirmed ticks until that start arrives on the watch, then
// continues from it bit for bit.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>

#include "fulcrum/status.h"
#include "fulcrum/v1/session.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::client {

struct LockstepOptions {
  // A report of this copy's hashes every this many confirmed ticks, 1 to 1024 (0: only at a
  // desync).
  int report_every = 0;
  // At a desync, ask the server for a fresh start and wait for it (false: the copy stops at
  // the desync until the caller watches again).
  bool resync = false;
};

class LockstepWorld {
 public:
  LockstepWorld() = default;
  explicit LockstepWorld(const LockstepOptions& options) : options_(options) {}

  // Feed every SessionEvent of a watch, in order. A SessionStart (re)starts the copy from its
  // snapshot (FAILED_PRECONDITION when the server's determinism fingerprint is not this
  // build's: the copies would differ). A ConfirmedTick before any start is FAILED_PRECONDITION;
  // a hash that differs is DATA_LOSS naming the tick, and the copy stops there (waiting for
  // the resync it asked for: confirmed ticks are then skipped, OK, until the start arrives).
  Status on_event(const v1::SessionEvent& event);

  // The report due after the last on_event, if any: first_tick, hashes, and at a desync the
  // snapshot and resync; the caller sends it (Client::report_hash fills in world and player)
  // and gives the reply to on_report_reply.
  std::optional<v1::ReportHashRequest> take_report();
  // The server's verdict: a desync this copy had not seen stops it (and waits for the resync
  // if one was sent); a resync asked for but not sent (no watch open as the player) ends the
  // wait with FAILED_PRECONDITION: watch again to restart.
  Status on_report_reply(const v1::ReportHashReply& reply);

  const World& world() const { return world_; }
  bool started() const { return started_; }
  bool desynced() const { return desynced_; }
  bool awaiting_resync() const { return awaiting_resync_; }
  int64_t ticks_confirmed() const { return ticks_confirmed_; }
  int64_t ticks_skipped() const { return ticks_skipped_; }  // while waiting for a resync
  int64_t resyncs() const { return resyncs_; }              // fresh starts taken mid-watch
  // The last reply given to on_report_reply with a DESYNC verdict (the tick, the field).
  const std::optional<v1::ReportHashReply>& last_desync() const { return last_desync_; }

  // For tests that desynchronise a copy on purpose: called with the copy right after each
  // confirmed tick is stepped, before its hash is checked.
  void set_after_step_for_test(std::function<void(World*)> hook) { after_step_ = std::move(hook); }

 private:
  // Starts a report through the newest hash (`with_snapshot`: this copy's world of that tick).
  void queue_report(bool with_snapshot);

  LockstepOptions options_;
  World world_;
  bool started_ = false;
  bool desynced_ = false;
  bool awaiting_resync_ = false;
  uint32_t skip_ = 0;  // batches of the next confirmed tick already in the start's snapshot
  int64_t ticks_confirmed_ = 0;
  int64_t ticks_skipped_ = 0;
  int64_t resyncs_ = 0;
  int64_t resync_tick_ = -1;         // the tick of the last fresh start taken mid-watch
  int64_t first_unreported_ = 0;     // the tick of unreported_[0]
  std::deque<uint64_t> unreported_;  // this copy's hashes since the last report
  std::optional<v1::ReportHashRequest> report_;
  std::optional<v1::ReportHashReply> last_desync_;
  std::function<void(World*)> after_step_;
};

}  // namespace fulcrum::client
