// fulcrum-server --agones against a stand-in for the Agones SDK sidecar. This is a contract
// test, not a cluster: the stand-in implements the SDK service of proto/agones/sdk.proto on
// loopback, records the calls, and the real fulcrum-server binary is pointed at it through
// AGONES_SDK_GRPC_PORT, as Agones does in a GameServer pod. It checks the order of calls a
// GameServer must make: Ready only once the server listens, Health pings every period, the
// label worlds following the world count, Shutdown on SIGTERM before the server exits 0.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "agones/sdk.grpc.pb.h"
#include "fulcrum/client.h"
#include "server_process.h"
#include "test_support.h"

namespace fulcrum {
namespace {

using namespace std::chrono_literals;
using testing_support::connect;
using testing_support::eventually;
using testing_support::pyramid_json;
using testing_support::ServerProcess;
namespace sdk = ::agones::dev::sdk;

class FakeSidecar final : public sdk::SDK::Service {
 public:
  grpc::Status Ready(grpc::ServerContext*, const sdk::Empty*, sdk::Empty*) override {
    record("Ready");
    return grpc::Status::OK;
  }
  grpc::Status Shutdown(grpc::ServerContext*, const sdk::Empty*, sdk::Empty*) override {
    record("Shutdown");
    return grpc::Status::OK;
  }
  grpc::Status Health(grpc::ServerContext*, grpc::ServerReader<sdk::Empty>* reader,
                      sdk::Empty*) override {
    sdk::Empty ping;
    while (reader->Read(&ping)) record("Health");
    return grpc::Status::OK;
  }
  grpc::Status SetLabel(grpc::ServerContext*, const sdk::KeyValue* kv, sdk::Empty*) override {
    record("SetLabel " + kv->key() + "=" + kv->value());
    return grpc::Status::OK;
  }

  std::vector<std::string> calls() {
    std::lock_guard<std::mutex> lock(mu_);
    return calls_;
  }
  int count(const std::string& call) {
    int n = 0;
    for (const std::string& c : calls()) n += c == call ? 1 : 0;
    return n;
  }

 private:
  void record(std::string call) {
    std::lock_guard<std::mutex> lock(mu_);
    calls_.push_back(std::move(call));
  }
  std::mutex mu_;
  std::vector<std::string> calls_;
};

TEST(AgonesContract, ReadyHealthLabelsAndShutdownInOrder) {
  FakeSidecar sidecar;
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&sidecar);
  std::unique_ptr<grpc::Server> sidecar_server = builder.BuildAndStart();
  ASSERT_GT(port, 0);
  setenv("AGONES_SDK_GRPC_PORT", std::to_string(port).c_str(), 1);

  ServerProcess server({"--agones", "--agones-health-ms", "100"});
  unsetenv("AGONES_SDK_GRPC_PORT");
  ASSERT_FALSE(server.address().empty()) << server.log();
  // Ready once listening (the address is printed first), then pings and the first label.
  ASSERT_TRUE(eventually([&] { return sidecar.count("Health") >= 3; }, 10s)) << server.log();
  std::vector<std::string> calls = sidecar.calls();
  ASSERT_FALSE(calls.empty());
  EXPECT_EQ(calls.front(), "Ready");
  EXPECT_EQ(sidecar.count("Ready"), 1);
  EXPECT_EQ(sidecar.count("SetLabel worlds=0"), 1);
  EXPECT_NE(server.log().find("event=agones_ready"), std::string::npos) << server.log();

  auto client = connect(server);
  ASSERT_TRUE(client->create_world_json(pyramid_json()).ok());
  ASSERT_TRUE(client->create_world_json(pyramid_json()).ok());
  ASSERT_TRUE(eventually([&] { return sidecar.count("SetLabel worlds=2") == 1; }, 5s));
  // The count is sampled once per health period and sent only when it changed: whether the two
  // creates fell into one period or two (a slow sanitizer build), no label repeats its
  // predecessor, and worlds=0 and worlds=2 are each sent once.
  std::vector<std::string> labels;
  for (const std::string& c : sidecar.calls())
    if (c.rfind("SetLabel", 0) == 0) labels.push_back(c);
  for (size_t i = 1; i < labels.size(); ++i) EXPECT_NE(labels[i], labels[i - 1]) << i;
  EXPECT_LE(labels.size(), 3u);

  // SIGTERM: Shutdown is called once, and the server still stops gracefully (exit 0).
  EXPECT_EQ(server.terminate(), 0) << server.log();
  calls = sidecar.calls();
  EXPECT_EQ(sidecar.count("Shutdown"), 1);
  int last_label = -1, shutdown = -1;
  for (int i = 0; i < static_cast<int>(calls.size()); ++i) {
    if (calls[i].rfind("SetLabel", 0) == 0) last_label = i;
    if (calls[i] == "Shutdown") shutdown = i;
  }
  EXPECT_GT(shutdown, last_label);
  sidecar_server->Shutdown();
}

// Without a sidecar the server does not pretend to be a GameServer: Ready is retried for
// --agones-ready-ms (the sidecar may start after the server; 30 s by default, 3 s here), then the
// server exits 1 naming the address.
TEST(AgonesContract, NoSidecarStopsTheServerAfterItsPatience) {
  setenv("AGONES_SDK_GRPC_PORT", "1", 1);  // port 1: nothing listens there
  ServerProcess server({"--agones", "--agones-ready-ms", "3000"});
  unsetenv("AGONES_SDK_GRPC_PORT");
  ASSERT_FALSE(server.address().empty());
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  ASSERT_TRUE(
      eventually([&] { return waitpid(server.pid(), &status, WNOHANG) == server.pid(); }, 30s));
  // Ready starts as the server listens and the test sees the address a moment later, so the
  // wait here is a little under 3 s; giving up at once would be far under.
  const auto waited = std::chrono::steady_clock::now() - t0;
  EXPECT_GT(waited, 2s);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  EXPECT_NE(server.log().find("agones: Ready:"), std::string::npos) << server.log();
  EXPECT_NE(server.log().find("(the SDK sidecar at localhost:1)"), std::string::npos)
      << server.log();
}

}  // namespace
}  // namespace fulcrum
