// fulcrum replay record|verify|info: replay files (proto/convert/replay.h).
#include <cstdio>
#include <limits>
#include <ostream>

#include <fstream>

#include "command.h"
#include "edit_convert.h"
#include "remote.h"
#include "replay.h"
#include "snapshot_convert.h"

namespace fulcrum::cli {

namespace {

int record(const Invocation& inv) {
  std::string error;
  const std::optional<std::string> ticks_text = inv.args.value("ticks");
  if (!ticks_text) return inv.usage_error("record: missing --ticks N");
  const std::optional<int64_t> ticks = parse_int(*ticks_text, 0, int64_t{1} << 40, &error);
  if (!ticks) return inv.usage_error("--ticks: " + error);
  const std::optional<std::string> out = inv.args.value("out");
  if (!out) return inv.usage_error("record: missing --out FILE");
  int64_t keyframes = 60;
  if (auto k = inv.args.value("keyframes")) {
    auto parsed = parse_int(*k, 0, std::numeric_limits<uint32_t>::max(), &error);
    if (!parsed) return inv.usage_error("--keyframes: " + error);
    keyframes = *parsed;
  }
  v1::EditScript script;
  if (auto edits = inv.args.value("edits")) {
    Result<v1::EditScript> loaded = load_edit_script(*edits);
    if (!loaded.ok()) return inv.fail(loaded.status().message());
    script = std::move(loaded).value();
  }
  LoadedScene loaded;
  int exit_code = kExitOk;
  if (!load_scene_from_args(inv, &loaded, &exit_code)) return exit_code;
  Result<World> world = build_world(loaded.scene);
  if (!world.ok()) return inv.fail(world.status().message());

  ReplayOptions options;
  options.keyframe_interval = static_cast<uint32_t>(keyframes);
  options.scene = loaded.label;
  auto writer = ReplayWriter::open(*out, *world, options);
  if (!writer.ok()) return inv.fail(writer.status().message());
  int next = 0;
  for (int64_t i = 0; i < *ticks; ++i) {
    std::vector<v1::EditBatch> batches;
    for (; next < script.entries_size() && script.entries(next).tick() <= world->tick(); ++next) {
      const v1::TimedEdits& e = script.entries(next);
      if (e.tick() < world->tick()) continue;
      Result<EditOutcome> applied = apply_edit_batch(&*world, e.batch());
      if (!applied.ok()) {
        return inv.fail("edit script entry for tick " + std::to_string(e.tick()) + ": " +
                        applied.status().message());
      }
      batches.push_back(e.batch());
    }
    world->step();
    Status st = (*writer)->record_tick(*world, batches);
    if (!st.ok()) return inv.fail(st.message());
  }
  Status st = (*writer)->close();
  if (!st.ok()) return inv.fail(st.message());
  inv.out << "recorded " << *ticks << " ticks of " << loaded.label << " to " << *out
          << "\nfinal tick " << world->tick() << ", state hash " << hex64(world->state_hash())
          << "\n";
  return kExitOk;
}

int verify(const Invocation& inv, const std::string& path) {
  Result<ReplayContents> replay = read_replay(path);
  if (!replay.ok()) return inv.fail(replay.status().message());
  Result<ReplayReport> report = verify_replay(*replay);
  if (!report.ok()) return inv.fail(path + ": " + report.status().message());
  if (replay->truncated) {
    inv.err << "fulcrum replay: note: " << path
            << " ends inside a record (cut off mid-write); verified up to its last complete "
               "tick\n";
  }
  if (!report->ok) {
    inv.err << "fulcrum replay: " << path << ": DIVERGED at tick " << report->first_divergent_tick
            << ": " << report->detail << "\n";
    return kExitError;
  }
  inv.out << path << ": OK: " << report->ticks_checked << " ticks match, final tick "
          << report->final_tick << ", state hash " << hex64(report->final_hash) << "\n";
  return kExitOk;
}

int info(const Invocation& inv, const std::string& path) {
  Result<ReplayContents> replay = read_replay(path);
  if (!replay.ok()) return inv.fail(replay.status().message());
  const ReplayContents& r = *replay;
  int bodies = 0;
  int64_t first_tick = 0;
  {
    Result<v1::Snapshot> initial = unwrap_snapshot(r.header.initial());
    if (!initial.ok()) return inv.fail(path + ": initial snapshot: " + initial.status().message());
    for (const v1::SnapshotBody& b : initial->bodies()) bodies += b.alive() ? 1 : 0;
    first_tick = initial->tick();
  }
  int keyframes = 0, batches = 0;
  for (const v1::ReplayTick& t : r.ticks) {
    keyframes += t.has_keyframe() ? 1 : 0;
    batches += t.edits_size();
  }
  inv.out << "replay      " << path << "\n"
          << "writer      " << r.header.writer() << " (format version " << r.header.version()
          << ")\n"
          << "scene       " << r.header.scene() << "\n"
          << "bodies      " << bodies << " at tick " << first_tick << "\n"
          << "ticks       " << r.ticks.size() << "\n"
          << "edit batches " << batches << "\n"
          << "keyframes   " << keyframes << " (every " << r.header.keyframe_interval()
          << " ticks)\n";
  if (!r.ticks.empty()) {
    inv.out << "final tick  " << r.ticks.back().tick() << "\n"
            << "final hash  " << hex64(r.ticks.back().state_hash()) << "\n";
  }
  if (r.truncated) inv.out << "truncated   yes (cut off mid-write; read up to the last tick)\n";
  return kExitOk;
}

// --- On a fulcrum-server: start, stop, download ---

int server_start(const Invocation& inv, client::Client* client, uint64_t world) {
  std::optional<uint32_t> keyframes;
  if (auto k = inv.args.value("keyframes")) {
    std::string error;
    auto parsed = parse_int(*k, 0, std::numeric_limits<uint32_t>::max(), &error);
    if (!parsed) return inv.usage_error("--keyframes: " + error);
    keyframes = static_cast<uint32_t>(*parsed);
  }
  Result<client::RecordingResult> r = client->start_recording(world, keyframes);
  if (!r.ok()) return inv.fail(r.status().message());
  inv.out << "world " << world << ": recording " << r->name << " from tick " << r->tick << "\n";
  return kExitOk;
}

int server_stop(const Invocation& inv, client::Client* client, uint64_t world) {
  Result<client::RecordingResult> r = client->stop_recording(world);
  if (!r.ok()) return inv.fail(r.status().message());
  inv.out << "world " << world << ": recording " << r->name << " closed: " << r->ticks << " ticks, "
          << r->bytes << " bytes\n";
  return kExitOk;
}

int server_download(const Invocation& inv, client::Client* client, const std::string& what) {
  const std::optional<std::string> out = inv.args.value("out");
  if (!out) return inv.usage_error("download: missing --out FILE");
  // A whole number names a world (its current or last recording); anything else a replay.
  std::string error;
  std::optional<int64_t> world = parse_int(what, 1, std::numeric_limits<int64_t>::max(), &error);
  std::ofstream file(*out, std::ios::binary | std::ios::trunc);
  if (!file) return inv.fail(*out + ": cannot write");
  Result<client::DownloadResult> r = client->download_replay(
      world ? static_cast<uint64_t>(*world) : 0, world ? std::string() : what,
      [&](std::string_view chunk) {
        file.write(chunk.data(), static_cast<std::streamsize>(chunk.size()));
        return file ? Status() : Status(StatusCode::kInternal, *out + ": write failed");
      });
  file.close();
  if (!r.ok()) {
    std::remove(out->c_str());
    return inv.fail(r.status().message());
  }
  if (!file) return inv.fail(*out + ": write failed");
  inv.out << "downloaded " << r->name << ": " << r->bytes << " bytes to " << *out << " (checksum "
          << hex64(r->checksum) << " matches the server's)\n";
  return kExitOk;
}

int on_server(const Invocation& inv, const std::string& action) {
  const auto& pos = inv.args.positional();
  if (pos.size() != 2) {
    return inv.usage_error(action + ": expected " +
                           (action == "download" ? "WORLD or NAME" : "WORLD"));
  }
  int exit_code = kExitOk;
  std::optional<uint64_t> world;
  if (action != "download") {
    world = world_arg(inv, 1, &exit_code);
    if (!world) return exit_code;
  }
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  if (action == "start") return server_start(inv, client.get(), *world);
  if (action == "stop") return server_stop(inv, client.get(), *world);
  return server_download(inv, client.get(), pos[1]);
}

}  // namespace

int run_replay(const Invocation& inv) {
  const auto& pos = inv.args.positional();
  if (pos.empty()) {
    return inv.usage_error("missing action: record, verify, info, start, stop or download");
  }
  const std::string& action = pos[0];
  if (action == "record") {
    if (pos.size() > 1) return inv.usage_error("record takes no FILE argument (use --out)");
    return record(inv);
  }
  if (action == "verify" || action == "info") {
    if (pos.size() != 2) return inv.usage_error(action + ": expected one replay FILE");
    return action == "verify" ? verify(inv, pos[1]) : info(inv, pos[1]);
  }
  if (action == "start" || action == "stop" || action == "download") return on_server(inv, action);
  return inv.usage_error("unknown action '" + action +
                         "' (record, verify, info, start, stop or download)");
}

}  // namespace fulcrum::cli
