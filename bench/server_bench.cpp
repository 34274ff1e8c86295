// What the wire costs: the server in-process on loopback, measured from a client in the same
// process. Step round trips against local steps, snapshot size and time, and frame streams
// (bytes per frame for all bodies against changed bodies only, frames delivered and coalesced
// for 10 readers). Prints Markdown tables. With --limits, only the largest requests the default
// limits let through (and the first ones past them), with the time the server took to answer.
//   fulcrum_server_bench [--calls N] [--limits]
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "fulcrum/scenes.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"
#include "server.h"

namespace {

using Clock = std::chrono::steady_clock;
using fulcrum::v1::Physics;

double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

uint64_t create(Physics::Stub* stub, const char* builtin) {
  fulcrum::v1::CreateWorldRequest request;
  auto scene = fulcrum::scenes::builtin(builtin);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    std::exit(1);
  }
  *request.mutable_scene() = fulcrum::scene_to_proto(*scene, builtin);
  fulcrum::v1::CreateWorldReply reply;
  grpc::ClientContext context;
  grpc::Status st = stub->CreateWorld(&context, request, &reply);
  if (!st.ok()) {
    std::fprintf(stderr, "create %s: %s\n", builtin, st.error_message().c_str());
    std::exit(1);
  }
  return reply.world_id();
}

double step_ms(Physics::Stub* stub, uint64_t world, uint32_t ticks) {
  fulcrum::v1::StepRequest request;
  request.set_world_id(world);
  request.set_ticks(ticks);
  fulcrum::v1::StepReply reply;
  grpc::ClientContext context;
  auto t = Clock::now();
  if (!stub->Step(&context, request, &reply).ok()) std::exit(1);
  return ms_since(t);
}

double local_ms_per_step(const char* builtin, int settle, int calls) {
  auto world = fulcrum::build_world(*fulcrum::scenes::builtin(builtin));
  for (int i = 0; i < settle; ++i) world->step();
  auto t = Clock::now();
  for (int i = 0; i < calls; ++i) world->step();
  return ms_since(t) / calls;
}

struct StreamFigures {
  double bytes_per_frame = 0;
  int64_t frames = 0;
  int64_t coalesced = 0;
};

// `readers` streams in `mode` while the world is stepped `ticks` times, one tick per call.
StreamFigures stream(Physics::Stub* stub, uint64_t world, fulcrum::v1::FrameBodies mode,
                     int readers, int ticks) {
  std::atomic<int64_t> bytes{0}, frames{0}, coalesced{0};
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::thread> threads;
  std::atomic<int> started{0};
  for (int r = 0; r < readers; ++r) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    grpc::ClientContext* context = contexts.back().get();
    threads.emplace_back([&, context] {
      fulcrum::v1::StreamFramesRequest request;
      request.set_world_id(world);
      request.set_every_ticks(1);
      request.set_bodies(mode);
      auto reader = stub->StreamFrames(context, request);
      fulcrum::v1::Frame frame;
      bool first = true;
      while (reader->Read(&frame)) {
        if (first) {
          ++started;
          first = false;
          continue;  // the subscription's first frame is always full
        }
        bytes += static_cast<int64_t>(frame.ByteSizeLong());
        ++frames;
        coalesced += static_cast<int64_t>(frame.skipped_frames());
      }
      (void)reader->Finish();
    });
  }
  while (started < readers) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  for (int i = 0; i < ticks; ++i) step_ms(stub, world, 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  for (auto& c : contexts) c->TryCancel();
  for (auto& t : threads) t.join();
  StreamFigures f;
  f.frames = frames;
  f.coalesced = coalesced;
  f.bytes_per_frame = frames > 0 ? static_cast<double>(bytes) / static_cast<double>(frames) : 0;
  return f;
}

// One circle of radius 0.5 per body, `bodies` of them: piled on one spot, or in a grid 1 m apart
// (`spread`). `shapes_on_first` puts that many circles, side by side, on one body instead.
fulcrum::v1::EditBatch bodies_batch(int bodies, bool spread, int shapes_on_first = 1) {
  fulcrum::v1::EditBatch batch;
  for (int i = 0; i < bodies; ++i) {
    fulcrum::v1::Body* b = batch.add_edits()->mutable_create_body();
    b->set_type(fulcrum::v1::BODY_TYPE_DYNAMIC);
    if (spread) {
      b->mutable_position()->set_x(i % 300);
      b->mutable_position()->set_y(i / 300);
    }
    const int shapes = i == 0 ? shapes_on_first : 1;
    for (int k = 0; k < shapes; ++k) {
      fulcrum::v1::Circle* c = b->add_shapes()->mutable_circle();
      c->set_radius(shapes > 1 ? 0.1 : 0.5);
      c->mutable_center()->set_x(0.25 * (k % 1000));
      c->mutable_center()->set_y(0.25 * (k / 1000));
    }
  }
  return batch;
}

uint64_t empty_world(Physics::Stub* stub) {
  fulcrum::v1::CreateWorldRequest request;
  request.mutable_scene()->set_name("limits");
  fulcrum::v1::CreateWorldReply reply;
  grpc::ClientContext context;
  (void)stub->CreateWorld(&context, request, &reply);
  return reply.world_id();
}

void limit_row(const char* what, size_t bytes, const grpc::Status& st, double ms) {
  std::printf("| %s | %.2f | %s | %.1f |\n", what, bytes / 1e6,
              st.ok() ? "OK"
                      : (st.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED
                             ? "RESOURCE_EXHAUSTED"
                             : st.error_message().c_str()),
              ms);
}

void apply_row(Physics::Stub* stub, const char* what, const fulcrum::v1::EditBatch& batch) {
  const uint64_t world = empty_world(stub);
  fulcrum::v1::ApplyEditsRequest request;
  request.set_world_id(world);
  *request.mutable_batch() = batch;
  fulcrum::v1::ApplyEditsReply reply;
  grpc::ClientContext context;
  const auto t = Clock::now();
  grpc::Status st = stub->ApplyEdits(&context, request, &reply);
  limit_row(what, request.ByteSizeLong(), st, ms_since(t));
}

// The largest requests the default limits allow, and the first past them.
void limits_table(Physics::Stub* stub) {
  std::printf("Requests at the default limits (in-process server, loopback)\n\n");
  std::printf("| request | MB | answer | ms |\n|---|---|---|---|\n");
  apply_row(stub, "ApplyEdits: one body of 1024 circles (max_shapes_per_body)",
            bodies_batch(1, false, 1024));
  apply_row(stub, "ApplyEdits: one body of 1025 circles", bodies_batch(1, false, 1025));
  apply_row(stub, "ApplyEdits: one body of 300 000 circles", bodies_batch(1, false, 300000));
  apply_row(stub, "ApplyEdits: 100 000 bodies 1 m apart (max_edits, max_bodies)",
            bodies_batch(100000, true));
  apply_row(stub, "ApplyEdits: 4400 bodies on one spot (near max_batch_work)",
            bodies_batch(4400, false));
  apply_row(stub, "ApplyEdits: 4600 bodies on one spot", bodies_batch(4600, false));
  {
    fulcrum::v1::CreateWorldRequest request;
    const fulcrum::v1::EditBatch pile = bodies_batch(4600, false);
    for (const auto& e : pile.edits()) {
      *request.mutable_scene()->add_bodies() = e.create_body();
    }
    fulcrum::v1::CreateWorldReply reply;
    grpc::ClientContext context;
    const auto t = Clock::now();
    grpc::Status st = stub->CreateWorld(&context, request, &reply);
    limit_row("CreateWorld: 4600 bodies on one spot", request.ByteSizeLong(), st, ms_since(t));
  }
  for (int pile : {1000, 1001, 4400}) {
    // 1000 bodies make 499 500 contacts (max_contacts is 500 000); 1001 make 500 500.
    const uint64_t world = empty_world(stub);
    fulcrum::v1::ApplyEditsRequest request;
    request.set_world_id(world);
    *request.mutable_batch() = bodies_batch(pile, false);
    fulcrum::v1::ApplyEditsReply reply;
    grpc::ClientContext context;
    (void)stub->ApplyEdits(&context, request, &reply);
    fulcrum::v1::StepRequest step;
    step.set_world_id(world);
    step.set_ticks(1);
    fulcrum::v1::StepReply stepped;
    grpc::ClientContext step_context;
    const auto t = Clock::now();
    grpc::Status st = stub->Step(&step_context, step, &stepped);
    const std::string what = "Step(1) of " + std::to_string(pile) + " bodies on one spot";
    limit_row(what.c_str(), step.ByteSizeLong(), st, ms_since(t));
  }
}

}  // namespace

int main(int argc, char** argv) {
  int calls = 500;
  bool limits = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--calls") == 0 && i + 1 < argc) {
      calls = std::max(1, std::atoi(argv[i + 1]));
    }
    if (std::strcmp(argv[i], "--limits") == 0) limits = true;
  }
  fulcrum::server::ServerOptions options;
  options.listen = "127.0.0.1:0";
  auto server = fulcrum::server::Server::start(options);
  if (!server.ok()) {
    std::fprintf(stderr, "%s\n", server.status().message().c_str());
    return 1;
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);  // snapshots of large worlds pass gRPC's 4 MB default
  auto channel =
      grpc::CreateCustomChannel((*server)->address(), grpc::InsecureChannelCredentials(), args);
  auto stub = Physics::NewStub(channel);
  if (limits) {
    limits_table(stub.get());
    (*server)->shutdown(std::chrono::milliseconds(1000));
    return 0;
  }

  std::printf("Step round trips (%d calls of 1 tick each, loopback, in-process server)\n\n", calls);
  std::printf("| scene | bodies | local ms/step | Step(1) ms/call | wire overhead ms |\n");
  std::printf("|---|---|---|---|---|\n");
  for (const char* name : {"vertical_stack", "large_pyramid", "mixed"}) {
    const uint64_t world = create(stub.get(), name);
    const int settle = 60;
    step_ms(stub.get(), world, settle);
    std::vector<double> t;
    for (int i = 0; i < calls; ++i) t.push_back(step_ms(stub.get(), world, 1));
    double total = 0;
    for (double x : t) total += x;
    const double remote = total / calls;
    const double local = local_ms_per_step(name, settle, calls);
    fulcrum::v1::GetWorldRequest get;
    get.set_world_id(world);
    fulcrum::v1::WorldInfo info;
    grpc::ClientContext context;
    (void)stub->GetWorld(&context, get, &info);
    std::printf("| %s | %d | %.4f | %.4f | %.4f |\n", name, info.body_count(), local, remote,
                remote - local);
  }

  std::printf("\nSnapshots over the wire\n\n| scene | bytes | GetSnapshot ms |\n|---|---|---|\n");
  for (const char* name : {"vertical_stack", "large_pyramid"}) {
    const uint64_t world = create(stub.get(), name);
    step_ms(stub.get(), world, 60);
    fulcrum::v1::GetSnapshotRequest request;
    request.set_world_id(world);
    fulcrum::v1::GetSnapshotReply reply;
    grpc::ClientContext context;
    auto t = Clock::now();
    grpc::Status st = stub->GetSnapshot(&context, request, &reply);
    if (!st.ok()) {
      std::fprintf(stderr, "GetSnapshot %s: %s\n", name, st.error_message().c_str());
      return 1;
    }
    const double ms = ms_since(t);
    std::printf("| %s | %zu | %.3f |\n", name, reply.snapshot().ByteSizeLong(), ms);
  }

  std::printf(
      "\nFrame streams: 10 readers, every tick, %d ticks stepped one per call (mixed scene, "
      "awake)\n\n| bodies sent | bytes/frame | frames delivered | coalesced |\n|---|---|---|---|\n",
      calls);
  for (auto mode : {fulcrum::v1::FRAME_BODIES_ALL, fulcrum::v1::FRAME_BODIES_CHANGED,
                    fulcrum::v1::FRAME_BODIES_NONE}) {
    const uint64_t world = create(stub.get(), "mixed");
    StreamFigures f = stream(stub.get(), world, mode, 10, calls);
    std::printf("| %s | %.0f | %lld | %lld |\n", fulcrum::v1::FrameBodies_Name(mode).c_str(),
                f.bytes_per_frame, static_cast<long long>(f.frames),
                static_cast<long long>(f.coalesced));
  }
  (*server)->shutdown(std::chrono::milliseconds(1000));
  return 0;
}
