// Recordings against faults of the process and the machine: fulcrum-server killed with SIGKILL
// while several worlds record (some on the real-time clock, one stepped and edited by a client),
// at many kill points; and a server whose replay files hit a file size limit (what a full disk
// looks like to the writer). Every file written must read and verify up to its last complete
// tick.
#include <sys/resource.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "fulcrum/client.h"
#include "replay.h"
#include "server_process.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using namespace std::chrono_literals;
using testing_support::connect;
using testing_support::eventually;
using testing_support::push;
using testing_support::pyramid_json;
using testing_support::reap;
using testing_support::ServerProcess;

struct Verified {
  int files = 0;
  int64_t ticks = 0;
  int truncated = 0;
};

// Reads and re-simulates every replay in `dir`; each must verify up to its last complete tick.
Verified verify_all(const std::string& dir) {
  Verified out;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".replay") continue;
    Result<ReplayContents> replay = read_replay(entry.path().string());
    EXPECT_TRUE(replay.ok()) << entry.path() << ": " << replay.status().message();
    if (!replay.ok()) continue;
    Result<ReplayReport> report = verify_replay(*replay);
    EXPECT_TRUE(report.ok()) << entry.path() << ": " << report.status().message();
    if (!report.ok()) continue;
    EXPECT_TRUE(report->ok) << entry.path() << ": " << report->detail;
    ++out.files;
    out.ticks += report->ticks_checked;
    out.truncated += replay->truncated ? 1 : 0;
  }
  return out;
}

// Eight kill points, 40 ms to 600 ms into a run of three recording worlds: two on the server's
// clock and one a client steps and edits as fast as it can. SIGKILL gives the server no chance
// to close anything; replay records are written whole and flushed one tick at a time, so each
// file reads up to its last complete tick (a record cut in half is the truncated tail) and
// re-simulates to the recorded hashes.
TEST(CrashTest, RecordingsSurviveSigkillAtAnyPoint) {
  int kill_points = 0, files = 0, truncated = 0;
  int64_t ticks = 0;
  for (int k = 0; k < 8; ++k) {
    const std::string replays = ::testing::TempDir() + "fulcrum_crash_" + std::to_string(k);
    std::filesystem::remove_all(replays);
    std::filesystem::create_directories(replays);
    ServerProcess server({"--replay-dir", replays, "--log", "off"});
    ASSERT_FALSE(server.address().empty()) << server.log();
    auto client = connect(server);
    std::vector<uint64_t> worlds;
    for (int w = 0; w < 3; ++w) {
      Result<client::WorldSummary> created = client->create_world_json(pyramid_json());
      ASSERT_TRUE(created.ok()) << created.status().message();
      worlds.push_back(created->id);
      ASSERT_TRUE(client->start_recording(created->id, 7).ok());
    }
    ASSERT_TRUE(client->set_run_mode(worlds[0], client::RunMode::kRealTime).ok());
    ASSERT_TRUE(client->set_run_mode(worlds[1], client::RunMode::kRealTime).ok());
    std::atomic<bool> stop{false};
    std::thread driver([&] {
      for (int i = 0; !stop; ++i) {
        if (i % 5 == 0) (void)client->apply_edits(worlds[2], push(5 + i % 40, 0.5));
        if (!client->step(worlds[2], 3).ok()) break;
      }
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(40 + 80 * k));
    kill(server.pid(), SIGKILL);
    stop = true;
    driver.join();
    ++kill_points;
    const Verified v = verify_all(replays);
    EXPECT_EQ(v.files, 3) << "kill point " << k;
    files += v.files;
    ticks += v.ticks;
    truncated += v.truncated;
    std::filesystem::remove_all(replays);
  }
  std::printf(
      "kill points %d, replay files verified %d (%d cut mid-record), ticks re-simulated %lld\n",
      kill_points, files, truncated, static_cast<long long>(ticks));
}

// The replay directory's files limited to 600 kB (ulimit -f, set for the server alone): the
// write that passes it fails with EFBIG (the server ignores SIGXFSZ), the recording stops with
// the reason in the log, GetWorld and the counters, the world keeps running on the clock, and
// the file up to its last complete tick verifies.
TEST(CrashTest, AFullReplayFileStopsTheRecordingNotTheWorld) {
  const std::string replays = ::testing::TempDir() + "fulcrum_full_disk";
  std::filesystem::remove_all(replays);
  std::filesystem::create_directories(replays);
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  rlimit small = saved;
  small.rlim_cur = 600 * 1024;  // the child inherits it; the test process gets its own back
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  ServerProcess server({"--replay-dir", replays});
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
  ASSERT_FALSE(server.address().empty()) << server.log();
  auto client = connect(server);
  Result<client::WorldSummary> created = client->create_world_json(pyramid_json());
  ASSERT_TRUE(created.ok()) << created.status().message();
  const uint64_t id = created->id;
  ASSERT_TRUE(client->start_recording(id, 10).ok());
  ASSERT_TRUE(client->set_run_mode(id, client::RunMode::kRealTime).ok());
  // Keyframes of the 211-body pyramid are about 60 kB: the limit is reached within a second.
  ASSERT_TRUE(eventually(
      [&] {
        Result<v1::ServerStats> stats = client->get_stats();
        return stats.ok() && stats->recordings_failed() == 1;
      },
      20s))
      << server.log();
  Result<client::WorldSummary> info = client->get_world(id);
  ASSERT_TRUE(info.ok());
  EXPECT_FALSE(info->recording.active);
  EXPECT_NE(info->recording.error.find("File too large"), std::string::npos)
      << info->recording.error;
  const int64_t tick = info->tick;
  std::this_thread::sleep_for(200ms);
  Result<client::WorldSummary> later = client->get_world(id);
  ASSERT_TRUE(later.ok());
  EXPECT_GT(later->tick, tick) << "the world stopped with its recording";
  const std::string log = server.log();
  EXPECT_NE(log.find("event=recording_closed"), std::string::npos) << log;
  EXPECT_NE(log.find("File too large"), std::string::npos) << log;
  const Verified v = verify_all(replays);
  EXPECT_EQ(v.files, 1);
  EXPECT_GT(v.ticks, 20);
  EXPECT_EQ(server.terminate(), 0);
}

// The replay directory gone from under a running server, a file in its place (so that even
// root cannot create a replay there): StartRecording is refused with FAILED_PRECONDITION and
// the operating system's reason, which also goes to the log, the counters and GetWorld; the
// world keeps stepping; once the directory is back, recording works again.
TEST(CrashTest, AnUnwritableReplayDirectoryRefusesRecordingsNotTheWorld) {
  const std::string replays = ::testing::TempDir() + "fulcrum_unwritable";
  std::filesystem::remove_all(replays);
  std::filesystem::create_directories(replays);
  ServerProcess server({"--replay-dir", replays});
  ASSERT_FALSE(server.address().empty()) << server.log();
  auto client = connect(server);
  Result<client::WorldSummary> created = client->create_world_json(pyramid_json());
  ASSERT_TRUE(created.ok()) << created.status().message();
  const uint64_t id = created->id;

  std::filesystem::remove_all(replays);
  std::ofstream(replays) << "not a directory";
  auto refused = client->start_recording(id, 10);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  const std::string& why = refused.status().message();
  EXPECT_NE(why.find("the recording could not start: " + replays + "/world1-"), std::string::npos)
      << why;
  EXPECT_NE(why.find("cannot create the replay file (Not a directory)"), std::string::npos) << why;
  Result<client::WorldSummary> info = client->get_world(id);
  ASSERT_TRUE(info.ok());
  EXPECT_FALSE(info->recording.active);
  EXPECT_NE(info->recording.error.find("Not a directory"), std::string::npos)
      << info->recording.error;
  Result<v1::ServerStats> stats = client->get_stats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->recordings_failed(), 1u);
  EXPECT_EQ(stats->recordings_started(), 0u);
  EXPECT_NE(server.log().find("event=recording_failed world=1"), std::string::npos) << server.log();
  Result<client::StepResult> stepped = client->step(id, 5);
  ASSERT_TRUE(stepped.ok()) << stepped.status().message();
  EXPECT_EQ(stepped->tick, 5);

  std::filesystem::remove(replays);
  std::filesystem::create_directories(replays);
  auto started = client->start_recording(id, 10);
  ASSERT_TRUE(started.ok()) << started.status().message();
  ASSERT_TRUE(client->step(id, 3).ok());
  ASSERT_TRUE(client->stop_recording(id).ok());
  info = client->get_world(id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->recording.error, "") << "a recording that worked keeps an old error";
  const Verified v = verify_all(replays);
  EXPECT_EQ(v.files, 1);
  EXPECT_EQ(v.ticks, 3);
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace fulcrum
