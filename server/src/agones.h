// fulcrum-server --agones: the server as an Agones GameServer. It tells the SDK sidecar (a gRPC
// service on localhost, proto/agones/sdk.proto) that it is Ready once it listens, pings Health
// while it runs, keeps the label "worlds" (agones.dev/sdk-worlds on the GameServer) at its world
// count so that allocators can pick servers by load, and calls Shutdown when it is asked to
// stop, so that the fleet replaces it.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "fulcrum/status.h"

namespace grpc {
class Channel;
}

namespace fulcrum::server {

class AgonesSdk {
 public:
  // The sidecar's address: localhost and AGONES_SDK_GRPC_PORT (default 9357), as Agones sets
  // it in the pod.
  static std::string address_from_environment();

  explicit AgonesSdk(const std::string& address);
  ~AgonesSdk();  // stops the health thread
  AgonesSdk(const AgonesSdk&) = delete;
  AgonesSdk& operator=(const AgonesSdk&) = delete;

  // Ready, retried until `patience` runs out: the sidecar may start after the server.
  Status ready(std::chrono::milliseconds patience);
  Status shutdown();
  Status set_label(const std::string& key, const std::string& value);

  // A thread that pings Health every `period` (reopening the stream if the sidecar dropped
  // it) and sets the label "worlds" to worlds() whenever it changes.
  void start_health(std::chrono::milliseconds period, std::function<int()> worlds);

 private:
  void health_loop(std::chrono::milliseconds period, std::function<int()> worlds);

  struct Stub;
  std::unique_ptr<Stub> stub_;
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
};

}  // namespace fulcrum::server
