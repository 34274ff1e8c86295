#include "call_guard.h"

#include <grpcpp/grpcpp.h>

#include <cctype>
#include <string_view>

#include "stats.h"

namespace fulcrum::server {

BearerCheck check_bearer(const grpc::ServerContextBase& context, const std::string& token) {
  const auto& metadata = context.client_metadata();
  auto it = metadata.find("authorization");
  if (it == metadata.end()) return BearerCheck::kMissing;
  std::string_view value(it->second.data(), it->second.size());
  constexpr std::string_view kScheme = "bearer";
  if (value.size() <= kScheme.size() || value[kScheme.size()] != ' ') return BearerCheck::kWrong;
  for (size_t i = 0; i < kScheme.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(value[i])) != kScheme[i]) {
      return BearerCheck::kWrong;
    }
  }
  value.remove_prefix(kScheme.size());
  while (!value.empty() && value.front() == ' ') value.remove_prefix(1);
  if (value.size() != token.size()) return BearerCheck::kWrong;
  unsigned char diff = 0;  // no early exit: the time says nothing about the guess
  for (size_t i = 0; i < value.size(); ++i) {
    diff |= static_cast<unsigned char>(value[i] ^ token[i]);
  }
  return diff == 0 ? BearerCheck::kMatches : BearerCheck::kWrong;
}

namespace {

using grpc::experimental::InterceptionHookPoints;

class CallGuard final : public grpc::experimental::Interceptor {
 public:
  CallGuard(grpc::experimental::ServerRpcInfo* info, const std::string& token,
            std::atomic<int>* in_flight)
      : info_(info),
        token_(token),
        method_(info->method()),
        in_flight_(method_.rfind("/fulcrum.", 0) == 0 ? in_flight : nullptr) {
    if (in_flight_ != nullptr) in_flight_->fetch_add(1);
  }
  ~CallGuard() override {
    if (in_flight_ != nullptr) in_flight_->fetch_sub(1);
  }

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_INITIAL_METADATA)) {
      const bool guarded = !token_.empty() && method_.rfind("/grpc.reflection.", 0) == 0;
      locked_out_ =
          guarded && check_bearer(*info_->server_context(), token_) != BearerCheck::kMatches;
    }
    if (locked_out_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_MESSAGE)) {
      grpc::ByteBuffer* message = methods->GetSerializedSendMessage();
      if (message != nullptr) {
        grpc::Slice empty;
        *message = grpc::ByteBuffer(&empty, 1);
      }
    }
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      grpc::Status status = methods->GetSendStatus();
      if (locked_out_) {
        status = grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                              "authorization: missing or wrong (expected \"Bearer <token>\")");
        methods->ModifySendStatus(status);
      }
      // Server streams count their own refusals (physics_service's Refused), since they can
      // also end with an error after a good start.
      const bool stream = method_ == "/fulcrum.v1.Physics/StreamFrames" ||
                          method_ == "/fulcrum.v1.Physics/DownloadReplay";
      if (!status.ok() && !stream && status.error_code() != grpc::StatusCode::CANCELLED) {
        counters().add_refused(status.error_code());
        log_event("refused", {{"rpc", rpc_name()},
                              {"code", status_code_name(status.error_code())},
                              {"field", field_of(status.error_message())},
                              {"message", status.error_message()}});
      }
    }
    methods->Proceed();
  }

 private:
  std::string_view rpc_name() const {
    const size_t slash = method_.rfind('/');
    return slash == std::string::npos ? std::string_view(method_)
                                      : std::string_view(method_).substr(slash + 1);
  }

  grpc::experimental::ServerRpcInfo* info_;
  const std::string& token_;
  const std::string method_;
  std::atomic<int>* const in_flight_;  // null: a call that is not counted
  bool locked_out_ = false;
};

class CallGuardFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  CallGuardFactory(std::string token, std::shared_ptr<std::atomic<int>> in_flight)
      : token_(std::move(token)), in_flight_(std::move(in_flight)) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override {
    return new CallGuard(info, token_, in_flight_.get());
  }

 private:
  const std::string token_;
  const std::shared_ptr<std::atomic<int>> in_flight_;
};

}  // namespace

std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
make_call_guards(std::string token, std::shared_ptr<std::atomic<int>> in_flight) {
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> out;
  out.push_back(std::make_unique<CallGuardFactory>(std::move(token), std::move(in_flight)));
  return out;
}

}  // namespace fulcrum::server
