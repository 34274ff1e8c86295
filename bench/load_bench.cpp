// A load benchmark of fulcrum-server: the server in this process on loopback (its log off),
// driven through real gRPC connections.
//   1. Step(1) round-trip latency, p50 and p99, on a small world (the 41-body `mixed` scene)
//      and on a 1000-body world (1000 circles drifting in zero gravity, all awake).
//   2. How many 1000-body worlds fit in real time at 60 Hz: the measured cost of one tick of the
//      drifting world, against 16.7 ms per tick on each of the machine's cores.
//   3. Frame streams of the 1000-body world while one client steps it with Step(1) as fast as
//      it can: frames per second delivered to each reader and bytes per body per frame, for
//      every body (ALL) and changed bodies (CHANGED), full precision and quantized, with 1, 10
//      and 100 readers on connections of their own.
//   4. With --abuse, only this: Step(1) p50 and p99 on the `mixed` world alone, and again while
//      other clients misbehave: 20 frame streams that never read, 100 idle connections, and 4
//      clients calling GetWorld and Step(1) on a 1000-body world as fast as they can; with the
//      process's resident memory before and after.
// Prints Markdown tables.
//   fulcrum_load_bench [--calls N] [--seconds S] [--readers 1,10,100] [--abuse]
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "fulcrum/scenes.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "scene_convert.h"
#include "server.h"
#include "stats.h"

namespace {

using Clock = std::chrono::steady_clock;
using fulcrum::v1::Physics;

double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

[[noreturn]] void die(const std::string& what) {
  std::fprintf(stderr, "fulcrum_load_bench: %s\n", what.c_str());
  std::exit(1);
}

uint64_t create(Physics::Stub* stub, const fulcrum::v1::Scene& scene) {
  fulcrum::v1::CreateWorldRequest request;
  *request.mutable_scene() = scene;
  fulcrum::v1::CreateWorldReply reply;
  grpc::ClientContext context;
  grpc::Status st = stub->CreateWorld(&context, request, &reply);
  if (!st.ok()) die("create " + scene.name() + ": " + st.error_message());
  return reply.world_id();
}

fulcrum::v1::Scene builtin(const char* name) {
  auto scene = fulcrum::scenes::builtin(name);
  if (!scene.ok()) die(scene.status().message());
  return fulcrum::scene_to_proto(*scene, name);
}

// 1000 circles of radius 0.25 m on a 40 x 25 grid 1 m apart, in zero gravity, each with its
// own velocity (up to 2 m/s, from a fixed formula) and sleeping off: every body moves every
// tick, now and then two collide. The worst case for CHANGED frames: everything changed.
fulcrum::v1::Scene drifting_circles() {
  fulcrum::v1::Scene scene;
  scene.set_name("drifting_1000");
  scene.mutable_settings()->mutable_gravity()->set_y(0.0);
  for (int i = 0; i < 1000; ++i) {
    fulcrum::v1::Body* b = scene.add_bodies();
    b->set_type(fulcrum::v1::BODY_TYPE_DYNAMIC);
    b->mutable_position()->set_x(i % 40);
    b->mutable_position()->set_y(i / 40);
    b->mutable_linear_velocity()->set_x(2.0 * std::sin(i * 1.7));
    b->mutable_linear_velocity()->set_y(2.0 * std::cos(i * 2.3));
    b->set_angular_velocity(std::sin(i * 0.9));
    b->set_enable_sleep(false);
    b->add_shapes()->mutable_circle()->set_radius(0.25);
  }
  return scene;
}

double step_once(Physics::Stub* stub, uint64_t world, double* server_ms = nullptr) {
  fulcrum::v1::StepRequest request;
  request.set_world_id(world);
  request.set_ticks(1);
  fulcrum::v1::StepReply reply;
  grpc::ClientContext context;
  const auto t = Clock::now();
  grpc::Status st = stub->Step(&context, request, &reply);
  if (!st.ok()) die("step: " + st.error_message());
  if (server_ms != nullptr) *server_ms += reply.step_ms();
  return ms_since(t);
}

double server_step_ms(Physics::Stub* stub, uint64_t world, uint32_t ticks) {
  fulcrum::v1::StepRequest request;
  request.set_world_id(world);
  request.set_ticks(ticks);
  fulcrum::v1::StepReply reply;
  grpc::ClientContext context;
  if (!stub->Step(&context, request, &reply).ok()) die("step");
  return reply.step_ms() / ticks;
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5));
  return v[i];
}

std::shared_ptr<grpc::Channel> own_channel(const std::string& address, int tag) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  args.SetInt("fulcrum.bench.connection", tag);  // distinct arguments: a connection of its own
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

struct StreamResult {
  double ticks_per_s = 0;         // the world's pace while streaming
  double frames_per_s = 0;        // per reader, mean
  double bytes_per_body = 0;      // per frame and body carried
  double bodies_per_frame = 0;    // mean bodies carried (all 1000 unless CHANGED skips some)
  double coalesced = 0;           // fraction of due frames coalesced away
  double encodings_per_tick = 0;  // frame encodings the server built per tick (shared by readers)
  double server_ms_per_tick = 0;  // the step and the frames' hand-over to readers, on the server
};

StreamResult stream_run(const std::string& address, Physics::Stub* driver, uint64_t world,
                        int readers, fulcrum::v1::FrameBodies mode, bool quantized,
                        double seconds) {
  struct Reader {
    std::shared_ptr<grpc::Channel> channel;
    std::unique_ptr<Physics::Stub> stub;
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReader<fulcrum::v1::Frame>> stream;
    std::thread thread;
    uint64_t frames = 0, bytes = 0, bodies = 0, skipped = 0;
  };
  std::atomic<bool> measuring{false};
  std::vector<std::unique_ptr<Reader>> all;
  for (int i = 0; i < readers; ++i) {
    auto r = std::make_unique<Reader>();
    r->channel = own_channel(address, i);
    r->stub = Physics::NewStub(r->channel);
    fulcrum::v1::StreamFramesRequest request;
    request.set_world_id(world);
    request.set_bodies(mode);
    request.set_quantized(quantized);
    r->stream = r->stub->StreamFrames(&r->context, request);
    Reader* raw = r.get();
    r->thread = std::thread([raw, &measuring] {
      fulcrum::v1::Frame f;
      while (raw->stream->Read(&f)) {
        if (!measuring) continue;
        ++raw->frames;
        raw->bytes += f.ByteSizeLong();
        raw->bodies += f.bodies_size() + f.quantized_bodies_size();
        raw->skipped += f.skipped_frames();
      }
    });
    all.push_back(std::move(r));
  }
  for (int i = 0; i < 30; ++i) step_once(driver, world);  // every reader has its first frame
  measuring = true;
  const uint64_t encoded_before = fulcrum::server::counters().frames_encoded;
  const auto start = Clock::now();
  int ticks = 0;
  double server_ms = 0;
  while (ms_since(start) < seconds * 1000.0) {
    step_once(driver, world, &server_ms);
    ++ticks;
  }
  const double elapsed_s = ms_since(start) / 1000.0;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the last frames land
  const uint64_t encoded = fulcrum::server::counters().frames_encoded - encoded_before;
  measuring = false;
  for (auto& r : all) r->context.TryCancel();
  for (auto& r : all) {
    r->thread.join();
    (void)r->stream->Finish();
  }
  StreamResult out;
  out.ticks_per_s = ticks / elapsed_s;
  out.encodings_per_tick = static_cast<double>(encoded) / ticks;
  out.server_ms_per_tick = server_ms / ticks;
  uint64_t frames = 0, bytes = 0, bodies = 0, skipped = 0;
  for (auto& r : all) {
    frames += r->frames;
    bytes += r->bytes;
    bodies += r->bodies;
    skipped += r->skipped;
  }
  out.frames_per_s = frames / elapsed_s / readers;
  out.bytes_per_body = bodies > 0 ? static_cast<double>(bytes) / bodies : 0.0;
  out.bodies_per_frame = frames > 0 ? static_cast<double>(bodies) / frames : 0.0;
  out.coalesced = frames + skipped > 0 ? static_cast<double>(skipped) / (frames + skipped) : 0.0;
  return out;
}

// This process's resident memory, MB.
double rss_mb() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (f == nullptr) return -1;
  char line[256];
  long kb = -1;
  while (std::fgets(line, sizeof line, f) != nullptr) {
    if (std::strncmp(line, "VmRSS:", 6) == 0) kb = std::atol(line + 6);
  }
  std::fclose(f);
  return kb / 1024.0;
}

void abuse_table(const std::string& address, Physics::Stub* driver, int calls) {
  const uint64_t small = create(driver, builtin("mixed"));
  const uint64_t big = create(driver, drifting_circles());
  auto latencies = [&] {
    std::vector<double> ms;
    for (int i = 0; i < 20; ++i) step_once(driver, small);
    for (int i = 0; i < calls; ++i) ms.push_back(step_once(driver, small));
    return ms;
  };
  std::printf("## A client's Step(1) round trips while others misbehave (%d calls)\n\n", calls);
  std::printf("| while | p50 ms | p99 ms | RSS MB |\n|---|---|---|---|\n");
  std::vector<double> alone = latencies();
  std::printf("| nothing else | %.3f | %.3f | %.0f |\n", percentile(alone, 0.5),
              percentile(alone, 0.99), rss_mb());

  // 20 streams of the 1000-body world (frames of about 70 kB) that are never read.
  struct Idle {
    std::shared_ptr<grpc::Channel> channel;
    std::unique_ptr<Physics::Stub> stub;
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReader<fulcrum::v1::Frame>> stream;
  };
  std::vector<std::unique_ptr<Idle>> silent;
  for (int i = 0; i < 20; ++i) {
    auto r = std::make_unique<Idle>();
    r->channel = own_channel(address, 1000 + i);
    r->stub = Physics::NewStub(r->channel);
    fulcrum::v1::StreamFramesRequest request;
    request.set_world_id(big);
    r->stream = r->stub->StreamFrames(&r->context, request);
    silent.push_back(std::move(r));
  }
  // 100 connections that made one call and then sit idle.
  std::vector<std::shared_ptr<grpc::Channel>> idle;
  for (int i = 0; i < 100; ++i) {
    idle.push_back(own_channel(address, 2000 + i));
    auto stub = Physics::NewStub(idle.back());
    fulcrum::v1::GetWorldRequest get;
    get.set_world_id(small);
    fulcrum::v1::WorldInfo info;
    grpc::ClientContext context;
    (void)stub->GetWorld(&context, get, &info);
  }
  // 4 clients flooding the 1000-body world.
  std::atomic<bool> stop{false};
  std::vector<std::thread> flood;
  for (int i = 0; i < 4; ++i) {
    flood.emplace_back([&, i] {
      auto channel = own_channel(address, 3000 + i);
      auto stub = Physics::NewStub(channel);
      while (!stop) {
        fulcrum::v1::GetWorldRequest get;
        get.set_world_id(big);
        fulcrum::v1::WorldInfo info;
        grpc::ClientContext c1;
        (void)stub->GetWorld(&c1, get, &info);
        step_once(stub.get(), big);
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  std::vector<double> abused = latencies();
  std::printf(
      "| 20 unread streams, 100 idle connections, 4 flooding clients | %.3f | %.3f | %.0f |\n",
      percentile(abused, 0.5), percentile(abused, 0.99), rss_mb());
  stop = true;
  for (std::thread& t : flood) t.join();
  for (auto& r : silent) r->context.TryCancel();
  silent.clear();
  std::fflush(stdout);
}

std::vector<int> parse_list(const char* text) {
  std::vector<int> out;
  for (const char* p = text; *p != '\0';) {
    out.push_back(std::atoi(p));
    const char* comma = std::strchr(p, ',');
    if (comma == nullptr) break;
    p = comma + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  int calls = 1000;
  double seconds = 2.0;
  std::vector<int> reader_counts = {1, 10, 100};
  bool abuse = false;
  for (int i = 1; i < argc; i += 2) {
    if (std::strcmp(argv[i], "--abuse") == 0) {
      abuse = true;
      --i;  // takes no value
      continue;
    }
    if (i + 1 >= argc) die(std::string("flag ") + argv[i] + " needs a value");
    if (std::strcmp(argv[i], "--calls") == 0) {
      calls = std::max(10, std::atoi(argv[i + 1]));
    } else if (std::strcmp(argv[i], "--seconds") == 0) {
      seconds = std::max(0.2, std::atof(argv[i + 1]));
    } else if (std::strcmp(argv[i], "--readers") == 0) {
      reader_counts = parse_list(argv[i + 1]);
    } else {
      die(std::string("unknown flag ") + argv[i]);
    }
  }
  fulcrum::server::set_logging(false);
  fulcrum::server::ServerOptions options;
  options.listen = "127.0.0.1:0";
  auto server = fulcrum::server::Server::start(options);
  if (!server.ok()) die(server.status().message());
  const std::string address = (*server)->address();
  auto driver_channel = own_channel(address, -1);
  auto driver = Physics::NewStub(driver_channel);

  if (abuse) {
    abuse_table(address, driver.get(), calls);
    driver.reset();
    (*server)->shutdown(std::chrono::milliseconds(100));
    return 0;
  }

  std::printf("## Step(1) round trips (%d calls each)\n\n", calls);
  std::printf("| world | bodies | p50 ms | p99 ms | server ms per tick |\n|---|---|---|---|---|\n");
  struct Case {
    const char* label;
    fulcrum::v1::Scene scene;
    int bodies;
  };
  std::vector<Case> cases = {{"mixed", builtin("mixed"), 41},
                             {"drifting_1000", drifting_circles(), 1000}};
  double tick_ms_1000 = 0;
  for (Case& c : cases) {
    const uint64_t world = create(driver.get(), c.scene);
    for (int i = 0; i < 20; ++i) step_once(driver.get(), world);
    std::vector<double> ms;
    ms.reserve(calls);
    for (int i = 0; i < calls; ++i) ms.push_back(step_once(driver.get(), world));
    const double server_ms = server_step_ms(driver.get(), world, 100);
    if (c.bodies == 1000) tick_ms_1000 = server_ms;
    std::printf("| %s | %d | %.3f | %.3f | %.4f |\n", c.label, c.bodies, percentile(ms, 0.5),
                percentile(ms, 0.99), server_ms);
  }
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  std::printf(
      "\n1000-body worlds in real time at 60 Hz: %.3f ms per tick, so %.0f per core (16.67 ms "
      "per tick), about %.0f on %u cores with nothing else running (an estimate from the tick "
      "cost, not a run of real-time worlds)\n",
      tick_ms_1000, std::floor(16.667 / tick_ms_1000), std::floor(16.667 / tick_ms_1000) * cores,
      cores);

  std::printf("\n## Frames of drifting_1000, Step(1) as fast as one client can (%.1f s each)\n\n",
              seconds);
  std::printf(
      "| bodies | precision | readers | world ticks/s | server ms per tick | frames/s per reader | "
      "coalesced | encodings per tick | bodies per frame | bytes per body per frame |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
  const uint64_t world = create(driver.get(), drifting_circles());
  for (auto mode : {fulcrum::v1::FRAME_BODIES_ALL, fulcrum::v1::FRAME_BODIES_CHANGED}) {
    for (bool quantized : {false, true}) {
      for (int readers : reader_counts) {
        StreamResult r =
            stream_run(address, driver.get(), world, readers, mode, quantized, seconds);
        std::printf("| %s | %s | %d | %.0f | %.2f | %.0f | %.0f %% | %.2f | %.0f | %.1f |\n",
                    mode == fulcrum::v1::FRAME_BODIES_ALL ? "ALL" : "CHANGED",
                    quantized ? "quantized" : "full", readers, r.ticks_per_s, r.server_ms_per_tick,
                    r.frames_per_s, 100.0 * r.coalesced, r.encodings_per_tick, r.bodies_per_frame,
                    r.bytes_per_body);
        std::fflush(stdout);
      }
    }
  }
  driver.reset();
  (*server)->shutdown(std::chrono::milliseconds(100));
  return 0;
}
