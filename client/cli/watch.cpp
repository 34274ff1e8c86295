// fulcrum watch: follow a world's frames; one line per second with the newest tick, awake
// bodies and state hash.
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <ostream>
#include <thread>

#include "remote.h"

namespace fulcrum::cli {

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
  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;

  std::mutex mu;
  std::condition_variable cv;
  client::Frame latest;
  int64_t frames = 0;
  uint64_t skipped = 0;
  bool ended = false;
  client::SubscribeOptions options;
  options.every_ticks = static_cast<uint32_t>(every);
  options.bodies = client::FrameBodies::kNone;
  auto sub = client->subscribe(*world, options, [&](const client::Frame& f) {
    std::lock_guard<std::mutex> lock(mu);
    latest = f;
    ++frames;
    skipped += f.skipped_frames;
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
  int64_t printed_frames = 0;
  for (int64_t second = 1;; ++second) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_until(lock, start + std::chrono::seconds(second), [&] { return ended; });
    if (frames > printed_frames) {
      inv.out << "tick " << latest.tick << "  awake " << latest.awake_body_count << "/"
              << latest.body_count << "  hash " << hex64(latest.state_hash) << "  frames " << frames
              << " (" << skipped << " coalesced)" << std::endl;
      printed_frames = frames;
    }
    if (ended || (seconds > 0 && second >= seconds)) break;
  }
  (*sub)->cancel();
  waiter.join();
  if (!end_status.ok()) return inv.fail("stream ended: " + end_status.message());
  return kExitOk;
}

}  // namespace fulcrum::cli
