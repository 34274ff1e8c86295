// The server's counters and its structured log. Counters are process-wide atomics (one
// fulcrum-server hosts one Server; servers started in one test process share them), read by
// GetStats. Log lines go to stderr, one per world event and per refused request, in a stable
// key=value format:
//   fulcrum-server ts=2026-11-21T14:25:04.123Z event=world_created world=1 name=pyramid bodies=211
// Values with spaces, quotes or '=' are double-quoted with \" and \\ escaped.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <iterator>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "fulcrum/v1/stats.pb.h"

namespace fulcrum::server {

struct Counters {
  std::atomic<uint64_t> worlds_created{0};
  std::atomic<uint64_t> worlds_deleted{0};
  std::atomic<uint64_t> worlds_restored{0};
  std::atomic<uint64_t> ticks_stepped{0};
  std::atomic<uint64_t> step_ns_total{0};
  std::atomic<uint64_t> step_ns_max{0};
  std::atomic<int64_t> streams_open{0};
  std::atomic<uint64_t> streams_opened{0};
  std::atomic<uint64_t> frames_sent{0};
  std::atomic<uint64_t> frames_coalesced{0};
  std::atomic<uint64_t> frames_encoded{0};
  std::atomic<uint64_t> readers_too_slow{0};
  std::atomic<uint64_t> recordings_started{0};
  std::atomic<uint64_t> recordings_failed{0};
  std::atomic<uint64_t> hash_reports{0};   // ReportHash calls answered
  std::atomic<uint64_t> desyncs{0};        // of them, those that found a hash that differs
  std::atomic<uint64_t> resyncs{0};        // fresh starts sent to a desynchronised player
  std::atomic<uint64_t> refused[17] = {};  // by grpc::StatusCode (0..16)
  // Ticks by their wall time (a Step call's or a real-time wake's average per tick), in the
  // buckets of kStepBucketSeconds and one past the last (the Prometheus histogram of metrics.h).
  static constexpr double kStepBucketSeconds[] = {1e-4, 2.5e-4, 5e-4, 1e-3, 2.5e-3, 5e-3,
                                                  1e-2, 2.5e-2, 5e-2, 0.1,  0.25,   1.0};
  static constexpr int kStepBuckets = std::size(kStepBucketSeconds) + 1;
  std::atomic<uint64_t> step_ticks_by_time[kStepBuckets] = {};

  // One Step call's ticks and their wall time (the max is per tick, the call's average).
  void add_steps(uint32_t ticks, std::chrono::nanoseconds elapsed);
  void add_refused(int code);
  void to_proto(uint32_t worlds_alive, v1::ServerStats* out) const;
};

Counters& counters();

// "INVALID_ARGUMENT" for 3, and so on ("CODE_n" beyond 16).
std::string_view status_code_name(int code);

struct LogField {
  std::string_view key;
  std::string value;
  LogField(std::string_view k, std::string v) : key(k), value(std::move(v)) {}
  LogField(std::string_view k, const char* v) : key(k), value(v) {}
  LogField(std::string_view k, std::string_view v) : key(k), value(v) {}
  template <typename Int>
  requires std::is_integral_v<Int> LogField(std::string_view k, Int v)
      : key(k), value(std::to_string(v)) {}
};

// Writes one line (atomically with respect to other log_event calls).
void log_event(std::string_view event, std::initializer_list<LogField> fields);
// Turns the log off (benchmarks) or on; on by default.
void set_logging(bool on);

// The field a refusal names: the text of `message` before its first ": " ("batch.edits[1]...")
// when that looks like a field path, else empty.
std::string field_of(std::string_view message);

}  // namespace fulcrum::server
