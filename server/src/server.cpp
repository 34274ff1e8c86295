#include "server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <algorithm>
#include <filesystem>
#include <thread>

#include "call_guard.h"
#include "clock.h"
#include "physics_service.h"
#include "recorder.h"

namespace fulcrum::server {

Result<std::unique_ptr<Server>> Server::start(const ServerOptions& options) {
  if (options.listen.empty() || options.listen.rfind(':') == std::string::npos) {
    return invalid_argument("listen: expected HOST:PORT (got '" + options.listen + "')");
  }
  if (options.max_message_bytes < ServerOptions::kMinMessageBytes) {
    return invalid_argument("max_message_bytes: must be at least " +
                            std::to_string(ServerOptions::kMinMessageBytes) + " (got " +
                            std::to_string(options.max_message_bytes) + ")");
  }
  if (options.tls_cert_pem.empty() != options.tls_key_pem.empty()) {
    return invalid_argument(options.tls_cert_pem.empty()
                                ? "tls_cert: required with a TLS key"
                                : "tls_key: required with a TLS certificate");
  }
  grpc::EnableDefaultHealthCheckService(true);
  if (options.reflection) grpc::reflection::InitProtoReflectionServerBuilderPlugin();

  if (options.worker_threads < 0) return invalid_argument("worker_threads: must be >= 0");
  if (options.keepalive_ms < 1 || options.keepalive_timeout_ms < 1) {
    return invalid_argument("keepalive_ms, keepalive_timeout_ms: must be >= 1");
  }
  if (options.max_streams_per_connection < 1) {
    return invalid_argument("max_streams_per_connection: must be >= 1");
  }
  if (!options.replay_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.replay_dir, ec);
    if (!std::filesystem::is_directory(options.replay_dir, ec)) {
      return invalid_argument("replay_dir: " + options.replay_dir + " is not a directory");
    }
  }

  std::unique_ptr<Server> server(new Server());
  Limits limits = options.limits;
  limits.max_message_bytes = options.max_message_bytes;
  server->registry_ = std::make_unique<Registry>(limits);
  const int threads = options.worker_threads > 0
                          ? options.worker_threads
                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  server->pool_ = std::make_unique<RealTimePool>(threads);
  server->replays_ = std::make_unique<ReplayStore>(options.replay_dir);
  server->registry_->attach(server->pool_.get(), server->replays_.get());
  server->service_ = std::make_unique<PhysicsService>(server->registry_.get(), options.token);

  grpc::ServerBuilder builder;
  int port = 0;
  std::shared_ptr<grpc::ServerCredentials> credentials = grpc::InsecureServerCredentials();
  if (!options.tls_cert_pem.empty()) {
    grpc::SslServerCredentialsOptions tls;
    tls.pem_key_cert_pairs.push_back({options.tls_key_pem, options.tls_cert_pem});
    credentials = grpc::SslServerCredentials(tls);
  }
  builder.AddListeningPort(options.listen, credentials, &port);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, options.keepalive_ms);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, options.keepalive_timeout_ms);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  // Clients may ping as often as every 10 s (or the keepalive period, if shorter) without
  // being told to go away for it.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                             std::min(options.keepalive_ms, 10000));
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, options.max_streams_per_connection);
  builder.experimental().SetInterceptorCreators(
      make_call_guards(options.token, server->calls_in_flight_));
  builder.RegisterService(server->service_.get());
  builder.SetMaxReceiveMessageSize(options.max_message_bytes);
  builder.SetMaxSendMessageSize(options.max_message_bytes);
  server->server_ = builder.BuildAndStart();
  if (!server->server_ || port == 0) {
    return Status(StatusCode::kFailedPrecondition,
                  "listen: cannot listen on " + options.listen +
                      (options.tls_cert_pem.empty()
                           ? " (in use, or a bad address)"
                           : " (in use, a bad address, or a TLS certificate and key that are not "
                             "PEM or do not match)"));
  }
  server->port_ = port;
  server->address_ =
      options.listen.substr(0, options.listen.rfind(':')) + ":" + std::to_string(port);
  // Health answers for the whole server ("") and for the Physics service by name.
  server->server_->GetHealthCheckService()->SetServingStatus(true);
  server->server_->GetHealthCheckService()->SetServingStatus(v1::Physics::service_full_name(),
                                                             true);
  if (!options.metrics_listen.empty()) {
    Registry* registry = server->registry_.get();
    auto metrics = MetricsEndpoint::start(options.metrics_listen,
                                          [registry] { return render_metrics(*registry); });
    if (!metrics.ok()) return metrics.status();  // the destructor shuts the gRPC side down
    server->metrics_ = std::move(metrics).value();
  }
  return server;
}

Server::~Server() {
  if (!stopped_) shutdown(std::chrono::milliseconds(0));
}

void Server::shutdown(std::chrono::milliseconds grace) {
  if (stopped_) return;
  stopped_ = true;
  metrics_.reset();  // no scrape reads the registry past this point
  if (!server_) {    // start() failed before serving
    if (pool_) pool_->shutdown();
    return;
  }
  server_->GetHealthCheckService()->SetServingStatus(false);
  service_->begin_shutdown();  // streams end, new calls are refused
  pool_->shutdown();
  // The calls still running get the grace period. gRPC's own Shutdown(deadline) would also wait,
  // up to the deadline, for every client connection to close after it is told to go away, and
  // a client with no call open notices that only when its poller next wakes (about every 5 s):
  // one idle client would hold the shutdown for the whole grace period. So the calls are waited
  // for here, and gRPC is then shut down with no grace left, which only cuts idle connections
  // (and cancels any call still running when the grace period is over).
  const auto deadline = std::chrono::steady_clock::now() + grace;
  while (calls_in_flight_->load() > 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  service_->abandon_calls();
  server_->Shutdown(std::chrono::system_clock::now());
  server_->Wait();
  registry_->close_all_recordings();  // after Wait: no call can open another
}

void Server::wait() {
  server_->Wait();
}

}  // namespace fulcrum::server
