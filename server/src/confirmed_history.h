// What a session remembers of the ticks it confirmed, for desync reports (ReportHash): the state
// hash of each of the last kHashWindow ticks, and enough to rebuild the world at any of the
// recent ones: a keyframe (the world's snapshot) every kKeyframeEvery ticks and the confirmed
// ticks after it, whose batches are applied and stepped again. Rebuilding is deterministic, so
// it gives the world the server had at that tick, bit for bit, without the server keeping a
// snapshot of every tick. A session that nobody reports to pays a snapshot every 256 ticks.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "fulcrum/state.h"
#include "fulcrum/status.h"
#include "fulcrum/v1/session.pb.h"
#include "fulcrum/world.h"

namespace fulcrum::server {

class ConfirmedHistory {
 public:
  static constexpr int64_t kHashWindow = 1024;    // ticks whose hashes are kept
  static constexpr int64_t kKeyframeEvery = 256;  // ticks between keyframes

  // The world when the session opened: the first keyframe (its hash is not a confirmed one).
  void start(const World& world);
  // After each confirmed tick (`world` just stepped it; `confirmed` holds its tick and hash):
  // its hash, its event, a keyframe when due; forgets what has fallen out of the window.
  void add(const World& world, std::shared_ptr<const v1::SessionEvent> confirmed);

  // The confirmed hash after `tick`, when it is in the window.
  std::optional<uint64_t> hash_after(int64_t tick) const;
  int64_t oldest_hash_tick() const { return first_hash_tick_; }  // newest: oldest + size - 1
  int64_t newest_hash_tick() const;

  // The keyframe at or before `tick` and the confirmed ticks after it through `tick`; nullopt
  // when `tick` is before the oldest keyframe or was never confirmed.
  struct Replay {
    std::shared_ptr<const WorldSnapshot> keyframe;
    std::vector<std::shared_ptr<const v1::SessionEvent>> ticks;  // in order
  };
  std::optional<Replay> replay_to(int64_t tick) const;

 private:
  int64_t first_hash_tick_ = 0;  // the tick of hashes_[0]
  std::deque<uint64_t> hashes_;
  std::deque<std::shared_ptr<const WorldSnapshot>> keyframes_;  // oldest first
  std::deque<std::shared_ptr<const v1::SessionEvent>> ticks_;   // since keyframes_[0]
};

// The world of the replay's last tick, rebuilt from its keyframe (no lock needed: it touches
// only what the replay holds). INTERNAL when a rebuilt tick's hash is not the confirmed one.
Result<WorldSnapshot> rebuild(const ConfirmedHistory::Replay& replay);

}  // namespace fulcrum::server
