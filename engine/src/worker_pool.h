// The threads one world's step may use. A stage is a count of chunks, each a pure function of
// its index; thread t of T (the caller is thread 0) owns the t-th of T equal runs of chunks and
// takes them from the front, and a thread done with its own run takes chunks from the back of
// the others' (a core slowed by another process, or a run of costlier chunks, does not hold
// the stage up). run() returns when every chunk has run; it waits only for the workers that
// came into the stage, never for one that was asleep or descheduled while the others did the
// work. What a chunk computes never depends on the thread that runs it (chunk boundaries come
// from the data, never from the thread count), and chunks of one stage write disjoint memory,
// so any number of threads gives the same bits as one.
//
// Workers spin between the stages of a step (a step has a few hundred) and sleep between
// steps: begin_busy() / end_busy() bracket a step.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

namespace fulcrum {

class WorkerPool {
 public:
  // `threads` >= 1 counts the caller: threads - 1 workers are started.
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  // Workers spin between stages from begin_busy() to the matching end_busy(); spans nest (a
  // stage's own span inside a step's keeps them spinning until the step's ends).
  void begin_busy();
  void end_busy();
  bool busy() const { return busy_.load(std::memory_order_relaxed); }

  // Runs fn(ctx, i) for every i in [0, chunks) and returns when all are done.
  using ChunkFn = void (*)(void* ctx, int chunk);
  void run(int chunks, ChunkFn fn, void* ctx);

  template <class F>
  void run(int chunks, F& f) {
    run(
        chunks, [](void* c, int i) { (*static_cast<F*>(c))(i); }, &f);
  }

 private:
  // The chunks of a thread's run not yet taken: [front, back), both in one word so that the
  // owner (from the front) and the others (from the back) take each chunk exactly once.
  struct alignas(64) Run {
    std::atomic<uint64_t> span{0};
  };
  static uint64_t span_of(uint32_t front, uint32_t back) {
    return static_cast<uint64_t>(back) << 32 | front;
  }
  static bool take(Run& run, bool from_front, int* chunk);

  void worker_loop(int index);
  void work_on(int thread);

  std::vector<std::thread> workers_;
  std::unique_ptr<Run[]> runs_;  // one per thread
  // Stage number * 2, + 1 while the stage is open to workers; workers wait on it.
  std::atomic<uint32_t> stage_{0};
  std::atomic<int> active_{0};  // workers inside a stage (in work_on)
  std::atomic<ChunkFn> fn_{nullptr};
  std::atomic<void*> ctx_{nullptr};
  std::atomic<bool> busy_{false};
  int busy_depth_ = 0;  // begin_busy() calls not yet ended (the caller's thread alone)
  std::atomic<bool> stop_{false};
};

// A busy span (begin_busy() / end_busy()) for this object's lifetime; nothing for a null pool.
class BusySpan {
 public:
  explicit BusySpan(WorkerPool* pool) : pool_(pool) {
    if (pool_ != nullptr) pool_->begin_busy();
  }
  ~BusySpan() {
    if (pool_ != nullptr) pool_->end_busy();
  }
  BusySpan(const BusySpan&) = delete;
  BusySpan& operator=(const BusySpan&) = delete;

 private:
  WorkerPool* pool_;
};

// Runs f(i) for every i in [0, chunks): shared among the pool's threads when there is a pool,
// else in order on this thread. `own_stage` brackets it with a busy span of its own, for a
// stage outside a tick (a tick keeps its pool busy from start to end: World::try_step).
template <class F>
void run_chunks(WorkerPool* pool, int chunks, F& f, bool own_stage = false) {
  if (pool == nullptr) {
    for (int i = 0; i < chunks; ++i) f(i);
    return;
  }
  const BusySpan span(own_stage ? pool : nullptr);
  pool->run(chunks, f);
}

}  // namespace fulcrum
