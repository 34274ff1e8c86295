// A gRPC server interceptor on every call: it logs and counts refused requests (every RPC but
// StreamFrames, whose reactor does that itself), and it puts server reflection behind the
// bearer token. gRPC C++ interceptors cannot stop a call before its handler runs, so for a
// reflection call without the right token the guard empties every reply message (nothing about
// the services leaks) and replaces the final status with UNAUTHENTICATED. The Physics service
// checks the token in its handlers; health checks need none.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <grpcpp/support/server_interceptor.h>

namespace fulcrum::server {

std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
make_call_guards(std::string token);

}  // namespace fulcrum::server
