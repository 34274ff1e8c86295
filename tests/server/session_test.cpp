// The engine side of the server (Registry, Session, RealTimePool, frames) driven from many
// threads at once, without gRPC: real-time worlds stepped by the pool while other threads edit,
// read, snapshot, pause and resume them, watchers come and go and encode the frames they are
// offered, and worlds are deleted while they run. tools/sanitize.sh runs it under
// ThreadSanitizer, which sees all of this code's synchronization (it cannot see Debian's gRPC's,
// so the tests through gRPC run under ASan and UBSan only; docs/robustness.md).
#include <sys/resource.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "frames.h"
#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "session.h"

namespace fulcrum::server {
namespace {

using namespace std::chrono_literals;

World pyramid_world() {
  Result<SceneDef> scene = scenes::builtin("mixed");
  EXPECT_TRUE(scene.ok());
  Result<World> world = build_world(*scene);
  EXPECT_TRUE(world.ok()) << world.status().message();
  return std::move(world).value();
}

// A stream reader, as StreamFrames' reactor is one: offer() keeps the newest frame, and a
// thread of its own (gRPC's, in the server) takes it and encodes it against the previous one.
class Reader final : public FrameSink {
 public:
  uint32_t every_ticks() const override { return 1; }
  void offer(std::shared_ptr<const PublishedFrame> frame) override {
    std::lock_guard<std::mutex> lock(mu_);
    pending_ = std::move(frame);
  }
  void close(const Status& status, bool shutting_down) override {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
  }
  // Encodes the pending frame, if any; false once closed.
  bool take(v1::FrameBodies mode) {
    std::shared_ptr<const PublishedFrame> next;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (closed_) return false;
      next = std::move(pending_);
    }
    if (next == nullptr) return true;
    if (previous_ != nullptr && next->epoch == previous_->epoch && next->tick < previous_->tick) {
      ++backwards_;
    }
    if (encode_shared(*next, previous_.get(), mode, mode == v1::FRAME_BODIES_ALL)->empty()) {
      ++empty_;
    }
    previous_ = std::move(next);
    ++frames_;
    return true;
  }

  int frames_ = 0;  // the fields below: the reading thread's own
  int backwards_ = 0;
  int empty_ = 0;

 private:
  std::mutex mu_;
  std::shared_ptr<const PublishedFrame> pending_;
  bool closed_ = false;
  std::shared_ptr<const PublishedFrame> previous_;
};

v1::EditBatch push(int index) {
  v1::EditBatch batch;
  v1::SetVelocity* v = batch.add_edits()->mutable_set_velocity();
  v->mutable_body()->set_index(index);
  v->mutable_body()->set_generation(1);
  v->mutable_linear()->set_y(3.0);
  return batch;
}

// Two real-time worlds (one stepping on 2 threads of its own) on a pool of 4 threads; for about
// half a second, threads edit, step (refused while real time), read, snapshot, pause and resume
// them, and readers subscribe, encode and unsubscribe. Then one world is deleted while it runs.
TEST(SessionThreads, RealTimeWorldsUnderConcurrentCallsAndReaders) {
  Limits limits;
  limits.world_threads = 2;
  Registry registry(limits);
  RealTimePool pool(4);
  registry.attach(&pool, nullptr);
  std::vector<std::shared_ptr<Session>> worlds;
  for (int i = 0; i < 2; ++i) {
    Result<std::shared_ptr<Session>> s = registry.create("mixed", pyramid_world());
    ASSERT_TRUE(s.ok()) << s.status().message();
    worlds.push_back(*s);
    v1::SetRunModeReply reply;
    ASSERT_TRUE((*s)->set_run_mode(&pool, v1::RUN_MODE_REAL_TIME, std::nullopt, &reply).ok());
  }

  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  for (const std::shared_ptr<Session>& s : worlds) {
    threads.emplace_back([&stop, s] {  // an editor, and Step calls refused while running
      const Session::KeepGoing go_on = [] { return Status(); };
      for (int i = 0; !stop; ++i) {
        v1::ApplyEditsReply edits;
        EXPECT_TRUE(s->apply_edits(push(i % 4), std::nullopt, go_on, &edits).ok());
        v1::StepReply step;
        s->step(1, std::nullopt, false, go_on, &step).ok();
        std::this_thread::sleep_for(2ms);
      }
    });
    threads.emplace_back([&stop, s] {  // readers of the world's state
      while (!stop) {
        v1::WorldInfo info;
        s->info(&info);
        v1::WorldInfo summary;
        s->summary(&summary);
        v1::GetSnapshotReply snapshot;
        s->snapshot(&snapshot);
        std::this_thread::sleep_for(5ms);
      }
    });
    threads.emplace_back([&stop, &pool, s] {  // pause and resume (NOT_FOUND once deleted)
      auto ok_or_deleted = [](const Status& status) {
        return status.ok() || status.code() == StatusCode::kNotFound;
      };
      while (!stop) {
        std::this_thread::sleep_for(40ms);
        v1::SetRunModeReply reply;
        EXPECT_TRUE(
            ok_or_deleted(s->set_run_mode(&pool, v1::RUN_MODE_PAUSED, std::nullopt, &reply)));
        std::this_thread::sleep_for(10ms);
        EXPECT_TRUE(ok_or_deleted(s->set_run_mode(&pool, v1::RUN_MODE_REAL_TIME, 3u, &reply)));
      }
    });
  }
  std::atomic<int> frames{0};
  std::atomic<int> backwards{0};
  for (int r = 0; r < 4; ++r) {
    threads.emplace_back([&, r] {  // readers that come and go
      const v1::FrameBodies mode = r % 2 == 0 ? v1::FRAME_BODIES_CHANGED : v1::FRAME_BODIES_ALL;
      while (!stop) {
        const std::shared_ptr<Session>& s = worlds[r % worlds.size()];
        auto reader = std::make_shared<Reader>();
        s->subscribe(reader);
        for (int k = 0; k < 20 && !stop && reader->take(mode); ++k) {
          std::this_thread::sleep_for(3ms);
        }
        s->unsubscribe(reader.get());
        frames += reader->frames_;
        backwards += reader->backwards_;
        EXPECT_EQ(reader->empty_, 0);
      }
    });
  }

  std::this_thread::sleep_for(500ms);
  // Deleted while it runs: off the clock, its readers closed, as DeleteWorld does.
  ASSERT_TRUE(registry.remove(worlds[1]->id()).ok());
  std::this_thread::sleep_for(100ms);
  stop = true;
  for (std::thread& t : threads) t.join();
  pool.shutdown();

  v1::WorldInfo info;
  worlds[0]->info(&info);
  std::printf("world 1 at tick %lld; readers took %d frames\n", static_cast<long long>(info.tick()),
              frames.load());
  EXPECT_GT(info.tick(), 0);
  EXPECT_GT(frames.load(), 0);
  EXPECT_EQ(backwards.load(), 0);
}

// CPU time of this process, s.
double cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

// What a stream was told when it was closed.
class Probe final : public FrameSink {
 public:
  uint32_t every_ticks() const override { return 1; }
  void offer(std::shared_ptr<const PublishedFrame>) override { ++frames; }
  void close(const Status& status, bool stopping) override {
    ++closes;
    message = status.message();
    shutting_down = stopping;
  }
  int frames = 0;
  int closes = 0;
  std::string message;
  bool shutting_down = false;
};

// A reader whose handler subscribes after the world's streams were closed (the server began
// stopping, or the world was deleted, while the call was on its way) is closed at once, as the
// readers before it were, instead of staying open until the shutdown's grace period runs out:
// ServerTest.ShutdownEndsStreams once waited its whole 2 s that way.
TEST(SessionStreams, ReadersArrivingAfterTheStreamsClosedAreClosedAtOnce) {
  Registry registry{Limits{}};
  Result<std::shared_ptr<Session>> s = registry.create("mixed", pyramid_world());
  ASSERT_TRUE(s.ok()) << s.status().message();
  auto before = std::make_shared<Probe>();
  (*s)->subscribe(before);
  EXPECT_EQ(before->frames, 1);  // the first frame, at once: the world is idle
  EXPECT_EQ(before->closes, 0);

  registry.close_all_streams(Status(StatusCode::kInternal, "the server is stopping"));
  EXPECT_EQ(before->closes, 1);
  EXPECT_TRUE(before->shutting_down);
  auto after = std::make_shared<Probe>();
  (*s)->subscribe(after);
  EXPECT_EQ(after->closes, 1);
  EXPECT_TRUE(after->shutting_down);
  EXPECT_EQ(after->message, "the server is stopping");
  EXPECT_EQ(after->frames, 0);
  v1::WorldInfo info;
  (*s)->summary(&info);
  EXPECT_EQ(info.watchers(), 0u);
}

// The tick length is only checked to be > 0 and at most 1e12 s, so the clock's schedule must
// hold for any such value. A tick far shorter than a nanosecond (more slots due than an int64
// holds) runs at the catch-up cap and drops the rest; a tick of 1e12 s (1e21 ns, past int64)
// never comes due, and the pool does not spin on it. Converting those slot counts and due times to
// integers overflowed (UBSan: float-cast-overflow in RealTimeClock::due_at and next_due); what a
// build without UBSan then did was up to the compiler (gcc -O2 happened to keep these facts).
TEST(SessionClock, TickLengthsBeyondTheClocksRangeKeepTheSchedule) {
  RealTimePool pool(2);
  // 1e12 s: the longest tick a world may have (kMaxInputMagnitude), beyond the clock's 1e9 s.
  for (double dt : {1e-300, kMaxInputMagnitude}) {
    Result<SceneDef> scene = scenes::builtin("bounce");
    ASSERT_TRUE(scene.ok());
    scene->settings.dt = dt;
    Result<World> world = build_world(*scene);
    ASSERT_TRUE(world.ok()) << world.status().message();
    auto session = std::make_shared<Session>(1, "bounce", std::move(world).value(), Limits());
    v1::SetRunModeReply reply;
    const double cpu_before = cpu_seconds();
    ASSERT_TRUE(session->set_run_mode(&pool, v1::RUN_MODE_REAL_TIME, std::nullopt, &reply).ok());
    std::this_thread::sleep_for(200ms);
    ASSERT_TRUE(session->set_run_mode(&pool, v1::RUN_MODE_PAUSED, std::nullopt, &reply).ok());
    const double cpu = cpu_seconds() - cpu_before;
    v1::WorldInfo info;
    session->info(&info);
    if (dt < 1.0) {
      EXPECT_GT(info.tick(), 0) << "dt " << dt;
      EXPECT_EQ(info.run().max_ticks_in_a_wake(), kDefaultMaxCatchUpTicks);
      EXPECT_GT(info.run().ticks_dropped(), 0);
    } else {
      EXPECT_EQ(info.tick(), 0) << "dt " << dt;
      EXPECT_LT(cpu, 0.1) << "dt " << dt << ": the pool spun for " << cpu << " s of CPU in 0.2 s";
    }
  }
}

}  // namespace
}  // namespace fulcrum::server
