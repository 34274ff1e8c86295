// StepTrajectory on the world's side: a Step in parts, each part holding the world only while
// it steps, so that the service sends a part's samples (and waits for a slow reader) with the
// world free.
#include <string>
#include <unordered_map>

#include "session.h"
#include "stats.h"

namespace fulcrum::server {

namespace {

std::string handle_text(BodyId id) {
  return "{" + std::to_string(id.index) + ", " + std::to_string(id.generation) + "}";
}

// An upper bound of a sample's encoding: a BodyFrame takes at most 77 bytes (two handle
// varints of 5 bytes, five doubles, a bool, the tags and lengths), a sample's tick and hash 20.
int64_t max_sample_bytes(size_t bodies) {
  return 32 + 80 * static_cast<int64_t>(bodies);
}
// What a chunk of samples may take: a message less room for the chunk's own framing and
// `done`.
int64_t message_room(const Limits& limits) {
  return limits.max_message_bytes - 1024;
}

// The world after the ticks run so far, as Step replies.
void fill_reply(const World& world, const Session::TrajectoryProgress& progress,
                v1::StepReply* reply) {
  reply->set_tick(world.tick());
  reply->set_state_hash(world.state_hash());
  int awake = 0;
  for (BodyId id : world.bodies()) {
    Result<BodyState> s = world.body_state(id);
    if (s.ok() && s->awake) ++awake;
  }
  reply->set_awake_body_count(awake);
  reply->set_step_ms(std::chrono::duration<double, std::milli>(progress.stepping).count());
}

// The sampled bodies, checked once when the call starts: each live and listed once.
Result<std::vector<BodyId>> sampled_bodies(const World& world,
                                           const v1::StepTrajectoryRequest& request) {
  if (request.bodies().empty()) return world.bodies();
  std::vector<BodyId> out;
  out.reserve(request.bodies_size());
  std::unordered_map<uint64_t, int> seen;
  for (int i = 0; i < request.bodies_size(); ++i) {
    const v1::Handle& h = request.bodies(i);
    const BodyId id{h.index(), h.generation()};
    const std::string field = "bodies[" + std::to_string(i) + "]";
    if (!world.body_state(id).ok()) return not_found(field + ": no live body " + handle_text(id));
    const uint64_t key = (uint64_t{h.generation()} << 32) | static_cast<uint32_t>(h.index());
    auto [at, fresh] = seen.emplace(key, i);
    if (!fresh) {
      return invalid_argument(field + ": body " + handle_text(id) + " is listed twice (also " +
                              "bodies[" + std::to_string(at->second) + "])");
    }
    out.push_back(id);
  }
  return out;
}

}  // namespace

Status Session::step_trajectory(const v1::StepTrajectoryRequest& request, size_t chunk_bytes,
                                std::chrono::steady_clock::duration part_time,
                                const KeepGoing& keep_going, TrajectoryProgress* progress,
                                v1::TrajectoryChunk* chunk) {
  chunk->Clear();
  Hold hold(this);
  if (clock_.mode == v1::RUN_MODE_REAL_TIME) {
    if (!progress->started) {
      return failed_precondition("world " + std::to_string(id_) +
                                 " runs in real time: pause it (SetRunMode PAUSED) to Step it");
    }
    fill_reply(world_, *progress, &progress->reply);
    return failed_precondition(
        "world " + std::to_string(id_) + " was set to run in real time by another call after " +
        std::to_string(progress->done) + " of " + std::to_string(progress->total) + " ticks");
  }
  size_t bytes = 0;
  auto sample = [&] {
    v1::TrajectorySample* s = chunk->add_samples();
    s->set_tick(world_.tick());
    s->set_state_hash(world_.state_hash());
    for (BodyId id : progress->bodies) {
      // Checked live when the part began; nothing but this part changes the world meanwhile.
      Result<BodyState> state = world_.body_state(id);
      if (state.ok()) motion_to_proto(motion_of(id, *state), s->add_bodies());
    }
    bytes += s->ByteSizeLong();
  };

  if (!progress->started) {
    if (request.ticks() == 0) return invalid_argument("ticks: must be >= 1 (got 0)");
    if (request.ticks() > limits_.max_step_ticks) {
      return resource_exhausted("ticks: at most " + std::to_string(limits_.max_step_ticks) +
                                " per Step on this server (got " + std::to_string(request.ticks()) +
                                "; max_step_ticks)");
    }
    FULCRUM_RETURN_IF_ERROR(check_expected_tick(
        request.has_expected_tick() ? std::optional<int64_t>(request.expected_tick())
                                    : std::nullopt,
        world_.tick()));
    Result<std::vector<BodyId>> bodies = sampled_bodies(world_, request);
    if (!bodies.ok()) return bodies.status();
    const int64_t sample_bytes = max_sample_bytes(bodies->size());
    if (sample_bytes > message_room(limits_)) {
      return resource_exhausted("bodies: a sample of " + std::to_string(bodies->size()) +
                                " bodies may take " + std::to_string(sample_bytes) +
                                " bytes, more than a message may hold on this server " +
                                "(--max-message-bytes " +
                                std::to_string(limits_.max_message_bytes) + "); name fewer bodies");
    }
    progress->bodies = std::move(*bodies);
    progress->total = request.ticks();
    progress->every = request.every_ticks() == 0 ? 1 : request.every_ticks();
    progress->started = true;
    if (request.include_start()) sample();
  } else {
    // Other calls may have taken the world since the last part.
    for (size_t i = 0; i < progress->bodies.size(); ++i) {
      if (!world_.body_state(progress->bodies[i]).ok()) {
        fill_reply(world_, *progress, &progress->reply);
        return not_found("bodies[" + std::to_string(i) + "]: body " +
                         handle_text(progress->bodies[i]) + " was destroyed by another call " +
                         "after " + std::to_string(progress->done) + " of " +
                         std::to_string(progress->total) + " ticks");
      }
    }
  }

  const auto start = std::chrono::steady_clock::now();
  uint32_t ran = 0;
  Status stopped;
  while (progress->done < progress->total) {
    if (keep_going && progress->done > 0) {
      stopped = keep_going();
      if (!stopped.ok()) break;
    }
    stopped = tick_locked();
    if (!stopped.ok()) break;
    ++ran;
    ++progress->done;
    if (progress->done % progress->every == 0) sample();
    // The chunk ends when it is full enough, when another sample might not fit a message,
    // or when the part has held the world long enough.
    if (bytes >= chunk_bytes ||
        static_cast<int64_t>(bytes) + max_sample_bytes(progress->bodies.size()) >
            message_room(limits_) ||
        std::chrono::steady_clock::now() - start >= part_time) {
      break;
    }
  }
  const auto end = std::chrono::steady_clock::now();
  counters().add_steps(ran, end - start);
  progress->stepping += end - start;
  fill_reply(world_, *progress, &progress->reply);
  refresh_summary_locked(progress->reply.state_hash());
  if (!stopped.ok()) {
    return Status(stopped.code(), "ticks: stopped after " + std::to_string(progress->done) +
                                      " of " + std::to_string(progress->total) +
                                      " ticks: " + stopped.message() +
                                      ". The world keeps the ticks it ran: it is at tick " +
                                      std::to_string(world_.tick()) + ", state hash " +
                                      World::hash_text(progress->reply.state_hash()));
  }
  if (progress->finished()) *chunk->mutable_done() = progress->reply;
  return {};
}

}  // namespace fulcrum::server
