#include "worker_pool.h"

namespace fulcrum {

namespace {

// Spins between stages this many times before sleeping (a step's stages follow each other
// within microseconds; between steps the workers sleep at once, see worker_loop).
constexpr int kSpinLimit = 1 << 16;

// A short pause for the first spins, then giving the core away: with more threads than free
// cores, the thread being waited for may need this one's core.
inline void cpu_relax(int spins) {
  if (spins < 256) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    asm volatile("yield");
#endif
  } else {
    std::this_thread::yield();
  }
}

}  // namespace

WorkerPool::WorkerPool(int threads) {
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this, i] { worker_loop(i); });
}

WorkerPool::~WorkerPool() {
  stop_.store(true, std::memory_order_relaxed);
  stage_.fetch_add(1, std::memory_order_release);
  stage_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::begin_busy() {
  busy_.store(true, std::memory_order_relaxed);
}

void WorkerPool::end_busy() {
  busy_.store(false, std::memory_order_relaxed);
}

void WorkerPool::run(int chunks, ChunkFn fn, void* ctx) {
  if (chunks <= 0) return;
  if (workers_.empty() || chunks == 1) {
    for (int i = 0; i < chunks; ++i) fn(ctx, i);
    return;
  }
  // Every worker has checked in for the previous stage, so none still reads these fields.
  const uint32_t stage = stage_.load(std::memory_order_relaxed) + 1;
  fn_.store(fn, std::memory_order_relaxed);
  ctx_.store(ctx, std::memory_order_relaxed);
  chunks_.store(chunks, std::memory_order_relaxed);
  done_.store(0, std::memory_order_relaxed);
  stage_.store(stage, std::memory_order_release);
  stage_.notify_all();
  work_on(0);
  const int workers = static_cast<int>(workers_.size());
  for (int spins = 0; done_.load(std::memory_order_acquire) < workers; ++spins) cpu_relax(spins);
}

void WorkerPool::work_on(int thread) {
  // Thread t takes the t-th of `threads` equal runs of chunks, the same run in every stage of a
  // step, so that it keeps touching the same part of the world (and its cache lines stay with
  // one core). Which thread runs a chunk never changes what the chunk computes.
  const ChunkFn fn = fn_.load(std::memory_order_relaxed);
  void* const ctx = ctx_.load(std::memory_order_relaxed);
  const int64_t chunks = chunks_.load(std::memory_order_relaxed);
  const int64_t n = threads();
  const int first = static_cast<int>(chunks * thread / n);
  const int end = static_cast<int>(chunks * (thread + 1) / n);
  for (int i = first; i < end; ++i) fn(ctx, i);
}

void WorkerPool::worker_loop(int index) {
  uint32_t seen = 0;
  for (;;) {
    uint32_t stage = stage_.load(std::memory_order_acquire);
    int spins = 0;
    while (stage == seen) {
      if (busy_.load(std::memory_order_relaxed) && spins < kSpinLimit) {
        cpu_relax(spins);
        ++spins;
      } else {
        stage_.wait(seen, std::memory_order_acquire);
        spins = 0;
      }
      stage = stage_.load(std::memory_order_acquire);
    }
    if (stop_.load(std::memory_order_relaxed)) return;
    seen = stage;
    work_on(index);
    done_.fetch_add(1, std::memory_order_release);
  }
}

}  // namespace fulcrum
