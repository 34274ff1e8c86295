// The world's thread pool (engine/src/worker_pool.h): every chunk of a stage runs exactly once,
// whatever the thread and chunk counts, stage after stage, busy or asleep between stages, and a
// thread with nothing left of its own run helps with the others'.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "union_find.h"
#include "worker_pool.h"

namespace fulcrum {
namespace {

TEST(WorkerPool, EveryChunkRunsOnceInEveryStage) {
  for (int threads : {1, 2, 3, 4, 7}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    pool.begin_busy();
    for (int chunks : {0, 1, 2, 3, 5, 64, 1000}) {
      for (int stage = 0; stage < 20; ++stage) {
        std::vector<std::atomic<int>> runs(chunks);
        auto f = [&](int i) { runs[i].fetch_add(1, std::memory_order_relaxed); };
        pool.run(chunks, f);
        for (int i = 0; i < chunks; ++i) {
          ASSERT_EQ(runs[i].load(), 1)
              << threads << " threads, " << chunks << " chunks, chunk " << i;
        }
      }
    }
    pool.end_busy();
  }
}

// A thread done with its own run takes chunks from the back of the others': here the worker's
// first chunk (2 of 4; the caller owns 0 and 1) cannot finish until its last chunk (3) has run,
// which only the caller, taking from the back, can do. Without that the stage would wait for
// the 10 s limit and the check below would fail.
TEST(WorkerPool, ThreadsTakeChunksFromTheOthersRuns) {
  WorkerPool pool(2);
  std::atomic<bool> last_ran{false};
  std::atomic<bool> gave_up{false};
  auto f = [&](int i) {
    if (i == 3) last_ran.store(true);
    if (i != 2) return;
    const auto limit = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!last_ran.load()) {
      if (std::chrono::steady_clock::now() > limit) {
        gave_up.store(true);
        return;
      }
      std::this_thread::yield();
    }
  };
  run_chunks(&pool, 4, f, true);
  EXPECT_TRUE(last_ran.load());
  EXPECT_FALSE(gave_up.load());
}

// Between steps the workers sleep; a stage after a pause still runs every chunk, and a pool
// destroyed while its workers sleep joins them.
TEST(WorkerPool, StagesAfterSleepAndDestructionWhileAsleep) {
  WorkerPool pool(3);
  std::atomic<int> sum{0};
  auto f = [&](int i) { sum.fetch_add(i + 1); };
  pool.run(10, f);  // not busy: workers wake for it
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  pool.run(10, f);
  EXPECT_EQ(sum.load(), 2 * 55);
}

// Busy spans nest: a stage's own span (run_chunks with own_stage) inside a step's leaves the
// workers spinning until the step's span ends, and they sleep after it.
TEST(WorkerPool, NestedBusySpansEndWithTheOutermost) {
  WorkerPool pool(2);
  EXPECT_FALSE(pool.busy());
  pool.begin_busy();
  std::atomic<int> sum{0};
  auto f = [&](int i) { sum.fetch_add(i + 1); };
  run_chunks(&pool, 10, f, true);
  EXPECT_TRUE(pool.busy());
  pool.run(10, f);
  pool.end_busy();
  EXPECT_FALSE(pool.busy());
  EXPECT_EQ(sum.load(), 2 * 55);
}

// Sets joined by several threads at once (unite_shared, as the joint budgets join their
// components) are the sets one thread's unite makes, with the same roots (each set's least
// index), whatever the order the threads happen to take the pairs in.
TEST(WorkerPool, SharedUnionsGiveOneThreadsSetsAndRoots) {
  constexpr int kItems = 5000;
  uint64_t seed = 12345;
  auto next = [&seed] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<int>((seed >> 33) % kItems);
  };
  for (int round = 0; round < 20; ++round) {
    // Chains (long paths to halve) and random pairs (sets merging from everywhere).
    std::vector<std::pair<int, int>> pairs;
    for (int i = 0; i + 1 < kItems; i += 2) pairs.emplace_back(i + 1, i);
    for (int i = 0; i < kItems / 2; ++i) pairs.emplace_back(next(), next());
    std::vector<int> serial(kItems), shared(kItems);
    for (int i = 0; i < kItems; ++i) serial[i] = shared[i] = i;
    for (const auto& [a, b] : pairs) unite(serial, a, b);
    WorkerPool pool(4);
    constexpr int kPerChunk = 64;
    const int chunks = static_cast<int>((pairs.size() + kPerChunk - 1) / kPerChunk);
    auto f = [&](int c) {
      for (size_t i = c * kPerChunk; i < std::min(pairs.size(), size_t(c + 1) * kPerChunk); ++i) {
        unite_shared(shared, pairs[i].first, pairs[i].second);
      }
    };
    run_chunks(&pool, chunks, f, true);
    int sets = 0;
    for (int i = 0; i < kItems; ++i) {
      ASSERT_EQ(find_root(shared, i), find_root(serial, i)) << "item " << i << ", round " << round;
      sets += find_root(serial, i) == i;
    }
    EXPECT_GT(sets, 1);
    EXPECT_LT(sets, kItems / 2);
  }
}

// The chunk a thread runs never changes what it computes: the results of a stage are the same
// at any thread count (here, chunks writing their own slots).
TEST(WorkerPool, ResultsDoNotDependOnTheThreadCount) {
  std::vector<double> reference;
  for (int threads = 1; threads <= 4; ++threads) {
    WorkerPool pool(threads);
    std::vector<double> out(97);
    auto f = [&](int i) {
      double x = 1.0;
      for (int k = 0; k < 100; ++k) x = x * 1.0001 + i;
      out[i] = x;
    };
    run_chunks(&pool, 97, f, true);
    if (threads == 1) {
      reference = out;
    } else {
      EXPECT_EQ(out, reference) << threads << " threads";
    }
  }
  std::vector<double> serial(97);
  auto g = [&](int i) { serial[i] = reference[i]; };
  run_chunks(nullptr, 97, g);
  EXPECT_EQ(serial, reference);
}

}  // namespace
}  // namespace fulcrum
