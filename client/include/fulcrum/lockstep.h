// A client's own copy of a multiplayer session's world, stepped only by what the server
// confirms (Client::watch_session): lockstep. Every confirmed tick's batches are applied and the
// world stepped, and its state hash must be the server's; a difference is a desync, reported at
// its tick with the server's hash and the local one.
#pragma once

#include <cstdint>

#include "fulcrum/status.h"
#include "fulcrum/v1/session.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::client {

class LockstepWorld {
 public:
  // Feed every SessionEvent of a watch, in order. A SessionStart (re)starts the copy from its
  // snapshot (FAILED_PRECONDITION when the server's determinism fingerprint is not this
  // build's: the copies would differ). A ConfirmedTick before any start is FAILED_PRECONDITION;
  // a hash that differs is DATA_LOSS naming the tick, and the copy stops there.
  Status on_event(const v1::SessionEvent& event);

  const World& world() const { return world_; }
  bool started() const { return started_; }
  int64_t ticks_confirmed() const { return ticks_confirmed_; }

 private:
  World world_;
  bool started_ = false;
  bool desynced_ = false;
  uint32_t skip_ = 0;  // batches of the next confirmed tick already in the start's snapshot
  int64_t ticks_confirmed_ = 0;
};

}  // namespace fulcrum::client
