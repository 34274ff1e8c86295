// A gRPC server interceptor on every call: it logs and counts refused requests (every RPC but
// StreamFrames, whose reactor does that itself), and it puts server reflection behind the
// bearer token. gRPC C++ interceptors cannot stop a call before its handler runs, so for a
// reflection call without the right token the guard empties every reply message (nothing about
// the services leaks) and replaces the final status with UNAUTHENTICATED. The Physics service
// checks the token in its handlers; health checks need none. The guards also count the Physics
// calls in flight (a guard lives exactly as long as its call), which shutdown waits on.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/server_context.h>
#include <grpcpp/support/server_interceptor.h>

namespace fulcrum::server {

// What a call's `authorization` header says about the server's bearer token. The scheme is
// matched case-insensitively, as HTTP authentication schemes are (RFC 9110, section 11.1),
// spaces after it are skipped, and the token is compared in time that does not depend on
// where it differs.
enum class BearerCheck { kMissing, kWrong, kMatches };
BearerCheck check_bearer(const grpc::ServerContextBase& context, const std::string& token);

// `in_flight` counts the calls to Fulcrum's own services whose guard exists, from the call's
// start until gRPC destroys it after the final status. Health and reflection calls are not
// counted: a health Watch stream stays open as long as its client likes, and shutdown must not
// wait for it.
std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
make_call_guards(std::string token, std::shared_ptr<std::atomic<int>> in_flight);

}  // namespace fulcrum::server
