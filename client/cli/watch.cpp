// fulcrum watch: follow a world's frames; one line per second with the newest tick, awake
// bodies, state hash, frame counts and the bytes received (so the cost of --bodies and the
// saving of --quantized show).
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <ostream>
#include <thread>

#include "remote.h"

namespace fulcrum::cli {
namespace {

// "12.3 kB/s (456 B/frame)" for `bytes` in `frames` frames over `seconds` (kB = 1000 B).
std::string rate_text(uint64_t bytes, int64_t frames, double seconds) {
  char text[96];
  const double per_second = seconds > 0.0 ? static_cast<double>(bytes) / seconds : 0.0;
  const uint64_t per_frame = frames > 0 ? bytes / static_cast<uint64_t>(frames) : 0;
  std::snprintf(text, sizeof text, "%.1f kB/s (%llu B/frame)", per_second / 1000.0,
                static_cast<unsigned long long>(per_frame));
  return text;
}

}  // namespace

int run_watch(const Invocation& inv) {
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 0, &exit_code);
  if (!world) return exit_code;
  std::string error;
  int64_t seconds = 0;  // 0: until the stream ends
  if (auto s = inv.args.value("seconds")) {
    auto parsed = parse_int(*s, 0, int64_t{1} << 31, &error);
    if (!parsed) return inv.usage_error("--seconds: " + error);
    seconds = *parsed;
  }
  int64_t every = 1;
  if (auto e = inv.args.value("every")) {
    auto parsed = parse_int(*e, 1, 0xffffffffLL, &error);
    if (!parsed) return inv.usage_error("--every: " + error);
    every = *parsed;
  }
  client::SubscribeOptions options;
  options.every_ticks = static_cast<uint32_t>(every);
  options.quantized = inv.args.has("quantized");
  // Bodies are what --quantized shrinks, so it asks for the changed ones unless told otherwise.
  options.bodies = options.quantized ? client::FrameBodies::kChanged : client::FrameBodies::kNone;
  if (auto b = inv.args.value("bodies")) {
    if (*b == "none") {
      options.bodies = client::FrameBodies::kNone;
    } else if (*b == "changed") {
      options.bodies = client::FrameBodies::kChanged;
    } else if (*b == "all") {
      options.bodies = client::FrameBodies::kAll;
    } else {
      return inv.usage_error("--bodies: expected none, changed or all, got '" + *b + "'");
    }
    if (options.quantized && options.bodies == client::FrameBodies::kNone) {
      return inv.usage_error("--quantized: needs bodies (--bodies changed or all), not none");
    }
  }
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;

  std::mutex mu;
  std::condition_variable cv;
  client::Frame latest;
  int64_t frames = 0;
  uint64_t skipped = 0;
  uint64_t bytes = 0;
  bool ended = false;
  auto sub = client->subscribe(*world, options, [&](const client::Frame& f) {
    std::lock_guard<std::mutex> lock(mu);
    latest = f;
    ++frames;
    skipped += f.skipped_frames;
    bytes += f.message_bytes;
  });
  if (!sub.ok()) return inv.fail(sub.status().message());
  // The stream's end is noticed by a second thread so that the printing loop can wait on time.
  Status end_status;
  std::thread waiter([&] {
    Status st = (*sub)->wait();
    std::lock_guard<std::mutex> lock(mu);
    end_status = st;
    ended = true;
    cv.notify_all();
  });

  const auto start = std::chrono::steady_clock::now();
  auto printed_at = start;
  int64_t printed_frames = 0;
  uint64_t printed_bytes = 0;
  for (int64_t second = 1;; ++second) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_until(lock, start + std::chrono::seconds(second), [&] { return ended; });
    if (frames > printed_frames) {
      const auto now = std::chrono::steady_clock::now();
      const double elapsed = std::chrono::duration<double>(now - printed_at).count();
      inv.out << "tick " << latest.tick << "  awake " << latest.awake_body_count << "/"
              << latest.body_count << "  hash " << hex64(latest.state_hash) << "  frames " << frames
              << " (" << skipped << " coalesced)  "
              << rate_text(bytes - printed_bytes, frames - printed_frames, elapsed) << std::endl;
      printed_frames = frames;
      printed_bytes = bytes;
      printed_at = now;
    }
    if (ended || (seconds > 0 && second >= seconds)) break;
  }
  (*sub)->cancel();
  waiter.join();
  if (!end_status.ok()) return inv.fail("stream ended: " + end_status.message());
  return kExitOk;
}

}  // namespace fulcrum::cli
