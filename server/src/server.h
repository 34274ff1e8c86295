// A running Fulcrum server: the world registry, the Physics service, gRPC's health service
// and (when Debian's gRPC ships it) server reflection, listening on one address. main.cpp wraps
// it with flags and signals; tests start it in-process on port 0.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <string>

#include "fulcrum/status.h"
#include "metrics.h"
#include "session.h"

namespace grpc {
class Server;
}

namespace fulcrum::server {

class PhysicsService;
class RealTimePool;
class ReplayStore;

struct ServerOptions {
  std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free one
  Limits limits;
  int max_message_bytes = 64 << 20;  // largest request or reply, bytes
  // At least room for one chunk of a replay or snapshot download (64 KiB) and its framing.
  static constexpr int kMinMessageBytes = 128 << 10;
  std::string token;       // bearer token; empty: no authentication
  bool reflection = true;  // register the server reflection service
  int worker_threads = 0;  // real-time pool threads; 0: the hardware's concurrency
  std::string replay_dir;  // where StartRecording writes; empty: recording is off
  // HTTP/2 keepalive: the server pings each connection this often and drops it when a ping is
  // not answered within the timeout, so the streams of a client that vanished without closing
  // (a dropped network, a frozen host) end within about the sum of the two.
  int keepalive_ms = 20000;
  int keepalive_timeout_ms = 10000;
  int max_streams_per_connection = 100;  // concurrent calls on one HTTP/2 connection
  // TLS: PEM text of the certificate chain and its private key. When set, the server serves
  // TLS only; both or neither.
  std::string tls_cert_pem;
  std::string tls_key_pem;
  // Prometheus metrics over HTTP at GET /metrics (metrics.h), "HOST:PORT"; empty: off.
  std::string metrics_listen;
};

class Server {
 public:
  static Result<std::unique_ptr<Server>> start(const ServerOptions& options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  int port() const { return port_; }
  // "HOST:PORT" with the port actually bound.
  const std::string& address() const { return address_; }
  Registry& registry() { return *registry_; }
  // The metrics endpoint's "HOST:PORT" with the port bound; empty when metrics are off.
  std::string metrics_address() const { return metrics_ ? metrics_->address() : std::string(); }

  // Health goes NOT_SERVING, open streams end (UNAVAILABLE), new calls are refused
  // (UNAVAILABLE), real-time clocks stop, calls in progress get up to `grace` to finish before
  // they are cancelled, client connections with no call open are closed without waiting,
  // recordings are closed. Returns when the server has stopped (its pool threads joined).
  void shutdown(std::chrono::milliseconds grace);
  // Blocks until shutdown() has run (from another thread).
  void wait();
  // Calls to the Physics service being served now (health and reflection calls not counted).
  int calls_in_flight() const { return calls_in_flight_->load(); }

 private:
  Server() = default;

  std::unique_ptr<RealTimePool> pool_;
  std::unique_ptr<ReplayStore> replays_;
  std::unique_ptr<Registry> registry_;
  std::unique_ptr<PhysicsService> service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<MetricsEndpoint> metrics_;
  std::shared_ptr<std::atomic<int>> calls_in_flight_ = std::make_shared<std::atomic<int>>(0);
  int port_ = 0;
  std::string address_;
  bool stopped_ = false;
};

}  // namespace fulcrum::server
