#include "game_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <random>
#include <utility>

#include "edit_convert.h"
#include "fulcrum/fingerprint.h"
#include "fulcrum/geometry.h"
#include "session.h"
#include "snapshot_convert.h"
#include "stats.h"

namespace fulcrum::server {

namespace {

constexpr uint32_t kDefaultPlayers = 8;
constexpr uint32_t kMaxInputDelay = 600;
constexpr uint32_t kDefaultLead = 600;
constexpr uint32_t kMaxLead = 36000;
constexpr int kMaxInputEdits = 64;
constexpr size_t kMaxNameLength = 64;

template <typename Id>
uint64_t key_of(Id id) {
  return (uint64_t{id.generation} << 32) | static_cast<uint32_t>(id.index);
}
template <typename Id>
std::string text_of(const char* kind, Id id) {
  return std::string(kind) + " {" + std::to_string(id.index) + ", " +
         std::to_string(id.generation) + "}";
}

std::string random_secret() {
  std::random_device device;
  std::string out;
  const char* hex = "0123456789abcdef";
  for (int i = 0; i < 8; ++i) {
    uint32_t word = device();
    for (int k = 0; k < 4; ++k) {
      out += hex[(word >> (8 * k + 4)) & 0xf];
      out += hex[(word >> (8 * k)) & 0xf];
    }
  }
  return out;  // 256 bits
}

// Compares without stopping at the first difference, so the time taken says nothing of the
// secret.
bool same_secret(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

Status check_value(const std::string& field, double v) {
  if (!std::isfinite(v) || std::abs(v) > kMaxInputMagnitude) {
    return invalid_argument(field + ": must be finite and at most 1e12 in magnitude (got " +
                            std::to_string(v) + ")");
  }
  return {};
}
Status check_vec(const std::string& field, const v1::Vec2& v) {
  FULCRUM_RETURN_IF_ERROR(check_value(field + ".x", v.x()));
  return check_value(field + ".y", v.y());
}

}  // namespace

GameSession::GameSession(const v1::SessionOptions& options, const World& world)
    : options_(options), open_tick_(world.tick()), sealed_through_(world.tick() - 1) {
  history_.start(world);
}

Status GameSession::check_options(v1::SessionOptions* o) {
  if (o->max_players() == 0) o->set_max_players(kDefaultPlayers);
  if (o->max_players() > kMaxPlayers) {
    return invalid_argument("options.max_players: at most " + std::to_string(kMaxPlayers) +
                            " (got " + std::to_string(o->max_players()) + ")");
  }
  if (o->input_delay() > kMaxInputDelay) {
    return invalid_argument("options.input_delay: at most " + std::to_string(kMaxInputDelay) +
                            " ticks (got " + std::to_string(o->input_delay()) + ")");
  }
  if (!v1::MissingInput_IsValid(o->missing_input())) {
    return invalid_argument("options.missing_input: unknown value " +
                            std::to_string(o->missing_input()));
  }
  if (o->missing_input() == v1::MISSING_INPUT_UNSPECIFIED) {
    o->set_missing_input(v1::MISSING_INPUT_NONE);
  }
  if (!v1::SealRule_IsValid(o->seal())) {
    return invalid_argument("options.seal: unknown value " + std::to_string(o->seal()));
  }
  if (o->seal() == v1::SEAL_RULE_UNSPECIFIED) o->set_seal(v1::SEAL_RULE_ON_STEP);
  if (o->max_input_lead() == 0) o->set_max_input_lead(kDefaultLead);
  if (o->max_input_lead() > kMaxLead) {
    return invalid_argument("options.max_input_lead: at most " + std::to_string(kMaxLead) +
                            " ticks (got " + std::to_string(o->max_input_lead()) + ")");
  }
  if (o->max_input_lead() < o->input_delay()) {
    return invalid_argument("options.max_input_lead: must be at least input_delay (" +
                            std::to_string(o->input_delay()) + "; got " +
                            std::to_string(o->max_input_lead()) + ")");
  }
  return {};
}

namespace {

// Handles of bodies or joints, in order.
template <class Id>
void add_handles(const std::vector<Id>& ids, google::protobuf::RepeatedPtrField<v1::Handle>* out) {
  for (const Id& id : ids) {
    v1::Handle* h = out->Add();
    h->set_index(id.index);
    h->set_generation(id.generation);
  }
}

}  // namespace

void GameSession::player_to_proto(const Player& p, v1::PlayerInfo* out) const {
  out->set_player_id(p.id);
  out->set_name(p.name);
  add_handles(p.bodies, out->mutable_bodies());
  add_handles(p.joints, out->mutable_joints());
}

Status GameSession::join(const v1::JoinSessionRequest& request, const World& world,
                         v1::JoinSessionReply* reply) {
  if (!request.fingerprint().empty() && request.fingerprint() != kDeterminismFingerprint) {
    return failed_precondition("fingerprint: this server's engine gives the results of " +
                               std::string(kDeterminismFingerprint) +
                               ", the client's engine those of " + request.fingerprint() +
                               ": their copies of the world would differ; use builds of " +
                               "the same fingerprint");
  }
  if (request.name().size() > kMaxNameLength) {
    return invalid_argument("name: at most " + std::to_string(kMaxNameLength) +
                            " characters (got " + std::to_string(request.name().size()) + ")");
  }
  if (players_.size() >= options_.max_players()) {
    return resource_exhausted("the session has its " + std::to_string(options_.max_players()) +
                              " players (options.max_players)");
  }
  Player p;
  p.id = players_.empty() ? 1 : players_.rbegin()->first + 1;
  p.name = request.name();
  FULCRUM_RETURN_IF_ERROR(
      check_objects(request.bodies(), request.joints(), world, true, &p.bodies, &p.joints));
  // Then what the scene gave this player id, where still alive and no player's.
  if (auto scene = scene_owners_.find(p.id); scene != scene_owners_.end()) {
    for (BodyId b : scene->second.bodies) {
      if (world.body_state(b).ok() && body_owner_.count(key_of(b)) == 0 &&
          std::find(p.bodies.begin(), p.bodies.end(), b) == p.bodies.end()) {
        p.bodies.push_back(b);
      }
    }
    for (JointId j : scene->second.joints) {
      if (world.joint_state(j).ok() && joint_owner_.count(key_of(j)) == 0 &&
          std::find(p.joints.begin(), p.joints.end(), j) == p.joints.end()) {
        p.joints.push_back(j);
      }
    }
  }
  p.secret = random_secret();
  for (BodyId b : p.bodies) body_owner_[key_of(b)] = p.id;
  for (JointId j : p.joints) joint_owner_[key_of(j)] = p.id;
  reply->set_player_id(p.id);
  reply->set_player_secret(p.secret);
  reply->set_tick(world.tick());
  p.first_input_tick = world.tick() + options_.input_delay();
  reply->set_first_input_tick(p.first_input_tick);
  add_handles(p.bodies, reply->mutable_bodies());
  add_handles(p.joints, reply->mutable_joints());
  joined_.push_back(p.id);
  players_.emplace(p.id, std::move(p));
  return {};
}

Status GameSession::check_objects(const google::protobuf::RepeatedPtrField<v1::Handle>& bodies,
                                  const google::protobuf::RepeatedPtrField<v1::Handle>& joints,
                                  const World& world, bool refuse_owned,
                                  std::vector<BodyId>* body_ids,
                                  std::vector<JointId>* joint_ids) const {
  std::map<uint64_t, int> seen;
  for (int i = 0; i < bodies.size(); ++i) {
    const std::string field = "bodies[" + std::to_string(i) + "]";
    const BodyId id{bodies[i].index(), bodies[i].generation()};
    Result<BodyState> state = world.body_state(id);
    if (!state.ok()) return not_found(field + ": no live " + text_of("body", id));
    if (state->type == BodyType::kStatic) {
      return invalid_argument(field + ": " + text_of("body", id) +
                              " is static: inputs could not move it");
    }
    if (auto owner = body_owner_.find(key_of(id)); refuse_owned && owner != body_owner_.end()) {
      return failed_precondition(field + ": " + text_of("body", id) + " is player " +
                                 std::to_string(owner->second) + "'s");
    }
    if (!seen.emplace(key_of(id), i).second) {
      return invalid_argument(field + ": " + text_of("body", id) + " is listed twice");
    }
    body_ids->push_back(id);
  }
  seen.clear();
  for (int i = 0; i < joints.size(); ++i) {
    const std::string field = "joints[" + std::to_string(i) + "]";
    const JointId id{joints[i].index(), joints[i].generation()};
    if (!world.joint_state(id).ok()) return not_found(field + ": no live " + text_of("joint", id));
    if (auto owner = joint_owner_.find(key_of(id)); refuse_owned && owner != joint_owner_.end()) {
      return failed_precondition(field + ": " + text_of("joint", id) + " is player " +
                                 std::to_string(owner->second) + "'s");
    }
    if (!seen.emplace(key_of(id), i).second) {
      return invalid_argument(field + ": " + text_of("joint", id) + " is listed twice");
    }
    joint_ids->push_back(id);
  }
  return {};
}

Status GameSession::set_ownership(const v1::SetOwnershipRequest& request, const World& world) {
  const uint32_t to = request.player_id();
  if (to != 0 && players_.find(to) == players_.end()) {
    return not_found("player_id: no player " + std::to_string(to) + " in this session");
  }
  std::vector<BodyId> bodies;
  std::vector<JointId> joints;
  FULCRUM_RETURN_IF_ERROR(
      check_objects(request.bodies(), request.joints(), world, false, &bodies, &joints));
  // Each object leaves its old owner's list (in the order the owner got them) and joins the
  // new owner's at the end.
  auto move = [&](auto& owners, auto member, const auto& ids) {
    for (const auto& id : ids) {
      const uint64_t key = key_of(id);
      auto owner = owners.find(key);
      if (owner != owners.end()) {
        if (owner->second == to) continue;
        auto& list = players_.at(owner->second).*member;
        list.erase(std::find(list.begin(), list.end(), id));
        owners_changed_.insert(owner->second);
        owners.erase(owner);
      }
      if (to == 0) continue;
      owners[key] = to;
      (players_.at(to).*member).push_back(id);
      owners_changed_.insert(to);
    }
  };
  move(body_owner_, &Player::bodies, bodies);
  move(joint_owner_, &Player::joints, joints);
  return {};
}

Status GameSession::check_input(const Player& player, const v1::EditBatch& input) const {
  if (input.edits_size() > kMaxInputEdits) {
    return resource_exhausted("input.edits: " + std::to_string(input.edits_size()) +
                              " edits; an input holds at most " + std::to_string(kMaxInputEdits));
  }
  auto own_body = [&](const std::string& field, const v1::Handle& h) -> Status {
    const BodyId id{h.index(), h.generation()};
    auto owner = body_owner_.find(key_of(id));
    if (owner == body_owner_.end() || owner->second != player.id) {
      return Status(
          StatusCode::kPermissionDenied,
          field + ": " + text_of("body", id) + " is " +
              (owner == body_owner_.end() ? std::string("no player's")
                                          : "player " + std::to_string(owner->second) + "'s") +
              ", not player " + std::to_string(player.id) + "'s");
    }
    return {};
  };
  auto own_joint = [&](const std::string& field, const v1::Handle& h) -> Status {
    const JointId id{h.index(), h.generation()};
    auto owner = joint_owner_.find(key_of(id));
    if (owner == joint_owner_.end() || owner->second != player.id) {
      return Status(
          StatusCode::kPermissionDenied,
          field + ": " + text_of("joint", id) + " is " +
              (owner == joint_owner_.end() ? std::string("no player's")
                                           : "player " + std::to_string(owner->second) + "'s") +
              ", not player " + std::to_string(player.id) + "'s");
    }
    return {};
  };
  for (int i = 0; i < input.edits_size(); ++i) {
    const v1::Edit& e = input.edits(i);
    std::string f = "input.edits[" + std::to_string(i) + "]";
    switch (e.kind_case()) {
      case v1::Edit::kApplyForce:
        f += ".apply_force";
        FULCRUM_RETURN_IF_ERROR(own_body(f + ".body", e.apply_force().body()));
        FULCRUM_RETURN_IF_ERROR(check_vec(f + ".force", e.apply_force().force()));
        if (e.apply_force().has_point()) {
          FULCRUM_RETURN_IF_ERROR(check_vec(f + ".point", e.apply_force().point()));
        }
        break;
      case v1::Edit::kApplyImpulse:
        f += ".apply_impulse";
        FULCRUM_RETURN_IF_ERROR(own_body(f + ".body", e.apply_impulse().body()));
        FULCRUM_RETURN_IF_ERROR(check_vec(f + ".impulse", e.apply_impulse().impulse()));
        if (e.apply_impulse().has_point()) {
          FULCRUM_RETURN_IF_ERROR(check_vec(f + ".point", e.apply_impulse().point()));
        }
        FULCRUM_RETURN_IF_ERROR(
            check_value(f + ".angular_impulse", e.apply_impulse().angular_impulse()));
        break;
      case v1::Edit::kApplyTorque:
        f += ".apply_torque";
        FULCRUM_RETURN_IF_ERROR(own_body(f + ".body", e.apply_torque().body()));
        FULCRUM_RETURN_IF_ERROR(check_value(f + ".torque", e.apply_torque().torque()));
        break;
      case v1::Edit::kSetVelocity:
        f += ".set_velocity";
        FULCRUM_RETURN_IF_ERROR(own_body(f + ".body", e.set_velocity().body()));
        FULCRUM_RETURN_IF_ERROR(check_vec(f + ".linear", e.set_velocity().linear()));
        FULCRUM_RETURN_IF_ERROR(check_value(f + ".angular", e.set_velocity().angular()));
        break;
      case v1::Edit::kSetMotor:
        f += ".set_motor";
        FULCRUM_RETURN_IF_ERROR(own_joint(f + ".joint", e.set_motor().joint()));
        FULCRUM_RETURN_IF_ERROR(check_value(f + ".speed", e.set_motor().speed()));
        break;
      case v1::Edit::kSetJointTarget:
        f += ".set_joint_target";
        FULCRUM_RETURN_IF_ERROR(own_joint(f + ".joint", e.set_joint_target().joint()));
        FULCRUM_RETURN_IF_ERROR(check_vec(f + ".target", e.set_joint_target().target()));
        break;
      case v1::Edit::KIND_NOT_SET:
        return invalid_argument(f + ": empty edit");
      default:
        return invalid_argument(
            f + "." + std::string(e.GetDescriptor()->FindFieldByNumber(e.kind_case())->name()) +
            ": not an input edit (an input may apply_force, apply_impulse, apply_torque or "
            "set_velocity on the player's bodies, set_motor or set_joint_target on its joints)");
    }
  }
  return {};
}

Status GameSession::check_player(uint32_t player_id, const std::string& secret) const {
  auto found = players_.find(player_id);
  if (found == players_.end()) {
    return not_found("player_id: no player " + std::to_string(player_id) + " in this session");
  }
  if (!same_secret(secret, found->second.secret)) {
    return Status(StatusCode::kPermissionDenied,
                  "player_secret: not player " + std::to_string(player_id) + "'s secret");
  }
  return {};
}

void GameSession::presence(uint32_t player_id, int change) {
  auto found = players_.find(player_id);
  if (found == players_.end()) return;
  Player& p = found->second;
  p.watches += change;
  p.left = p.watches <= 0;
}

Status GameSession::send_input(const v1::SendInputRequest& request, const World& world,
                               v1::SendInputReply* reply) {
  FULCRUM_RETURN_IF_ERROR(check_player(request.player_id(), request.player_secret()));
  const Player& player = players_.at(request.player_id());
  // Turn by turn the world waits for its inputs, so every tick not sealed yet is open; on the
  // clock, an input must leave its tick input_delay ticks to reach the other clients.
  const int64_t earliest =
      world.tick() +
      (options_.seal() == v1::SEAL_RULE_ALL_INPUTS ? 0 : int64_t{options_.input_delay()});
  if (request.tick() <= sealed_through_) {
    return failed_precondition("tick: " + std::to_string(request.tick()) +
                               " is sealed already; the earliest tick open to inputs is " +
                               std::to_string(earliest));
  }
  if (request.tick() < earliest) {
    return failed_precondition("tick: " + std::to_string(request.tick()) + " is less than " +
                               "input_delay (" + std::to_string(options_.input_delay()) +
                               ") past the world's tick " + std::to_string(world.tick()) +
                               "; the earliest tick open to inputs is " + std::to_string(earliest));
  }
  if (request.tick() > world.tick() + static_cast<int64_t>(options_.max_input_lead())) {
    return invalid_argument("tick: at most max_input_lead (" +
                            std::to_string(options_.max_input_lead()) + ") past the world's tick " +
                            std::to_string(world.tick()) + " (got " +
                            std::to_string(request.tick()) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_input(player, request.input()));
  reply->set_tick(request.tick());
  auto& at_tick = inputs_[request.tick()];
  reply->set_duplicate(!at_tick.emplace(player.id, request.input()).second);
  return {};
}

bool GameSession::complete(int64_t tick) const {
  if (players_.empty()) return false;
  auto at = inputs_.find(tick);
  bool anyone = false;
  for (const auto& [id, player] : players_) {
    if (player.left) continue;
    anyone = true;
    if (tick < player.first_input_tick) continue;
    if (at == inputs_.end() || !at->second.contains(id)) return false;
  }
  return anyone;
}

GameSession::Sealed GameSession::seal(int64_t tick) {
  Sealed out;
  out.batches = std::move(pending_);
  pending_.clear();
  // Sealed before, and its step refused: what it held was carried and is applied already.
  if (tick <= sealed_through_) return out;
  std::map<uint32_t, v1::EditBatch> arrived;
  if (auto at = inputs_.find(tick); at != inputs_.end()) {
    arrived = std::move(at->second);
    inputs_.erase(at);
  }
  // Inputs for ticks before this one can only be left from a tick that never ran (a world
  // restored from outside the session is refused, so this is defensive).
  inputs_.erase(inputs_.begin(), inputs_.lower_bound(tick));
  for (auto& [id, player] : players_) {
    auto input = arrived.find(id);
    if (input != arrived.end()) {
      player.last_input = input->second;
      if (input->second.edits_size() > 0) {
        out.batches.push_back({id, std::move(input->second), false});
      }
      continue;
    }
    if (tick < player.first_input_tick) continue;  // it could not have sent one
    out.missing.push_back(id);
    if (options_.missing_input() == v1::MISSING_INPUT_REPEAT_LAST &&
        player.last_input.edits_size() > 0) {
      out.batches.push_back({id, player.last_input, false});
    }
  }
  sealed_through_ = tick;
  return out;
}

void GameSession::carry(Sealed sealed) {
  for (Batch& b : pending_) sealed.batches.push_back(std::move(b));
  pending_ = std::move(sealed.batches);
  for (Batch& b : pending_) b.applied = true;
}

std::shared_ptr<const v1::SessionEvent> GameSession::confirm(const Sealed& applied,
                                                             const World& world) {
  auto event = std::make_shared<v1::SessionEvent>();
  v1::ConfirmedTick* c = event->mutable_confirmed();
  c->mutable_tick()->set_tick(world.tick());
  c->mutable_tick()->set_state_hash(world.state_hash());
  for (const Batch& b : applied.batches) {
    *c->mutable_tick()->add_edits() = b.edits;
    c->add_batch_players(b.player);
  }
  for (uint32_t id : applied.missing) c->add_missing_players(id);
  for (uint32_t id : joined_) {
    if (auto p = players_.find(id); p != players_.end()) {
      player_to_proto(p->second, c->add_joined());
    }
  }
  for (uint32_t id : owners_changed_) {
    const bool joined = std::find(joined_.begin(), joined_.end(), id) != joined_.end();
    if (auto p = players_.find(id); p != players_.end() && !joined) {
      player_to_proto(p->second, c->add_owners_changed());
    }
  }
  joined_.clear();
  owners_changed_.clear();
  history_.add(world, event);
  return event;
}

std::shared_ptr<const v1::SessionEvent> GameSession::start_event(const World& world,
                                                                 bool resync) const {
  auto event = std::make_shared<v1::SessionEvent>();
  v1::SessionStart* s = event->mutable_start();
  s->set_tick(world.tick());
  s->set_state_hash(world.state_hash());
  *s->mutable_snapshot() = wrap_snapshot(snapshot_to_proto(world.snapshot()));
  *s->mutable_options() = options_;
  for (const auto& [id, p] : players_) player_to_proto(p, s->add_players());
  s->set_fingerprint(kDeterminismFingerprint);
  s->set_applied_batches(static_cast<uint32_t>(pending_.size()));
  s->set_resync(resync);
  return event;
}

Status GameSession::compare_hashes(const v1::ReportHashRequest& request, const World& world,
                                   v1::ReportHashReply* reply) const {
  FULCRUM_RETURN_IF_ERROR(check_player(request.player_id(), request.player_secret()));
  const int64_t last = request.first_tick() + request.hashes_size() - 1;
  if (last > world.tick()) {
    return invalid_argument("first_tick: the hashes run to tick " + std::to_string(last) +
                            ", past the last confirmed tick " + std::to_string(world.tick()));
  }
  const int64_t from = std::max(request.first_tick(), history_.oldest_hash_tick());
  const int64_t through = std::min(last, history_.newest_hash_tick());
  if (from > through) {
    reply->set_verdict(v1::HASH_VERDICT_UNCHECKED);
    return {};
  }
  reply->set_checked_from(from);
  reply->set_checked_through(through);
  reply->set_verdict(v1::HASH_VERDICT_MATCH);
  for (int64_t tick = from; tick <= through; ++tick) {
    const uint64_t reported = request.hashes(static_cast<int>(tick - request.first_tick()));
    const uint64_t confirmed = *history_.hash_after(tick);
    if (reported == confirmed) continue;
    reply->set_verdict(v1::HASH_VERDICT_DESYNC);
    reply->set_divergent_tick(tick);
    reply->set_server_hash(confirmed);
    reply->set_client_hash(reported);
    break;
  }
  return {};
}

}  // namespace fulcrum::server

// --- Session: multiplayer ------------------------------------------------------------------------

namespace fulcrum::server {

Status Session::open_session(const v1::OpenSessionRequest& request, v1::OpenSessionReply* reply) {
  v1::SessionOptions options = request.options();
  FULCRUM_RETURN_IF_ERROR(GameSession::check_options(&options));
  Hold hold(this);
  if (game_) {
    return failed_precondition("world_id: world " + std::to_string(id_) + " is a session already");
  }
  game_ = std::make_unique<GameSession>(options, world_);
  game_->set_scene_owners(scene_owners_);
  reply->set_tick(world_.tick());
  *reply->mutable_options() = options;
  reply->set_fingerprint(kDeterminismFingerprint);
  log_event("session_opened", {{"world", id_},
                               {"tick", world_.tick()},
                               {"max_players", options.max_players()},
                               {"input_delay", options.input_delay()},
                               {"seal", v1::SealRule_Name(options.seal())}});
  return {};
}

namespace {

Status not_a_session(uint64_t id) {
  return failed_precondition("world_id: world " + std::to_string(id) +
                             " is not a multiplayer session (OpenSession first)");
}

}  // namespace

Status Session::join_session(const v1::JoinSessionRequest& request, v1::JoinSessionReply* reply) {
  Hold hold(this);
  if (!game_) return not_a_session(id_);
  FULCRUM_RETURN_IF_ERROR(game_->join(request, world_, reply));
  log_event("player_joined", {{"world", id_},
                              {"player", reply->player_id()},
                              {"tick", world_.tick()},
                              {"bodies", request.bodies_size()},
                              {"joints", request.joints_size()}});
  return {};
}

void Session::set_scene_owners(std::map<uint32_t, GameSession::SceneOwned> owners) {
  Hold hold(this);
  scene_owners_ = std::move(owners);
}

Status Session::set_ownership(const v1::SetOwnershipRequest& request,
                              v1::SetOwnershipReply* reply) {
  Hold hold(this);
  if (!game_) return not_a_session(id_);
  FULCRUM_RETURN_IF_ERROR(game_->set_ownership(request, world_));
  reply->set_tick(world_.tick());
  log_event("ownership_set", {{"world", id_},
                              {"player", request.player_id()},
                              {"tick", world_.tick()},
                              {"bodies", request.bodies_size()},
                              {"joints", request.joints_size()}});
  return {};
}

Status Session::send_input(const v1::SendInputRequest& request, v1::SendInputReply* reply) {
  Hold hold(this);
  if (!game_) return not_a_session(id_);
  FULCRUM_RETURN_IF_ERROR(game_->send_input(request, world_, reply));
  step_complete_ticks_locked();
  return {};
}

void Session::step_complete_ticks_locked() {
  if (game_->options().seal() != v1::SEAL_RULE_ALL_INPUTS ||
      clock_.mode == v1::RUN_MODE_REAL_TIME) {
    return;
  }
  // Turn by turn: every tick whose inputs are all in is sealed and stepped now.
  const auto start = std::chrono::steady_clock::now();
  uint32_t ran = 0;
  while (game_->complete(world_.tick())) {
    if (Status st = tick_locked(); !st.ok()) {
      log_event("session_tick_refused", {{"world", id_}, {"message", st.message()}});
      break;  // the input is held; the tick runs when the world can step it
    }
    ++ran;
  }
  if (ran > 0) {
    counters().add_steps(ran, std::chrono::steady_clock::now() - start);
    refresh_summary_locked(world_.state_hash());
  }
}

Status Session::watch_session(std::shared_ptr<SessionWatcher> watcher, uint32_t player_id,
                              const std::string& secret) {
  std::optional<Status> closed;  // close_streams ran while this call was on its way
  {
    Hold hold(this);
    if (!game_) return not_a_session(id_);
    if (player_id != 0 || !secret.empty()) {
      FULCRUM_RETURN_IF_ERROR(game_->check_player(player_id, secret));
      game_->presence(player_id, +1);
    }
    watcher->offer(game_->start_event(world_));
    std::lock_guard<std::mutex> wl(session_watchers_mu_);
    closed = session_watchers_closed_;
    if (!closed) session_watchers_.push_back(watcher);
  }
  // Outside the world's lock, as close_streams does: the stream's end leaves the player
  // (unwatch_session), which takes that lock.
  if (closed) watcher->close(*closed);
  return {};
}

void Session::unwatch_session(const SessionWatcher* watcher, uint32_t player_id) {
  {
    std::lock_guard<std::mutex> wl(session_watchers_mu_);
    std::erase_if(session_watchers_, [&](const std::weak_ptr<SessionWatcher>& w) {
      auto held = w.lock();
      return !held || held.get() == watcher;
    });
  }
  if (player_id == 0) return;
  Hold hold(this);
  if (!game_) return;
  game_->presence(player_id, -1);
  log_event("player_watch_ended", {{"world", id_}, {"player", player_id}});
  step_complete_ticks_locked();  // a turn may have waited only for this player
}

Status Session::report_hash(const v1::ReportHashRequest& request, v1::ReportHashReply* reply) {
  // The request's own shape first, and the snapshot checked whole, before the world is held.
  if (request.hashes_size() == 0) {
    return invalid_argument("hashes: at least one (the state hash after first_tick)");
  }
  if (request.hashes_size() > ConfirmedHistory::kHashWindow) {
    return invalid_argument("hashes: at most " + std::to_string(ConfirmedHistory::kHashWindow) +
                            " per report (got " + std::to_string(request.hashes_size()) + ")");
  }
  if (request.first_tick() < 1) {
    return invalid_argument("first_tick: the world's tick after a step, at least 1 (got " +
                            std::to_string(request.first_tick()) + ")");
  }
  const int64_t last = request.first_tick() + request.hashes_size() - 1;
  std::optional<v1::Snapshot> theirs;
  if (request.has_snapshot()) {
    Result<WorldSnapshot> records = decode_snapshot(request.snapshot(), limits_);
    if (!records.ok()) return records.status();  // its message names the place in the snapshot
    World check;  // the engine's own check of every value and link (NaN included)
    if (Status restored = check.restore(*records); !restored.ok()) {
      return invalid_argument(restored.message());
    }
    if (records->tick < request.first_tick() || records->tick > last) {
      return invalid_argument("snapshot: of tick " + std::to_string(records->tick) +
                              ", not one of the reported ticks " +
                              std::to_string(request.first_tick()) + " to " + std::to_string(last));
    }
    theirs = snapshot_to_proto(*records);
  }

  std::optional<ConfirmedHistory::Replay> replay;
  {
    Hold hold(this);
    if (!game_) return not_a_session(id_);
    FULCRUM_RETURN_IF_ERROR(game_->compare_hashes(request, world_, reply));
    ++counters().hash_reports;
    if (reply->verdict() != v1::HASH_VERDICT_DESYNC) return {};
    ++counters().desyncs;
    if (theirs && theirs->tick() == reply->divergent_tick()) {
      replay = game_->history().replay_to(reply->divergent_tick());
    }
    if (request.resync()) resync_player_locked(request.player_id(), reply);
  }

  // The field that differs: the server's world at the divergent tick is rebuilt from its
  // keyframe without the world held, then compared as `fulcrum replay verify` compares.
  const std::string tick = std::to_string(reply->divergent_tick());
  if (!theirs) {
    reply->set_note("no snapshot sent: send this player's snapshot of tick " + tick +
                    " to learn the first field that differs");
  } else if (theirs->tick() != reply->divergent_tick()) {
    reply->set_note("the snapshot is of tick " + std::to_string(theirs->tick()) +
                    ", not of the first tick that differs (" + tick + ")");
  } else if (!replay) {
    reply->set_note("tick " + tick + " is before the server's oldest keyframe");
  } else if (Result<WorldSnapshot> ours = rebuild(*replay); !ours.ok()) {
    reply->set_note("the server could not rebuild tick " + tick + ": " + ours.status().message());
  } else {
    const v1::Snapshot expected = snapshot_to_proto(*ours);
    reply->set_first_difference(first_difference(expected, *theirs));
    // "bodies[12].position.x: ..." names body slot 12; its handle takes the server's generation.
    const std::string& d = reply->first_difference();
    if (d.rfind("bodies[", 0) == 0) {
      const int slot = std::atoi(d.c_str() + 7);
      if (slot >= 0 && slot < expected.bodies_size()) {
        reply->mutable_body()->set_index(slot);
        reply->mutable_body()->set_generation(expected.bodies(slot).generation());
      }
    }
  }
  log_event("desync",
            {{"world", id_},
             {"player", request.player_id()},
             {"tick", reply->divergent_tick()},
             {"server_hash", World::hash_text(reply->server_hash())},
             {"client_hash", World::hash_text(reply->client_hash())},
             {"difference",
              reply->first_difference().empty() ? reply->note() : reply->first_difference()},
             {"resync_tick",
              reply->resynced() ? std::to_string(reply->resync_tick()) : std::string("none")}});
  return {};
}

void Session::resync_player_locked(uint32_t player_id, v1::ReportHashReply* reply) {
  std::vector<std::shared_ptr<SessionWatcher>> due;
  {
    std::lock_guard<std::mutex> wl(session_watchers_mu_);
    for (const auto& w : session_watchers_) {
      auto watcher = w.lock();
      if (watcher && watcher->player_id() == player_id) due.push_back(std::move(watcher));
    }
  }
  if (due.empty()) return;  // nothing to send it on: a new watch starts from the world anyway
  // Offered with the world held, so it sits between the same confirmed ticks on every stream.
  std::shared_ptr<const v1::SessionEvent> start = game_->start_event(world_, true);
  for (auto& watcher : due) watcher->offer(start);
  reply->set_resynced(true);
  reply->set_resync_tick(world_.tick());
  reply->set_resync_watches(static_cast<int32_t>(due.size()));
  ++counters().resyncs;
}

GameSession::Sealed Session::seal_inputs_locked() {
  GameSession::Sealed sealed = game_->seal(world_.tick());
  std::vector<GameSession::Batch> kept;
  kept.reserve(sealed.batches.size());
  for (GameSession::Batch& b : sealed.batches) {
    if (!b.applied) {
      // Checked when it arrived; the world may have changed since (the owner destroyed the
      // player's body): then the input is dropped, whole, and its player counts as missing.
      Result<EditOutcome> applied = apply_edit_batch(&world_, b.edits);
      if (!applied.ok()) {
        sealed.missing.push_back(b.player);
        log_event("input_dropped", {{"world", id_},
                                    {"player", b.player},
                                    {"tick", world_.tick()},
                                    {"message", applied.status().message()}});
        continue;
      }
      if (recorder_) recorder_->note_batch(b.edits);
      b.applied = true;
    }
    kept.push_back(std::move(b));
  }
  sealed.batches = std::move(kept);
  // A stand-in (MISSING_INPUT_REPEAT_LAST) the world refused lists its player a second time.
  std::sort(sealed.missing.begin(), sealed.missing.end());
  sealed.missing.erase(std::unique(sealed.missing.begin(), sealed.missing.end()),
                       sealed.missing.end());
  return sealed;
}

}  // namespace fulcrum::server
