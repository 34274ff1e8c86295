// `fulcrum sim` as a user runs it: the figures it reports over a run, its trace file and its
// --set overrides, each checked against the engine driven directly. The CLI and this test run
// the same engine build on the same scene, so every figure must agree to the bit: the JSON
// report prints doubles in their shortest round-trip form and the trace with 17 significant
// digits, both of which read back exactly.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "edit_convert.h"
#include "fulcrum/world.h"
#include "scene_convert.h"

namespace fulcrum {
namespace {

const std::string kScenes = FULCRUM_SCENES_DIR;
const std::string kData = FULCRUM_TEST_DATA_DIR;

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("fulcrum_sim_cli_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Runs the CLI with `args`; returns its stdout and sets *code to its exit code.
std::string run_cli(const std::string& args, int* code) {
  const std::string out = temp_path("stdout.txt");
  const std::string command = std::string(FULCRUM_CLI) + " " + args + " > " + out + " 2>&1";
  const int status = std::system(command.c_str());
  *code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return read_file(out);
}

// The number after "key": in `json`, from position `from` on (the "run" object holds keys that
// the top level has too). NaN when missing; -1 for null.
double json_number(const std::string& json, const std::string& key, size_t from = 0) {
  const size_t at = json.find("\"" + key + "\":", from);
  if (at == std::string::npos) return std::nan("");
  const char* p = json.c_str() + at + key.size() + 3;
  if (std::string_view(p, 4) == "null") return -1.0;
  return std::strtod(p, nullptr);
}

std::string hash_of(const std::string& json) {
  const size_t at = json.find("\"stateHash\":\"");
  return at == std::string::npos ? "" : json.substr(at + 13, 16);
}

World build(const std::string& path, const WorldSettings* settings = nullptr) {
  Result<SceneDef> scene = load_scene_json(path);
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  if (settings != nullptr) scene->settings = *settings;
  Result<World> world = build_world(*scene);
  EXPECT_TRUE(world.ok()) << world.status().message();
  return std::move(world).value();
}

// The run figures: the largest penetration, joint error and speed with their ticks, and the
// split of ticks into awake and asleep, equal those of a direct loop over World::metrics().
TEST(SimCli, RunFiguresEqualADirectEngineLoop) {
  const std::string pyramid = kScenes + "/pyramid.json";
  int code = 0;
  const std::string json = run_cli("sim --scene " + pyramid + " --ticks 300 --json", &code);
  ASSERT_EQ(code, 0) << json;
  const size_t run = json.find("\"run\":{");
  ASSERT_NE(run, std::string::npos) << json;

  World w = build(pyramid);
  double pen = 0.0, pen_late = 0.0, speed = 0.0, joint = 0.0;
  int64_t pen_tick = -1, pen_late_tick = -1, speed_tick = -1, asleep = 0;
  const double e0 = w.metrics().kinetic_energy + w.metrics().potential_energy;
  double loss = 0.0;
  for (int i = 0; i < 300; ++i) {
    asleep += w.metrics().awake_body_count == 0 ? 1 : 0;
    w.step();
    const WorldMetrics m = w.metrics();
    if (m.max_penetration > pen) pen = m.max_penetration, pen_tick = m.tick;
    if (m.tick > 60 && m.max_penetration > pen_late)
      pen_late = m.max_penetration, pen_late_tick = m.tick;
    if (m.max_speed > speed) speed = m.max_speed, speed_tick = m.tick;
    joint = std::max(joint, m.max_joint_error);
    loss = std::max(loss, e0 - (m.kinetic_energy + m.potential_energy));
  }
  EXPECT_NE(json.find("\"stateHash\":\"" + World::hash_text(w.state_hash()) + "\""),
            std::string::npos);
  EXPECT_GT(pen, 0.0);  // the boxes do overlap: the comparison below is not 0 == 0
  EXPECT_EQ(json_number(json, "maxPenetration", run), pen);
  EXPECT_EQ(json_number(json, "maxPenetrationTick", run), pen_tick);
  EXPECT_EQ(json_number(json, "maxPenetrationAfterFirstSecond", run), pen_late);
  EXPECT_EQ(json_number(json, "maxPenetrationAfterFirstSecondTick", run), pen_late_tick);
  EXPECT_EQ(json_number(json, "maxSpeed", run), speed);
  EXPECT_EQ(json_number(json, "maxSpeedTick", run), speed_tick);
  EXPECT_EQ(json_number(json, "maxJointError", run), 0.0);
  EXPECT_EQ(json_number(json, "maxJointErrorTick", run), -1.0);  // null: no joints
  EXPECT_EQ(json_number(json, "initialEnergy", run), e0);
  EXPECT_EQ(json_number(json, "maxEnergyLoss", run), loss);
  // The pyramid settles and sleeps: both kinds of tick occur.
  EXPECT_GT(asleep, 0);
  EXPECT_EQ(json_number(json, "asleepTicks", run), asleep);
  EXPECT_EQ(json_number(json, "awakeTicks", run), 300 - asleep);
}

// The same on a jointed scene: the largest joint error over the run and its tick.
TEST(SimCli, LargestJointErrorEqualsADirectEngineLoop) {
  const std::string bridge = kScenes + "/bridge.json";
  int code = 0;
  const std::string json = run_cli("sim --scene " + bridge + " --ticks 120 --json", &code);
  ASSERT_EQ(code, 0) << json;
  const size_t run = json.find("\"run\":{");
  World w = build(bridge);
  double joint = 0.0;
  int64_t joint_tick = -1;
  for (int i = 0; i < 120; ++i) {
    w.step();
    if (w.metrics().max_joint_error > joint)
      joint = w.metrics().max_joint_error, joint_tick = w.tick();
  }
  EXPECT_GT(joint, 0.0);
  EXPECT_EQ(json_number(json, "maxJointError", run), joint);
  EXPECT_EQ(json_number(json, "maxJointErrorTick", run), joint_tick);
}

// A frictionless ball with restitution 1 bouncing for 10 s never gains energy, and loses exactly
// what the integrator's measured energy loses in free flight: semi-implicit Euler over a
// substep h gives E' - E = -m g^2 h^2 / 2 (v' = v - g h, y' = y + v' h), so the bound over N
// ticks of S substeps is N S m g^2 h^2 / 2. The ticks in contact lose a little less (measured:
// 99.2 % of the bound), so the loss is within [97 %, 100 %] of it.
TEST(SimCli, ElasticBallEnergyDriftIsTheIntegratorsOwn) {
  const std::string ball = kData + "/elastic_ball.json";
  int code = 0;
  const std::string json = run_cli("sim --scene " + ball + " --ticks 600 --json", &code);
  ASSERT_EQ(code, 0) << json;
  const size_t run = json.find("\"run\":{");
  World w = build(ball);
  const WorldSettings& s = w.settings();
  const double mass = w.body_state(BodyId{1, 1})->mass;
  const double h = s.dt / s.substeps;
  const double g = -s.gravity.y();
  const double bound = 600.0 * s.substeps * mass * g * g * h * h / 2.0;
  const double e0 = json_number(json, "initialEnergy", run);
  EXPECT_EQ(json_number(json, "maxEnergyGain", run), 0.0);
  EXPECT_EQ(json_number(json, "maxEnergyGainTick", run), -1.0);
  const double loss = json_number(json, "maxEnergyLoss", run);
  EXPECT_LE(loss, bound * (1.0 + 1e-12));
  EXPECT_GE(loss, 0.97 * bound);
  EXPECT_LT(loss / e0, 0.05);  // small: 4 % of E0 after 10 s
  // It bounced: the ball came back up more than once (speed 0 at an apex, not at rest).
  EXPECT_GT(json_number(json, "maxSpeed", run), 9.0);
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

std::vector<std::string> cells(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  for (std::string cell; std::getline(in, cell, ',');) out.push_back(cell);
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

// --trace writes one row every K ticks (ticks / K rows after the header), each with the state
// hash of its tick and the traced bodies' exact states.
TEST(SimCli, TraceHasARowEveryKTicksWithExactStates) {
  const std::string pyramid = kScenes + "/pyramid.json";
  const std::string csv = temp_path("trace.csv");
  int code = 0;
  const std::string out = run_cli("sim --scene " + pyramid + " --ticks 100 --trace " + csv +
                                      " --trace-every 7 --trace-bodies 3,210",
                                  &code);
  ASSERT_EQ(code, 0) << out;
  const std::vector<std::string> rows = lines(read_file(csv));
  ASSERT_EQ(rows.size(), 1u + 100 / 7);
  EXPECT_EQ(rows[0].rfind("tick,state_hash,awake_bodies,contacts,max_penetration,", 0), 0u);
  EXPECT_NE(rows[0].find(",b210_x,b210_y,b210_angle,b210_vx,b210_vy,b210_angular_velocity"),
            std::string::npos);
  World w = build(pyramid);
  for (size_t r = 1; r < rows.size(); ++r) {
    while (w.tick() < static_cast<int64_t>(7 * r)) w.step();
    const std::vector<std::string> c = cells(rows[r]);
    ASSERT_EQ(c.size(), 9u + 2 * 7) << rows[r];
    EXPECT_EQ(std::stoll(c[0]), w.tick());
    EXPECT_EQ(c[1], World::hash_text(w.state_hash()));
    EXPECT_EQ(std::strtod(c[4].c_str(), nullptr), w.metrics().max_penetration);
    const BodyState top = *w.body_state(BodyId{210, 1});
    EXPECT_EQ(std::strtod(c[16].c_str(), nullptr), top.transform.p.x());
    EXPECT_EQ(std::strtod(c[17].c_str(), nullptr), top.transform.p.y());
    EXPECT_EQ(std::strtod(c[20].c_str(), nullptr), top.linear_velocity.y());
  }
}

// A traced body that an edit creates (pyramid_pokes.json creates body 211 at tick 120) has empty
// cells until it exists, and its state after.
TEST(SimCli, TraceFollowsABodyAnEditCreates) {
  const std::string csv = temp_path("created.csv");
  int code = 0;
  const std::string out = run_cli("sim --scene " + kScenes + "/pyramid.json --ticks 210 --edits " +
                                      kScenes + "/edits/pyramid_pokes.json --trace " + csv +
                                      " --trace-every 10 --trace-bodies 211",
                                  &code);
  ASSERT_EQ(code, 0) << out;
  const std::vector<std::string> rows = lines(read_file(csv));
  ASSERT_EQ(rows.size(), 1u + 21);
  for (size_t r = 1; r < rows.size(); ++r) {
    const std::vector<std::string> c = cells(rows[r]);
    ASSERT_EQ(c.size(), 9u + 7) << rows[r];
    EXPECT_EQ(c[9].empty(), r <= 12) << rows[r];  // ticks 10 to 120: not yet created
  }
  // Created at (-6, 30), it has fallen by tick 130.
  const std::vector<std::string> first = cells(rows[13]);
  EXPECT_EQ(std::strtod(first[9].c_str(), nullptr), -6.0);
  EXPECT_LT(std::strtod(first[10].c_str(), nullptr), 30.0);
}

// A .jsonl trace: one object per sample, the same samples.
TEST(SimCli, TraceAsJsonLines) {
  const std::string jsonl = temp_path("trace.jsonl");
  int code = 0;
  const std::string out = run_cli(
      "sim --builtin bounce --ticks 60 --trace " + jsonl + " --trace-every 20 --trace-bodies 1",
      &code);
  ASSERT_EQ(code, 0) << out;
  const std::vector<std::string> rows = lines(read_file(jsonl));
  ASSERT_EQ(rows.size(), 3u);
  for (size_t r = 0; r < rows.size(); ++r) {
    EXPECT_EQ(rows[r].rfind("{\"tick\":" + std::to_string(20 * (r + 1)) + ",\"stateHash\":\"", 0),
              0u)
        << rows[r];
    EXPECT_NE(rows[r].find("\"bodies\":[{\"index\":1,\"generation\":1,\"alive\":true,\"x\":"),
              std::string::npos)
        << rows[r];
  }
}

// --set changes the world's settings before it is built: the run reaches the state of a world
// built with those settings directly, nested fields (gravity.y) included.
TEST(SimCli, SetOverridesTheScenesSettings) {
  const std::string stack = kScenes + "/stack.json";
  int code = 0;
  const std::string json =
      run_cli("sim --scene " + stack +
                  " --ticks 90 --json --set substeps=6 --set joint_hertz=120 --set gravity.y=-4.5"
                  " --set enableSleep=false",
              &code);
  ASSERT_EQ(code, 0) << json;
  Result<SceneDef> scene = load_scene_json(stack);
  ASSERT_TRUE(scene.ok());
  WorldSettings s = scene->settings;
  s.substeps = 6;
  s.joint_hertz = 120.0;
  s.gravity = Vec2(s.gravity.x(), -4.5);
  s.enable_sleep = false;
  World w = build(stack, &s);
  World plain = build(stack);
  for (int i = 0; i < 90; ++i) w.step(), plain.step();
  EXPECT_NE(json.find("\"stateHash\":\"" + World::hash_text(w.state_hash()) + "\""),
            std::string::npos)
      << json;
  EXPECT_NE(w.state_hash(), plain.state_hash());  // the overrides did change the run
}

// replay record takes --set as sim does: the recording reaches sim's state hash and verifies on
// its own (its initial snapshot carries the settings).
TEST(SimCli, ReplayRecordTakesSetAsSimDoes) {
  const std::string replay = temp_path("set.replay");
  const std::string sets = " --set substeps=6 --set gravity.x=1";
  int code = 0;
  const std::string sim = run_cli("sim --builtin vertical_stack --ticks 90 --json" + sets, &code);
  ASSERT_EQ(code, 0) << sim;
  std::string out =
      run_cli("replay record --builtin vertical_stack --ticks 90 --out " + replay + sets, &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("final tick 90, state hash " + hash_of(sim)), std::string::npos) << out;
  out = run_cli("replay verify " + replay, &code);
  EXPECT_EQ(code, 0) << out;
  out = run_cli("replay verify " + replay + " --set substeps=6", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--set is for record only"), std::string::npos) << out;
}

// A number may be a fraction: dt=1/120 is the double 1.0 / 120.0, which prints (shortest form) as
// 0.008333333333333333.
TEST(SimCli, SetTakesFractions) {
  int code = 0;
  const std::string fraction =
      run_cli("sim --builtin bounce --ticks 100 --json --set dt=1/120", &code);
  ASSERT_EQ(code, 0) << fraction;
  const std::string decimal =
      run_cli("sim --builtin bounce --ticks 100 --json --set dt=0.008333333333333333", &code);
  ASSERT_EQ(code, 0) << decimal;
  const std::string plain = run_cli("sim --builtin bounce --ticks 100 --json", &code);
  EXPECT_EQ(hash_of(fraction), hash_of(decimal));
  EXPECT_NE(hash_of(fraction), hash_of(plain));
}

// An edit script that names bodies by scene index runs exactly as the same script with their
// handles (scenes/edits/pyramid_pokes.json), in sim and in a recorded replay.
TEST(SimCli, EditsBySceneIndexEqualEditsByHandle) {
  const std::string pyramid = kScenes + "/pyramid.json";
  int code = 0;
  const std::string by_handle = run_cli("sim --scene " + pyramid + " --ticks 240 --json --edits " +
                                            kScenes + "/edits/pyramid_pokes.json",
                                        &code);
  ASSERT_EQ(code, 0) << by_handle;
  const std::string by_index = run_cli("sim --scene " + pyramid + " --ticks 240 --json --edits " +
                                           kData + "/pyramid_pokes_by_scene_index.json",
                                       &code);
  ASSERT_EQ(code, 0) << by_index;
  const std::string plain = run_cli("sim --scene " + pyramid + " --ticks 240 --json", &code);
  EXPECT_EQ(hash_of(by_index), hash_of(by_handle));
  EXPECT_NE(hash_of(by_index), hash_of(plain));  // the edits did apply
  // The edits count in the run: 212 bodies at the end (one created), energy gained.
  EXPECT_EQ(json_number(by_index, "bodyCount"), 212);
  EXPECT_GT(json_number(by_index, "maxEnergyGain", by_index.find("\"run\":{")), 0.0);
}

// A scene index names a joint too: the bridge's fourth joint, destroyed at tick 10.
TEST(SimCli, EditsNameJointsBySceneIndex) {
  const std::string bridge = kScenes + "/bridge.json";
  const std::string script = temp_path("cut_bridge.json");
  std::ofstream(script) << R"({"entries": [{"tick": 10, "batch": {"edits": [)"
                        << R"({"destroyJoint": {"sceneIndex": 3}}]}}]})";
  int code = 0;
  const std::string json =
      run_cli("sim --scene " + bridge + " --ticks 30 --json --edits " + script, &code);
  ASSERT_EQ(code, 0) << json;
  World w = build(bridge);
  const std::vector<JointId> joints = w.joints();
  for (int i = 0; i < 10; ++i) w.step();
  ASSERT_TRUE(w.destroy_joint(joints[3]).ok());
  for (int i = 10; i < 30; ++i) w.step();
  EXPECT_EQ(hash_of(json), World::hash_text(w.state_hash()));
  EXPECT_EQ(json_number(json, "jointCount"), static_cast<double>(joints.size()));
}

// Only edit scripts resolve scene indices: a batch that still holds one (a client's ApplyEdits)
// is refused whole, naming the field, and the world is unchanged.
TEST(SimCli, ApplyEditBatchRefusesSceneIndices) {
  World w = build(kScenes + "/pyramid.json");
  const uint64_t before = w.state_hash();
  v1::EditBatch batch;
  batch.add_edits()->mutable_set_awake()->mutable_body()->set_index(3);
  batch.mutable_edits(0)->mutable_set_awake()->mutable_body()->set_generation(1);
  batch.add_edits()->mutable_set_velocity()->mutable_body()->set_scene_index(3);
  Result<EditOutcome> out = apply_edit_batch(&w, batch);
  ASSERT_FALSE(out.ok());
  EXPECT_EQ(out.status().message().rfind("edits[1].set_velocity.body.scene_index: ", 0), 0u)
      << out.status().message();
  EXPECT_EQ(w.state_hash(), before);
}

// `replay info --ticks all` lists every tick's state hash, which are those of the engine
// stepping the same scene with the same edits, and each batch at the tick it applied.
TEST(SimCli, ReplayInfoListsEveryTicksHashAndEdits) {
  const std::string pyramid = kScenes + "/pyramid.json";
  const std::string replay = temp_path("pokes.replay");
  int code = 0;
  std::string out = run_cli("replay record --scene " + pyramid + " --ticks 240 --out " + replay +
                                " --edits " + kData + "/pyramid_pokes_by_scene_index.json",
                            &code);
  ASSERT_EQ(code, 0) << out;
  out = run_cli("replay info " + replay + " --ticks all", &code);
  ASSERT_EQ(code, 0) << out;
  const size_t table = out.find("\ntick      state hash");
  ASSERT_NE(table, std::string::npos) << out;
  const std::vector<std::string> rows = lines(out.substr(table + 1));
  ASSERT_EQ(rows.size(), 1u + 240);
  World w = build(pyramid);
  const SceneHandles scene = scene_handles(w);
  EditScriptOptions options;
  options.scene = &scene;
  Result<v1::EditScript> script =
      load_edit_script(kData + "/pyramid_pokes_by_scene_index.json", options);
  ASSERT_TRUE(script.ok()) << script.status().message();
  for (int t = 0; t < 240; ++t) {
    bool edited = false;
    for (const v1::TimedEdits& e : script->entries()) {
      if (e.tick() != t) continue;
      ASSERT_TRUE(apply_edit_batch(&w, e.batch()).ok());
      edited = true;
    }
    w.step();
    const std::string& row = rows[t + 1];
    EXPECT_EQ(row.rfind(std::to_string(w.tick()) + " ", 0), 0u) << row;
    EXPECT_NE(row.find(" " + World::hash_text(w.state_hash()) + " "), std::string::npos) << row;
    EXPECT_EQ(row.find("at tick " + std::to_string(t) + ": {\"edits\":") != std::string::npos,
              edited)
        << row;
  }
}

}  // namespace
}  // namespace fulcrum
