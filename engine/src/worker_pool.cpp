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

WorkerPool::WorkerPool(int threads) : runs_(std::make_unique<Run[]>(threads)) {
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this, i] { worker_loop(i); });
}

WorkerPool::~WorkerPool() {
  stop_.store(true, std::memory_order_release);
  stage_.fetch_add(2, std::memory_order_release);
  stage_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::begin_busy() {
  if (busy_depth_++ == 0) busy_.store(true, std::memory_order_relaxed);
}

void WorkerPool::end_busy() {
  if (--busy_depth_ == 0) busy_.store(false, std::memory_order_relaxed);
}

void WorkerPool::run(int chunks, ChunkFn fn, void* ctx) {
  if (chunks <= 0) return;
  if (workers_.empty() || chunks == 1) {
    for (int i = 0; i < chunks; ++i) fn(ctx, i);
    return;
  }
  // The previous stage is closed and no worker is inside it (below), so none reads these fields.
  fn_.store(fn, std::memory_order_relaxed);
  ctx_.store(ctx, std::memory_order_relaxed);
  const int64_t n = threads();
  for (int64_t t = 0; t < n; ++t) {
    runs_[t].span.store(
        span_of(static_cast<uint32_t>(chunks * t / n), static_cast<uint32_t>(chunks * (t + 1) / n)),
        std::memory_order_relaxed);
  }
  const uint32_t open = (stage_.load(std::memory_order_relaxed) | 1u) + 2u;
  stage_.store(open, std::memory_order_release);
  stage_.notify_all();
  work_on(0);
  // Every chunk has been taken. Closing the stage and then waiting for the workers inside it
  // waits for the chunks they took, and for nobody else: a worker that has not come in yet (asleep,
  // or its core taken by another process) finds the stage closed and stays out, so it never holds
  // the step up. The two sequentially consistent pairs (close, then read `active_`; enter, then
  // read `stage_`) let no worker in unseen.
  stage_.store(open & ~1u, std::memory_order_seq_cst);
  for (int spins = 0; active_.load(std::memory_order_seq_cst) != 0; ++spins) cpu_relax(spins);
}

bool WorkerPool::take(Run& run, bool from_front, int* chunk) {
  uint64_t span = run.span.load(std::memory_order_relaxed);
  for (;;) {
    const uint32_t front = static_cast<uint32_t>(span), back = static_cast<uint32_t>(span >> 32);
    if (front >= back) return false;
    const uint64_t rest = from_front ? span_of(front + 1, back) : span_of(front, back - 1);
    if (run.span.compare_exchange_weak(span, rest, std::memory_order_relaxed)) {
      *chunk = static_cast<int>(from_front ? front : back - 1);
      return true;
    }
  }
}

void WorkerPool::work_on(int thread) {
  // Thread t owns the t-th of `threads` equal runs of chunks, the same run in every stage of a
  // step, so that it keeps touching the same part of the world (and its cache lines stay with
  // one core); it takes them in order, and then helps the others from the ends of their runs.
  // Which thread runs a chunk never changes what the chunk computes.
  const ChunkFn fn = fn_.load(std::memory_order_relaxed);
  void* const ctx = ctx_.load(std::memory_order_relaxed);
  const int n = threads();
  int chunk = 0;
  while (take(runs_[thread], true, &chunk)) fn(ctx, chunk);
  for (int k = 1; k < n; ++k) {
    Run& other = runs_[(thread + k) % n];
    while (take(other, false, &chunk)) fn(ctx, chunk);
  }
}

void WorkerPool::worker_loop(int index) {
  uint32_t seen = 0;  // the last stage this worker went into
  for (;;) {
    uint32_t stage = stage_.load(std::memory_order_acquire);
    int spins = 0;
    // Wait for an open stage (odd) that this worker has not been into.
    while (stage == seen || (stage & 1u) == 0) {
      if (stop_.load(std::memory_order_acquire)) return;
      if (busy_.load(std::memory_order_relaxed) && spins < kSpinLimit) {
        cpu_relax(spins);
        ++spins;
      } else {
        stage_.wait(stage, std::memory_order_acquire);
        spins = 0;
      }
      stage = stage_.load(std::memory_order_acquire);
    }
    seen = stage;
    active_.fetch_add(1, std::memory_order_seq_cst);
    if (stage_.load(std::memory_order_seq_cst) == stage) work_on(index);
    active_.fetch_sub(1, std::memory_order_release);
  }
}

}  // namespace fulcrum
