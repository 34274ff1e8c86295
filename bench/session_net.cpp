// fulcrum_session_bench over the network: a fulcrum-server child process on loopback, players
// on gRPC connections of their own.
//
// Latency: turn by turn (SEAL_RULE_ALL_INPUTS, input_delay 0), each player watches the session
// as itself and, whenever the world reaches tick T, sends its input for T and waits for the
// ConfirmedTick that carries it (the world at T + 1). Input to confirmation is the time from
// just before SendInput to that event read off the stream: the player's own call, the wait for
// the slowest player's input, the seal and step of a 1000-body world, and the fan-out to every
// watcher. The players only play (a bot's empty fingerprint): no copy of the world is stepped
// on the client side, whose cost the rollback table gives.
//
// Bytes: 4 players on the server's clock at 60 Hz push their own bodies; a spectator watches
// the session stream while four StreamFrames readers take every tick of the same world (every
// body or the changed ones, exact or quantized). Sizes are protobuf encodings as received,
// without gRPC and HTTP/2 framing (about 14 bytes a message).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "fulcrum/client.h"
#include "fulcrum/v1/service.grpc.pb.h"
#include "session_bench.h"

extern char** environ;

namespace fulcrum::session_bench {
namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

[[noreturn]] void die(const std::string& what) {
  std::fprintf(stderr, "fulcrum_session_bench: %s\n", what.c_str());
  std::exit(1);
}

// fulcrum-server --listen 127.0.0.1:0 --log off as a child; stopped with SIGTERM.
class ServerChild {
 public:
  explicit ServerChild(const std::string& binary) {
    out_ = (std::filesystem::temp_directory_path() /
            ("fulcrum_session_bench_" + std::to_string(getpid()) + ".out"))
               .string();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    std::vector<std::string> argv = {binary, "--listen", "127.0.0.1:0", "--log", "off"};
    std::vector<char*> args;
    for (std::string& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    if (posix_spawn(&pid_, args[0], &actions, nullptr, args.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    if (pid_ < 0) die("cannot start " + binary);
    for (auto until = Clock::now() + 10s; Clock::now() < until; std::this_thread::sleep_for(10ms)) {
      std::ifstream in(out_);
      std::stringstream text;
      text << in.rdbuf();
      const std::string s = text.str();
      const size_t at = s.find("listening on ");
      if (at != std::string::npos && s.find('\n', at) != std::string::npos) {
        address_ = s.substr(at + 13, s.find('\n', at) - at - 13);
        return;
      }
    }
    die(binary + " did not start listening in 10 s");
  }
  ~ServerChild() {
    kill(pid_, SIGTERM);
    waitpid(pid_, nullptr, 0);
    std::filesystem::remove(out_);
  }
  const std::string& address() const { return address_; }

 private:
  pid_t pid_ = -1;
  std::string out_;
  std::string address_;
};

// A channel of its own (no TCP connection shared with another player's channel).
std::unique_ptr<v1::Physics::Stub> own_connection(const std::string& address) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetMaxReceiveMessageSize(-1);
  return v1::Physics::NewStub(
      grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args));
}

// A force on one of the bodies [first, first + count) that changes every tick.
v1::EditBatch push(int first, int count, int64_t tick) {
  v1::EditBatch batch;
  v1::ApplyForce* force = batch.add_edits()->mutable_apply_force();
  force->mutable_body()->set_index(first + static_cast<int>(tick % count));
  force->mutable_body()->set_generation(1);
  force->mutable_force()->set_x(0.5 * static_cast<double>(tick % 7) - 1.5);
  force->mutable_force()->set_y(0.25 * static_cast<double>(tick % 5) - 0.5);
  return batch;
}

// A world of the bytes table: its 1000 movable bodies are scene bodies first_body to
// first_body + 999.
struct BenchWorld {
  const char* name;
  SceneDef (*scene)();
  int first_body;
};

// A session on a new world: its id, and the players' joins (each owning an equal share of the
// 1000 bodies).
struct Session {
  uint64_t world = 0;
  std::vector<v1::JoinSessionReply> players;
  int first_body = 0;
  int owned = 0;  // bodies per player
};

Session open_session(client::Client* c, const BenchWorld& w, int players,
                     const v1::SessionOptions& options) {
  Session s;
  s.first_body = w.first_body;
  Result<client::WorldSummary> created = c->create_world(w.scene());
  if (!created.ok()) die("create: " + created.status().message());
  s.world = created->id;
  Result<v1::OpenSessionReply> opened = c->open_session(s.world, options);
  if (!opened.ok()) die("open session: " + opened.status().message());
  s.owned = 1000 / players;
  for (int p = 0; p < players; ++p) {
    v1::JoinSessionRequest join;
    join.set_world_id(s.world);
    join.set_name("bench " + std::to_string(p + 1));
    for (int i = 0; i < s.owned; ++i) {
      v1::Handle* body = join.add_bodies();
      body->set_index(s.first_body + p * s.owned + i);
      body->set_generation(1);
    }
    Result<v1::JoinSessionReply> joined = c->join_session(join);
    if (!joined.ok()) die("join: " + joined.status().message());
    s.players.push_back(*joined);
  }
  return s;
}

double percentile(std::vector<double>* v, double p) {
  if (v->empty()) return 0.0;
  std::sort(v->begin(), v->end());
  return (*v)[std::min(v->size() - 1, static_cast<size_t>(p * static_cast<double>(v->size())))];
}

// One player of the latency table, on its own thread and connection: watches as itself and,
// whenever the world reaches tick T, sends its input for T + `ahead` (0 turn by turn; the
// input delay on the clock) without waiting for the reply, as a game loop would, then times
// until the confirmation of that tick is read (the world at T + ahead + 1). A tick sealed
// without the input (the missing-input rule stood in for it: it arrived late) counts in
// `late`, not in the samples.
struct Turns {
  std::vector<double> latency_ms;
  int64_t late = 0;
  std::atomic<int64_t> failures{0};  // refused other than as late
};

void play(const std::string& address, const Session& s, int slot, int64_t end, int64_t ahead,
          int warm_up, Turns* out) {
  const v1::JoinSessionReply& me = s.players[static_cast<size_t>(slot)];
  auto stub = own_connection(address);
  grpc::ClientContext watch_context;
  v1::WatchSessionRequest request;
  request.set_world_id(s.world);
  request.set_player_id(me.player_id());
  request.set_player_secret(me.player_secret());
  auto reader = stub->WatchSession(&watch_context, request);

  struct Call {
    grpc::ClientContext context;
    v1::SendInputRequest request;
    v1::SendInputReply reply;
  };
  std::mutex mu;
  std::condition_variable cv;
  int64_t in_flight = 0;
  // Every call's state lives until the last reply is in: the calls never outlive what they use.
  std::vector<std::unique_ptr<Call>> calls;
  auto send = [&](int64_t tick) {
    calls.push_back(std::make_unique<Call>());
    Call* call = calls.back().get();
    call->context.set_deadline(std::chrono::system_clock::now() + 30s);
    call->request.set_world_id(s.world);
    call->request.set_player_id(me.player_id());
    call->request.set_player_secret(me.player_secret());
    call->request.set_tick(tick);
    *call->request.mutable_input() = push(s.first_body + slot * s.owned, s.owned, tick);
    {
      std::lock_guard<std::mutex> lock(mu);
      ++in_flight;
    }
    stub->async()->SendInput(
        &call->context, &call->request, &call->reply, [&mu, &cv, &in_flight, out](grpc::Status st) {
          // FAILED_PRECONDITION: sealed already (late, counted below).
          if (!st.ok() && st.error_code() != grpc::StatusCode::FAILED_PRECONDITION) {
            ++out->failures;
          }
          std::lock_guard<std::mutex> lock(mu);
          --in_flight;
          cv.notify_all();
        });
  };

  v1::SessionEvent event;
  std::map<int64_t, Clock::time_point> sent;  // inputs not confirmed yet, by tick
  while (reader->Read(&event)) {
    const int64_t tick = event.has_start() ? event.start().tick() : event.confirmed().tick().tick();
    const auto confirmed = sent.find(tick - 1);
    if (confirmed != sent.end()) {
      const auto& missing = event.confirmed().missing_players();
      if (std::find(missing.begin(), missing.end(), me.player_id()) != missing.end()) {
        ++out->late;
      } else if (confirmed->first >= warm_up) {
        out->latency_ms.push_back(
            std::chrono::duration<double, std::milli>(Clock::now() - confirmed->second).count());
      }
      sent.erase(sent.begin(), std::next(confirmed));
    }
    if (tick >= end) break;
    const int64_t for_tick = tick + ahead;
    if (for_tick < me.first_input_tick() || for_tick >= end || sent.count(for_tick) > 0) continue;
    sent[for_tick] = Clock::now();
    send(for_tick);
  }
  watch_context.TryCancel();
  reader->Finish();
  std::unique_lock<std::mutex> lock(mu);
  cv.wait(lock, [&] { return in_flight == 0; });
}

// p50, p99 and max of every player's samples, and the late inputs.
struct Summary {
  double p50 = 0.0;
  double p99 = 0.0;
  double max = 0.0;
  size_t samples = 0;
  int64_t late = 0;
  double ticks_per_second = 0.0;
};

// One row: `players` players on a new drifting world, for `end` ticks.
Summary latency_row(client::Client* owner, const std::string& address, int players, bool clock,
                    int64_t end, int64_t clock_delay) {
  v1::SessionOptions session;
  session.set_max_players(static_cast<uint32_t>(players));
  session.set_input_delay(clock ? clock_delay : 0);
  session.set_missing_input(v1::MISSING_INPUT_REPEAT_LAST);
  session.set_seal(clock ? v1::SEAL_RULE_ON_STEP : v1::SEAL_RULE_ALL_INPUTS);
  const Session s = open_session(owner, {"drifting_1000", drifting, 0}, players, session);
  const int warm_up = static_cast<int>(std::min<int64_t>(20, end / 4));  // connections settle
  std::vector<Turns> turns(static_cast<size_t>(players));
  const auto began = Clock::now();
  std::vector<std::thread> threads;
  for (int p = 0; p < players; ++p) {
    threads.emplace_back(play, address, std::cref(s), p, end, clock ? clock_delay : 0, warm_up,
                         &turns[static_cast<size_t>(p)]);
  }
  if (clock) {
    std::this_thread::sleep_for(200ms);  // every watch open
    if (!owner->set_run_mode(s.world, client::RunMode::kRealTime).ok()) die("real time");
  }
  for (std::thread& t : threads) t.join();
  Summary out;
  out.ticks_per_second =
      static_cast<double>(end) / std::chrono::duration<double>(Clock::now() - began).count();
  if (clock) (void)owner->set_run_mode(s.world, client::RunMode::kPaused);
  std::vector<double> all;
  for (const Turns& t : turns) {
    if (t.failures > 0) die(std::to_string(t.failures) + " inputs refused");
    all.insert(all.end(), t.latency_ms.begin(), t.latency_ms.end());
    out.late += t.late;
  }
  out.samples = all.size();
  out.p50 = percentile(&all, 0.50);
  out.p99 = percentile(&all, 0.99);
  out.max = all.empty() ? 0.0 : all.back();
  (void)owner->delete_world(s.world);
  return out;
}

}  // namespace

void latency_table(const NetOptions& options) {
  ServerChild server(options.server);
  client::ClientOptions direct;
  direct.address = server.address();
  auto owner = client::Client::connect(direct);
  std::printf(
      "## Input to confirmation on loopback, 1000-body drifting world, %d ticks a row (ms)\n\n"
      "Turn by turn: SEAL_RULE_ALL_INPUTS, input_delay 0, each player sends the input for the "
      "tick the world is at. On the clock: SEAL_RULE_ON_STEP at 60 Hz, input_delay %d, each "
      "player sends the input for %d ticks past the tick it sees.\n\n"
      "| players | turn by turn: ticks/s | p50 | p99 | max | samples | on the clock: p50 | "
      "p99 | max | late inputs |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n",
      options.ticks, options.clock_delay, options.clock_delay);
  for (int players : options.players) {
    const Summary turns =
        latency_row(owner.get(), server.address(), players, false, options.ticks, 0);
    const Summary clock = latency_row(owner.get(), server.address(), players, true, options.ticks,
                                      options.clock_delay);
    std::printf("| %d | %.0f | %.3f | %.3f | %.3f | %zu | %.3f | %.3f | %.3f | %lld |\n", players,
                turns.ticks_per_second, turns.p50, turns.p99, turns.max, turns.samples, clock.p50,
                clock.p99, clock.max, static_cast<long long>(clock.late));
    std::fflush(stdout);
  }
  std::printf("\n");
}

namespace {

// One world's rows of the bytes table.
void bytes_rows(const std::string& address, const BenchWorld& w, const NetOptions& options) {
  client::ClientOptions direct;
  direct.address = address;
  auto owner = client::Client::connect(direct);
  constexpr int kPlayers = 4;
  constexpr int64_t kDelay = 3;
  v1::SessionOptions session;
  session.set_max_players(kPlayers);
  session.set_input_delay(kDelay);
  session.set_missing_input(v1::MISSING_INPUT_REPEAT_LAST);
  session.set_seal(v1::SEAL_RULE_ON_STEP);
  const Session s = open_session(owner.get(), w, kPlayers, session);

  // The session stream as a spectator receives it.
  std::mutex mu;
  size_t start_bytes = 0;
  size_t tick_bytes = 0;
  int64_t ticks_seen = 0;
  auto spectator = owner->watch_session(s.world, [&](const v1::SessionEvent& e) {
    std::lock_guard<std::mutex> lock(mu);
    if (e.has_start()) {
      start_bytes = e.ByteSizeLong();
    } else {
      tick_bytes += e.ByteSizeLong();
      ++ticks_seen;
    }
  });
  if (!spectator.ok()) die("watch: " + spectator.status().message());

  // Four frame readers of the same world, on connections of their own.
  struct Reader {
    const char* name;
    client::FrameBodies bodies;
    bool quantized;
    std::unique_ptr<client::Client> client = nullptr;
    std::unique_ptr<client::Subscription> subscription = nullptr;
    size_t bytes = 0;
    int64_t frames = 0;
    int64_t skipped_ticks = 0;
    size_t first_bytes = 0;
  };
  Reader readers[] = {
      {"StreamFrames, every body, exact", client::FrameBodies::kAll, false},
      {"StreamFrames, every body, quantized", client::FrameBodies::kAll, true},
      {"StreamFrames, changed bodies, exact", client::FrameBodies::kChanged, false},
      {"StreamFrames, changed bodies, quantized", client::FrameBodies::kChanged, true}};
  for (Reader& r : readers) {
    r.client = client::Client::connect(direct);
    client::SubscribeOptions subscribe;
    subscribe.bodies = r.bodies;
    subscribe.quantized = r.quantized;
    auto sub = r.client->subscribe(s.world, subscribe, [&mu, &r](const client::Frame& f) {
      std::lock_guard<std::mutex> lock(mu);
      if (r.frames == 0) {
        r.first_bytes = f.message_bytes;  // the first frame of a stream lists every body
      } else {
        r.bytes += f.message_bytes;
        r.skipped_ticks += f.skipped_ticks;
      }
      ++r.frames;
    });
    if (!sub.ok()) die("subscribe: " + sub.status().message());
    r.subscription = std::move(sub).value();
  }

  // The players: each sends, whenever the world reaches tick T, its input for T + input_delay.
  std::vector<std::unique_ptr<client::Client>> clients;
  std::vector<std::unique_ptr<client::Subscription>> watches;
  std::atomic<int> failures{0};
  for (int p = 0; p < kPlayers; ++p) {
    clients.push_back(client::Client::connect(direct));
    client::Client* c = clients.back().get();
    const v1::JoinSessionReply& me = s.players[static_cast<size_t>(p)];
    auto watch = c->watch_session(
        s.world,
        [&, c, p, me](const v1::SessionEvent& e) {
          const int64_t tick = e.has_start() ? e.start().tick() : e.confirmed().tick().tick();
          if (!c->send_input(s.world, me, tick + kDelay,
                             push(s.first_body + p * s.owned, s.owned, tick))
                   .ok()) {
            ++failures;
          }
        },
        &me);
    if (!watch.ok()) die("watch: " + watch.status().message());
    watches.push_back(std::move(watch).value());
  }
  std::this_thread::sleep_for(200ms);  // every stream open before the clock starts
  if (!owner->set_run_mode(s.world, client::RunMode::kRealTime).ok()) die("real time");
  std::this_thread::sleep_for(std::chrono::milliseconds(options.bytes_ticks * 1000 / 60));
  if (!owner->set_run_mode(s.world, client::RunMode::kPaused).ok()) die("pause");
  std::this_thread::sleep_for(200ms);  // the last ticks delivered
  for (auto& watch : watches) watch->cancel();
  for (Reader& r : readers) r.subscription->cancel();
  (*spectator)->cancel();

  std::lock_guard<std::mutex> lock(mu);
  std::printf("| %s | session stream (WatchSession) | %zu | %.1f | %lld | 0 |\n", w.name,
              start_bytes, ticks_seen ? static_cast<double>(tick_bytes) / ticks_seen : 0.0,
              static_cast<long long>(ticks_seen + 1));
  for (const Reader& r : readers) {
    const int64_t later = r.frames - 1;
    std::printf("| %s | %s | %zu | %.1f | %lld | %lld |\n", w.name, r.name, r.first_bytes,
                later > 0
                    ? static_cast<double>(r.bytes) / static_cast<double>(later + r.skipped_ticks)
                    : 0.0,
                static_cast<long long>(r.frames), static_cast<long long>(r.skipped_ticks));
  }
  if (failures > 0)
    std::printf("| %s | %d inputs refused (late on the clock) |\n", w.name, failures.load());
  (void)owner->delete_world(s.world);
}

}  // namespace

void bytes_table(const NetOptions& options) {
  ServerChild server(options.server);
  std::printf(
      "## Bytes per client per tick: 4 players on the server's clock at 60 Hz, %d ticks\n\n"
      "| world | stream | first message | bytes per tick | messages | ticks skipped |\n"
      "|---|---|---|---|---|---|\n",
      options.bytes_ticks);
  const BenchWorld worlds[] = {{"drifting_1000 (every body moves)", drifting, 0},
                               {"stacks_1000 (at rest until pushed)", stacks, 1}};
  for (const BenchWorld& w : worlds) {
    bytes_rows(server.address(), w, options);
    std::fflush(stdout);
  }
  std::printf("\n");
}

}  // namespace fulcrum::session_bench
