#include "metrics.h"  // first: Eigen (through session.h) before httplib.h's <resolv.h>

#include <httplib.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "stats.h"

namespace fulcrum::server {

namespace {

std::string number(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// A label value: backslash, double quote and newline escaped (the exposition format's rules).
std::string label(std::string_view v) {
  std::string out;
  for (char c : v) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

class Text {
 public:
  // Starts a metric family: its help line and type.
  void family(std::string_view name, std::string_view type, std::string_view help) {
    out_ += "# HELP ";
    out_ += name;
    out_ += ' ';
    out_ += help;
    out_ += "\n# TYPE ";
    out_ += name;
    out_ += ' ';
    out_ += type;
    out_ += '\n';
  }
  void sample(std::string_view name, std::string_view labels, double value) {
    out_ += name;
    if (!labels.empty()) {
      out_ += '{';
      out_ += labels;
      out_ += '}';
    }
    out_ += ' ';
    out_ += number(value);
    out_ += '\n';
  }
  // A family of one unlabelled sample.
  void single(std::string_view name, std::string_view type, std::string_view help, double value) {
    family(name, type, help);
    sample(name, "", value);
  }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

}  // namespace

std::string render_metrics(Registry& registry) {
  const auto sessions = registry.list();
  v1::ServerStats stats;
  const Counters& c = counters();
  c.to_proto(static_cast<uint32_t>(sessions.size()), &stats);
  Text t;
  t.single("fulcrum_uptime_seconds", "gauge", "Seconds since the server started.",
           stats.uptime_s());
  t.single("fulcrum_worlds", "gauge", "Worlds alive now.", stats.worlds());
  t.single("fulcrum_worlds_created_total", "counter", "Worlds created by CreateWorld and by forks.",
           stats.worlds_created());
  t.single("fulcrum_worlds_deleted_total", "counter", "Worlds deleted.", stats.worlds_deleted());
  t.single("fulcrum_worlds_restored_total", "counter",
           "Rollbacks: snapshots restored into an existing world.", stats.worlds_restored());
  t.single("fulcrum_ticks_total", "counter", "Ticks stepped over all worlds.",
           stats.ticks_stepped());

  // The histogram's buckets are cumulative; its count is every tick, its sum the step time.
  t.family("fulcrum_step_seconds", "histogram",
           "Wall time per tick (a Step call's or a real-time wake's average per tick).");
  uint64_t cumulative = 0;
  for (int b = 0; b < Counters::kStepBuckets; ++b) {
    cumulative += c.step_ticks_by_time[b].load();
    const std::string le = b < Counters::kStepBuckets - 1 ? number(Counters::kStepBucketSeconds[b])
                                                          : std::string("+Inf");
    t.sample("fulcrum_step_seconds_bucket", "le=\"" + le + "\"", static_cast<double>(cumulative));
  }
  t.sample("fulcrum_step_seconds_sum", "", stats.step_ms_total() * 1e-3);
  t.sample("fulcrum_step_seconds_count", "", static_cast<double>(cumulative));

  t.single("fulcrum_streams_open", "gauge", "StreamFrames calls open now.", stats.streams_open());
  t.single("fulcrum_streams_opened_total", "counter", "StreamFrames calls opened.",
           stats.streams_opened());
  t.single("fulcrum_frames_sent_total", "counter", "Frames written to readers.",
           stats.frames_sent());
  t.single("fulcrum_frames_coalesced_total", "counter",
           "Frames replaced by a newer one before a slow reader took them.",
           stats.frames_coalesced());
  t.single("fulcrum_frames_encoded_total", "counter",
           "Frame encodings built (shared by readers of the same kind).", stats.frames_encoded());
  t.single("fulcrum_readers_too_slow_total", "counter",
           "Streams ended because their reader stalled (--max-reader-stall-ms).",
           stats.readers_too_slow());
  t.single("fulcrum_recordings_started_total", "counter", "Replay recordings started.",
           stats.recordings_started());
  t.single("fulcrum_recordings_failed_total", "counter",
           "Recordings that could not start or stopped on a failed write.",
           stats.recordings_failed());
  t.single("fulcrum_session_hash_reports_total", "counter",
           "Multiplayer state-hash reports answered (ReportHash).", stats.hash_reports());
  t.single("fulcrum_session_desyncs_total", "counter",
           "Hash reports that found a player's state hash differing from the server's.",
           stats.desyncs());
  t.single("fulcrum_session_resyncs_total", "counter",
           "Fresh session starts sent to resynchronise a desynchronised player.", stats.resyncs());
  t.family("fulcrum_refused_total", "counter", "Requests refused, by gRPC status code.");
  for (int code = 1; code < 17; ++code) {
    t.sample("fulcrum_refused_total", "code=\"" + std::string(status_code_name(code)) + "\"",
             static_cast<double>(c.refused[code].load()));
  }

  // Per world, from each world's summary (no world lock is taken: a scrape never waits on a
  // step). The labels are the world's id and its scene's name.
  std::vector<std::pair<std::string, v1::WorldInfo>> worlds;
  for (const auto& session : sessions) {
    v1::WorldInfo info;
    session->summary(&info);
    worlds.emplace_back(
        "world=\"" + std::to_string(info.world_id()) + "\",name=\"" + label(info.name()) + "\"",
        std::move(info));
  }
  struct WorldMetric {
    const char* name;
    const char* type;
    const char* help;
    double (*value)(const v1::WorldInfo&);
  };
  const WorldMetric per_world[] = {
      {"fulcrum_world_tick", "gauge", "The world's tick (ticks stepped so far).",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.tick()); }},
      {"fulcrum_world_bodies", "gauge", "Live bodies.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.body_count()); }},
      {"fulcrum_world_awake_bodies", "gauge", "Bodies awake.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.awake_body_count()); }},
      {"fulcrum_world_contacts", "gauge", "Touching contact manifolds.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.contact_count()); }},
      {"fulcrum_world_budget_islands", "gauge",
       "Islands given more substeps or relax passes than the world's at the last tick (solver "
       "budgets).",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.budget_islands()); }},
      {"fulcrum_world_max_substeps", "gauge", "The most substeps any island ran at the last tick.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.max_substeps()); }},
      {"fulcrum_world_max_relax_iterations", "gauge",
       "The most relax passes per substep any island ran at the last tick.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.max_relax_iterations()); }},
      {"fulcrum_world_watchers", "gauge", "Open StreamFrames streams on the world.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.watchers()); }},
      {"fulcrum_world_real_time", "gauge", "1 while the world runs on the server's clock.",
       [](const v1::WorldInfo& w) { return w.run().mode() == v1::RUN_MODE_REAL_TIME ? 1.0 : 0.0; }},
      {"fulcrum_world_realtime_ticks_dropped_total", "counter",
       "Due ticks skipped because the server fell behind, in the current real-time run.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.run().ticks_dropped()); }},
      {"fulcrum_world_realtime_late_wakes_total", "counter",
       "Wakes with more ticks due than the catch-up cap, in the current real-time run.",
       [](const v1::WorldInfo& w) { return static_cast<double>(w.run().late_wakes()); }},
      {"fulcrum_world_recording", "gauge", "1 while a replay recording is open.",
       [](const v1::WorldInfo& w) { return w.recording().active() ? 1.0 : 0.0; }},
  };
  for (const WorldMetric& m : per_world) {
    t.family(m.name, m.type, m.help);
    for (const auto& [labels, info] : worlds) t.sample(m.name, labels, m.value(info));
  }
  return t.take();
}

struct MetricsEndpoint::Impl {
  httplib::Server http;
  std::thread thread;
  std::atomic<bool> listen_returned{false};
};

MetricsEndpoint::MetricsEndpoint(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

MetricsEndpoint::~MetricsEndpoint() {
  impl_->http.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

Result<std::unique_ptr<MetricsEndpoint>> MetricsEndpoint::start(
    const std::string& listen, std::function<std::string()> render) {
  const size_t colon = listen.rfind(':');
  int port = -1;
  if (colon != std::string::npos && colon + 1 < listen.size() &&
      listen.find_first_not_of("0123456789", colon + 1) == std::string::npos &&
      listen.size() - colon - 1 <= 5) {
    port = std::stoi(listen.substr(colon + 1));
  }
  if (port < 0 || port > 65535 || colon == 0) {
    return invalid_argument("metrics_listen: expected HOST:PORT (got '" + listen + "')");
  }
  std::string host = listen.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);  // [::1]:9100
  }
  auto impl = std::make_unique<Impl>();
  // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which a second server on the
  // same port would bind too and the two would share the scrapes without a word.
  impl->http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  impl->http.Get("/metrics", [render](const httplib::Request&, httplib::Response& res) {
    res.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
  });
  const int bound = port == 0 ? impl->http.bind_to_any_port(host)
                              : (impl->http.bind_to_port(host, port) ? port : -1);
  if (bound <= 0) {
    return Status(StatusCode::kUnavailable,
                  "metrics_listen: cannot listen on " + listen + " (in use, or not this host's)");
  }
  Impl* raw = impl.get();
  impl->thread = std::thread([raw] {
    raw->http.listen_after_bind();
    raw->listen_returned = true;
  });
  // httplib's stop() does nothing until the listening loop has started, so an endpoint stopped
  // right after it started would leave the thread listening and the destructor waiting on it.
  while (!impl->http.is_running() && !impl->listen_returned) {
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  std::unique_ptr<MetricsEndpoint> endpoint(new MetricsEndpoint(std::move(impl)));
  endpoint->address_ = listen.substr(0, colon) + ":" + std::to_string(bound);
  return endpoint;
}

}  // namespace fulcrum::server
