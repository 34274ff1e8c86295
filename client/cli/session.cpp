// fulcrum session: open (or create) a world as a multiplayer session, join it as a player for
// another program to play, join it as a bot that pushes its own bodies and checks every
// confirmed hash on its own copy of the world (lockstep), or watch it.
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <ostream>

#include "fulcrum/fingerprint.h"
#include "fulcrum/lockstep.h"
#include "remote.h"

namespace fulcrum::cli {
namespace {

// Follows a session until `ticks` confirmed ticks (0: until the stream ends), in lockstep.
// `on_confirmed` runs on the stream's thread after each tick checked (the bot sends from it).
struct Follow {
  std::mutex mu;
  std::condition_variable cv;
  client::LockstepWorld lockstep;
  Status error;
  int64_t start_tick = -1;
  int64_t confirmed = 0;
  bool done = false;
  int64_t reports = 0;  // hash reports the server answered
  int64_t reports_matched = 0;
};

// Sends the copy's due hash report as the player; a desync the server found is printed with
// the first field that differs and becomes the follow's error.
void send_report(const Invocation& inv, client::Client* c, uint64_t world,
                 const v1::JoinSessionReply& player, Follow* f,
                 std::unique_lock<std::mutex>& lock) {
  std::optional<v1::ReportHashRequest> due = f->lockstep.take_report();
  if (!due) return;
  lock.unlock();
  Result<v1::ReportHashReply> reply = c->report_hash(world, player, *std::move(due));
  lock.lock();
  if (!reply.ok()) {
    inv.err << "hash report: " << reply.status().message() << "\n";
    return;
  }
  ++f->reports;
  (void)f->lockstep.on_report_reply(*reply);
  if (reply->verdict() == v1::HASH_VERDICT_MATCH) ++f->reports_matched;
  if (reply->verdict() != v1::HASH_VERDICT_DESYNC) return;
  inv.out << "the server finds a desync at tick " << reply->divergent_tick() << ": "
          << (reply->first_difference().empty() ? reply->note() : reply->first_difference())
          << "\n";
  inv.out.flush();
}

int follow(const Invocation& inv, client::Client* c, uint64_t world, int64_t ticks,
           const std::function<void(int64_t tick, Follow*)>& on_tick, Follow* f,
           int64_t print_every, const v1::JoinSessionReply* as_player = nullptr,
           bool report = false) {
  auto sub = c->watch_session(
      world,
      [&](const v1::SessionEvent& event) {
        std::unique_lock<std::mutex> lock(f->mu);
        if (f->done) return;
        Status st = f->lockstep.on_event(event);
        if (report) send_report(inv, c, world, *as_player, f, lock);
        if (!st.ok()) {
          f->error = st;
          f->done = true;
          f->cv.notify_all();
          return;
        }
        const int64_t tick = f->lockstep.world().tick();
        if (event.has_start()) {
          f->start_tick = tick;
        } else {
          ++f->confirmed;
          if (print_every > 0 && f->confirmed % print_every == 0) {
            inv.out << "tick " << tick << "  hash " << hex64(f->lockstep.world().state_hash())
                    << "  matches the server's (" << f->confirmed << " ticks confirmed)\n";
            inv.out.flush();
          }
          if (ticks > 0 && f->confirmed >= ticks) {
            f->done = true;
            f->cv.notify_all();
            return;
          }
        }
        lock.unlock();
        if (on_tick) on_tick(tick, f);
      },
      as_player);
  if (!sub.ok()) return inv.fail(sub.status().message());
  {
    std::unique_lock<std::mutex> lock(f->mu);
    f->cv.wait(lock, [&] { return f->done; });
  }
  (*sub)->cancel();
  Status ended = (*sub)->wait();
  std::lock_guard<std::mutex> lock(f->mu);
  if (!f->error.ok()) return inv.fail(f->error.message());
  if (!ended.ok()) return inv.fail(ended.message());
  return kExitOk;
}

int open_session(const Invocation& inv, client::Client* c, uint64_t world) {
  v1::SessionOptions options;
  std::string error;
  if (auto p = inv.args.value("players")) {
    auto n = parse_int(*p, 1, 64, &error);
    if (!n) return inv.usage_error("--players: " + error);
    options.set_max_players(static_cast<uint32_t>(*n));
  }
  if (auto d = inv.args.value("input-delay")) {
    auto n = parse_int(*d, 0, 600, &error);
    if (!n) return inv.usage_error("--input-delay: " + error);
    options.set_input_delay(static_cast<uint32_t>(*n));
  }
  if (auto s = inv.args.value("seal")) {
    if (*s == "on-step") {
      options.set_seal(v1::SEAL_RULE_ON_STEP);
    } else if (*s == "all-inputs") {
      options.set_seal(v1::SEAL_RULE_ALL_INPUTS);
    } else {
      return inv.usage_error("--seal: expected on-step or all-inputs, got '" + *s + "'");
    }
  }
  if (auto m = inv.args.value("missing")) {
    if (*m == "none") {
      options.set_missing_input(v1::MISSING_INPUT_NONE);
    } else if (*m == "repeat") {
      options.set_missing_input(v1::MISSING_INPUT_REPEAT_LAST);
    } else {
      return inv.usage_error("--missing: expected none or repeat, got '" + *m + "'");
    }
  }
  Result<v1::OpenSessionReply> r = c->open_session(world, options);
  if (!r.ok()) return inv.fail(r.status().message());
  inv.out << "world " << world << ": a session from tick " << r->tick() << ", at most "
          << r->options().max_players() << " players, input delay " << r->options().input_delay()
          << ", seal "
          << (r->options().seal() == v1::SEAL_RULE_ALL_INPUTS ? "all-inputs" : "on-step")
          << ", missing inputs "
          << (r->options().missing_input() == v1::MISSING_INPUT_REPEAT_LAST ? "repeat" : "none")
          << ", engine " << r->fingerprint() << "\n";
  return kExitOk;
}

// The JoinSessionRequest of `join` and `bot`: --name (default `name`) and --bodies. False after
// a usage error, whose exit code is in *exit_code.
bool join_request(const Invocation& inv, uint64_t world, const char* name,
                  v1::JoinSessionRequest* join, int* exit_code) {
  join->set_world_id(world);
  join->set_name(inv.args.value("name").value_or(name));
  if (auto b = inv.args.value("bodies")) {
    std::string error;
    std::optional<std::vector<BodyId>> ids = parse_body_list(*b, &error);
    if (!ids) {
      *exit_code = inv.usage_error("--bodies: " + error);
      return false;
    }
    for (BodyId id : *ids) {
      v1::Handle* h = join->add_bodies();
      h->set_index(id.index);
      h->set_generation(id.generation);
    }
  }
  return true;
}

void print_handles(std::ostream& out, const char* what,
                   const google::protobuf::RepeatedPtrField<v1::Handle>& handles) {
  out << what << ":";
  for (int i = 0; i < handles.size(); ++i) {
    out << (i == 0 ? " " : ",") << handles[i].index() << ":" << handles[i].generation();
  }
  out << "\n";
}

// A player for another program to play (the Python or C++ client, with the id and secret
// printed here): joins, prints what it owns, and leaves the slot taken. Until a program
// watches the session as this player, its inputs are missing and the session's rule stands in.
int join(const Invocation& inv, client::Client* c, uint64_t world) {
  v1::JoinSessionRequest request;
  int exit_code = kExitOk;
  if (!join_request(inv, world, "player", &request, &exit_code)) return exit_code;
  Result<v1::JoinSessionReply> me = c->join_session(request);
  if (!me.ok()) return inv.fail(me.status().message());
  inv.out << "player " << me->player_id() << " joined world " << world << " at tick " << me->tick()
          << "; first input for tick " << me->first_input_tick() << "\n"
          << "secret: " << me->player_secret() << "\n";
  print_handles(inv.out, "bodies", me->bodies());
  print_handles(inv.out, "joints", me->joints());
  return kExitOk;
}

// A player that pushes its own bodies with seeded random impulses, one input per tick sent
// input_delay ticks ahead of each confirmed tick, and checks every hash on its own copy.
int bot(const Invocation& inv, client::Client* c, uint64_t world, int64_t ticks) {
  std::string error;
  v1::JoinSessionRequest join;
  int exit_code = kExitOk;
  if (!join_request(inv, world, "bot", &join, &exit_code)) return exit_code;
  join.set_fingerprint(kDeterminismFingerprint);
  uint64_t seed = 1;
  if (auto s = inv.args.value("seed")) {
    auto n = parse_int(*s, 0, int64_t{1} << 62, &error);
    if (!n) return inv.usage_error("--seed: " + error);
    seed = static_cast<uint64_t>(*n);
  }
  double strength = 1.0;
  if (auto s = inv.args.value("impulse")) {
    char* end = nullptr;
    strength = std::strtod(s->c_str(), &end);
    if (end == s->c_str() || *end != '\0' || !(strength >= 0.0) || strength > 1e6) {
      return inv.usage_error("--impulse: expected a number from 0 to 1e6, got '" + *s + "'");
    }
  }
  client::LockstepOptions lockstep;
  if (auto k = inv.args.value("report-every")) {
    auto n = parse_int(*k, 1, 1024, &error);
    if (!n) return inv.usage_error("--report-every: " + error);
    lockstep.report_every = static_cast<int>(*n);
  }
  Result<v1::JoinSessionReply> me = c->join_session(join);
  if (!me.ok()) return inv.fail(me.status().message());
  inv.out << "player " << me->player_id() << " joined world " << world << " at tick " << me->tick()
          << " with " << join.bodies_size() << " bodies; first input for tick "
          << me->first_input_tick() << "\n";
  inv.out.flush();

  // The delay the session asks for: the first input tick less the tick at join.
  const int64_t delay = me->first_input_tick() - me->tick();
  int64_t sent = 0, late = 0, next = me->first_input_tick();
  uint64_t state = seed * 0x9E3779B97F4A7C15ULL + me->player_id();
  auto random_unit = [&] {  // in [-1, 1), from a seeded generator: the same run every time
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / static_cast<double>(uint64_t{1} << 52) - 1.0;
  };
  auto send_through = [&](int64_t last) {
    for (; next <= last; ++next) {
      v1::EditBatch input;
      for (const v1::Handle& h : join.bodies()) {
        v1::ApplyImpulse* push = input.add_edits()->mutable_apply_impulse();
        *push->mutable_body() = h;
        push->mutable_impulse()->set_x(strength * random_unit());
        push->mutable_impulse()->set_y(strength * random_unit());
      }
      Result<v1::SendInputReply> r = c->send_input(world, *me, next, input);
      if (r.ok()) {
        ++sent;
      } else if (r.status().code() == StatusCode::kFailedPrecondition) {
        ++late;  // sealed before it arrived: the missing-input rule stood in
      } else {
        inv.err << "input for tick " << next << ": " << r.status().message() << "\n";
      }
    }
  };
  Follow f;
  f.lockstep = client::LockstepWorld(lockstep);
  int rc = follow(
      inv, c, world, ticks, [&](int64_t tick, Follow*) { send_through(tick + delay); }, &f, 60,
      &*me, lockstep.report_every > 0);
  if (rc != kExitOk) return rc;
  inv.out << "player " << me->player_id() << ": " << f.confirmed
          << " ticks confirmed, every state hash matched this copy; " << sent << " inputs sent, "
          << late << " late";
  if (lockstep.report_every > 0) {
    inv.out << "; " << f.reports << " hash reports, " << f.reports_matched
            << " matched the server's";
  }
  inv.out << "\n";
  return kExitOk;
}

}  // namespace

int run_session(const Invocation& inv) {
  if (inv.args.positional().empty()) {
    return inv.usage_error("missing open (or create), join, bot or watch");
  }
  std::string action = inv.args.positional()[0];
  if (action == "create") action = "open";
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 1, &exit_code);
  if (!world) return exit_code;
  std::string error;
  int64_t ticks = 0;
  if (auto t = inv.args.value("ticks")) {
    auto n = parse_int(*t, 1, int64_t{1} << 40, &error);
    if (!n) return inv.usage_error("--ticks: " + error);
    ticks = *n;
  }
  if (action != "open" && action != "join" && action != "bot" && action != "watch") {
    return inv.usage_error("expected open (or create), join, bot or watch, got '" +
                           inv.args.positional()[0] + "'");
  }
  auto c = connect_from_args(inv, &exit_code);
  if (!c) return exit_code;
  if (action == "open") return open_session(inv, c.get(), *world);
  if (action == "join") return join(inv, c.get(), *world);
  if (action == "bot") return bot(inv, c.get(), *world, ticks);
  Follow f;
  int rc = follow(inv, c.get(), *world, ticks, nullptr, &f, 60);
  if (rc != kExitOk) return rc;
  inv.out << "world " << *world << ": " << f.confirmed << " ticks confirmed from tick "
          << f.start_tick << ", every state hash matched this copy\n";
  return kExitOk;
}

}  // namespace fulcrum::cli
