// Fuzz target: replay files, as `fulcrum replay verify` and CI jobs read them. The first byte
// chooses the form:
//   even: the rest is a replay file as it is on disk (framing, checksums, records);
//   odd:  the same, but each whole record's checksum is rewritten to match before reading, so
//         that mutations of the records themselves get past the checksum.
// Checks: reading refuses with a message or gives a header and ticks; verifying refuses with a
// message or reports; a report that says ok names no divergent tick, and one that does not
// says what differs.
#include "fuzz_support.h"
#include "replay.h"
#include "snapshot_convert.h"

namespace {

// Rewrites the checksum after each complete record (replay.cpp: varint length, record, 8-byte
// little-endian FNV-1a).
void fix_checksums(std::string& data) {
  size_t pos = 0;
  while (pos < data.size()) {
    uint64_t len = 0;
    int shift = 0;
    size_t p = pos;
    bool complete = false;
    while (p < data.size() && shift < 64) {
      const auto byte = static_cast<unsigned char>(data[p++]);
      len |= static_cast<uint64_t>(byte & 0x7f) << shift;
      shift += 7;
      if ((byte & 0x80) == 0) {
        complete = true;
        break;
      }
    }
    if (!complete || len > data.size() || data.size() - p < len + 8) return;
    const uint64_t sum = fulcrum::fnv1a64(std::string_view(data).substr(p, len));
    for (int i = 0; i < 8; ++i) data[p + len + i] = static_cast<char>(sum >> (8 * i));
    pos = p + len + 8;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace fulcrum;
  if (size == 0) return 0;
  std::string file(fuzz::bytes(data + 1, size - 1));
  if (data[0] % 2 == 1) fix_checksums(file);
  Result<ReplayContents> replay = parse_replay(file, "fuzz.replay");
  if (!replay.ok()) {
    fuzz::check_refusal(replay.status(), "parse_replay");
    return 0;
  }
  Result<ReplayReport> report = verify_replay(*replay);
  if (std::getenv("FULCRUM_FUZZ_PRINT") != nullptr) {
    std::fprintf(stderr, "replay of %zu ticks: %s\n", replay->ticks.size(),
                 report.ok() ? (report->ok ? "verifies" : report->detail.c_str())
                             : report.status().message().c_str());
  }
  if (!report.ok()) {
    fuzz::check_refusal(report.status(), "verify_replay");
    return 0;
  }
  if (report->ok) {
    fuzz::check(report->first_divergent_tick == -1, "an ok report names a divergent tick");
  } else {
    fuzz::check(!report->detail.empty(), "a failed report does not say what differs");
  }
  return 0;
}
