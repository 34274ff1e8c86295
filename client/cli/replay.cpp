// fulcrum replay record|verify|info: replay files (proto/convert/replay.h).
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <ostream>
#include <sstream>
#include <vector>

#include "command.h"
#include "edit_convert.h"
#include "edit_script.h"
#include "remote.h"
#include "replay.h"
#include "set_settings.h"
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
  Result<std::vector<SettingOverride>> overrides = parse_setting_overrides(inv.args.values("set"));
  if (!overrides.ok()) return inv.usage_error(overrides.status().message());
  LoadedScene loaded;
  int exit_code = kExitOk;
  if (!load_scene_from_args(inv, &loaded, &exit_code)) return exit_code;
  // The replay's initial snapshot carries the settings, so verify needs no --set.
  if (Status st = apply_setting_overrides(*overrides, &loaded.scene.settings); !st.ok()) {
    return inv.usage_error(st.message());
  }
  Result<World> world = build_world(loaded.scene);
  if (!world.ok()) return inv.fail(scene_error(loaded, world.status()));
  // Read against the world just built: scene indices name its bodies and joints.
  std::optional<EditScriptRun> script;
  if (auto edits = inv.args.value("edits")) {
    Result<EditScriptRun> read = EditScriptRun::load(*edits, *world, *ticks);
    if (!read.ok()) return inv.fail(read.status().message());
    script = std::move(read).value();
  }

  ReplayOptions options;
  options.keyframe_interval = static_cast<uint32_t>(keyframes);
  options.scene = loaded.label;
  auto writer = ReplayWriter::open(*out, *world, options);
  if (!writer.ok()) return inv.fail(writer.status().message());
  for (int64_t i = 0; i < *ticks; ++i) {
    std::vector<v1::EditBatch> batches;
    if (script) {
      if (Status st = script->apply_due(&*world, &batches); !st.ok()) return inv.fail(st.message());
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

// One replay's verification, for the console and the JUnit report.
struct Verdict {
  std::string path;
  enum Kind { kOk, kDiverged, kError } kind = kOk;
  std::string summary;  // one line
  std::string detail;   // what differs, or the error
  int64_t divergent_tick = -1;
  double seconds = 0.0;
};

Verdict verify_one(const std::string& path) {
  const auto start = std::chrono::steady_clock::now();
  Verdict v;
  v.path = path;
  Result<ReplayContents> replay = read_replay(path);
  Result<ReplayReport> report =
      replay.ok() ? verify_replay(*replay) : Result<ReplayReport>(replay.status());
  if (!report.ok()) {
    v.kind = Verdict::kError;
    v.summary = "cannot be verified";
    v.detail = report.status().message();
    if (v.detail.rfind(path, 0) != 0) v.detail = path + ": " + v.detail;
  } else if (!report->ok) {
    v.kind = Verdict::kDiverged;
    v.divergent_tick = report->first_divergent_tick;
    v.summary = "diverged at tick " + std::to_string(report->first_divergent_tick);
    v.detail = report->detail;
  } else {
    v.summary = std::to_string(report->ticks_checked) + " ticks match, final tick " +
                std::to_string(report->final_tick) + ", state hash " + hex64(report->final_hash);
    if (replay->truncated) {
      v.summary +=
          " (the file ends inside a record, cut off mid-write: verified up to its last "
          "complete tick)";
    }
  }
  v.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return v;
}

// Text for an XML attribute or element.
std::string xml_escape(std::string_view text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        // XML 1.0 allows no control characters but tab, newline and carriage return.
        if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n' && c != '\r') {
          out += '?';
        } else {
          out += c;
        }
    }
  }
  return out;
}

// The JUnit XML that CI systems (Jenkins, GitLab, GitHub Actions' test reporters) read: one
// suite, one test case per replay; a divergence is a failure, an unreadable replay an error.
Status write_junit(const std::string& path, const std::vector<Verdict>& verdicts) {
  int failures = 0, errors = 0;
  double seconds = 0.0;
  for (const Verdict& v : verdicts) {
    failures += v.kind == Verdict::kDiverged ? 1 : 0;
    errors += v.kind == Verdict::kError ? 1 : 0;
    seconds += v.seconds;
  }
  char total[32];
  std::snprintf(total, sizeof total, "%.3f", seconds);
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<testsuites tests=\"" << verdicts.size() << "\" failures=\"" << failures << "\" errors=\""
      << errors << "\" time=\"" << total << "\">\n"
      << "  <testsuite name=\"fulcrum replay verify\" tests=\"" << verdicts.size()
      << "\" failures=\"" << failures << "\" errors=\"" << errors << "\" time=\"" << total
      << "\">\n";
  for (const Verdict& v : verdicts) {
    char time[32];
    std::snprintf(time, sizeof time, "%.3f", v.seconds);
    xml << "    <testcase classname=\"fulcrum.replay\" name=\"" << xml_escape(v.path)
        << "\" time=\"" << time << "\">";
    if (v.kind == Verdict::kOk) {
      xml << "<system-out>" << xml_escape(v.summary) << "</system-out>";
    } else {
      const char* element = v.kind == Verdict::kDiverged ? "failure" : "error";
      xml << "\n      <" << element << " message=\"" << xml_escape(v.summary) << "\" type=\""
          << (v.kind == Verdict::kDiverged ? "divergence" : "unreadable") << "\">"
          << xml_escape(v.detail) << "</" << element << ">\n    ";
    }
    xml << "</testcase>\n";
  }
  xml << "  </testsuite>\n</testsuites>\n";
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out || !(out << xml.str()) || !out.flush()) {
    return Status(StatusCode::kFailedPrecondition, path + ": cannot write the JUnit report");
  }
  return {};
}

// Files as given; directories as their *.replay files in name order.
Result<std::vector<std::string>> replay_files(const std::vector<std::string>& args) {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  for (const std::string& arg : args) {
    std::error_code ec;
    if (!fs::is_directory(arg, ec)) {
      out.push_back(arg);
      continue;
    }
    std::vector<std::string> in_dir;
    for (const fs::directory_entry& e : fs::directory_iterator(arg, ec)) {
      if (e.path().extension() == ".replay") in_dir.push_back(e.path().string());
    }
    if (ec) return not_found(arg + ": cannot list the directory (" + ec.message() + ")");
    if (in_dir.empty()) return not_found(arg + ": no *.replay files in the directory");
    std::sort(in_dir.begin(), in_dir.end());
    out.insert(out.end(), in_dir.begin(), in_dir.end());
  }
  return out;
}

int verify(const Invocation& inv, const std::vector<std::string>& args) {
  Result<std::vector<std::string>> files = replay_files(args);
  if (!files.ok()) return inv.fail(files.status().message());
  std::vector<Verdict> verdicts;
  bool all_ok = true;
  for (const std::string& path : *files) {
    verdicts.push_back(verify_one(path));
    const Verdict& v = verdicts.back();
    if (v.kind == Verdict::kOk) {
      inv.out << path << ": OK: " << v.summary << "\n";
    } else if (v.kind == Verdict::kDiverged) {
      inv.err << "fulcrum replay: " << path << ": DIVERGED at tick " << v.divergent_tick << ": "
              << v.detail << "\n";
    } else {
      inv.err << "fulcrum replay: error: " << v.detail << "\n";
    }
    all_ok = all_ok && v.kind == Verdict::kOk;
  }
  if (auto junit = inv.args.value("junit")) {
    Status written = write_junit(*junit, verdicts);
    if (!written.ok()) return inv.fail(written.message());
  }
  if (files->size() > 1) {
    int ok = 0;
    for (const Verdict& v : verdicts) ok += v.kind == Verdict::kOk ? 1 : 0;
    inv.out << ok << " of " << files->size() << " replays verified\n";
  }
  return all_ok ? kExitOk : kExitError;
}

// Which ticks `info --ticks` lists: "all" (or no value), "T" or "FROM-TO" (ticks after the step,
// inclusive).
struct TickRange {
  int64_t from = 0;
  int64_t to = std::numeric_limits<int64_t>::max();
};

std::optional<TickRange> parse_tick_range(const std::string& text, std::string* error) {
  if (text == "all" || text.empty()) return TickRange{};
  const size_t dash = text.find('-');
  std::optional<int64_t> from =
      parse_int(text.substr(0, dash), 0, std::numeric_limits<int64_t>::max(), error);
  if (!from) return std::nullopt;
  if (dash == std::string::npos) return TickRange{*from, *from};
  std::optional<int64_t> to =
      parse_int(text.substr(dash + 1), *from, std::numeric_limits<int64_t>::max(), error);
  if (!to) return std::nullopt;
  return TickRange{*from, *to};
}

// One line per tick: the tick reached, its state hash, whether a keyframe was kept there, and
// each batch applied before the step that reached it, with the tick it applied at (the tick an
// edit script names), as one line of Protobuf JSON.
void list_ticks(const Invocation& inv, const ReplayContents& r, const TickRange& range) {
  inv.out << "\ntick      state hash        keyframe  edits applied before the step\n";
  google::protobuf::util::JsonPrintOptions options;
  for (const v1::ReplayTick& t : r.ticks) {
    if (t.tick() < range.from || t.tick() > range.to) continue;
    std::string tick = std::to_string(t.tick());
    tick.resize(std::max<size_t>(tick.size() + 1, 10), ' ');
    inv.out << tick << hex64(t.state_hash()) << "  " << (t.has_keyframe() ? "yes" : "-");
    for (int i = 0; i < t.edits_size(); ++i) {
      std::string json;
      (void)google::protobuf::util::MessageToJsonString(t.edits(i), &json, options);
      inv.out << (i == 0 ? (t.has_keyframe() ? "       " : "         ")
                         : "\n                                      ")
              << "at tick " << t.tick() - 1 << ": " << json;
    }
    inv.out << "\n";
  }
}

int info(const Invocation& inv, const std::string& path) {
  std::optional<TickRange> list;
  if (auto text = inv.args.value("ticks")) {
    std::string error;
    list = parse_tick_range(*text, &error);
    if (!list) return inv.usage_error("--ticks: expected all, T or FROM-TO: " + error);
  }
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
  if (list) list_ticks(inv, r, *list);
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
  if (action != "record" && inv.args.has("set")) return inv.usage_error("--set is for record only");
  if (action == "record") {
    if (pos.size() > 1) return inv.usage_error("record takes no FILE argument (use --out)");
    return record(inv);
  }
  if (action == "verify") {
    if (pos.size() < 2) return inv.usage_error("verify: expected replay FILEs or DIRs");
    return verify(inv, std::vector<std::string>(pos.begin() + 1, pos.end()));
  }
  if (action != "verify" && inv.args.has("junit")) {
    return inv.usage_error("--junit is for verify only");
  }
  if (action == "info") {
    if (pos.size() != 2) return inv.usage_error("info: expected one replay FILE");
    return info(inv, pos[1]);
  }
  if (action == "start" || action == "stop" || action == "download") return on_server(inv, action);
  return inv.usage_error("unknown action '" + action +
                         "' (record, verify, info, start, stop or download)");
}

}  // namespace fulcrum::cli
