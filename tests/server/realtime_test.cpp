// Real-time worlds and replays recorded on the server, against a server in-process on an
// ephemeral loopback port, through the client library.
//
// Timing: these tests sleep, but they assert facts of the schedule, not speed. The one bound
// that depends on the machine (a light world reaches at least 2/3 of its due ticks) is loose
// enough for a loaded 2-core CI machine; see RealTimeKeepsToTheSchedule.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include <unistd.h>

#include "fulcrum/client.h"
#include "replay.h"
#include "server.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using Clock = std::chrono::steady_clock;
using server::Server;
using server::ServerOptions;

using testing_support::pyramid_json;

constexpr double kDt = 1.0 / 60.0;  // pyramid.json's tick

// Slots of a 60 Hz schedule that can have come due between two instants.
int64_t slots_between(Clock::time_point from, Clock::time_point to, double dt = kDt) {
  return static_cast<int64_t>(std::floor(std::chrono::duration<double>(to - from).count() / dt));
}

v1::EditBatch push_body(int index, double vx) {
  v1::EditBatch batch;
  v1::SetVelocity* v = batch.add_edits()->mutable_set_velocity();
  v->mutable_body()->set_index(index);
  v->mutable_body()->set_generation(1);
  v->mutable_linear()->set_x(vx);
  v->mutable_linear()->set_y(4.0);
  return batch;
}

class RealTimeTest : public ::testing::Test {
 protected:
  void start(ServerOptions options = {}) {
    options.listen = "127.0.0.1:0";
    if (options.worker_threads == 0) options.worker_threads = 2;
    auto started = Server::start(options);
    ASSERT_TRUE(started.ok()) << started.status().message();
    server_ = std::move(started).value();
    client::ClientOptions copts;
    copts.address = server_->address();
    client_ = client::Client::connect(copts);
  }

  void start_recording_server() {
    replay_dir_ = testing::TempDir() + "fulcrum_realtime_test_" + std::to_string(::getpid());
    std::filesystem::remove_all(replay_dir_);
    ServerOptions options;
    options.replay_dir = replay_dir_;
    start(options);
  }

  void TearDown() override {
    server_.reset();
    if (!replay_dir_.empty()) std::filesystem::remove_all(replay_dir_);
  }

  uint64_t create(const std::string& json) {
    Result<client::WorldSummary> w = client_->create_world_json(json);
    EXPECT_TRUE(w.ok()) << w.status().message();
    return w.ok() ? w->id : 0;
  }

  client::WorldSummary world(uint64_t id) {
    Result<client::WorldSummary> w = client_->get_world(id);
    EXPECT_TRUE(w.ok()) << w.status().message();
    return w.ok() ? *w : client::WorldSummary();
  }

  // Downloads a replay into a file; returns its path ("" on failure).
  std::string download(uint64_t world, const std::string& name, const std::string& file) {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    Result<client::DownloadResult> r =
        client_->download_replay(world, name, [&](std::string_view chunk) {
          out.write(chunk.data(), static_cast<std::streamsize>(chunk.size()));
          return Status();
        });
    out.close();
    EXPECT_TRUE(r.ok()) << r.status().message();
    return r.ok() ? file : std::string();
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<client::Client> client_;
  std::string replay_dir_;
};

// After about 1 s at 60 Hz, the world has stepped about 60 ticks. Upper bound, exact: ticks run
// plus ticks dropped never exceed the slots due since the run started, floor(elapsed / dt),
// with elapsed measured from before the call that started the clock to after the read.
// Lower bound, loose: at least 2/3 of the slots due, i.e. 40 after 1 s. The pyramid costs well
// under 1 ms a tick, so only a machine stalled for a third of a second would miss it.
TEST_F(RealTimeTest, RealTimeKeepsToTheSchedule) {
  start();
  const uint64_t id = create(pyramid_json());
  const Clock::time_point before = Clock::now();
  Result<client::RunModeResult> run = client_->set_run_mode(id, client::RunMode::kRealTime);
  ASSERT_TRUE(run.ok()) << run.status().message();
  EXPECT_EQ(run->mode, client::RunMode::kRealTime);
  EXPECT_EQ(run->tick, 0);
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const client::WorldSummary w = world(id);
  const int64_t due = slots_between(before, Clock::now());
  EXPECT_EQ(w.run.mode, client::RunMode::kRealTime);
  EXPECT_EQ(w.run.ticks_run, w.tick);
  EXPECT_LE(w.run.ticks_run + w.run.ticks_dropped, due) << "ticks ran ahead of the clock";
  EXPECT_GE(w.tick, due * 2 / 3) << "tick " << w.tick << " of " << due << " due";
  EXPECT_GE(w.tick, 40);
  EXPECT_LE(w.run.max_ticks_in_a_wake, w.run.max_catch_up_ticks);
  EXPECT_EQ(w.run.max_catch_up_ticks, 5u);  // the default cap
  EXPECT_DOUBLE_EQ(w.run.dt, kDt);
}

// Pool threads with no tick due all wait for the earliest entry of the queue; when it comes
// due one of them takes it out (freeing its node) while the others are still waiting on its due
// time, which wait_until reads again when they wake. Four threads on one world: under ASan
// (tools/sanitize.sh) the pool read the freed node here until it waited on a copy.
TEST_F(RealTimeTest, IdlePoolThreadsWaitingOnOneWorld) {
  ServerOptions options;
  options.worker_threads = 4;
  start(options);
  const uint64_t id = create(pyramid_json());
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kRealTime).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kPaused).ok());
  EXPECT_GT(world(id).tick, 0);
}

TEST_F(RealTimeTest, PauseStopsTheClockAndResumeContinues) {
  start();
  const uint64_t id = create(pyramid_json());
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kRealTime).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));

  // Step is refused while the clock runs, and says why.
  Result<client::StepResult> refused = client_->step(id, 1);
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.status().message().find("real time"), std::string::npos)
      << refused.status().message();

  Result<client::RunModeResult> paused = client_->set_run_mode(id, client::RunMode::kPaused);
  ASSERT_TRUE(paused.ok()) << paused.status().message();
  EXPECT_EQ(paused->mode, client::RunMode::kPaused);
  EXPECT_GT(paused->tick, 0);
  // No tick runs after the reply: two reads 200 ms (12 slots) apart see the paused tick.
  EXPECT_EQ(world(id).tick, paused->tick);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(world(id).tick, paused->tick);
  EXPECT_EQ(world(id).run.mode, client::RunMode::kPaused);

  // Paused worlds step on request again; then the clock resumes from there.
  Result<client::StepResult> stepped = client_->step(id, 3);
  ASSERT_TRUE(stepped.ok()) << stepped.status().message();
  EXPECT_EQ(stepped->tick, paused->tick + 3);
  Result<client::RunModeResult> resumed = client_->set_run_mode(id, client::RunMode::kRealTime, 2);
  ASSERT_TRUE(resumed.ok());
  EXPECT_EQ(resumed->tick, paused->tick + 3);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const client::WorldSummary w = world(id);
  EXPECT_GT(w.tick, resumed->tick);
  EXPECT_EQ(w.run.start_tick, resumed->tick);
  EXPECT_EQ(w.run.max_catch_up_ticks, 2u);
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kPaused).ok());

  // Bad values name the field.
  Result<client::RunModeResult> bad = client_->set_run_mode(id, client::RunMode::kRealTime, 0);
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("max_catch_up_ticks"), std::string::npos);
  EXPECT_EQ(client_->set_run_mode(999, client::RunMode::kRealTime).status().code(),
            StatusCode::kNotFound);
}

// A world at 100 kHz (dt = 10 us) cannot keep up on any machine: the pyramid's step costs far
// more than 10 us. Every wake then has more ticks due than the cap; it steps exactly the cap
// and drops the rest, so the world never runs ahead of the schedule and never more than the
// cap per wake.
TEST_F(RealTimeTest, FallingBehindDropsTicksBeyondTheCatchUpCap) {
  start();
  std::string json = pyramid_json();
  const std::string dt_field = "\"dt\": 0.016666666666666666";
  ASSERT_NE(json.find(dt_field), std::string::npos);
  json.replace(json.find(dt_field), dt_field.size(), "\"dt\": 0.00001");
  const uint64_t id = create(json);
  const Clock::time_point before = Clock::now();
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kRealTime, 3).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kPaused).ok());
  const int64_t due = slots_between(before, Clock::now(), 1e-5);
  const client::WorldSummary w = world(id);
  std::printf("100 kHz world: %lld ticks run, %lld dropped, %lld wakes (%lld late)\n",
              static_cast<long long>(w.run.ticks_run), static_cast<long long>(w.run.ticks_dropped),
              static_cast<long long>(w.run.wakes), static_cast<long long>(w.run.late_wakes));
  EXPECT_GT(w.run.ticks_dropped, 0);
  EXPECT_GT(w.run.late_wakes, 0);
  EXPECT_EQ(w.run.max_ticks_in_a_wake, 3u);
  EXPECT_LE(w.run.ticks_run, 3 * w.run.wakes);
  EXPECT_LE(w.run.ticks_run + w.run.ticks_dropped, due);
  EXPECT_EQ(w.tick, w.run.ticks_run);
}

// Frames stream as the clock steps the world: a reader sees increasing ticks, and the newest
// frame it got before the pause is at most the paused tick.
TEST_F(RealTimeTest, FramesStreamWhileTheWorldRuns) {
  start();
  const uint64_t id = create(pyramid_json());
  std::mutex mu;
  std::vector<int64_t> ticks;
  client::SubscribeOptions options;
  options.bodies = client::FrameBodies::kNone;
  auto sub = client_->subscribe(id, options, [&](const client::Frame& f) {
    std::lock_guard<std::mutex> lock(mu);
    ticks.push_back(f.tick);
  });
  ASSERT_TRUE(sub.ok());
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kRealTime).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  Result<client::RunModeResult> paused = client_->set_run_mode(id, client::RunMode::kPaused);
  ASSERT_TRUE(paused.ok());
  // The last frame may still be in flight: wait for the paused tick (bounded).
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mu);
      if (!ticks.empty() && ticks.back() == paused->tick) break;
    }
    ASSERT_LT(Clock::now(), deadline) << "the paused tick's frame never arrived";
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  (*sub)->cancel();
  std::lock_guard<std::mutex> lock(mu);
  EXPECT_GE(ticks.size(), 3u);  // the first frame (tick 0) and frames as the world ran
  for (size_t i = 1; i < ticks.size(); ++i) EXPECT_LT(ticks[i - 1], ticks[i]);
}

// The clock decides when ticks run, never what they compute: a world that ran in real time with
// edits along the way has the hash of a copy stepped by Step to the same ticks with the same
// edits at the same ticks.
TEST_F(RealTimeTest, RealTimeHashEqualsAStepDrivenCopy) {
  start();
  const uint64_t live = create(pyramid_json());
  ASSERT_TRUE(client_->set_run_mode(live, client::RunMode::kRealTime).ok());
  std::vector<std::pair<int64_t, v1::EditBatch>> applied;
  for (int i = 0; i < 3; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(120));
    v1::EditBatch batch = push_body(5 + i, 1.0 + i);
    Result<client::EditResult> r = client_->apply_edits(live, batch);
    ASSERT_TRUE(r.ok()) << r.status().message();
    applied.emplace_back(r->tick, batch);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(120));
  Result<client::RunModeResult> paused = client_->set_run_mode(live, client::RunMode::kPaused);
  ASSERT_TRUE(paused.ok());
  const client::WorldSummary end = world(live);
  ASSERT_GT(end.tick, applied.back().first);

  const uint64_t copy = create(pyramid_json());
  int64_t tick = 0;
  for (const auto& [at, batch] : applied) {
    if (at > tick) {
      ASSERT_TRUE(client_->step(copy, static_cast<uint32_t>(at - tick)).ok());
    }
    tick = at;
    ASSERT_TRUE(client_->apply_edits(copy, batch, at).ok());
  }
  Result<client::StepResult> last = client_->step(copy, static_cast<uint32_t>(end.tick - tick));
  ASSERT_TRUE(last.ok());
  EXPECT_EQ(last->tick, end.tick);
  EXPECT_EQ(last->state_hash, end.state_hash);
}

// Many worlds run at once; deleting one stops its clock and the others go on; shutdown with
// worlds running returns (the pool's threads are joined).
TEST_F(RealTimeTest, DeleteAndShutdownStopTheClocks) {
  start();
  std::vector<uint64_t> ids;
  for (int i = 0; i < 4; ++i) {
    ids.push_back(create(pyramid_json()));
    ASSERT_TRUE(client_->set_run_mode(ids.back(), client::RunMode::kRealTime).ok());
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ASSERT_TRUE(client_->delete_world(ids[0]).ok());
  EXPECT_EQ(client_->get_world(ids[0]).status().code(), StatusCode::kNotFound);
  const int64_t t1 = world(ids[1]).tick;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_GT(world(ids[1]).tick, t1);
  for (size_t i = 1; i < ids.size(); ++i) EXPECT_GT(world(ids[i]).tick, 0);
  server_->shutdown(std::chrono::milliseconds(1000));
}

TEST_F(RealTimeTest, RecordedReplayDownloadsAndVerifies) {
  start_recording_server();
  const uint64_t id = create(pyramid_json());
  Result<client::RecordingResult> rec = client_->start_recording(id, 30);
  ASSERT_TRUE(rec.ok()) << rec.status().message();
  EXPECT_EQ(rec->tick, 0);
  EXPECT_EQ(rec->name, "world1-1.replay");
  EXPECT_EQ(client_->start_recording(id).status().code(), StatusCode::kFailedPrecondition);

  // Steps and edits by RPC, one edit creating a body.
  ASSERT_TRUE(client_->step(id, 20).ok());
  ASSERT_TRUE(client_->apply_edits(id, push_body(7, 2.0)).ok());
  v1::EditBatch create_ball;
  v1::Body* ball = create_ball.add_edits()->mutable_create_body();
  ball->set_type(v1::BODY_TYPE_DYNAMIC);
  ball->mutable_position()->set_y(30);
  ball->add_shapes()->mutable_circle()->set_radius(0.5);
  ASSERT_TRUE(client_->apply_edits(id, create_ball).ok());
  Result<client::StepResult> stepped = client_->step(id, 25);
  ASSERT_TRUE(stepped.ok());

  // Downloaded while recording: the file up to the last complete tick.
  const std::string mid = download(id, "", testing::TempDir() + "rt_mid.replay");
  ASSERT_FALSE(mid.empty());
  {
    Result<ReplayContents> replay = read_replay(mid);
    ASSERT_TRUE(replay.ok()) << replay.status().message();
    EXPECT_FALSE(replay->truncated);
    Result<ReplayReport> report = verify_replay(*replay);
    ASSERT_TRUE(report.ok()) << report.status().message();
    EXPECT_TRUE(report->ok) << report->detail;
    EXPECT_EQ(report->final_tick, 45);
    EXPECT_EQ(report->final_hash, stepped->state_hash);
  }
  EXPECT_TRUE(world(id).recording.active);

  // Then real time with an edit on the way, paused, and stopped.
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kRealTime).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  ASSERT_TRUE(client_->apply_edits(id, push_body(9, -3.0)).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  ASSERT_TRUE(client_->set_run_mode(id, client::RunMode::kPaused).ok());
  // An edit applied after the last tick of a recording is not in it; step past it.
  ASSERT_TRUE(client_->step(id, 1).ok());
  Result<client::RecordingResult> stopped = client_->stop_recording(id);
  ASSERT_TRUE(stopped.ok()) << stopped.status().message();
  const client::WorldSummary w = world(id);
  EXPECT_FALSE(w.recording.active);
  EXPECT_EQ(w.recording.name, rec->name);
  EXPECT_EQ(stopped->ticks, w.tick);
  EXPECT_EQ(w.recording.bytes, stopped->bytes);

  const std::string full = download(0, rec->name, testing::TempDir() + "rt_full.replay");
  ASSERT_FALSE(full.empty());
  EXPECT_EQ(std::filesystem::file_size(full), stopped->bytes);
  Result<ReplayContents> replay = read_replay(full);
  ASSERT_TRUE(replay.ok()) << replay.status().message();
  int batches = 0;
  for (const v1::ReplayTick& t : replay->ticks) batches += t.edits_size();
  EXPECT_EQ(batches, 3);  // exactly the batches ApplyEdits applied
  Result<ReplayReport> report = verify_replay(*replay);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_TRUE(report->ok) << report->detail;
  EXPECT_EQ(report->final_tick, w.tick);
  EXPECT_EQ(report->final_hash, w.state_hash);
  std::filesystem::remove(mid);
  std::filesystem::remove(full);
}

TEST_F(RealTimeTest, RecordingAndDownloadErrors) {
  start_recording_server();
  const uint64_t id = create(pyramid_json());
  auto sink = [](std::string_view) { return Status(); };
  // Unknown names and worlds without recordings are NOT_FOUND; paths are not names.
  EXPECT_EQ(client_->download_replay(0, "world9-1.replay", sink).status().code(),
            StatusCode::kNotFound);
  EXPECT_EQ(client_->download_replay(id, "", sink).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(client_->download_replay(77, "", sink).status().code(), StatusCode::kNotFound);
  Result<client::DownloadResult> escape = client_->download_replay(0, "../../etc/passwd", sink);
  EXPECT_EQ(escape.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(escape.status().message().find("name"), std::string::npos);
  EXPECT_EQ(client_->stop_recording(id).status().code(), StatusCode::kFailedPrecondition);

  // A world that records refuses a rollback, which a replay cannot hold.
  Result<client::SnapshotResult> snap = client_->get_snapshot(id);
  ASSERT_TRUE(snap.ok());
  ASSERT_TRUE(client_->start_recording(id).ok());
  Result<client::RestoreResult> restored = client_->restore(id, snap->bytes);
  EXPECT_EQ(restored.status().code(), StatusCode::kFailedPrecondition);
  // Deleting the world closes its recording; the file stays downloadable by name.
  const std::string name = world(id).recording.name;
  ASSERT_TRUE(client_->step(id, 2).ok());
  ASSERT_TRUE(client_->delete_world(id).ok());
  const std::string file = download(0, name, testing::TempDir() + "rt_deleted.replay");
  ASSERT_FALSE(file.empty());
  Result<ReplayContents> replay = read_replay(file);
  ASSERT_TRUE(replay.ok());
  EXPECT_EQ(replay->ticks.size(), 2u);
  std::filesystem::remove(file);
}

TEST_F(RealTimeTest, RecordingNeedsAReplayDirectory) {
  start();
  const uint64_t id = create(pyramid_json());
  Result<client::RecordingResult> r = client_->start_recording(id);
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("--replay-dir"), std::string::npos) << r.status().message();
}

}  // namespace
}  // namespace fulcrum
