#include "stats.h"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <mutex>

namespace fulcrum::server {

namespace {

const auto kStart = std::chrono::steady_clock::now();
std::atomic<bool> g_logging{true};
std::mutex g_log_mu;

constexpr std::string_view kCodeNames[17] = {
    "OK",        "CANCELLED",      "UNKNOWN",           "INVALID_ARGUMENT",   "DEADLINE_EXCEEDED",
    "NOT_FOUND", "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION",
    "ABORTED",   "OUT_OF_RANGE",   "UNIMPLEMENTED",     "INTERNAL",           "UNAVAILABLE",
    "DATA_LOSS", "UNAUTHENTICATED"};

void append_value(std::string* line, std::string_view v) {
  bool plain = !v.empty();
  for (char c : v) {
    if (c == ' ' || c == '"' || c == '=' || c == '\\' || c == '\n' || c == '\t') plain = false;
  }
  if (plain) {
    line->append(v);
    return;
  }
  line->push_back('"');
  for (char c : v) {
    if (c == '"' || c == '\\') line->push_back('\\');
    line->push_back(c == '\n' || c == '\t' ? ' ' : c);
  }
  line->push_back('"');
}

}  // namespace

Counters& counters() {
  static Counters c;
  return c;
}

void Counters::add_steps(uint32_t ticks, std::chrono::nanoseconds elapsed) {
  if (ticks == 0) return;
  const uint64_t ns = static_cast<uint64_t>(elapsed.count());
  ticks_stepped += ticks;
  step_ns_total += ns;
  const uint64_t per_tick = ns / ticks;
  int bucket = 0;
  while (bucket < kStepBuckets - 1 &&
         static_cast<double>(per_tick) * 1e-9 > kStepBucketSeconds[bucket]) {
    ++bucket;
  }
  step_ticks_by_time[bucket] += ticks;
  uint64_t seen = step_ns_max.load();
  while (per_tick > seen && !step_ns_max.compare_exchange_weak(seen, per_tick)) {
  }
}

void Counters::add_refused(int code) {
  if (code > 0 && code < 17) ++refused[code];
}

void Counters::to_proto(uint32_t worlds_alive, v1::ServerStats* out) const {
  out->set_uptime_s(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - kStart).count());
  out->set_worlds(worlds_alive);
  out->set_worlds_created(worlds_created);
  out->set_worlds_deleted(worlds_deleted);
  out->set_worlds_restored(worlds_restored);
  out->set_ticks_stepped(ticks_stepped);
  out->set_step_ms_total(static_cast<double>(step_ns_total.load()) * 1e-6);
  out->set_step_ms_max(static_cast<double>(step_ns_max.load()) * 1e-6);
  out->set_streams_open(static_cast<uint32_t>(std::max<int64_t>(0, streams_open.load())));
  out->set_streams_opened(streams_opened);
  out->set_frames_sent(frames_sent);
  out->set_frames_coalesced(frames_coalesced);
  out->set_frames_encoded(frames_encoded);
  out->set_readers_too_slow(readers_too_slow);
  out->set_recordings_started(recordings_started);
  out->set_recordings_failed(recordings_failed);
  out->set_hash_reports(hash_reports);
  out->set_desyncs(desyncs);
  out->set_resyncs(resyncs);
  for (int code = 1; code < 17; ++code) {
    const uint64_t n = refused[code];
    if (n == 0) continue;
    v1::CodeCount* c = out->add_refused();
    c->set_code(std::string(kCodeNames[code]));
    c->set_count(n);
  }
}

std::string_view status_code_name(int code) {
  if (code >= 0 && code < 17) return kCodeNames[code];
  return "UNKNOWN";
}

void set_logging(bool on) {
  g_logging = on;
}

void log_event(std::string_view event, std::initializer_list<LogField> fields) {
  if (!g_logging) return;
  const auto now = std::chrono::system_clock::now();
  const std::time_t seconds = std::chrono::system_clock::to_time_t(now);
  const int millis = static_cast<int>(
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char ts[96];
  std::snprintf(ts, sizeof ts, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", utc.tm_year + 1900,
                utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, millis);
  std::string line = "fulcrum-server ts=";
  line += ts;
  line += " event=";
  line += event;
  for (const LogField& f : fields) {
    line += ' ';
    line += f.key;
    line += '=';
    append_value(&line, f.value);
  }
  line += '\n';
  std::lock_guard<std::mutex> lock(g_log_mu);
  std::fwrite(line.data(), 1, line.size(), stderr);
}

std::string field_of(std::string_view message) {
  const size_t colon = message.find(": ");
  if (colon == std::string_view::npos || colon == 0) return {};
  const std::string_view head = message.substr(0, colon);
  for (char c : head) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '.' || c == '[' || c == ']';
    if (!ok) return {};
  }
  return std::string(head);
}

}  // namespace fulcrum::server
