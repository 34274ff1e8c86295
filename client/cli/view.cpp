// fulcrum view: serves one page (client/cli/view/, embedded at build time) that draws a world
// live from its frame stream, or plays a replay file with a timeline.
//
// Live: the page reads frames as Server-Sent Events from /events (one StreamFrames call per
// page, FRAME_BODIES_CHANGED at full precision, coalesced here while the page is busy) and the
// shapes from /api/describe (DescribeWorld). Run, pause and step are SetRunMode and Step;
// dragging a body is a target joint made by an edit (CreateJoint), moved by SetJointTarget and
// destroyed on release. Replay: /api/replay/frame?tick=N re-steps the file locally (view.h).
//
// Signals: SIGINT and SIGTERM stop the HTTP server, end the streams and exit 0.
#include "view.h"  // first: Eigen (through fulcrum/world.h) before httplib.h's <resolv.h>

#include <google/protobuf/util/json_util.h>
#include <httplib.h>
#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <map>
#include <mutex>
#include <ostream>
#include <thread>

#include "remote.h"
#include "view_assets.h"

namespace fulcrum::cli {

std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\u00";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

std::string json_number(double value) {
  if (!std::isfinite(value)) return "null";
  char buf[64];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value);
  return std::string(buf, ec == std::errc() ? end - buf : 0);
}

std::string frame_json(const FrameJson& f) {
  std::string out = "{\"tick\":" + std::to_string(f.tick) + ",\"hash\":\"" +
                    World::hash_text(f.hash) + "\",\"bodies\":" + std::to_string(f.body_count) +
                    ",\"awake\":" + std::to_string(f.awake_count) +
                    ",\"full\":" + (f.full ? "true" : "false") + ",\"destroyed\":[";
  for (size_t i = 0; i < f.destroyed.size(); ++i) {
    if (i > 0) out += ',';
    out += "[" + std::to_string(f.destroyed[i].index) + "," +
           std::to_string(f.destroyed[i].generation) + "]";
  }
  out += "],\"b\":[";
  for (size_t i = 0; i < f.bodies.size(); ++i) {
    const client::BodyFrame& b = f.bodies[i];
    if (i > 0) out += ',';
    out += "[" + std::to_string(b.id.index) + "," + std::to_string(b.id.generation) + "," +
           json_number(b.position.x()) + "," + json_number(b.position.y()) + "," +
           json_number(b.angle) + "," + (b.awake ? "1" : "0") + "]";
  }
  return out + "]" + f.extra + "}";
}

std::string description_json(const v1::DescribeWorldReply& reply) {
  google::protobuf::util::JsonPrintOptions options;
  options.always_print_primitive_fields = true;
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(reply, &out, options);
  return out;
}

namespace {

constexpr const char* kJson = "application/json";

void reply_json(httplib::Response& res, const std::string& json) {
  res.set_header("Cache-Control", "no-store");
  res.set_content(json, kJson);
}

// An error as the page shows it: {"error": message}, with a status that fits the code.
void reply_error(httplib::Response& res, const Status& status) {
  switch (status.code()) {
    case StatusCode::kInvalidArgument:
      res.status = 400;
      break;
    case StatusCode::kNotFound:
      res.status = 404;
      break;
    case StatusCode::kFailedPrecondition:
      res.status = 409;
      break;
    default:
      res.status = 502;  // the fulcrum-server refused or did not answer
  }
  reply_json(res, "{\"error\":" + json_string(status.message()) + "}");
}

// A query parameter as a number; INVALID_ARGUMENT naming it when absent or malformed.
Result<int64_t> int_param(const httplib::Request& req, const char* name, int64_t min, int64_t max) {
  if (!req.has_param(name)) return invalid_argument(std::string(name) + ": required");
  std::string error;
  std::optional<int64_t> v = parse_int(req.get_param_value(name), min, max, &error);
  if (!v) return invalid_argument(std::string(name) + ": " + error);
  return *v;
}

Result<double> double_param(const httplib::Request& req, const char* name) {
  if (!req.has_param(name)) return invalid_argument(std::string(name) + ": required");
  const std::string text = req.get_param_value(name);
  double v = 0.0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v)) {
    return invalid_argument(std::string(name) + ": expected a number, got '" + text + "'");
  }
  return v;
}

// "index:generation".
Result<JointId> joint_param(const httplib::Request& req) {
  const std::string text = req.has_param("joint") ? req.get_param_value("joint") : "";
  const size_t colon = text.find(':');
  std::string error;
  std::optional<int64_t> index, generation;
  if (colon != std::string::npos) {
    index = parse_int(text.substr(0, colon), 0, std::numeric_limits<int32_t>::max(), &error);
    generation = parse_int(text.substr(colon + 1), 1, std::numeric_limits<uint32_t>::max(), &error);
  }
  if (!index || !generation) {
    return invalid_argument("joint: expected INDEX:GENERATION, got '" + text + "'");
  }
  return JointId{static_cast<int32_t>(*index), static_cast<uint32_t>(*generation)};
}

void set_handle(int32_t index, uint32_t generation, v1::Handle* out) {
  out->set_index(index);
  out->set_generation(generation);
}

const char* run_mode_name(client::RunMode mode) {
  return mode == client::RunMode::kRealTime ? "real_time" : "paused";
}

// What one page's /events stream has not sent yet: the changes of every frame that arrived
// since the last event, merged (a body's newest state wins), so a page that is slow to take
// events gets fewer, larger ones and never an unbounded queue.
struct EventStream {
  std::mutex mu;
  std::condition_variable cv;
  FrameJson pending;
  std::map<int32_t, client::BodyFrame> changed;  // by index
  std::map<int32_t, uint32_t> destroyed;         // index -> generation
  bool has_frame = false;
  bool ended = false;
  std::string end_message;
  std::unique_ptr<client::Subscription> subscription;
  std::thread waiter;  // sees the stream end (world deleted, server gone)

  void merge(const client::Frame& f) {
    std::lock_guard<std::mutex> lock(mu);
    if (f.full) {
      pending.full = true;
      changed.clear();
      destroyed.clear();
    }
    for (const BodyId& gone : f.destroyed) {
      changed.erase(gone.index);
      destroyed[gone.index] = gone.generation;
    }
    for (const client::BodyFrame& b : f.bodies) changed[b.id.index] = b;
    pending.tick = f.tick;
    pending.hash = f.state_hash;
    pending.body_count = f.body_count;
    pending.awake_count = f.awake_body_count;
    has_frame = true;
    cv.notify_all();
  }

  // Called with mu held.
  std::string take_locked() {
    for (const auto& [index, generation] : destroyed) {
      pending.destroyed.push_back(BodyId{index, generation});
    }
    for (const auto& [index, body] : changed) pending.bodies.push_back(body);
    std::string json = frame_json(pending);
    pending = FrameJson();
    changed.clear();
    destroyed.clear();
    has_frame = false;
    return json;
  }
};

// The live viewer's routes, against one fulcrum-server.
class LiveView {
 public:
  LiveView(std::unique_ptr<client::Client> client, const std::atomic<bool>* stopping)
      : client_(std::move(client)), stopping_(stopping) {}

  void install(httplib::Server& http) {
    http.Get("/api/info", [](const httplib::Request&, httplib::Response& res) {
      reply_json(res, "{\"mode\":\"live\"}");
    });
    http.Get("/api/worlds", [this](const httplib::Request&, httplib::Response& res) {
      auto worlds = client_->list_worlds();
      if (!worlds.ok()) return reply_error(res, worlds.status());
      std::string out = "[";
      for (const client::WorldSummary& w : *worlds) {
        if (out.size() > 1) out += ',';
        out += "{\"id\":" + std::to_string(w.id) + ",\"name\":" + json_string(w.name) +
               ",\"tick\":" + std::to_string(w.tick) +
               ",\"bodies\":" + std::to_string(w.body_count) + ",\"mode\":\"" +
               run_mode_name(w.run.mode) + "\"}";
      }
      reply_json(res, out + "]");
    });
    http.Get("/api/describe", [this](const httplib::Request& req, httplib::Response& res) {
      Result<int64_t> world = world_param(req);
      if (!world.ok()) return reply_error(res, world.status());
      auto d = client_->describe_world(static_cast<uint64_t>(*world));
      if (!d.ok()) return reply_error(res, d.status());
      reply_json(res, description_json(*d));
    });
    http.Get("/api/status", [this](const httplib::Request& req, httplib::Response& res) {
      Result<int64_t> world = world_param(req);
      if (!world.ok()) return reply_error(res, world.status());
      status(static_cast<uint64_t>(*world), res);
    });
    http.Post("/api/run", [this](const httplib::Request& req, httplib::Response& res) {
      set_mode(req, res, client::RunMode::kRealTime);
    });
    http.Post("/api/pause", [this](const httplib::Request& req, httplib::Response& res) {
      set_mode(req, res, client::RunMode::kPaused);
    });
    http.Post("/api/step", [this](const httplib::Request& req, httplib::Response& res) {
      Result<int64_t> world = world_param(req);
      if (!world.ok()) return reply_error(res, world.status());
      int64_t ticks = 1;
      if (req.has_param("ticks")) {
        Result<int64_t> t = int_param(req, "ticks", 1, 100000);
        if (!t.ok()) return reply_error(res, t.status());
        ticks = *t;
      }
      auto stepped = client_->step(static_cast<uint64_t>(*world), static_cast<uint32_t>(ticks));
      if (!stepped.ok()) return reply_error(res, stepped.status());
      reply_json(res, "{\"tick\":" + std::to_string(stepped->tick) + ",\"hash\":\"" +
                          World::hash_text(stepped->state_hash) +
                          "\",\"stepMs\":" + json_number(stepped->step_ms) + "}");
    });
    http.Post("/api/drag/start", [this](const httplib::Request& req, httplib::Response& res) {
      drag_start(req, res);
    });
    http.Post("/api/drag/move",
              [this](const httplib::Request& req, httplib::Response& res) { drag_move(req, res); });
    http.Post("/api/drag/end", [this](const httplib::Request& req, httplib::Response& res) {
      Result<int64_t> world = world_param(req);
      Result<JointId> joint = joint_param(req);
      if (!world.ok()) return reply_error(res, world.status());
      if (!joint.ok()) return reply_error(res, joint.status());
      v1::EditBatch batch;
      set_handle(joint->index, joint->generation, batch.add_edits()->mutable_destroy_joint());
      auto applied = client_->apply_edits(static_cast<uint64_t>(*world), batch);
      if (!applied.ok()) return reply_error(res, applied.status());
      reply_json(res, "{}");
    });
    http.Get("/events", [this](const httplib::Request& req, httplib::Response& res) {
      Result<int64_t> world = world_param(req);
      if (!world.ok()) return reply_error(res, world.status());
      events(static_cast<uint64_t>(*world), res);
    });
  }

 private:
  static Result<int64_t> world_param(const httplib::Request& req) {
    return int_param(req, "world", 1, std::numeric_limits<int64_t>::max());
  }

  void set_mode(const httplib::Request& req, httplib::Response& res, client::RunMode mode) {
    Result<int64_t> world = world_param(req);
    if (!world.ok()) return reply_error(res, world.status());
    auto set = client_->set_run_mode(static_cast<uint64_t>(*world), mode);
    if (!set.ok()) return reply_error(res, set.status());
    reply_json(res, "{\"mode\":\"" + std::string(run_mode_name(set->mode)) +
                        "\",\"tick\":" + std::to_string(set->tick) + "}");
  }

  // The world's summary, and the server's mean step time per tick since the previous status
  // call (GetStats counts over all worlds; the page asks about once a second).
  void status(uint64_t world, httplib::Response& res) {
    auto w = client_->get_world(world);
    if (!w.ok()) return reply_error(res, w.status());
    auto stats = client_->get_stats();
    double step_ms = -1.0;
    if (stats.ok()) {
      std::lock_guard<std::mutex> lock(stats_mu_);
      const uint64_t ticks = stats->ticks_stepped() - last_ticks_;
      if (ticks > 0 && last_ticks_ > 0) {
        last_step_ms_ = (stats->step_ms_total() - last_step_ms_total_) / static_cast<double>(ticks);
      }
      last_ticks_ = stats->ticks_stepped();
      last_step_ms_total_ = stats->step_ms_total();
      step_ms = last_step_ms_;
    }
    reply_json(
        res,
        "{\"id\":" + std::to_string(w->id) + ",\"name\":" + json_string(w->name) +
            ",\"tick\":" + std::to_string(w->tick) + ",\"hash\":\"" +
            World::hash_text(w->state_hash) + "\",\"bodies\":" + std::to_string(w->body_count) +
            ",\"awake\":" + std::to_string(w->awake_body_count) + ",\"mode\":\"" +
            run_mode_name(w->run.mode) + "\",\"dropped\":" + std::to_string(w->run.ticks_dropped) +
            ",\"stepMsPerTick\":" + (step_ms < 0 ? "null" : json_number(step_ms)) + "}");
  }

  // Picks the dynamic body under (x, y) and ties it to the point with a target joint whose
  // body A is the world's first static body (a shapeless static body is made when there is
  // none). The pull is capped at 1000 times the body's weight in kg, as Box2D's samples do.
  void drag_start(const httplib::Request& req, httplib::Response& res) {
    Result<int64_t> world_id = world_param(req);
    if (!world_id.ok()) return reply_error(res, world_id.status());
    const uint64_t world = static_cast<uint64_t>(*world_id);
    Result<double> x = double_param(req, "x"), y = double_param(req, "y");
    if (!x.ok()) return reply_error(res, x.status());
    if (!y.ok()) return reply_error(res, y.status());
    auto hits = client_->overlap_point(world, Vec2(*x, *y));
    if (!hits.ok()) return reply_error(res, hits.status());
    if (hits->empty()) return reply_json(res, "{\"joint\":null}");
    auto d = client_->describe_world(world);
    if (!d.ok()) return reply_error(res, d.status());
    const v1::DescribedBody* picked = nullptr;
    const v1::DescribedBody* anchor = nullptr;
    for (const v1::DescribedBody& b : d->bodies()) {
      if (anchor == nullptr && b.body().type() == v1::BODY_TYPE_STATIC) anchor = &b;
      const bool movable =
          b.body().type() == v1::BODY_TYPE_DYNAMIC || b.body().type() == v1::BODY_TYPE_PARTICLE;
      for (const client::ShapeHit& h : *hits) {
        if (picked == nullptr && movable && h.body.index == b.handle().index() &&
            h.body.generation == b.handle().generation()) {
          picked = &b;
        }
      }
    }
    if (picked == nullptr) return reply_json(res, "{\"joint\":null}");
    v1::Handle ground;
    if (anchor != nullptr) {
      ground = anchor->handle();
    } else {
      v1::EditBatch make;
      make.add_edits()->mutable_create_body();  // static, at the origin, no shapes
      auto made = client_->apply_edits(world, make);
      if (!made.ok()) return reply_error(res, made.status());
      set_handle(made->bodies.at(0).index, made->bodies.at(0).generation, &ground);
    }
    // The grabbed point in the body's frame.
    const v1::Body& body = picked->body();
    const double c = std::cos(body.angle()), s = std::sin(body.angle());
    const double dx = *x - body.position().x(), dy = *y - body.position().y();
    v1::EditBatch batch;
    v1::CreateJoint* cj = batch.add_edits()->mutable_create_joint();
    *cj->mutable_body_a() = ground;
    *cj->mutable_body_b() = picked->handle();
    v1::Joint* joint = cj->mutable_joint();
    joint->mutable_local_anchor_b()->set_x(c * dx + s * dy);
    joint->mutable_local_anchor_b()->set_y(-s * dx + c * dy);
    v1::TargetJoint* target = joint->mutable_target();
    target->mutable_target()->set_x(*x);
    target->mutable_target()->set_y(*y);
    target->set_max_force(1000.0 * std::max(picked->mass(), 1e-3));
    v1::SetAwake* awake = batch.add_edits()->mutable_set_awake();
    *awake->mutable_body() = picked->handle();
    awake->set_awake(true);
    auto applied = client_->apply_edits(world, batch);
    if (!applied.ok()) return reply_error(res, applied.status());
    const JointId j = applied->joints.at(0);
    reply_json(res, "{\"joint\":\"" + std::to_string(j.index) + ":" + std::to_string(j.generation) +
                        "\",\"body\":" + std::to_string(picked->handle().index()) + "}");
  }

  void drag_move(const httplib::Request& req, httplib::Response& res) {
    Result<int64_t> world = world_param(req);
    Result<JointId> joint = joint_param(req);
    Result<double> x = double_param(req, "x"), y = double_param(req, "y");
    for (const Status& s : {world.status(), joint.status(), x.status(), y.status()}) {
      if (!s.ok()) return reply_error(res, s);
    }
    v1::EditBatch batch;
    v1::SetJointTarget* t = batch.add_edits()->mutable_set_joint_target();
    set_handle(joint->index, joint->generation, t->mutable_joint());
    t->mutable_target()->set_x(*x);
    t->mutable_target()->set_y(*y);
    auto applied = client_->apply_edits(static_cast<uint64_t>(*world), batch);
    if (!applied.ok()) return reply_error(res, applied.status());
    reply_json(res, "{}");
  }

  // Server-Sent Events: one "data:" line of frame JSON per event, at most one event per 15 ms
  // (what arrives meanwhile is merged); a comment line every second while nothing arrives, so
  // that a page that went away is noticed; "event: end" with the reason when the stream ends.
  void events(uint64_t world, httplib::Response& res) {
    auto stream = std::make_shared<EventStream>();
    client::SubscribeOptions options;
    options.bodies = client::FrameBodies::kChanged;
    auto sub = client_->subscribe(
        world, options, [weak = std::weak_ptr<EventStream>(stream)](const client::Frame& f) {
          if (auto s = weak.lock()) s->merge(f);
        });
    if (!sub.ok()) return reply_error(res, sub.status());
    stream->subscription = std::move(sub).value();
    stream->waiter = std::thread([raw = stream.get()] {
      Status end = raw->subscription->wait();
      std::lock_guard<std::mutex> lock(raw->mu);
      raw->ended = true;
      raw->end_message = end.ok() ? "the stream ended" : end.message();
      raw->cv.notify_all();
    });
    res.set_header("Cache-Control", "no-store");
    res.set_chunked_content_provider(
        "text/event-stream",
        [stream, stopping = stopping_, last = std::chrono::steady_clock::time_point()](
            size_t, httplib::DataSink& sink) mutable {
          std::unique_lock<std::mutex> lock(stream->mu);
          stream->cv.wait_until(lock, last + std::chrono::milliseconds(15),
                                [&] { return stream->ended || stopping->load(); });
          stream->cv.wait_for(lock, std::chrono::seconds(1), [&] {
            return stream->has_frame || stream->ended || stopping->load();
          });
          std::string message;
          if (stream->ended || stopping->load()) {
            message =
                "event: end\ndata: " +
                json_string(stopping->load() ? "fulcrum view is stopping" : stream->end_message) +
                "\n\n";
            lock.unlock();
            sink.write(message.data(), message.size());
            sink.done();
            return true;
          }
          if (!stream->has_frame) {
            lock.unlock();
            return sink.write(": idle\n\n", 9);
          }
          message = "data: " + stream->take_locked() + "\n\n";
          lock.unlock();
          last = std::chrono::steady_clock::now();
          return sink.write(message.data(), message.size());
        },
        [stream](bool) {
          stream->subscription->cancel();
          if (stream->waiter.joinable()) stream->waiter.join();
        });
  }

  std::unique_ptr<client::Client> client_;
  const std::atomic<bool>* stopping_;
  std::mutex stats_mu_;
  uint64_t last_ticks_ = 0;
  double last_step_ms_total_ = 0.0;
  double last_step_ms_ = -1.0;
};

void install_replay(httplib::Server& http, ReplayPlayer* player) {
  http.Get("/api/info", [player](const httplib::Request&, httplib::Response& res) {
    reply_json(res, "{\"mode\":\"replay\",\"replay\":" + player->info_json() + "}");
  });
  http.Get("/api/replay/frame", [player](const httplib::Request& req, httplib::Response& res) {
    Result<int64_t> tick = int_param(req, "tick", 0, std::numeric_limits<int64_t>::max());
    if (!tick.ok()) return reply_error(res, tick.status());
    reply_json(res, player->frame_json_at(*tick));
  });
  http.Get("/api/describe", [player](const httplib::Request&, httplib::Response& res) {
    reply_json(res, player->describe_json());
  });
}

// "HOST:PORT" (port 0: any free one).
bool split_listen(const std::string& listen, std::string* host, int* port) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0) return false;
  std::string error;
  std::optional<int64_t> p = parse_int(listen.substr(colon + 1), 0, 65535, &error);
  if (!p) return false;
  *host = listen.substr(0, colon);
  if (host->size() > 2 && host->front() == '[' && host->back() == ']') {
    *host = host->substr(1, host->size() - 2);
  }
  *port = static_cast<int>(*p);
  return true;
}

}  // namespace

int run_view(const Invocation& inv) {
  const std::string listen = inv.args.value("listen").value_or("127.0.0.1:8080");
  std::string host;
  int port = 0;
  if (!split_listen(listen, &host, &port)) {
    return inv.usage_error("--listen: expected HOST:PORT, got '" + listen + "'");
  }
  std::optional<int64_t> world;
  if (auto w = inv.args.value("world")) {
    std::string error;
    world = parse_int(*w, 1, std::numeric_limits<int64_t>::max(), &error);
    if (!world) return inv.usage_error("--world: " + error);
  }
  const std::optional<std::string> replay_path = inv.args.value("replay");
  if (replay_path && (world || inv.args.has("server"))) {
    return inv.usage_error("--replay plays a file locally: no --server or --world with it");
  }

  std::atomic<bool> stopping{false};
  httplib::Server http;
  // SO_REUSEADDR only (httplib's default adds SO_REUSEPORT: a second viewer would share the
  // port silently).
  http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  // Each open page holds a worker for its event stream; httplib's default pool (8) would let a
  // few tabs starve the JSON calls.
  http.new_task_queue = [] { return new httplib::ThreadPool(32); };
  for (const ViewAsset& asset : kViewAssets) {
    http.Get(std::string(asset.path), [&asset](const httplib::Request&, httplib::Response& res) {
      res.set_content(asset.body.data(), asset.body.size(), std::string(asset.content_type));
    });
  }

  // A replay is re-stepped before the signals are blocked (no thread runs yet), so that Ctrl-C
  // ends a long one at once.
  std::unique_ptr<ReplayPlayer> player;
  if (replay_path) {
    Result<std::unique_ptr<ReplayPlayer>> opened = ReplayPlayer::open(*replay_path);
    if (!opened.ok()) return inv.fail(opened.status().message());
    player = std::move(opened).value();
  }

  // SIGINT and SIGTERM are taken by sigwait below; blocked before any thread starts, so that
  // every thread (gRPC's, httplib's) inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  std::unique_ptr<LiveView> live;
  if (player) {
    install_replay(http, player.get());
  } else {
    int exit_code = kExitOk;
    auto client = connect_from_args(inv, &exit_code);
    if (!client) return exit_code;
    // Fail early, with the server's words, when it cannot be reached or refuses the token.
    auto worlds = client->list_worlds();
    if (!worlds.ok()) return inv.fail(worlds.status().message());
    live = std::make_unique<LiveView>(std::move(client), &stopping);
    live->install(http);
  }

  const int bound =
      port == 0 ? http.bind_to_any_port(host) : (http.bind_to_port(host, port) ? port : -1);
  if (bound <= 0) return inv.fail("--listen: cannot listen on " + listen);
  std::string url = "http://" + (host.find(':') != std::string::npos ? "[" + host + "]" : host) +
                    ":" + std::to_string(bound) + "/";
  if (world) url += "?world=" + std::to_string(*world);
  if (player) inv.out << player->info_json() << "\n";
  inv.out << "serving " << url << std::endl;

  std::thread server([&] { http.listen_after_bind(); });
  int signal_number = 0;
  sigwait(&signals, &signal_number);
  stopping = true;
  http.stop();
  server.join();
  inv.out << "stopped by " << (signal_number == SIGINT ? "SIGINT" : "SIGTERM") << std::endl;
  return kExitOk;
}

}  // namespace fulcrum::cli
