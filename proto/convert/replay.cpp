// Replay files: records framed as [varint length][ReplayRecord bytes][FNV-1a 64, little endian].
#include "replay.h"

#include <cerrno>
#include <cstring>

#include <fstream>
#include <sstream>

#include "edit_convert.h"
#include "fulcrum/fingerprint.h"
#include "fulcrum/state.h"
#include "snapshot_convert.h"

namespace fulcrum {

namespace {

void append_varint(uint64_t v, std::string* out) {
  while (v >= 0x80) {
    out->push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out->push_back(static_cast<char>(v));
}

std::string frame(const v1::ReplayRecord& record) {
  std::string body = record.SerializeAsString();
  std::string out;
  append_varint(body.size(), &out);
  out += body;
  uint64_t sum = fnv1a64(body);
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((sum >> (8 * i)) & 0xff));
  return out;
}

}  // namespace

ReplayWriter::ReplayWriter(std::FILE* file, std::string path, uint32_t keyframe_interval)
    : file_(file), path_(std::move(path)), keyframe_interval_(keyframe_interval) {}

ReplayWriter::~ReplayWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

Result<std::unique_ptr<ReplayWriter>> ReplayWriter::open(const std::string& path,
                                                         const World& world,
                                                         const ReplayOptions& options) {
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    // A missing or unwritable directory, a full disk: the reason is what an operator acts on.
    return Status(StatusCode::kFailedPrecondition,
                  path + ": cannot create the replay file (" +
                      (errno != 0 ? std::strerror(errno) : "unknown error") + ")");
  }
  std::unique_ptr<ReplayWriter> w(new ReplayWriter(f, path, options.keyframe_interval));
  v1::ReplayRecord record;
  v1::ReplayHeader* h = record.mutable_header();
  h->set_format(kReplayFormat);
  h->set_version(kReplayVersion);
  h->set_writer(kWriterName);
  *h->mutable_initial() = wrap_snapshot(snapshot_to_proto(world.snapshot()));
  h->set_keyframe_interval(options.keyframe_interval);
  h->set_scene(options.scene);
  FULCRUM_RETURN_IF_ERROR(w->write_record(record));
  return w;
}

Status ReplayWriter::write_record(const v1::ReplayRecord& record) {
  std::string bytes = frame(record);
  errno = 0;
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size() ||
      std::fflush(file_) != 0) {
    // "No space left on device", "File too large": what an operator needs to act on.
    return Status(StatusCode::kInternal,
                  path_ + ": write failed after " + std::to_string(bytes_) + " bytes (" +
                      (errno != 0 ? std::strerror(errno) : "unknown error") + ")");
  }
  bytes_ += bytes.size();
  return {};
}

Status ReplayWriter::record_tick(const World& world, const std::vector<v1::EditBatch>& batches) {
  v1::ReplayRecord record;
  v1::ReplayTick* t = record.mutable_tick();
  t->set_tick(world.tick());
  for (const v1::EditBatch& b : batches) *t->add_edits() = b;
  t->set_state_hash(world.state_hash());
  if (keyframe_interval_ > 0 && world.tick() % keyframe_interval_ == 0) {
    *t->mutable_keyframe() = wrap_snapshot(snapshot_to_proto(world.snapshot()));
  }
  FULCRUM_RETURN_IF_ERROR(write_record(record));
  ++ticks_;
  return {};
}

Status ReplayWriter::close() {
  if (file_ == nullptr) return {};
  int rc = std::fclose(file_);
  file_ = nullptr;
  if (rc != 0) return Status(StatusCode::kInternal, path_ + ": close failed");
  return {};
}

Result<ReplayContents> read_replay(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return not_found(path + ": cannot open the replay file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return parse_replay(buffer.str(), path);
}

Result<ReplayContents> parse_replay(std::string_view data, const std::string& path) {
  ReplayContents out;
  size_t pos = 0;
  int64_t index = 0;
  bool have_header = false;
  while (pos < data.size()) {
    // The length prefix, then the record and its checksum; a short tail is a cut-off write.
    uint64_t len = 0;
    int shift = 0;
    size_t p = pos;
    bool complete = false;
    while (p < data.size() && shift < 64) {
      auto byte = static_cast<unsigned char>(data[p++]);
      len |= static_cast<uint64_t>(byte & 0x7f) << shift;
      shift += 7;
      if ((byte & 0x80) == 0) {
        complete = true;
        break;
      }
    }
    if (!complete || len > data.size() || data.size() - p < len + 8) {
      out.truncated = true;
      break;
    }
    std::string_view body(data.data() + p, len);
    uint64_t sum = 0;
    for (int i = 0; i < 8; ++i) {
      sum |= static_cast<uint64_t>(static_cast<unsigned char>(data[p + len + i])) << (8 * i);
    }
    const std::string where =
        path + ": record " + std::to_string(index) + " (byte " + std::to_string(pos) + ")";
    if (fnv1a64(body) != sum) return data_loss(where + ": checksum mismatch: the file is damaged");
    v1::ReplayRecord record;
    if (!record.ParseFromArray(body.data(), static_cast<int>(body.size()))) {
      return data_loss(where + ": does not parse");
    }
    if (!have_header) {
      if (!record.has_header()) return data_loss(where + ": the first record must be the header");
      const v1::ReplayHeader& h = record.header();
      if (h.format() != kReplayFormat) {
        return Status(
            StatusCode::kFailedPrecondition,
            path + ": format is \"" + h.format() + "\", expected \"" + kReplayFormat + "\"");
      }
      if (h.version() != kReplayVersion) {
        return Status(StatusCode::kFailedPrecondition,
                      path + ": replay format version " + std::to_string(h.version()) +
                          " (written by \"" + h.writer() + "\"); this build reads version " +
                          std::to_string(kReplayVersion));
      }
      out.header = record.header();
      have_header = true;
    } else if (record.has_tick()) {
      out.ticks.push_back(record.tick());
    } else {
      return data_loss(where + ": a second header");
    }
    pos = p + len + 8;
    ++index;
  }
  if (!have_header) {
    return data_loss(path + ": no complete header (empty, cut off, or not a replay file)");
  }
  return out;
}

Status write_replay(const std::string& path, const ReplayContents& contents) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return not_found(path + ": cannot create the replay file");
  v1::ReplayRecord header;
  *header.mutable_header() = contents.header;
  out << frame(header);
  for (const v1::ReplayTick& t : contents.ticks) {
    v1::ReplayRecord record;
    *record.mutable_tick() = t;
    out << frame(record);
  }
  out.close();
  if (!out) return Status(StatusCode::kInternal, path + ": write failed");
  return {};
}

namespace {

Result<v1::Snapshot> keyframe_of(const v1::ReplayTick& t) {
  Result<v1::Snapshot> s = unwrap_snapshot(t.keyframe());
  if (!s.ok()) return s.status().with_prefix("keyframe of tick " + std::to_string(t.tick()) + ": ");
  return s;
}

// A divergence of a replay recorded by an engine of other results is what that engine change
// did, not a fault: the report says so first.
ReplayReport explained(const ReplayContents& replay, ReplayReport report) {
  const std::string& recorded = replay.header.initial().fingerprint();
  if (report.ok || recorded == kDeterminismFingerprint) return report;
  report.detail =
      (recorded.empty() ? std::string("recorded by an engine older than determinism "
                                      "fingerprints")
                        : "recorded by an engine that gives the results of " + recorded) +
      ", and this build gives those of " + kDeterminismFingerprint +
      ", so a divergence is expected; re-record it with this build. " + report.detail;
  return report;
}

}  // namespace

Result<ReplayReport> verify_replay(const ReplayContents& replay) {
  Result<v1::Snapshot> initial = unwrap_snapshot(replay.header.initial());
  if (!initial.ok()) return initial.status().with_prefix("initial snapshot: ");
  Result<WorldSnapshot> records = snapshot_from_proto(*initial);
  if (!records.ok()) return records.status().with_prefix("initial snapshot: ");
  World world;
  FULCRUM_RETURN_IF_ERROR(world.restore(*records));

  ReplayReport report;
  report.final_tick = world.tick();
  report.final_hash = world.state_hash();
  size_t diverged_at = replay.ticks.size();  // index of the first divergent tick record
  for (size_t i = 0; i < replay.ticks.size(); ++i) {
    const v1::ReplayTick& t = replay.ticks[i];
    if (t.tick() != world.tick() + 1) {
      return data_loss("replay: tick records out of order: expected tick " +
                       std::to_string(world.tick() + 1) + ", found " + std::to_string(t.tick()));
    }
    for (int b = 0; b < t.edits_size(); ++b) {
      Result<EditOutcome> applied = apply_edit_batch(&world, t.edits(b));
      if (!applied.ok() && diverged_at == replay.ticks.size()) {
        report.first_divergent_tick = t.tick();
        report.detail = "edit batch " + std::to_string(b) + " before tick " +
                        std::to_string(t.tick()) +
                        " was refused on replay: " + applied.status().message();
        diverged_at = i;
      }
    }
    world.step();
    ++report.ticks_checked;
    report.final_tick = world.tick();
    report.final_hash = world.state_hash();
    const bool hash_differs = world.state_hash() != t.state_hash();
    std::string keyframe_diff;
    if (t.has_keyframe()) {
      Result<v1::Snapshot> recorded = keyframe_of(t);
      if (!recorded.ok()) return recorded.status();
      keyframe_diff = first_difference(*recorded, snapshot_to_proto(world.snapshot()));
    }
    if (diverged_at == replay.ticks.size() && (hash_differs || !keyframe_diff.empty())) {
      diverged_at = i;
      report.first_divergent_tick = t.tick();
      report.detail = hash_differs ? "state hash " + World::hash_text(world.state_hash()) +
                                         ", recorded " + World::hash_text(t.state_hash())
                                   : "state hash matches but the keyframe differs";
    }
    // Once diverged, run on to the first keyframe to say what differs.
    if (diverged_at != replay.ticks.size() && t.has_keyframe()) {
      report.detail += t.tick() == report.first_divergent_tick
                           ? "; first difference: "
                           : "; no keyframe at that tick; at the next keyframe (tick " +
                                 std::to_string(t.tick()) + ") the first difference is: ";
      report.detail += keyframe_diff.empty() ? "(none in the records)" : keyframe_diff;
      return explained(replay, std::move(report));
    }
  }
  report.ok = diverged_at == replay.ticks.size();
  if (!report.ok) report.detail += "; no keyframe after it to compare";
  return explained(replay, std::move(report));
}

}  // namespace fulcrum
