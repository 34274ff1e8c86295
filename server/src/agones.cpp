#include "agones.h"

#include <grpcpp/grpcpp.h>

#include <cstdlib>

#include "agones/sdk.grpc.pb.h"
#include "stats.h"

namespace fulcrum::server {

namespace sdk = ::agones::dev::sdk;

struct AgonesSdk::Stub {
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<sdk::SDK::Stub> stub;
};

namespace {

constexpr auto kCallDeadline = std::chrono::seconds(5);

Status call_status(const char* what, const grpc::Status& s) {
  if (s.ok()) return {};
  return Status(StatusCode::kUnavailable, std::string("agones: ") + what + ": " +
                                              s.error_message() + " (gRPC code " +
                                              std::to_string(s.error_code()) + ")");
}

void set_deadline(grpc::ClientContext* context) {
  context->set_deadline(std::chrono::system_clock::now() + kCallDeadline);
}

}  // namespace

std::string AgonesSdk::address_from_environment() {
  const char* port = std::getenv("AGONES_SDK_GRPC_PORT");
  return std::string("localhost:") + (port != nullptr && *port != '\0' ? port : "9357");
}

AgonesSdk::AgonesSdk(const std::string& address) : stub_(std::make_unique<Stub>()) {
  stub_->channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
  stub_->stub = sdk::SDK::NewStub(stub_->channel);
}

AgonesSdk::~AgonesSdk() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

Status AgonesSdk::ready(std::chrono::milliseconds patience) {
  const auto give_up = std::chrono::steady_clock::now() + patience;
  for (;;) {
    grpc::ClientContext context;
    set_deadline(&context);
    sdk::Empty reply;
    const grpc::Status s = stub_->stub->Ready(&context, sdk::Empty(), &reply);
    if (s.ok() || std::chrono::steady_clock::now() >= give_up) return call_status("Ready", s);
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

Status AgonesSdk::shutdown() {
  grpc::ClientContext context;
  set_deadline(&context);
  sdk::Empty reply;
  return call_status("Shutdown", stub_->stub->Shutdown(&context, sdk::Empty(), &reply));
}

Status AgonesSdk::set_label(const std::string& key, const std::string& value) {
  grpc::ClientContext context;
  set_deadline(&context);
  sdk::KeyValue request;
  request.set_key(key);
  request.set_value(value);
  sdk::Empty reply;
  return call_status("SetLabel", stub_->stub->SetLabel(&context, request, &reply));
}

void AgonesSdk::start_health(std::chrono::milliseconds period, std::function<int()> worlds) {
  thread_ =
      std::thread([this, period, worlds = std::move(worlds)] { health_loop(period, worlds); });
}

void AgonesSdk::health_loop(std::chrono::milliseconds period, std::function<int()> worlds) {
  std::unique_ptr<grpc::ClientContext> context;
  std::unique_ptr<grpc::ClientWriter<sdk::Empty>> stream;
  sdk::Empty reply;
  int labelled = -1;
  std::unique_lock<std::mutex> lock(mu_);
  while (!stop_) {
    lock.unlock();
    if (!stream) {
      context = std::make_unique<grpc::ClientContext>();
      stream = stub_->stub->Health(context.get(), &reply);
    }
    if (!stream->Write(sdk::Empty())) {
      // The sidecar closed the stream (or is not there yet): the next period opens a new one.
      const grpc::Status s = stream->Finish();
      log_event("agones_health_failed", {{"error", s.error_message()}});
      stream.reset();
    }
    const int n = worlds();
    if (n != labelled && set_label("worlds", std::to_string(n)).ok()) labelled = n;
    lock.lock();
    cv_.wait_for(lock, period, [this] { return stop_; });
  }
  lock.unlock();
  if (stream) {
    stream->WritesDone();
    context->TryCancel();
    stream->Finish();
  }
}

}  // namespace fulcrum::server
