// Islands and sleep. Each step the awake bodies are joined into islands by union-find over
// touching contacts (static and kinematic bodies do not join islands). An island whose every
// body has rested for settings.time_to_sleep goes to sleep as a whole; it then costs nothing
// until an awake body touches it or an edit wakes it.
#include <algorithm>

#include "union_find.h"
#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

void WorldImpl::update_sleep(const std::vector<int>& awake) {
  if (awake.empty()) return;
  const int n = static_cast<int>(awake.size());
  // The rest timers, each body its own, in chunks of bodies (on the world's threads when there
  // are many): with sleep on, every awake body's record is read and written once a tick.
  constexpr int kBodiesPerChunk = 1024;
  const int chunks = (n + kBodiesPerChunk - 1) / kBodiesPerChunk;
  WorkerPool* const timers = chunks > 1 ? pool : nullptr;
  if (!settings.enable_sleep) {
    // Once cleared they stay zero: only a tick with sleep on, or a restore, sets a timer, and
    // a body that wakes starts from zero (set_awake_flag).
    if (awake_timers_zero) return;
    awake_timers_zero = true;
    auto clear = [&](int c) {
      for (int k = c * kBodiesPerChunk; k < std::min(n, (c + 1) * kBodiesPerChunk); ++k) {
        bodies[awake[k]].sleep_time = 0.0;
      }
    };
    run_chunks(timers, chunks, clear, true);
    return;
  }
  awake_timers_zero = false;
  const double h = settings.dt;
  const double lin_tol2 = settings.linear_sleep_tolerance * settings.linear_sleep_tolerance;
  const double ang_tol2 = settings.angular_sleep_tolerance * settings.angular_sleep_tolerance;
  std::vector<int>& slot = solver_scratch.body_slot;  // body -> 1 + position in `awake`

  // Rest timers; whether any body has rested long enough is an or over the chunks.
  std::vector<double>& island_min = scratch_rest;
  island_min.resize(n);
  std::vector<uint8_t>& dynamic = budget.dynamic;  // whether each awake body is dynamic
  dynamic.resize(n);
  std::vector<uint8_t>& chunk_rested = scratch_chunk_rested;
  chunk_rested.assign(chunks, 0);
  auto tick_timers = [&](int c) {
    bool rested = false;
    for (int k = c * kBodiesPerChunk; k < std::min(n, (c + 1) * kBodiesPerChunk); ++k) {
      Body& b = bodies[awake[k]];
      dynamic[k] = b.is_dynamic();
      const bool resting =
          b.enable_sleep && length_squared(b.v) <= lin_tol2 && b.w * b.w <= ang_tol2;
      b.sleep_time = resting ? b.sleep_time + h : 0.0;
      island_min[k] = b.sleep_time;
      rested = rested || b.sleep_time >= settings.time_to_sleep;
    }
    chunk_rested[c] = rested;
  };
  run_chunks(timers, chunks, tick_timers, true);
  bool any_rested = false;
  for (uint8_t r : chunk_rested) any_rested = any_rested || r != 0;
  // An island sleeps only when every body in it has rested long enough: if none has, no
  // island can, and building them is wasted (a world in motion pays only the timers).
  if (!any_rested) return;

  // Union over touching solid contacts between awake dynamic bodies. collide listed every
  // touching solid contact with an awake body (touching_contacts, in id order), and nothing
  // since has made or touched one; no other contact can join two awake bodies or hold an awake
  // body against a kinematic one. (The whole pool was read before: in a world of sleeping piles
  // it is mostly contacts this loop skips.) Each root is the least index of its island, so the
  // islands are the same in any order. A body touching a moving kinematic body may not sleep.
  std::vector<int>& parent = scratch_parent;
  parent.resize(n);
  for (int k = 0; k < n; ++k) parent[k] = k;
  // A body's position in `awake` if it is there and dynamic; -1 otherwise.
  if (slot.size() < bodies.size()) slot.resize(bodies.size(), 0);
  auto awake_dynamic = [&](int body) {
    const int k = slot[body] - 1;
    return k >= 0 && k < n && awake[k] == body && dynamic[k] ? k : -1;
  };
  auto moving_kinematic = [&](int body) {
    return bodies[body].type == BodyType::kKinematic && bodies[body].sleep_time == 0.0;
  };
  for (const ContactBodies& c : touching_bodies) {
    const int ka = awake_dynamic(c.a);
    const int kb = awake_dynamic(c.b);
    if (ka >= 0 && kb >= 0) {
      unite(parent, ka, kb);
    } else if (ka >= 0 && moving_kinematic(c.b)) {
      island_min[ka] = 0.0;
    } else if (kb >= 0 && moving_kinematic(c.a)) {
      island_min[kb] = 0.0;
    }
  }

  // Joints join islands too.
  for (int k = 0; k < n; ++k) {
    int bi = awake[k];
    if (!bodies[bi].is_dynamic()) continue;
    for (int ji : bodies[bi].joints) {
      const Joint& j = joints[ji];
      int other = j.body_a == bi ? j.body_b : j.body_a;
      const Body& o = bodies[other];
      if (o.type == BodyType::kKinematic && o.sleep_time == 0.0) island_min[k] = 0.0;
      if (!o.is_dynamic() || !o.awake || other < bi) continue;
      unite(parent, k, slot[other] - 1);
    }
  }

  // An island sleeps when its least rested body has rested long enough.
  std::vector<double>& root_min = scratch_root_rest;
  root_min.assign(n, 1e300);
  for (int k = 0; k < n; ++k) {
    int r = find_root(parent, k);
    root_min[r] = std::min(root_min[r], island_min[k]);
  }
  for (int k = 0; k < n; ++k) {
    if (root_min[find_root(parent, k)] >= settings.time_to_sleep) {
      set_awake_flag(awake[k], false);
    }
  }
}

}  // namespace fulcrum
