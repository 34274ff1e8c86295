// Fuzz target: multiplayer sessions (session.proto, game_session.cpp) driven in process, as gRPC
// drives them: OpenSession, JoinSession, SendInput, Step, WatchSession and its end, ApplyEdits
// and SetOwnership by the world's owner, on worlds started from the base worlds (fuzz_worlds.h).
//
// Input: a byte choosing the base world of the first world (mixed, bounce, bridge), then calls,
// each a method byte, a two-byte little-endian length and that many bytes of the call's message:
//   0 OpenSessionRequest   1 JoinSessionRequest   2 SendInputRequest   3 StepRequest
//   4 WatchSessionRequest (a watch through Session::watch_session, as the WatchSession stream
//     opens one)           5 ends an open watch (the first byte picks which)
//   6 ApplyEditsRequest    7 another world (the first byte picks its base world)
//   8 SetOwnershipRequest
// So that seeds and mutations reach live sessions: a world_id of 1 to 16 names the 1st to 16th
// world this input created; a SendInput's tick counts from the world's tick (0: the tick the
// world steps next); a player_secret of 0 bytes is that player's own secret, of 1 or 2 bytes its
// own secret with the byte at (first % length) xor'd with the second (0: unchanged); longer
// secrets go through as they are. Fingerprints and handles go through as they are (the seeds
// carry the server's fingerprint and the base worlds' own handles).
//
// Checks after every call:
// - a refused call has a message naming a field of its request (or of the session's options)
//   and changed nothing: the same worlds, ticks and hashes, no tick confirmed, and a later join
//   still gets the next player id;
// - replies say what the model of the session expects (player ids 1 up, first input ticks,
//   SendInput's duplicate flag);
// - every tick a session world steps is confirmed to its watchers, in order, none skipped; a
//   client's copy of the world (from the first watch's start, applying each confirmed tick's
//   batches) reaches every confirmed state hash;
// - every accepted input is applied exactly once, at its tick, attributed to its player (or, if
//   the world refused it when the tick was sealed, its player is listed missing); a player
//   without an input is listed missing once it could have sent one, and with
//   MISSING_INPUT_REPEAT_LAST its last input stands in;
// - at the end, every world passes check_world (through its snapshot, as a client fetches it).
#include <google/protobuf/util/message_differencer.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <cctype>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "fulcrum/fingerprint.h"
#include "fuzz_server.h"
#include "fuzz_support.h"
#include "fuzz_worlds.h"
#include "physics_service.h"
#include "session.h"
#include "snapshot_convert.h"

namespace {

using namespace fulcrum;
using google::protobuf::util::MessageDifferencer;
using server::PhysicsService;
using server::Registry;

// The fuzz limits, with room for every contact the shapes allowed could make: a refused tick
// would carry its inputs to the next tick that runs, which the exactly-once check does not model.
constexpr int kMaxShapes = 512;

server::Limits fuzz_server_limits() {
  server::Limits l;
  const EditLimits e = fuzz::limits();
  l.max_worlds = 4;
  l.max_bodies = 256;
  l.max_shapes = kMaxShapes;
  l.max_shapes_per_body = e.max_shapes_per_body;
  l.max_batch_work = e.max_work;
  l.max_edits = e.max_edits;
  l.max_contacts = int64_t{kMaxShapes} * (kMaxShapes - 1) / 2;
  l.max_step_ticks = 8;
  return l;
}

// A watch: every event offered, in order.
class Watcher final : public server::SessionWatcher {
 public:
  void offer(std::shared_ptr<const v1::SessionEvent> event) override {
    events.push_back(std::move(event));
  }
  void close(const Status& status) override { closed = "closed: " + status.message(); }
  uint32_t player_id() const override { return player; }

  uint32_t player = 0;  // as whom it watches (0: a spectator)

  std::deque<std::shared_ptr<const v1::SessionEvent>> events;
  std::string closed;  // only deleting the world ends a watch, and no call here deletes one
};

struct Player {
  std::string secret;
  int64_t first_input_tick = 0;
  v1::EditBatch last_input;  // as MISSING_INPUT_REPEAT_LAST repeats it
};

struct OpenWatch {
  uint64_t world = 0;
  uint32_t player = 0;
  std::shared_ptr<Watcher> watcher;
  int64_t next_tick = -1;  // the tick of the next confirmed event (-1: the start not seen yet)
};

// What the input did to one world, as the harness models it.
struct WorldModel {
  std::shared_ptr<server::Session> session;
  bool is_session = false;
  v1::SessionOptions options;
  std::shared_ptr<Watcher> auditor;  // the harness's own watch, opened with the session
  World copy{WorldSettings{}};       // a client's copy, following the auditor's events
  int64_t copy_tick = 0;
  uint32_t skip_batches = 0;  // the start's applied_batches, skipped from the next event
  std::map<uint32_t, Player> players;
  std::map<int64_t, std::map<uint32_t, v1::EditBatch>> inputs;  // accepted, by tick and player
};

struct Harness {
  Registry registry{fuzz_server_limits()};
  PhysicsService service{&registry, ""};
  std::vector<uint64_t> created;
  std::map<uint64_t, WorldModel> models;
  std::vector<OpenWatch> watches;
};

uint64_t map_world(uint64_t id, const std::vector<uint64_t>& created) {
  if (id >= 1 && id <= 16 && !created.empty()) return created[(id - 1) % created.size()];
  return id;
}

std::string map_secret(const std::string& given, const WorldModel* model, uint32_t player) {
  if (given.size() > 2 || model == nullptr) return given;
  auto p = model->players.find(player);
  if (p == model->players.end()) return given;
  std::string secret = p->second.secret;
  if (given.size() == 2 && !secret.empty()) {
    secret[static_cast<uint8_t>(given[0]) % secret.size()] ^= given[1];
  }
  return secret;
}

// A refusal names the field at fault: a field of the request, or a session option (which
// explains a refused join, "options.max_players").
void check_names_a_field(const std::string& message, const google::protobuf::Descriptor* request) {
  auto named = [&](const std::string& field) {
    for (size_t at = message.find(field); at != std::string::npos;
         at = message.find(field, at + 1)) {
      const bool starts = at == 0 || !(std::isalnum(static_cast<unsigned char>(message[at - 1])) ||
                                       message[at - 1] == '_');
      const size_t end = at + field.size();
      // "tick: ...", "input.edits[0]...", "(options.max_players)"
      const bool ends = end < message.size() && (message[end] == ':' || message[end] == '.' ||
                                                 message[end] == '[' || message[end] == ')');
      if (starts && ends) return true;
    }
    return false;
  };
  for (int i = 0; i < request->field_count(); ++i) {
    if (named(request->field(i)->name())) return;
  }
  const google::protobuf::Descriptor* options = v1::SessionOptions::descriptor();
  for (int i = 0; i < options->field_count(); ++i) {
    if (named("options." + options->field(i)->name())) return;
  }
  fuzz::fail(request->name() + ": a refusal that names no field: " + message);
}

void check_world_of(server::Session& session, const std::string& where) {
  v1::GetSnapshotReply snapshot;
  session.snapshot(&snapshot);
  World copy{WorldSettings{}};
  Status s = restore_encoded(&copy, snapshot.snapshot().SerializeAsString());
  fuzz::check(s.ok(), where + "'s snapshot does not restore: " + s.message());
  fuzz::check_world(copy, where);
}

// One confirmed tick, as the auditor saw it: checked against the accepted inputs, and replayed
// on the client's copy.
void confirm(WorldModel& m, const v1::ConfirmedTick& c, const std::string& where) {
  const int64_t tick = c.tick().tick() - 1;  // the tick sealed: its inputs came before the step
  fuzz::check(c.tick().tick() == m.copy_tick + 1, where + ": confirmed tick " +
                                                      std::to_string(c.tick().tick()) + " after " +
                                                      std::to_string(m.copy_tick));
  fuzz::check(c.batch_players_size() == c.tick().edits_size(),
              where + ": batch_players and edits differ in length");
  for (int i = 1; i < c.missing_players_size(); ++i) {
    fuzz::check(c.missing_players(i - 1) < c.missing_players(i),
                where + ": missing_players not in order or listed twice, at tick " +
                    std::to_string(tick) + ": " + c.ShortDebugString());
  }
  // Players join between ticks; the event lists those that joined since the last one.
  const std::set<uint32_t> missing(c.missing_players().begin(), c.missing_players().end());
  std::map<uint32_t, int> first_batch;
  uint32_t previous = 0;
  for (int i = 0; i < c.batch_players_size(); ++i) {
    const uint32_t p = c.batch_players(i);
    // The owner's batches first, then at most one per player, in player-id order.
    fuzz::check(p == 0 ? previous == 0 : p > previous,
                where + ": batches out of player order at tick " + std::to_string(tick));
    if (p != 0) {
      fuzz::check(m.players.count(p) == 1,
                  where + ": a batch of unknown player " + std::to_string(p));
      first_batch[p] = i;
    }
    previous = p;
  }
  auto arrived = m.inputs.find(tick);
  for (auto& [id, player] : m.players) {
    const std::string who =
        where + ", player " + std::to_string(id) + ", tick " + std::to_string(tick);
    const v1::EditBatch* input = nullptr;
    if (arrived != m.inputs.end()) {
      if (auto it = arrived->second.find(id); it != arrived->second.end()) input = &it->second;
    }
    auto batch = first_batch.find(id);
    if (input != nullptr) {
      player.last_input = *input;
      if (input->edits_size() == 0) {
        fuzz::check(batch == first_batch.end() && missing.count(id) == 0,
                    who + ": an empty input became a batch or a missing player");
      } else if (batch == first_batch.end()) {
        fuzz::check(missing.count(id) == 1, who + ": an accepted input was not applied");
      } else {
        fuzz::check(missing.count(id) == 0, who + ": applied and listed missing");
        fuzz::check(MessageDifferencer::Equals(c.tick().edits(batch->second), *input),
                    who + ": the batch applied is not the input sent");
      }
      continue;
    }
    if (tick < player.first_input_tick) {
      fuzz::check(batch == first_batch.end() && missing.count(id) == 0,
                  who + ": a player that could not have sent an input was stood in for");
      continue;
    }
    fuzz::check(missing.count(id) == 1, who + ": no input and not listed missing");
    if (batch != first_batch.end()) {
      fuzz::check(m.options.missing_input() == v1::MISSING_INPUT_REPEAT_LAST,
                  who + ": a batch without an input");
      fuzz::check(MessageDifferencer::Equals(c.tick().edits(batch->second), player.last_input),
                  who + ": the batch standing in is not the last input");
    }
  }
  if (arrived != m.inputs.end()) m.inputs.erase(arrived);
  fuzz::check(m.inputs.empty() || m.inputs.begin()->first > tick,
              where + ": inputs held for a tick already sealed");

  // The client's copy: the batches (less those the start's snapshot holds), then the step.
  for (int i = 0; i < c.tick().edits_size(); ++i) {
    if (m.skip_batches > 0) {
      --m.skip_batches;
      continue;
    }
    Result<EditOutcome> applied = apply_edit_batch(&m.copy, c.tick().edits(i));
    fuzz::check(applied.ok(), where + ": a confirmed batch does not apply to a client's copy: " +
                                  applied.status().message());
  }
  m.skip_batches = 0;
  m.copy.step();
  m.copy_tick = c.tick().tick();
  fuzz::check(m.copy.tick() == c.tick().tick() && m.copy.state_hash() == c.tick().state_hash(),
              where + ": a client's copy differs from the confirmed tick " +
                  std::to_string(c.tick().tick()));
}

// Takes the auditor's events: the start once, then confirmed ticks.
void audit(WorldModel& m, const std::string& where) {
  while (!m.auditor->events.empty()) {
    std::shared_ptr<const v1::SessionEvent> e = std::move(m.auditor->events.front());
    m.auditor->events.pop_front();
    if (e->has_start()) {
      fuzz::check(m.copy_tick == -1, where + ": a second start");
      Status s = restore_encoded(&m.copy, e->start().snapshot().SerializeAsString());
      fuzz::check(s.ok(), where + ": the start's snapshot does not restore: " + s.message());
      fuzz::check(
          m.copy.state_hash() == e->start().state_hash() && m.copy.tick() == e->start().tick(),
          where + ": the start's snapshot is not its tick and hash");
      m.copy_tick = e->start().tick();
      m.skip_batches = e->start().applied_batches();
    } else {
      fuzz::check(e->has_confirmed() && m.copy_tick >= 0, where + ": an event before the start");
      fuzz::print(e->confirmed());
      confirm(m, e->confirmed(), where);
    }
  }
}

// A watch the input opened: a start with the players so far, then every tick in order.
void check_watch(Harness& h, OpenWatch& w) {
  const std::string where = "watch of world " + std::to_string(w.world);
  fuzz::check(w.watcher->closed.empty(), where + ": " + w.watcher->closed);
  while (!w.watcher->events.empty()) {
    const std::shared_ptr<const v1::SessionEvent> e = std::move(w.watcher->events.front());
    w.watcher->events.pop_front();
    if (w.next_tick < 0) {
      fuzz::check(e->has_start(), where + ": the first event is not the start");
      fuzz::check(e->start().players_size() == static_cast<int>(h.models[w.world].players.size()),
                  where + ": the start does not list every player");
      w.next_tick = e->start().tick() + 1;
      continue;
    }
    fuzz::check(e->has_confirmed() && e->confirmed().tick().tick() == w.next_tick,
                where + ": expected confirmed tick " + std::to_string(w.next_tick));
    ++w.next_tick;
  }
}

template <typename Request>
bool parse(std::string_view bytes, Request* request) {
  return request->ParseFromArray(bytes.data(), static_cast<int>(bytes.size()));
}

// A world from the mixed (every shape kind, a motorized joint: 41 bodies), bounce (2 bodies) or
// bridge (162 bodies, joints) base world; the ragdolls (551 bodies) are over the limits, and
// slow to step here.
uint64_t add_world(Harness& h, uint8_t choice) {
  constexpr uint8_t kBases[] = {2, 3, 0};
  Result<std::shared_ptr<server::Session>> s =
      h.registry.create("fuzz", fuzz::base_world(kBases[choice % 3]));
  if (!s.ok()) return 0;
  h.created.push_back((*s)->id());
  h.models[(*s)->id()].session = *s;
  return (*s)->id();
}

WorldModel* model_of(Harness& h, uint64_t world) {
  auto m = h.models.find(world);
  return m == h.models.end() ? nullptr : &m->second;
}

// Runs one call; returns its status (OK for calls that cannot be refused).
grpc::Status run_call(Harness& h, int method, std::string_view bytes,
                      const std::map<uint64_t, std::pair<int64_t, uint64_t>>& before,
                      const google::protobuf::Descriptor** request_type) {
  grpc::ServerContext context;
  const grpc::Status unparsed = grpc::Status::OK;  // bytes that do not parse are no call
  auto world_of = [&](uint64_t id) { return map_world(id, h.created); };
  switch (method) {
    case 0: {
      v1::OpenSessionRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      v1::OpenSessionReply reply;
      grpc::Status s = h.service.OpenSession(&context, &request, &reply);
      if (!s.ok()) return s;
      WorldModel& m = h.models.at(request.world_id());
      fuzz::check(!m.is_session, "OpenSession: accepted twice");
      fuzz::check(reply.tick() == before.at(request.world_id()).first, "OpenSession: reply.tick");
      fuzz::check(reply.fingerprint() == kDeterminismFingerprint, "OpenSession: fingerprint");
      fuzz::check(
          reply.options().max_players() >= 1 && reply.options().max_players() <= 64 &&
              reply.options().missing_input() != v1::MISSING_INPUT_UNSPECIFIED &&
              reply.options().seal() != v1::SEAL_RULE_UNSPECIFIED &&
              reply.options().max_input_lead() >= reply.options().input_delay(),
          "OpenSession: options without their defaults: " + reply.options().ShortDebugString());
      m.is_session = true;
      m.options = reply.options();
      m.auditor = std::make_shared<Watcher>();
      m.copy_tick = -1;
      fuzz::check(m.session->watch_session(m.auditor, 0, "").ok(), "a spectator's watch");
      return s;
    }
    case 1: {
      v1::JoinSessionRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      v1::JoinSessionReply reply;
      grpc::Status s = h.service.JoinSession(&context, &request, &reply);
      if (!s.ok()) return s;
      WorldModel& m = h.models.at(request.world_id());
      const uint32_t expected = m.players.empty() ? 1 : m.players.rbegin()->first + 1;
      fuzz::check(reply.player_id() == expected, "JoinSession: player " +
                                                     std::to_string(reply.player_id()) +
                                                     ", expected " + std::to_string(expected));
      const int64_t tick = before.at(request.world_id()).first;
      fuzz::check(
          reply.tick() == tick && reply.first_input_tick() == tick + m.options.input_delay(),
          "JoinSession: tick or first_input_tick");
      fuzz::check(reply.player_secret().size() == 64, "JoinSession: a secret of 256 bits");
      for (const auto& [id, p] : m.players) {
        fuzz::check(p.secret != reply.player_secret(), "JoinSession: two players, one secret");
      }
      Player& p = m.players[reply.player_id()];
      p.secret = reply.player_secret();
      p.first_input_tick = reply.first_input_tick();
      return s;
    }
    case 2: {
      v1::SendInputRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      WorldModel* m = model_of(h, request.world_id());
      if (auto w = before.find(request.world_id()); w != before.end()) {
        request.set_tick(static_cast<int64_t>(static_cast<uint64_t>(w->second.first) +
                                              static_cast<uint64_t>(request.tick())));
      }
      request.set_player_secret(map_secret(request.player_secret(), m, request.player_id()));
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      v1::SendInputReply reply;
      grpc::Status s = h.service.SendInput(&context, &request, &reply);
      if (!s.ok()) return s;
      fuzz::check(reply.tick() == request.tick(), "SendInput: reply.tick");
      auto& at_tick = m->inputs[request.tick()];
      const bool duplicate = at_tick.count(request.player_id()) == 1;
      fuzz::check(reply.duplicate() == duplicate,
                  "SendInput: duplicate is " + std::string(reply.duplicate() ? "" : "not ") +
                      "set for a " + (duplicate ? "second" : "first") + " input");
      if (!duplicate) at_tick.emplace(request.player_id(), request.input());
      return s;
    }
    case 3: {
      v1::StepRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      v1::StepReply reply;
      grpc::Status s = h.service.Step(&context, &request, &reply);
      fuzz::check(s.error_message().find("max_contacts") == std::string::npos,
                  "Step: a tick was refused; the harness's contact limit is too low");
      return s;
    }
    case 4: {
      v1::WatchSessionRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      WorldModel* m = model_of(h, request.world_id());
      if (request.player_id() != 0) {
        request.set_player_secret(map_secret(request.player_secret(), m, request.player_id()));
      }
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      Result<std::shared_ptr<server::Session>> session = h.registry.find(request.world_id());
      if (!session.ok()) return server::to_grpc_status(session.status());
      auto watcher = std::make_shared<Watcher>();
      watcher->player = request.player_id();
      Status s = (*session)->watch_session(watcher, request.player_id(), request.player_secret());
      if (!s.ok()) {
        fuzz::check(watcher->events.empty(), "WatchSession: a refused watch got an event");
        return server::to_grpc_status(s);
      }
      h.watches.push_back({request.world_id(), request.player_id(), watcher, -1});
      // A watch as a player marks it present; a secret that is not the player's is refused.
      if (request.player_id() != 0 || !request.player_secret().empty()) {
        fuzz::check(m != nullptr && m->players.count(request.player_id()) == 1 &&
                        m->players.at(request.player_id()).secret == request.player_secret(),
                    "WatchSession: a watch as a player with a wrong secret was accepted");
      }
      return grpc::Status::OK;
    }
    case 5: {
      if (h.watches.empty() || bytes.empty()) return grpc::Status::OK;
      const size_t which = static_cast<uint8_t>(bytes[0]) % h.watches.size();
      OpenWatch w = h.watches[which];
      h.watches.erase(h.watches.begin() + static_cast<std::ptrdiff_t>(which));
      check_watch(h, w);
      if (WorldModel* m = model_of(h, w.world); m != nullptr && m->session) {
        m->session->unwatch_session(w.watcher.get(), w.player);
      }
      return grpc::Status::OK;
    }
    case 6: {
      v1::ApplyEditsRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      v1::ApplyEditsReply reply;
      return h.service.ApplyEdits(&context, &request, &reply);
    }
    case 8: {
      v1::SetOwnershipRequest request;
      if (!parse(bytes, &request)) return unparsed;
      request.set_world_id(world_of(request.world_id()));
      fuzz::print(request);
      *request_type = request.GetDescriptor();
      v1::SetOwnershipReply reply;
      grpc::Status s = h.service.SetOwnership(&context, &request, &reply);
      if (s.ok()) {
        fuzz::check(reply.tick() == before.at(request.world_id()).first, "SetOwnership: tick");
      }
      return s;
    }
    default:
      if (!bytes.empty()) add_world(h, static_cast<uint8_t>(bytes[0]));
      return grpc::Status::OK;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Harness* h = new Harness;  // one service for the process, as in the server
  if (size < 1) return 0;
  add_world(*h, data[0]);
  size_t pos = 1;
  while (pos + 3 <= size) {
    const int method = data[pos] % 9;
    const size_t len = std::min<size_t>(data[pos + 1] | (data[pos + 2] << 8), size - pos - 3);
    const std::string_view bytes = fuzz::bytes(data + pos + 3, len);
    pos += 3 + len;
    const auto before = fuzz::worlds(h->registry);
    const google::protobuf::Descriptor* request_type = nullptr;
    const grpc::Status status = run_call(*h, method, bytes, before, &request_type);
    const auto after = fuzz::worlds(h->registry);
    if (std::getenv("FULCRUM_FUZZ_PRINT") != nullptr) {
      std::fprintf(stderr, "-> %s\n", status.ok() ? "OK" : status.error_message().c_str());
    }
    if (!status.ok()) {
      fuzz::check(!status.error_message().empty(), "a refusal without a message");
      if (request_type != nullptr) check_names_a_field(status.error_message(), request_type);
      fuzz::check(after == before, "a refused call changed a world: " + status.error_message());
    }
    for (auto& [id, m] : h->models) {
      if (!m.is_session) continue;
      if (!status.ok()) {
        fuzz::check(m.auditor->events.empty(),
                    "a refused call confirmed a tick: " + status.error_message());
      }
      const std::string where = "world " + std::to_string(id);
      audit(m, where);
      fuzz::check(m.copy_tick == after.at(id).first,
                  where + ": at tick " + std::to_string(after.at(id).first) +
                      " but confirmed through " + std::to_string(m.copy_tick));
    }
    for (OpenWatch& w : h->watches) check_watch(*h, w);
  }
  // The world checks once at the end (a snapshot and a restore each): between calls, the
  // client's copies already match every confirmed hash.
  for (const auto& session : h->registry.list()) {
    check_world_of(*session, "world " + std::to_string(session->id()));
  }
  for (OpenWatch& w : h->watches) {
    if (WorldModel* m = model_of(*h, w.world); m != nullptr && m->session) {
      m->session->unwatch_session(w.watcher.get(), w.player);
    }
  }
  h->watches.clear();
  for (const auto& session : h->registry.list()) (void)h->registry.remove(session->id());
  h->models.clear();
  h->created.clear();
  return 0;
}
