// Prometheus metrics (fulcrum-server --metrics-listen ADDR): the server's counters, the same
// values GetStats answers, and per-world gauges, in Prometheus' text exposition format 0.0.4,
// served over plain HTTP at GET /metrics by cpp-httplib (Debian's libcpp-httplib-dev).
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "fulcrum/status.h"
#include "session.h"

namespace fulcrum::server {

// The exposition text for the registry's worlds and the process's counters (stats.h).
std::string render_metrics(Registry& registry);

// An HTTP listener on its own thread answering GET /metrics with render().
class MetricsEndpoint {
 public:
  // `listen` is "HOST:PORT"; port 0 picks a free one.
  static Result<std::unique_ptr<MetricsEndpoint>> start(const std::string& listen,
                                                        std::function<std::string()> render);
  ~MetricsEndpoint();  // stops listening and joins the thread
  MetricsEndpoint(const MetricsEndpoint&) = delete;
  MetricsEndpoint& operator=(const MetricsEndpoint&) = delete;

  // "HOST:PORT" with the port actually bound.
  const std::string& address() const { return address_; }

 private:
  struct Impl;
  explicit MetricsEndpoint(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  std::string address_;
};

}  // namespace fulcrum::server
