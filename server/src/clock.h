// Real time: worlds stepped by the server on its monotonic clock, on a pool of worker threads.
//
// The schedule. When a world switches to REAL_TIME at time t0 with tick length dt, its k-th
// tick of the run is due at t0 + k * dt. Each wake computes how many ticks are due from the
// clock itself (floor((now - t0) / dt) minus the ticks already consumed), never by adding up
// sleeps, so lateness in one wake does not shift later ticks: the world does not drift. When
// more ticks are due than the world's cap (max_catch_up_ticks), the wake steps the cap and
// drops the rest from the schedule; they are counted (ticks_dropped, late_wakes) and logged.
// The tick count of a run therefore never exceeds the schedule: ticks_run + ticks_dropped
// <= floor(elapsed / dt).
//
// Threads. RealTimePool holds the running worlds in a queue ordered by the time their next
// tick is due; each of its threads takes the earliest due world out of the queue, so one
// world is stepped by one thread at a time while many worlds step in parallel. A pool thread
// never waits for a world: it only try-locks it (Session::run_due_ticks), and when an RPC
// holds the world (edits, snapshot, query) it puts the world back for a moment later; the
// ticks stay due and the next wake catches them up. RPCs on a running world therefore apply
// between two ticks.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "fulcrum/status.h"
#include "fulcrum/v1/runtime.pb.h"

namespace fulcrum::server {

class Session;

using SteadyClock = std::chrono::steady_clock;

inline constexpr uint32_t kDefaultMaxCatchUpTicks = 5;
inline constexpr uint32_t kMaxMaxCatchUpTicks = 1000;

// The real-time state of one world; guarded by the world's lock (Session::mu_).
struct RealTimeClock {
  v1::RunMode mode = v1::RUN_MODE_PAUSED;
  uint32_t max_catch_up = kDefaultMaxCatchUpTicks;  // ticks per wake, at most
  SteadyClock::time_point start;                    // t0 of the schedule
  double dt = 0.0;                                  // s: the period of the schedule
  int64_t slots = 0;                                // ticks run + dropped since `start`

  // Counters of the current run (RealTimeInfo).
  int64_t start_tick = 0;
  int64_t ticks_run = 0;
  int64_t ticks_dropped = 0;
  int64_t late_wakes = 0;
  int64_t wakes = 0;
  uint32_t max_ticks_in_a_wake = 0;
  int64_t busy_retries = 0;
  std::string paused_reason;  // RealTimeInfo.paused_reason

  // Dropped ticks are logged at most once a second per world.
  SteadyClock::time_point last_log;
  int64_t dropped_unlogged = 0;

  // The schedule's period: dt within [1 ns, 1e9 s]. dt is only checked to be finite and > 0;
  // counted in the clock's nanoseconds, a shorter tick would overflow the slot count (it is
  // always due: the world runs at the catch-up cap) and a longer one the due time (it never
  // comes due, about 32 years ahead).
  double period() const;
  // When tick `slots + 1` of the schedule is due.
  SteadyClock::time_point next_due() const;
  // Ticks of the schedule due by `now` and not yet consumed (0 when early).
  int64_t due_at(SteadyClock::time_point now) const;
  // Starts a run at `now` from `tick` with period `dt` (counters reset).
  void begin(SteadyClock::time_point now, int64_t tick, double period);
  void to_proto(v1::RealTimeInfo* out) const;
};

class RealTimePool {
 public:
  // threads >= 1.
  explicit RealTimePool(int threads);
  ~RealTimePool();
  RealTimePool(const RealTimePool&) = delete;
  RealTimePool& operator=(const RealTimePool&) = delete;

  // Puts a world on the clock (no effect when it is already on it). UNAVAILABLE after
  // shutdown().
  Status start(std::shared_ptr<Session> session, SteadyClock::time_point first_due);
  // Takes a world off the clock; when a pool thread is stepping it, waits for that wake to end
  // (at most max_catch_up ticks), so no tick runs after stop() returns.
  void stop(const Session* session);
  // Stops every world and joins the threads. Idempotent.
  void shutdown();
  int threads() const { return static_cast<int>(threads_.size()); }

 private:
  struct Entry {
    std::shared_ptr<Session> session;
    bool busy = false;   // a pool thread is stepping it
    bool wanted = true;  // false: stop() was called while busy; do not requeue
  };

  void work();
  void erase_due_locked(const Session* session);

  std::mutex mu_;
  std::condition_variable wake_;             // the queue changed, or shutdown
  std::condition_variable idle_;             // a busy entry was released
  std::map<const Session*, Entry> entries_;  // worlds on the clock (looked up, not iterated)
  std::multimap<SteadyClock::time_point, const Session*> due_;  // by next due time
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace fulcrum::server
