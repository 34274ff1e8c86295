// Edit batches and replay files: atomic batches, honest replays verify, and a replay altered on
// purpose is caught at the right tick with the right body named.
#include "replay.h"
#include "fulcrum/fingerprint.h"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "edit_convert.h"
#include "fulcrum/scenes.h"
#include "snapshot_convert.h"

namespace fulcrum {
namespace {

World build(const char* name) {
  Result<SceneDef> scene = scenes::builtin(name);
  EXPECT_TRUE(scene.ok());
  Result<World> world = build_world(*scene);
  EXPECT_TRUE(world.ok());
  return std::move(world).value();
}

v1::Handle handle(int index, uint32_t generation = 1) {
  v1::Handle h;
  h.set_index(index);
  h.set_generation(generation);
  return h;
}

v1::Edit impulse(int body, double ix, double iy) {
  v1::Edit e;
  *e.mutable_apply_impulse()->mutable_body() = handle(body);
  e.mutable_apply_impulse()->mutable_impulse()->set_x(ix);
  e.mutable_apply_impulse()->mutable_impulse()->set_y(iy);
  return e;
}

v1::Edit velocity(int body, double vx, double vy) {
  v1::Edit e;
  *e.mutable_set_velocity()->mutable_body() = handle(body);
  e.mutable_set_velocity()->mutable_linear()->set_x(vx);
  e.mutable_set_velocity()->mutable_linear()->set_y(vy);
  return e;
}

v1::Edit new_ball(double x, double y) {
  v1::Edit e;
  v1::Body* b = e.mutable_create_body();
  b->set_type(v1::BODY_TYPE_DYNAMIC);
  b->mutable_position()->set_x(x);
  b->mutable_position()->set_y(y);
  b->add_shapes()->mutable_circle()->set_radius(0.3);
  return e;
}

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("fulcrum_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

// Records `ticks` ticks of a ragdoll scene with edits at several ticks.
std::string record(const std::string& name, uint32_t keyframes, int ticks = 120) {
  World w = build("ragdolls");
  std::map<int64_t, v1::EditBatch> script;
  *script[10].add_edits() = impulse(30, 40.0, 60.0);
  *script[25].add_edits() = velocity(50, -3.0, 2.0);
  *script[25].add_edits() = new_ball(-200.0, 100.0);  // falls alone: body 551
  {
    v1::Edit destroy;
    *destroy.mutable_destroy_body() = handle(12);
    *script[40].add_edits() = destroy;
  }
  *script[70].add_edits() = impulse(551, -25.0, 10.0);
  ReplayOptions options;
  options.keyframe_interval = keyframes;
  std::string path = temp_path(name);
  auto writer = ReplayWriter::open(path, w, options);
  EXPECT_TRUE(writer.ok());
  for (int i = 0; i < ticks; ++i) {
    std::vector<v1::EditBatch> batches;
    if (auto it = script.find(w.tick()); it != script.end()) {
      Result<EditOutcome> r = apply_edit_batch(&w, it->second);
      EXPECT_TRUE(r.ok()) << r.status().message();
      batches.push_back(it->second);
    }
    w.step();
    EXPECT_TRUE((*writer)->record_tick(w, batches).ok());
  }
  EXPECT_TRUE((*writer)->close().ok());
  return path;
}

// Constant forces and attractors through edits: applied, and refused with the field named
// when not finite or beyond 1e12 (kMaxInputMagnitude), leaving the world unchanged.
TEST(EditBatch, ConstantForcesAndAttractors) {
  World w = build("ragdolls");
  for (int i = 0; i < 5; ++i) w.step();
  const uint64_t before = w.state_hash();
  v1::EditBatch bad;
  v1::SetConstantForce* f = bad.add_edits()->mutable_set_constant_force();
  *f->mutable_body() = handle(30);
  f->mutable_force()->set_x(std::nan(""));
  Result<EditOutcome> r = apply_edit_batch(&w, bad);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message().rfind("edits[0].set_constant_force.force: must be finite", 0), 0u)
      << r.status().message();
  f->mutable_force()->set_x(1.0);
  f->set_torque(2e12);
  r = apply_edit_batch(&w, bad);
  EXPECT_EQ(r.status().message().rfind("edits[0].set_constant_force.torque", 0), 0u)
      << r.status().message();

  v1::EditBatch bad_pull;
  v1::SetAttractors* a = bad_pull.add_edits()->mutable_set_attractors();
  a->add_attractors()->set_strength(1.0);
  a->add_attractors()->set_strength(std::nan(""));
  r = apply_edit_batch(&w, bad_pull);
  EXPECT_EQ(r.status().message().rfind("edits[0].set_attractors.attractors[1].strength", 0), 0u)
      << r.status().message();
  a->mutable_attractors(1)->set_strength(1.0);
  a->mutable_attractors(1)->set_falloff(static_cast<v1::Falloff>(7));
  r = apply_edit_batch(&w, bad_pull);
  EXPECT_EQ(r.status().message().rfind("edits[0].set_attractors.attractors[1].falloff", 0), 0u)
      << r.status().message();
  EXPECT_EQ(w.state_hash(), before);

  v1::EditBatch good;
  f = good.add_edits()->mutable_set_constant_force();
  *f->mutable_body() = handle(30);
  f->mutable_force()->set_y(50.0);
  v1::Attractor* pull = good.add_edits()->mutable_set_attractors()->add_attractors();
  pull->mutable_point()->set_y(20.0);
  pull->set_strength(5.0);
  pull->set_falloff(v1::FALLOFF_INVERSE_SQUARE);
  ASSERT_TRUE(apply_edit_batch(&w, good).ok());
  ASSERT_EQ(w.attractors().size(), 1u);
  EXPECT_EQ(w.attractors()[0].falloff, Falloff::kInverseSquare);
  EXPECT_EQ(w.attractors()[0].min_distance, 0.5);  // the default
  EXPECT_EQ(w.body_state(BodyId{30, 1})->constant_force, Vec2(0.0, 50.0));
}

TEST(EditBatch, RefusedBatchChangesNothing) {
  World w = build("ragdolls");
  for (int i = 0; i < 20; ++i) w.step();
  const uint64_t before = w.state_hash();
  const int bodies = w.body_count();
  v1::EditBatch batch;
  *batch.add_edits() = new_ball(1.0, 10.0);
  *batch.add_edits() = impulse(30, 5.0, 0.0);
  *batch.add_edits() = velocity(31, std::nan(""), 0.0);
  Result<EditOutcome> r = apply_edit_batch(&w, batch);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message().rfind("edits[2].set_velocity", 0), 0u) << r.status().message();
  EXPECT_EQ(w.state_hash(), before);
  EXPECT_EQ(w.body_count(), bodies);

  v1::EditBatch stale;
  *stale.add_edits() = impulse(30, 5.0, 0.0);
  *stale.add_edits() = impulse(31, 5.0, 0.0);
  stale.mutable_edits(1)->mutable_apply_impulse()->mutable_body()->set_generation(7);
  r = apply_edit_batch(&w, stale);
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("edits[1].apply_impulse: body {31, 7}"), std::string::npos)
      << r.status().message();
  EXPECT_EQ(w.state_hash(), before);

  EXPECT_EQ(apply_edit_batch(&w, v1::EditBatch()).status().code(), StatusCode::kInvalidArgument);
  v1::EditBatch big;
  for (int i = 0; i < 11; ++i) *big.add_edits() = impulse(30, 1.0, 0.0);
  EXPECT_EQ(apply_edit_batch(&w, big, 10).status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(w.state_hash(), before);
}

TEST(EditBatch, AcceptedBatchReturnsHandlesInOrder) {
  World w = build("ragdolls");
  v1::EditBatch batch;
  *batch.add_edits() = new_ball(1.0, 10.0);
  *batch.add_edits() = new_ball(2.0, 10.0);
  Result<EditOutcome> r = apply_edit_batch(&w, batch);
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r->bodies.size(), 2u);
  EXPECT_EQ(r->bodies[1].index, r->bodies[0].index + 1);
  EXPECT_EQ(r->shapes.size(), 2u);
}

TEST(Replay, HonestReplayVerifies) {
  std::string path = record("honest.replay", 30);
  Result<ReplayContents> replay = read_replay(path);
  ASSERT_TRUE(replay.ok()) << replay.status().message();
  EXPECT_FALSE(replay->truncated);
  ASSERT_EQ(replay->ticks.size(), 120u);
  Result<ReplayReport> report = verify_replay(*replay);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_TRUE(report->ok) << report->detail;
  EXPECT_EQ(report->ticks_checked, 120);
  EXPECT_EQ(report->final_hash, replay->ticks.back().state_hash());
  std::filesystem::remove(path);
}

// One recorded value altered: the impulse of the edit before tick 71 on body 551, a ball
// falling alone. Re-simulation diverges at tick 71, and the keyframe of that tick names the
// ball. (An impulse on a ragdoll part would first show on the lowest-numbered part of that
// ragdoll, which the joints move in the same tick.)
TEST(Replay, AlteredEditIsFoundAtItsTickAndBody) {
  std::string path = record("altered.replay", 1);
  Result<ReplayContents> replay = read_replay(path);
  ASSERT_TRUE(replay.ok());
  v1::ReplayTick& t = replay->ticks[70];
  ASSERT_EQ(t.tick(), 71);
  ASSERT_EQ(t.edits_size(), 1);
  t.mutable_edits(0)->mutable_edits(0)->mutable_apply_impulse()->mutable_impulse()->set_x(-25.5);
  ASSERT_TRUE(write_replay(path, *replay).ok());

  Result<ReplayContents> reread = read_replay(path);
  ASSERT_TRUE(reread.ok());
  Result<ReplayReport> report = verify_replay(*reread);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_FALSE(report->ok);
  EXPECT_EQ(report->first_divergent_tick, 71);
  EXPECT_NE(report->detail.find("bodies[551]."), std::string::npos) << "detail: " << report->detail;
  std::filesystem::remove(path);
}

// A replay recorded by an engine of other results (its fingerprint differs): a divergence is
// reported as what that engine change did, first; one that still verifies stays OK.
TEST(Replay, ADivergenceOfAnotherEnginesReplaySaysSoFirst) {
  std::string path = record("foreign.replay", 30);
  Result<ReplayContents> replay = read_replay(path);
  ASSERT_TRUE(replay.ok());
  EXPECT_EQ(replay->header.initial().fingerprint(), kDeterminismFingerprint);
  replay->header.mutable_initial()->set_fingerprint("fulcrum-results-0");
  Result<ReplayReport> same = verify_replay(*replay);
  ASSERT_TRUE(same.ok());
  EXPECT_TRUE(same->ok) << same->detail;
  replay->ticks[40].set_state_hash(replay->ticks[40].state_hash() ^ 1);
  Result<ReplayReport> report = verify_replay(*replay);
  ASSERT_TRUE(report.ok());
  EXPECT_FALSE(report->ok);
  EXPECT_EQ(report->first_divergent_tick, 41);
  EXPECT_EQ(report->detail.rfind("recorded by an engine that gives the results of "
                                 "fulcrum-results-0, and this build gives those of " +
                                     std::string(kDeterminismFingerprint) +
                                     ", so a divergence is expected",
                                 0),
            0u)
      << report->detail;
  std::filesystem::remove(path);
}

// With keyframes every 30 ticks the divergence tick is still exact (from the hashes) and the
// field comes from the next keyframe.
TEST(Replay, SparseKeyframesStillNameTheTick) {
  std::string path = record("sparse.replay", 30);
  Result<ReplayContents> replay = read_replay(path);
  ASSERT_TRUE(replay.ok());
  replay->ticks[25]
      .mutable_edits(0)
      ->mutable_edits(0)
      ->mutable_set_velocity()
      ->mutable_linear()
      ->set_x(-3.25);
  ASSERT_TRUE(write_replay(path, *replay).ok());
  Result<ReplayReport> report = verify_replay(*read_replay(path));
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->first_divergent_tick, 26);
  EXPECT_NE(report->detail.find("next keyframe (tick 30)"), std::string::npos) << report->detail;
  std::filesystem::remove(path);
}

TEST(Replay, CutOffFileReadsUpToItsLastCompleteTick) {
  std::string path = record("cut.replay", 30);
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size - 37);
  Result<ReplayContents> replay = read_replay(path);
  ASSERT_TRUE(replay.ok()) << replay.status().message();
  EXPECT_TRUE(replay->truncated);
  EXPECT_EQ(replay->ticks.size(), 119u);
  Result<ReplayReport> report = verify_replay(*replay);
  ASSERT_TRUE(report.ok());
  EXPECT_TRUE(report->ok) << report->detail;
  std::filesystem::remove(path);
}

TEST(Replay, DamagedOrForeignFilesAreRefused) {
  std::string path = record("damaged.replay", 30, 40);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto write = [&](const std::string& b) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << b;
  };
  std::string flipped = bytes;
  flipped[bytes.size() / 2] = static_cast<char>(flipped[bytes.size() / 2] ^ 0x04);
  write(flipped);
  Result<ReplayContents> r = read_replay(path);
  EXPECT_EQ(r.status().code(), StatusCode::kDataLoss);
  EXPECT_NE(r.status().message().find("checksum mismatch"), std::string::npos)
      << r.status().message();

  write("");
  EXPECT_EQ(read_replay(path).status().code(), StatusCode::kDataLoss);

  write(bytes);
  Result<ReplayContents> good = read_replay(path);
  ASSERT_TRUE(good.ok());
  good->header.set_version(kReplayVersion + 1);
  ASSERT_TRUE(write_replay(path, *good).ok());
  r = read_replay(path);
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("version 2"), std::string::npos) << r.status().message();
  std::filesystem::remove(path);
  EXPECT_EQ(read_replay(path).status().code(), StatusCode::kNotFound);
}

// `fulcrum replay verify DIR --junit FILE`, as a CI job runs it over a folder of recordings:
// one test case per replay, in name order; the altered replay is a failure naming its tick and
// body, a file that is not a replay an error; the exit code is 1; every replay is still checked.
TEST(ReplayCli, VerifiesAFolderIntoAJUnitReport) {
  namespace fs = std::filesystem;
  const fs::path dir = temp_path("junit_dir");
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::rename(record("a.replay", 30, 40), dir / "a_honest.replay");
  const std::string altered = record("b.replay", 1);
  {
    Result<ReplayContents> replay = read_replay(altered);
    ASSERT_TRUE(replay.ok());
    replay->ticks[70]
        .mutable_edits(0)
        ->mutable_edits(0)
        ->mutable_apply_impulse()
        ->mutable_impulse()
        ->set_x(-25.5);
    ASSERT_TRUE(write_replay((dir / "b_altered.replay").string(), *replay).ok());
    fs::remove(altered);
  }
  std::ofstream(dir / "c_junk.replay") << "not a replay";
  std::ofstream(dir / "notes.txt") << "not named *.replay: skipped";
  const std::string report = (dir / "report.xml").string();
  const std::string command = std::string(FULCRUM_CLI) + " replay verify " + dir.string() +
                              " --junit " + report + " > " + (dir / "out.txt").string() + " 2>&1";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream in(report);
  const std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(xml.find("<testsuites tests=\"3\" failures=\"1\" errors=\"1\""), std::string::npos)
      << xml;
  const size_t a = xml.find("a_honest.replay\""), b = xml.find("b_altered.replay\""),
               c = xml.find("c_junk.replay\"");
  ASSERT_TRUE(a != std::string::npos && b != std::string::npos && c != std::string::npos) << xml;
  EXPECT_TRUE(a < b && b < c) << "test cases in name order";
  EXPECT_NE(xml.find("<system-out>40 ticks match, final tick 40"), std::string::npos) << xml;
  EXPECT_NE(xml.find("<failure message=\"diverged at tick 71\" type=\"divergence\">"),
            std::string::npos)
      << xml;
  EXPECT_NE(xml.find("first difference: bodies[551].position.x"), std::string::npos) << xml;
  EXPECT_NE(xml.find("<error message=\"cannot be verified\" type=\"unreadable\">"),
            std::string::npos)
      << xml;
  EXPECT_EQ(xml.find("notes.txt"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fulcrum
