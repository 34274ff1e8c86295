// fulcrum_fuzz_seeds DIR: writes a seed corpus for every fuzz target into DIR/<target>/ (made
// fresh each time from the built-in scenes, so the repository keeps only its findings, in
// tests/fuzz/findings/). Each seed is a valid input that reaches deep into its decoder: small
// built-in scenes, edit batches of every kind against the base worlds' own handles, snapshots
// and deltas of them, a recorded replay, frames of both kinds, and server call sequences.
#include <google/protobuf/text_format.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "fulcrum/fingerprint.h"
#include "fulcrum/scenes.h"
#include "fulcrum/v1/frames.pb.h"
#include "fulcrum/v1/service.pb.h"
#include "fulcrum/v1/session.pb.h"
#include "fuzz_worlds.h"
#include "replay.h"
#include "scene_convert.h"
#include "snapshot_convert.h"

namespace {

using namespace fulcrum;
namespace fs = std::filesystem;

fs::path out_dir;

void write(const std::string& target, const std::string& name, const std::string& bytes) {
  const fs::path dir = out_dir / target;
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary) << bytes;
}

template <typename Message>
Message from_text(const std::string& text) {
  Message m;
  fuzz::check(google::protobuf::TextFormat::ParseFromString(text, &m), "seed text: " + text);
  return m;
}

std::string handle(const BodyId& id) {
  return "{ index: " + std::to_string(id.index) + " generation: " + std::to_string(id.generation) +
         " }";
}

// Built-in scenes of at most 120 bodies (the fuzz limits allow 512).
std::vector<std::pair<std::string, SceneDef>> small_scenes() {
  std::vector<std::pair<std::string, SceneDef>> out;
  for (const std::string& name : scenes::builtin_names()) {
    Result<SceneDef> scene = scenes::builtin(name);
    if (scene.ok() && scene->bodies.size() <= 120) out.emplace_back(name, *scene);
  }
  return out;
}

// One batch per edit kind, and one of several kinds, against a base world's handles.
std::vector<std::string> edit_batches(World& w) {
  const std::vector<BodyId> bodies = w.bodies();
  const std::string a = handle(bodies[1 % bodies.size()]);
  const std::string b = handle(bodies[2 % bodies.size()]);
  std::string shape = "{ index: 0 generation: 1 }";
  if (Result<std::vector<ShapeId>> shapes = w.body_shapes(bodies[1 % bodies.size()]);
      shapes.ok() && !shapes->empty()) {
    shape = "{ index: " + std::to_string((*shapes)[0].index) +
            " generation: " + std::to_string((*shapes)[0].generation) + " }";
  }
  const std::string joint = "{ index: 0 generation: 1 }";
  return {
      "edits { set_velocity { body: " + a + " linear { x: 3 y: -1 } angular: 2 } }",
      "edits { apply_impulse { body: " + a + " impulse { x: 5 y: 9 } point { x: 0.1 y: 1 } } }",
      "edits { apply_force { body: " + b + " force { x: -40 y: 0 } } }",
      "edits { apply_torque { body: " + b + " torque: 12 } }",
      "edits { set_transform { body: " + a + " position { x: 2 y: 6 } angle: 0.5 } }",
      "edits { set_awake { body: " + b + " awake: false } }",
      "edits { destroy_body: " + a + " }",
      "edits { destroy_shape: " + shape + " }",
      "edits { set_material { shape: " + shape + " friction: 0.1 restitution: 0.9 } }",
      "edits { set_filter { shape: " + shape + " filter { category_bits: 2 mask_bits: 5 } } }",
      "edits { set_gravity { x: 1 y: -3 } }",
      "edits { set_settings { substeps: 2 contact_hertz: 20 } }",
      "edits { destroy_joint: " + joint + " }",
      "edits { set_motor { joint: " + joint + " speed: 3 } }",
      "edits { set_joint_target { joint: " + joint + " target { x: 1 y: 4 } } }",
      "edits { create_body { type: BODY_TYPE_DYNAMIC position { x: 0 y: 8 } shapes { circle { "
      "radius: 0.5 } } } }",
      "edits { create_body { type: BODY_TYPE_DYNAMIC position { x: 1 y: 9 } shapes { box { "
      "half_width: 0.5 half_height: 0.25 } density: 3 } shapes { capsule { center1 { x: -0.5 } "
      "center2 { x: 0.5 } radius: 0.2 } } } }",
      "edits { create_shape { body: " + a +
          " shape { polygon { vertices { x: 0 y: 0 } vertices { x: 1 y: 0 } vertices { x: 0 y: 1 "
          "} } } } }",
      "edits { create_shape { body: " + b +
          " shape { segment { point1 { x: 0 } point2 { x: 2 } "
          "} } } }",
      "edits { create_joint { body_a: " + a + " body_b: " + b +
          " joint { revolute { enable_motor: true motor_speed: 1 max_motor_torque: 50 } } } }",
      "edits { create_joint { body_a: " + a + " body_b: " + b +
          " joint { distance { length: 2 "
          "} } } }",
      "edits { create_joint { body_a: " + a + " body_b: " + b + " joint { weld { } } } }",
      "edits { create_joint { body_a: " + a + " body_b: " + b +
          " joint { prismatic { local_axis_a { x: 1 } enable_limit: true lower_translation: -1 "
          "upper_translation: 1 } } "
          "} }",
      "edits { create_joint { body_a: " + a + " body_b: " + b +
          " joint { wheel { local_axis_a { y: 1 } } } } }",
      "edits { create_joint { body_a: " + a + " body_b: " + b + " joint { motor { } } } }",
      "edits { set_velocity { body: " + a + " linear { x: 1 } } } edits { apply_torque { body: " +
          b + " torque: 3 } } edits { destroy_body: " + b + " }",
  };
}

std::string with_length(int method, const std::string& bytes) {
  std::string out;
  out.push_back(static_cast<char>(method));
  out.push_back(static_cast<char>(bytes.size() & 0xff));
  out.push_back(static_cast<char>((bytes.size() >> 8) & 0xff));
  return out + bytes;
}

// The dynamic bodies of a world, in index order.
std::vector<BodyId> dynamic_bodies(const World& w) {
  std::vector<BodyId> out;
  for (BodyId id : w.bodies()) {
    if (w.body_state(id)->type == BodyType::kDynamic) out.push_back(id);
  }
  return out;
}

std::string repeated(const std::string& text, int times) {
  std::string out;
  for (int i = 0; i < times; ++i) out += text;
  return out;
}

// Session call sequences (sessions_fuzz.cpp): a base world byte, then calls that open a
// session, join players owning the base world's own bodies and joints, watch as them, send
// inputs (ticks counted from the world's tick, secrets left empty for the player's own) and
// step, so that mutations start from live sessions with inputs in flight.
void session_seeds() {
  const auto call = [](int method, const std::string& bytes) { return with_length(method, bytes); };
  // Turn by turn on the mixed world: two players, every input in, so ticks run as they arrive.
  // (The first byte picks the mixed, bounce or bridge world.)
  {
    World w = fuzz::base_world(2);
    const std::vector<BodyId> bodies = dynamic_bodies(w);
    const std::string a = handle(bodies[0]);
    const std::string b = handle(bodies[1 % bodies.size()]);
    const std::string fingerprint =
        std::string(" fingerprint: \"") + kDeterminismFingerprint + "\"";
    write(
        "sessions", "turns",
        std::string(1, '\0') +
            call(0, from_text<v1::OpenSessionRequest>(
                        "world_id: 1 options { max_players: 2 seal: SEAL_RULE_ALL_INPUTS }")
                        .SerializeAsString()) +
            call(1, from_text<v1::JoinSessionRequest>("world_id: 1 name: \"a\"" + fingerprint +
                                                      " bodies " + a)
                        .SerializeAsString()) +
            call(1, from_text<v1::JoinSessionRequest>("world_id: 1 name: \"b\" bodies " + b)
                        .SerializeAsString()) +
            call(1,
                 from_text<v1::JoinSessionRequest>("world_id: 1 name: \"c\"").SerializeAsString()) +
            call(4, from_text<v1::WatchSessionRequest>("world_id: 1 player_id: 1")
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 1 input { edits { set_velocity { body: " + a +
                        " linear { x: 2 y: 1 } angular: 1 } } }")
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 2 input { edits { apply_impulse { body: " + b +
                        " impulse { x: -3 y: 4 } point { x: 0.1 } angular_impulse: 0.5 } } }")
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 2 tick: 1 input { edits { apply_torque { body: " +
                        b + " torque: 5 } } }")
                        .SerializeAsString()) +
            call(5, std::string(1, '\0')) +
            call(2, from_text<v1::SendInputRequest>("world_id: 1 player_id: 1 tick: 1")
                        .SerializeAsString()) +
            call(3, from_text<v1::StepRequest>("world_id: 1 ticks: 2").SerializeAsString()) +
            // The owner gives player 1's body to player 2, who pushes it; then takes it back.
            call(8, from_text<v1::SetOwnershipRequest>("world_id: 1 player_id: 2 bodies " + a)
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 2 tick: 1 input { edits { set_velocity { body: " +
                        a + " linear { x: -1 } } } }")
                        .SerializeAsString()) +
            call(8, from_text<v1::SetOwnershipRequest>("world_id: 1 bodies " + a + " bodies " + a)
                        .SerializeAsString()) +
            call(
                8,
                from_text<v1::SetOwnershipRequest>("world_id: 1 bodies " + a).SerializeAsString()) +
            call(3, from_text<v1::StepRequest>("world_id: 1 ticks: 1").SerializeAsString()));
  }
  // On the clock of Step on the bridge: an input delay, the last input repeated, a joint owned,
  // and the owner destroying a player's body with an input for it in flight.
  {
    World w = fuzz::base_world(0);
    const std::vector<BodyId> bodies = dynamic_bodies(w);
    const std::vector<JointId> joints = w.joints();
    const std::string a = handle(bodies[0]);
    const std::string b = handle(bodies[1 % bodies.size()]);
    const std::string j = joints.empty()
                              ? std::string("{ index: 0 generation: 1 }")
                              : "{ index: " + std::to_string(joints[0].index) +
                                    " generation: " + std::to_string(joints[0].generation) + " }";
    write(
        "sessions", "clock",
        std::string(1, '\2') +
            call(0, from_text<v1::OpenSessionRequest>(
                        "world_id: 1 options { input_delay: 2 missing_input: "
                        "MISSING_INPUT_REPEAT_LAST max_input_lead: 8 }")
                        .SerializeAsString()) +
            call(1, from_text<v1::JoinSessionRequest>("world_id: 1 bodies " + a + " bodies " + b +
                                                      " joints " + j)
                        .SerializeAsString()) +
            call(1,
                 from_text<v1::JoinSessionRequest>("world_id: 1 bodies " + b).SerializeAsString()) +
            call(1, from_text<v1::JoinSessionRequest>("world_id: 1 name: \"spectator\"")
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>("world_id: 1 player_id: 1 tick: 1")
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 1 tick: 2 input { edits { apply_force { body: " +
                        a + " force { x: 40 y: 0 } } } edits { set_motor { joint: " + j +
                        " speed: 2 } } }")
                        .SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 1 tick: 3 input { edits { set_joint_target { "
                        "joint: " +
                        j + " target { x: 1 y: 2 } } } }")
                        .SerializeAsString()) +
            call(3, from_text<v1::StepRequest>("world_id: 1 ticks: 3").SerializeAsString()) +
            call(2, from_text<v1::SendInputRequest>(
                        "world_id: 1 player_id: 1 tick: 2 input { edits { set_velocity { body: " +
                        b + " linear { y: 3 } } } }")
                        .SerializeAsString()) +
            call(6, from_text<v1::ApplyEditsRequest>(
                        "world_id: 1 batch { edits { destroy_body: " + b + " } }")
                        .SerializeAsString()) +
            call(3, from_text<v1::StepRequest>("world_id: 1 ticks: 4").SerializeAsString()));
  }
  // Refusals: a second world, another engine's fingerprint, a long name, a wrong secret, a tick
  // sealed and one too far, too many edits; and a duplicate input.
  write(
      "sessions", "refusals",
      std::string(1, '\1') + call(7, std::string(1, '\0')) +
          call(0, from_text<v1::OpenSessionRequest>("world_id: 2").SerializeAsString()) +
          call(1, from_text<v1::JoinSessionRequest>("world_id: 2 fingerprint: \"other\"")
                      .SerializeAsString()) +
          call(1, from_text<v1::JoinSessionRequest>("world_id: 2 name: \"" + std::string(65, 'n') +
                                                    "\"")
                      .SerializeAsString()) +
          call(1, from_text<v1::JoinSessionRequest>("world_id: 2").SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>("world_id: 2 player_id: 1 tick: -1")
                      .SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>("world_id: 2 player_id: 1 input { " +
                                                  repeated("edits { } ", 65) + "}")
                      .SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>("world_id: 2 player_id: 1 tick: 1")
                      .SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>("world_id: 2 player_id: 1 tick: 1")
                      .SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>(
                      "world_id: 2 player_id: 1 player_secret: \"\\x05\\x01\"")
                      .SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>("world_id: 2 player_id: 1 tick: 100000")
                      .SerializeAsString()) +
          call(2, from_text<v1::SendInputRequest>("world_id: 1 player_id: 1").SerializeAsString()) +
          call(3, from_text<v1::StepRequest>("world_id: 2 ticks: 1").SerializeAsString()));
}

// One chunk of a snapshot_stream input (snapshot_stream_fuzz.cpp): flags, offset from the bytes
// sent so far, size, a byte to flip and where, and a value for the fields not set right.
std::string stream_chunk(uint8_t flags, size_t size, uint32_t value = 0) {
  std::string out(12, '\0');
  out[0] = static_cast<char>(flags);
  out[3] = static_cast<char>(size & 0xff);
  out[4] = static_cast<char>((size >> 8) & 0xff);
  for (int i = 0; i < 4; ++i) out[8 + i] = static_cast<char>((value >> (8 * i)) & 0xff);
  return out;
}

// Uploads of a base world's snapshot 5 ticks on, as the target makes them: whole and sound
// (fork and rollback, one chunk or many), with a wrong checksum, and cut short.
void snapshot_stream_seeds() {
  constexpr uint8_t kFirst = 1, kLast = 2, kChecksum = 4, kTotal = 8;
  // Set-up bytes name the bridge, mixed and bounce worlds 0, 1 and 2.
  for (uint8_t source : {0, 2}) {
    World w = fuzz::base_world(source == 0 ? 0 : 3);
    for (int t = 0; t < 5; ++t) w.step();
    const size_t size = encode_snapshot(w).size();
    // In pieces of `piece` bytes (at most 65535, the size field's range).
    auto upload = [&](size_t piece, bool checksum_right, bool to_the_end) {
      std::string out;
      for (size_t sent = 0; sent < size; sent += piece) {
        const size_t n = std::min(piece, size - sent);
        const bool last = sent + n == size;
        if (last && !to_the_end) break;
        uint8_t flags = sent == 0 ? kFirst | kTotal : 0;
        if (last) flags |= kLast | (checksum_right ? kChecksum : 0);
        out += stream_chunk(flags, n, 12345);
      }
      return out;
    };
    const std::string name = source == 0 ? "bridge" : "bounce";
    const auto setup = [&](uint8_t base, bool rollback, bool download) {
      return std::string(
          1, static_cast<char>(base | (rollback ? 4 : 0) | (download ? 8 : 0) | (source << 4)));
    };
    write("snapshot_stream", name + "_fork", setup(2, false, false) + upload(60000, true, true));
    write("snapshot_stream", name + "_rollback",
          setup(source == 0 ? 1 : 0, true, true) + upload(4096, true, true));
    write("snapshot_stream", name + "_bad_checksum",
          setup(1, true, false) + upload(8192, false, true));
    write("snapshot_stream", name + "_cut_short",
          setup(2, false, false) + upload(size / 4 + 1, true, false));
    // A StepTrajectory on the mixed world first (set-up bit 6), sampling two bodies every 3
    // ticks, or every body every tick; then the upload.
    World mixed = fuzz::base_world(2);
    const std::vector<BodyId> bodies = dynamic_bodies(mixed);
    const std::string trajectory =
        source == 0
            ? from_text<v1::StepTrajectoryRequest>(
                  "world_id: 1 ticks: 10 every_ticks: 3 include_start: true bodies " +
                  handle(bodies[0]) + " bodies " + handle(bodies[1]))
                  .SerializeAsString()
            : from_text<v1::StepTrajectoryRequest>("world_id: 1 ticks: 4").SerializeAsString();
    write("snapshot_stream", name + "_after_trajectory",
          std::string(1, static_cast<char>(0x40 | 1 | (source << 4))) +
              static_cast<char>(trajectory.size() & 0xff) +
              static_cast<char>((trajectory.size() >> 8) & 0xff) + trajectory +
              upload(60000, true, true));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fulcrum_fuzz_seeds DIR\n");
    return 2;
  }
  out_dir = argv[1];
  const auto scenes = small_scenes();
  for (const auto& [name, scene] : scenes) {
    write("scene_json", name + ".json", scene_to_json(scene, name));
    write("scene_proto", name + ".pb", scene_to_proto(scene, name).SerializeAsString());
  }
  write("scene_proto", "builders.pb",
        from_text<v1::Scene>("builders { ground { half_width: 20 } } builders { pyramid { base: "
                             "4 } } builders { stack { count: 3 origin { x: 8 } } }")
            .SerializeAsString());

  const std::vector<fuzz::BaseWorld>& bases = fuzz::base_worlds();
  for (size_t bi = 0; bi < bases.size(); ++bi) {
    World w = fuzz::base_world(static_cast<uint8_t>(bi));
    const std::vector<std::string> batches = edit_batches(w);
    for (size_t i = 0; i < batches.size(); ++i) {
      write("edits", bases[bi].name + "_" + std::to_string(i),
            std::string(1, static_cast<char>(bi)) +
                from_text<v1::EditBatch>(batches[i]).SerializeAsString());
    }
    // Snapshots of the world a few ticks on, in each of the target's three forms.
    const v1::Snapshot base = snapshot_to_proto(w.snapshot());
    for (int t = 0; t < 5; ++t) w.step();
    const v1::Snapshot next = snapshot_to_proto(w.snapshot());
    const auto prefix = [&](int form) { return std::string(1, static_cast<char>(form + 3 * bi)); };
    write("snapshot", bases[bi].name + "_file",
          prefix(0) + wrap_snapshot(next).SerializeAsString());
    write("snapshot", bases[bi].name + "_payload", prefix(1) + next.SerializeAsString());
    write("snapshot", bases[bi].name + "_delta",
          prefix(2) + make_delta(base, next).SerializeAsString());
  }

  // A replay of the bounce world (small, so that fuzzing it is fast): 24 ticks, a keyframe
  // every 8, edits at two ticks.
  {
    World w = fuzz::base_world(3);
    const std::string path = (out_dir / "seed.replay").string();
    ReplayOptions options;
    options.keyframe_interval = 8;
    auto writer = ReplayWriter::open(path, w, options);
    fuzz::check(writer.ok(), "replay writer: " + writer.status().message());
    const std::vector<std::string> batches = edit_batches(w);
    for (int t = 0; t < 24; ++t) {
      std::vector<v1::EditBatch> applied;
      if (t == 3 || t == 11) {
        applied.push_back(from_text<v1::EditBatch>(batches[t == 3 ? 0 : 15]));
        fuzz::check(apply_edit_batch(&w, applied.back()).ok(), "replay seed edits apply");
      }
      w.step();
      fuzz::check((*writer)->record_tick(w, applied).ok(), "replay seed records");
    }
    fuzz::check((*writer)->close().ok(), "replay seed closes");
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    fs::remove(path);
    write("replay", "bounce_raw", std::string(1, '\0') + bytes);
    write("replay", "bounce_fixed", std::string(1, '\1') + bytes);
  }

  write("frames", "exact",
        from_text<v1::Frame>("world_id: 1 tick: 40 state_hash: 77 body_count: 2 full: true "
                             "bodies { body { index: 1 generation: 1 } position { x: 1 y: 2 } "
                             "angle: 0.5 linear_velocity { x: -1 } angular_velocity: 3 awake: "
                             "true } bodies { body { index: 2 generation: 1 } }")
            .SerializeAsString());
  write("frames", "quantized",
        from_text<v1::Frame>("world_id: 1 tick: 41 quantized_bodies { index: 1 generation: 1 "
                             "x: 4096 y: -8192 angle: 16384 vx: 1024 vy: 0 angular_velocity: "
                             "-2048 awake: true } quantized_bodies { index: 3 generation: 2 } "
                             "bodies { body { index: 2 generation: 1 } position { x: 1e9 } } "
                             "destroyed { index: 4 generation: 1 }")
            .SerializeAsString());

  // Server calls: create a world, edit, step, snapshot, fork, query, delete.
  {
    const SceneDef& bridge = scenes[0].second;
    v1::CreateWorldRequest create;
    *create.mutable_scene() = scene_to_proto(bridge, scenes[0].first);
    v1::CreateWorldRequest builtin;
    builtin.mutable_scene()->set_builtin("bounce");
    World w = fuzz::base_world(0);
    const std::string edits = "world_id: 1 batch { " + edit_batches(w)[1] + " }";
    v1::RestoreSnapshotRequest fork;
    *fork.mutable_snapshot() = wrap_snapshot(snapshot_to_proto(w.snapshot()));
    v1::RestoreSnapshotRequest rollback = fork;
    rollback.set_world_id(1);
    std::string calls =
        with_length(0, create.SerializeAsString()) +
        with_length(4, from_text<v1::ApplyEditsRequest>(edits).SerializeAsString()) +
        with_length(5, from_text<v1::StepRequest>("world_id: 1 ticks: 3 "
                                                  "include_snapshot: true")
                           .SerializeAsString()) +
        with_length(2, from_text<v1::GetWorldRequest>("world_id: 1").SerializeAsString()) +
        with_length(6, from_text<v1::GetSnapshotRequest>("world_id: 1").SerializeAsString()) +
        with_length(7, fork.SerializeAsString()) +
        with_length(8, from_text<v1::QueryRequest>("world_id: 2 ray_cast { origin { x: -5 y: 5 } "
                                                   "translation { x: 10 y: -5 } all: true }")
                           .SerializeAsString()) +
        with_length(
            8, from_text<v1::QueryRequest>("world_id: 1 aabb { lower { x: -2 y: -2 } upper { x: "
                                           "2 y: 2 } }")
                   .SerializeAsString()) +
        with_length(1, "") + with_length(9, "") +
        with_length(3, from_text<v1::DeleteWorldRequest>("world_id: 2").SerializeAsString());
    write("requests", "bridge_session", calls);
    write("requests", "builtin_rollback",
          with_length(0, builtin.SerializeAsString()) +
              with_length(7, rollback.SerializeAsString()) +
              with_length(5, from_text<v1::StepRequest>("world_id: 1 ticks: 2 expected_tick: 40")
                                 .SerializeAsString()));
  }
  session_seeds();
  snapshot_stream_seeds();
  std::printf("seeds written to %s\n", out_dir.c_str());
  return 0;
}
