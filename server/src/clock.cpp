#include "clock.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "session.h"
#include "stats.h"

namespace fulcrum::server {

// --- The schedule -----------------------------------------------------------------------------

double RealTimeClock::period() const {
  return std::clamp(dt, 1e-9, 1e9);
}

SteadyClock::time_point RealTimeClock::next_due() const {
  const std::chrono::duration<double> offset(static_cast<double>(slots + 1) * period());
  // Rounded up, so that a wake at the returned time finds the tick due.
  return start + std::chrono::ceil<SteadyClock::duration>(offset);
}

int64_t RealTimeClock::due_at(SteadyClock::time_point now) const {
  if (now <= start) return 0;
  const double elapsed = std::chrono::duration<double>(now - start).count();
  const auto slots_by_now = static_cast<int64_t>(std::floor(elapsed / period()));
  return slots_by_now > slots ? slots_by_now - slots : 0;
}

void RealTimeClock::begin(SteadyClock::time_point now, int64_t tick, double period) {
  const uint32_t cap = max_catch_up;
  *this = RealTimeClock();
  mode = v1::RUN_MODE_REAL_TIME;
  max_catch_up = cap;
  start = now;
  dt = period;
  start_tick = tick;
  last_log = now;
}

void RealTimeClock::to_proto(v1::RealTimeInfo* out) const {
  out->set_mode(mode);
  out->set_dt(dt);
  out->set_max_catch_up_ticks(max_catch_up);
  out->set_start_tick(start_tick);
  out->set_ticks_run(ticks_run);
  out->set_ticks_dropped(ticks_dropped);
  out->set_late_wakes(late_wakes);
  out->set_wakes(wakes);
  out->set_max_ticks_in_a_wake(max_ticks_in_a_wake);
  out->set_busy_retries(busy_retries);
  out->set_paused_reason(paused_reason);
}

// --- Session: run mode and one wake -----------------------------------------------------------

Status Session::set_run_mode(RealTimePool* pool, v1::RunMode mode,
                             std::optional<uint32_t> max_catch_up, v1::SetRunModeReply* reply) {
  if (mode != v1::RUN_MODE_PAUSED && mode != v1::RUN_MODE_REAL_TIME) {
    return invalid_argument("mode: PAUSED or REAL_TIME (got " + std::to_string(mode) + ")");
  }
  if (max_catch_up && (*max_catch_up < 1 || *max_catch_up > kMaxMaxCatchUpTicks)) {
    return invalid_argument("max_catch_up_ticks: must be in [1, " +
                            std::to_string(kMaxMaxCatchUpTicks) + "] (got " +
                            std::to_string(*max_catch_up) + ")");
  }
  if (pool == nullptr) return Status(StatusCode::kInternal, "no real-time pool");
  // Serializes run-mode changes, so that the mode and the pool's table always agree.
  std::lock_guard<std::mutex> order(run_mode_mu_);
  SteadyClock::time_point first_due;
  bool was_running = false;
  {
    Hold hold(this);
    if (retired_) return not_found("world_id: world " + std::to_string(id_) + " was deleted");
    was_running = clock_.mode == v1::RUN_MODE_REAL_TIME;
    if (mode == v1::RUN_MODE_REAL_TIME) {
      if (max_catch_up || !was_running) {
        clock_.max_catch_up = max_catch_up.value_or(kDefaultMaxCatchUpTicks);
      }
      if (!was_running) {
        clock_.begin(SteadyClock::now(), world_.tick(), world_.settings().dt);
        char hz[32];
        std::snprintf(hz, sizeof hz, "%g", 1.0 / clock_.dt);
        log_event("world_running", {{"world", id_},
                                    {"hz", std::string(hz)},
                                    {"tick", world_.tick()},
                                    {"max_catch_up", clock_.max_catch_up}});
      }
      first_due = clock_.next_due();
    } else if (was_running) {
      clock_.mode = v1::RUN_MODE_PAUSED;
      log_event("world_paused", {{"world", id_},
                                 {"tick", world_.tick()},
                                 {"ticks_run", clock_.ticks_run},
                                 {"ticks_dropped", clock_.ticks_dropped}});
    }
    reply->set_mode(clock_.mode);
    reply->set_tick(world_.tick());
    refresh_summary_locked(world_.state_hash());
  }
  if (mode == v1::RUN_MODE_REAL_TIME && !was_running) {
    Status started = pool->start(shared_from_this(), first_due);
    if (!started.ok()) {
      Hold hold(this);
      clock_.mode = v1::RUN_MODE_PAUSED;
      refresh_summary_locked(world_.state_hash());
      return started;
    }
  } else if (mode == v1::RUN_MODE_PAUSED && was_running) {
    pool->stop(this);  // waits for a wake in progress: the tick in the reply is final
  }
  return {};
}

void Session::retire() {
  Hold hold(this);
  retired_ = true;
  clock_.mode = v1::RUN_MODE_PAUSED;  // a wake already under way stops at its next look
}

std::optional<SteadyClock::time_point> Session::run_due_ticks(SteadyClock::time_point now) {
  std::unique_lock<std::mutex> lock(mu_, std::try_to_lock);
  if (!lock.owns_lock()) {
    // An RPC holds the world between two ticks. The ticks stay due; look again shortly. The
    // counter is not guarded here, so it is bumped at the next wake that holds the world.
    ++busy_retries_pending_;
    return now + std::chrono::microseconds(500);
  }
  if (clock_.mode != v1::RUN_MODE_REAL_TIME) return std::nullopt;
  clock_.busy_retries += busy_retries_pending_.exchange(0);
  if (world_.settings().dt != clock_.dt) {
    // An edit changed dt: the schedule goes on from the last tick's slot at the new period.
    const std::chrono::duration<double> consumed(static_cast<double>(clock_.slots) *
                                                 clock_.period());
    clock_.start += std::chrono::duration_cast<SteadyClock::duration>(consumed);
    clock_.slots = 0;
    clock_.dt = world_.settings().dt;
  }
  const int64_t due = clock_.due_at(now);
  if (due > 0) {
    const int64_t run = std::min<int64_t>(due, clock_.max_catch_up);
    const auto stepping = SteadyClock::now();
    int64_t ran = 0;
    Status refused;
    while (ran < run && (refused = tick_locked()).ok()) ++ran;
    counters().add_steps(static_cast<uint32_t>(ran), SteadyClock::now() - stepping);
    if (!refused.ok()) {
      // A tick that cannot run will not run at the next wake either: the world pauses, and
      // the reason stays in RealTimeInfo for whoever looks.
      clock_.mode = v1::RUN_MODE_PAUSED;
      clock_.paused_reason = refused.message();
      clock_.ticks_run += ran;
      log_event("world_paused",
                {{"world", id_}, {"tick", world_.tick()}, {"reason", refused.message()}});
      refresh_summary_locked(world_.state_hash());
      lock.unlock();
      deliver_first_frames();
      return std::nullopt;
    }
    clock_.slots += due;  // the ticks beyond the cap are dropped from the schedule
    clock_.ticks_run += run;
    ++clock_.wakes;
    clock_.max_ticks_in_a_wake = std::max(clock_.max_ticks_in_a_wake, static_cast<uint32_t>(run));
    if (due > run) {
      clock_.ticks_dropped += due - run;
      clock_.dropped_unlogged += due - run;
      ++clock_.late_wakes;
    }
    if (clock_.dropped_unlogged > 0 && now - clock_.last_log >= std::chrono::seconds(1)) {
      log_event("world_behind", {{"world", id_},
                                 {"tick", world_.tick()},
                                 {"dropped_last_second", clock_.dropped_unlogged},
                                 {"dropped_this_run", clock_.ticks_dropped}});
      clock_.dropped_unlogged = 0;
      clock_.last_log = now;
    }
    refresh_summary_locked(world_.state_hash());
  }
  const SteadyClock::time_point next = clock_.next_due();
  lock.unlock();
  deliver_first_frames();
  return next;
}

void Session::runtime_to_proto_locked(v1::WorldInfo* out) const {
  clock_.to_proto(out->mutable_run());
  v1::RecordingInfo* r = out->mutable_recording();
  r->Clear();
  if (recorder_) {
    const ReplayFileRef file = recorder_->file();
    r->set_active(true);
    r->set_name(file.name);
    r->set_start_tick(recorder_->start_tick());
    r->set_ticks(recorder_->ticks());
    r->set_bytes(file.bytes);
  } else if (!last_replay_.name.empty()) {
    r->set_name(last_replay_.name);
    r->set_start_tick(last_replay_start_tick_);
    r->set_ticks(last_replay_ticks_);
    r->set_bytes(last_replay_.bytes);
  }
  r->set_error(recording_error_);
}

// --- The pool ---------------------------------------------------------------------------------

RealTimePool::RealTimePool(int threads) {
  threads_.reserve(static_cast<size_t>(std::max(threads, 1)));
  for (int i = 0; i < std::max(threads, 1); ++i) threads_.emplace_back([this] { work(); });
}

RealTimePool::~RealTimePool() {
  shutdown();
}

Status RealTimePool::start(std::shared_ptr<Session> session, SteadyClock::time_point first_due) {
  std::lock_guard<std::mutex> lock(mu_);
  if (stopping_) return Status(StatusCode::kUnavailable, "the server is stopping");
  const Session* key = session.get();
  auto it = entries_.find(key);
  if (it != entries_.end()) {
    it->second.wanted = true;  // a stop() in flight lost the race; keep it on the clock
    return {};
  }
  entries_.emplace(key, Entry{std::move(session)});
  due_.emplace(first_due, key);
  wake_.notify_all();
  return {};
}

void RealTimePool::erase_due_locked(const Session* session) {
  for (auto it = due_.begin(); it != due_.end(); ++it) {
    if (it->second == session) {
      due_.erase(it);
      return;
    }
  }
}

void RealTimePool::stop(const Session* session) {
  std::unique_lock<std::mutex> lock(mu_);
  auto it = entries_.find(session);
  if (it == entries_.end()) return;
  if (!it->second.busy) {
    erase_due_locked(session);
    entries_.erase(it);
    return;
  }
  it->second.wanted = false;
  idle_.wait(lock, [&] { return entries_.count(session) == 0; });
}

void RealTimePool::shutdown() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_ && threads_.empty()) return;
    stopping_ = true;
    wake_.notify_all();
  }
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  std::lock_guard<std::mutex> lock(mu_);
  threads_.clear();
  due_.clear();
  entries_.clear();
  idle_.notify_all();
}

void RealTimePool::work() {
  std::unique_lock<std::mutex> lock(mu_);
  while (!stopping_) {
    if (due_.empty()) {
      wake_.wait(lock);
      continue;
    }
    const auto first = due_.begin();
    const SteadyClock::time_point now = SteadyClock::now();
    if (first->first > now) {
      // A copy: wait_until reads its deadline again after the wait, by which time another pool
      // thread may have taken this entry out of due_ (and freed its node).
      const SteadyClock::time_point deadline = first->first;
      wake_.wait_until(lock, deadline);
      continue;
    }
    const Session* key = first->second;
    due_.erase(first);
    Entry& entry = entries_.at(key);
    entry.busy = true;
    std::shared_ptr<Session> session = entry.session;
    lock.unlock();
    const std::optional<SteadyClock::time_point> next = session->run_due_ticks(now);
    lock.lock();
    auto it = entries_.find(key);
    if (it == entries_.end()) continue;  // shutdown() cleared the table
    it->second.busy = false;
    if (!next || !it->second.wanted || stopping_) {
      entries_.erase(it);
      idle_.notify_all();
    } else {
      due_.emplace(*next, key);
      wake_.notify_one();
    }
  }
}

}  // namespace fulcrum::server
