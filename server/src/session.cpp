#include "session.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <utility>

#include "describe_convert.h"
#include "edit_convert.h"
#include "fulcrum/scene.h"
#include "scene_convert.h"
#include "snapshot_convert.h"
#include "stats.h"

namespace fulcrum::server {

namespace {

void handle_to_proto(int32_t index, uint32_t generation, v1::Handle* out) {
  out->set_index(index);
  out->set_generation(generation);
}

bool finite(const v1::Vec2& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y());
}
Vec2 to_vec(const v1::Vec2& v) {
  return Vec2(v.x(), v.y());
}
void to_proto(const Vec2& v, v1::Vec2* out) {
  out->set_x(v.x());
  out->set_y(v.y());
}

Status check_vec(const v1::Vec2& v, const std::string& field) {
  if (!finite(v)) {
    return invalid_argument(field + ": must be finite (got (" + std::to_string(v.x()) + ", " +
                            std::to_string(v.y()) + "))");
  }
  return {};
}

}  // namespace

Status check_expected_tick(std::optional<int64_t> expected, int64_t tick) {
  if (expected && *expected != tick) {
    return failed_precondition("expected_tick: the world is at tick " + std::to_string(tick) +
                               ", not " + std::to_string(*expected));
  }
  return {};
}

Session::Session(uint64_t id, std::string name, World world, const Limits& limits)
    : id_(id), name_(std::move(name)), limits_(limits), world_(std::move(world)) {
  // Checked when the server started (1 to World::kMaxThreads); a refusal leaves one thread.
  Status threads = world_.set_threads(limits.world_threads);
  (void)threads;
  Status contacts = world_.set_contact_limit(limits.max_contacts);  // checked >= 0 at start
  (void)contacts;
  refresh_summary_locked(world_.state_hash());  // nobody else can hold the world yet
}

void Session::refresh_summary_locked(uint64_t state_hash) {
  const WorldMetrics m = world_.metrics();
  std::lock_guard<std::mutex> sl(summary_mu_);
  summary_.set_world_id(id_);
  summary_.set_name(name_);
  summary_.set_tick(world_.tick());
  summary_.set_body_count(m.body_count);
  summary_.set_awake_body_count(m.awake_body_count);
  summary_.set_contact_count(m.contact_count);
  summary_.set_budget_islands(m.budget_islands);
  summary_.set_max_substeps(m.max_substeps);
  summary_.set_max_relax_iterations(m.max_relax_iterations);
  summary_.set_state_hash(state_hash);
  runtime_to_proto_locked(&summary_);
}

Status Session::tick_locked() {
  GameSession::Sealed sealed;
  if (game_) sealed = seal_inputs_locked();
  if (Status refused = world_.try_step(); !refused.ok()) {
    if (game_) game_->carry(std::move(sealed));
    return Status(refused.code(),
                  "world " + std::to_string(id_) + ": " + refused.message() +
                      " (max_contacts; overlapping shapes make contacts grow with the square of "
                      "their number), so the tick did not run");
  }
  if (recorder_) {
    Status recorded = recorder_->after_tick(world_);
    if (!recorded.ok()) end_recording_locked(recorded.message());
  }
  if (game_) {
    std::shared_ptr<const v1::SessionEvent> confirmed = game_->confirm(sealed, world_);
    std::vector<std::shared_ptr<SessionWatcher>> due;
    {
      std::lock_guard<std::mutex> wl(session_watchers_mu_);
      std::erase_if(session_watchers_,
                    [](const std::weak_ptr<SessionWatcher>& w) { return w.expired(); });
      for (const auto& w : session_watchers_) {
        if (auto watcher = w.lock()) due.push_back(std::move(watcher));
      }
    }
    for (auto& watcher : due) watcher->offer(confirmed);
  }
  publish_tick_locked();
  return {};
}

void Session::info(v1::WorldInfo* out) {
  v1::WorldSettings settings;
  {
    Hold hold(this);
    refresh_summary_locked(world_.state_hash());
    world_settings_to_proto(world_.settings(), &settings);
  }
  summary(out);
  *out->mutable_settings() = std::move(settings);
}

void Session::summary(v1::WorldInfo* out) {
  {
    std::lock_guard<std::mutex> sl(summary_mu_);
    *out = summary_;
  }
  std::lock_guard<std::mutex> wl(watchers_mu_);
  out->set_watchers(static_cast<uint32_t>(watchers_.size()));
}

Status Session::apply_edits(const v1::EditBatch& batch, std::optional<int64_t> expected_tick,
                            const KeepGoing& keep_going, v1::ApplyEditsReply* reply) {
  if (batch.edits_size() == 0) return invalid_argument("batch.edits: must not be empty");
  EditLimits limits;
  limits.max_edits = limits_.max_edits;
  limits.max_bodies = limits_.max_bodies;
  limits.max_shapes = limits_.max_shapes;
  limits.max_shapes_per_body = limits_.max_shapes_per_body;
  limits.max_work = limits_.max_batch_work;
  limits.keep_going = keep_going;
  {
    Hold hold(this);
    FULCRUM_RETURN_IF_ERROR(check_expected_tick(expected_tick, world_.tick()));
    Result<EditOutcome> outcome = apply_edit_batch(&world_, batch, limits);
    if (!outcome.ok()) return outcome.status().with_prefix("batch.");
    if (recorder_) recorder_->note_batch(batch);
    if (game_) game_->note_owner_batch(batch);
    reply->set_tick(world_.tick());
    for (BodyId id : outcome->bodies) handle_to_proto(id.index, id.generation, reply->add_bodies());
    for (ShapeId id : outcome->shapes)
      handle_to_proto(id.index, id.generation, reply->add_shapes());
    for (JointId id : outcome->joints)
      handle_to_proto(id.index, id.generation, reply->add_joints());
    reply->set_state_hash(world_.state_hash());
    refresh_summary_locked(reply->state_hash());
  }
  return {};
}

Status Session::step(uint32_t ticks, std::optional<int64_t> expected_tick, bool include_snapshot,
                     const KeepGoing& keep_going, v1::StepReply* reply) {
  if (ticks == 0) return invalid_argument("ticks: must be >= 1 (got 0)");
  if (ticks > limits_.max_step_ticks) {
    return resource_exhausted("ticks: at most " + std::to_string(limits_.max_step_ticks) +
                              " per Step on this server (got " + std::to_string(ticks) +
                              "; max_step_ticks)");
  }
  Status stopped;
  {
    Hold hold(this);
    if (clock_.mode == v1::RUN_MODE_REAL_TIME) {
      return failed_precondition("world " + std::to_string(id_) +
                                 " runs in real time: pause it (SetRunMode PAUSED) to Step it");
    }
    FULCRUM_RETURN_IF_ERROR(check_expected_tick(expected_tick, world_.tick()));
    const auto start = std::chrono::steady_clock::now();
    uint32_t done = 0;
    while (done < ticks) {
      if (keep_going && done > 0) {
        stopped = keep_going();
        if (!stopped.ok()) break;
      }
      stopped = tick_locked();
      if (!stopped.ok()) break;
      ++done;
    }
    const auto end = std::chrono::steady_clock::now();
    counters().add_steps(done, end - start);
    reply->set_tick(world_.tick());
    reply->set_state_hash(world_.state_hash());
    refresh_summary_locked(reply->state_hash());
    {
      std::lock_guard<std::mutex> sl(summary_mu_);
      reply->set_awake_body_count(summary_.awake_body_count());
    }
    reply->set_step_ms(std::chrono::duration<double, std::milli>(end - start).count());
    if (!stopped.ok()) {
      return Status(stopped.code(), "ticks: stopped after " + std::to_string(done) + " of " +
                                        std::to_string(ticks) + " ticks: " + stopped.message() +
                                        ". The world keeps the ticks it ran: it is at tick " +
                                        std::to_string(world_.tick()) + ", state hash " +
                                        World::hash_text(reply->state_hash()));
    }
    if (include_snapshot) {
      *reply->mutable_snapshot() = wrap_snapshot(snapshot_to_proto(world_.snapshot()));
    }
  }
  return {};
}

void Session::describe(v1::DescribeWorldReply* reply) {
  Hold hold(this);
  describe_world_to_proto(world_, reply);
  reply->set_world_id(id_);
}

void Session::snapshot(v1::GetSnapshotReply* reply) {
  Hold hold(this);
  reply->set_tick(world_.tick());
  reply->set_state_hash(world_.state_hash());
  *reply->mutable_snapshot() = wrap_snapshot(snapshot_to_proto(world_.snapshot()));
}

Result<WorldSnapshot> decode_snapshot(const v1::SnapshotFile& file, const Limits& limits) {
  // Their messages already start with "snapshot" and name the place.
  Result<v1::Snapshot> unwrapped = unwrap_snapshot(file);
  if (!unwrapped.ok()) return unwrapped.status();
  Result<WorldSnapshot> records = snapshot_from_proto(*unwrapped);
  if (!records.ok()) return records.status();
  int alive = 0;
  for (const Body& b : records->bodies) alive += b.alive ? 1 : 0;
  if (alive > limits.max_bodies) {
    return resource_exhausted("snapshot: " + std::to_string(alive) +
                              " bodies; this server allows " + std::to_string(limits.max_bodies) +
                              " per world (max_bodies)");
  }
  WorkLimits shape_limits;
  shape_limits.max_shapes = limits.max_shapes;
  shape_limits.max_shapes_per_body = limits.max_shapes_per_body;
  int64_t shapes = 0;
  for (size_t i = 0; i < records->bodies.size(); ++i) {
    const Body& b = records->bodies[i];
    if (!b.alive) continue;
    FULCRUM_RETURN_IF_ERROR(check_new_shapes(shape_limits, shapes, b.type, 0, b.shapes.size(),
                                             "snapshot: bodies[" + std::to_string(i) + "]"));
    shapes += static_cast<int64_t>(b.shapes.size());
  }
  int64_t contacts = 0;
  for (const Contact& c : records->contacts) contacts += c.alive ? 1 : 0;
  if (limits.max_contacts > 0 && contacts > limits.max_contacts) {
    return resource_exhausted("snapshot: " + std::to_string(contacts) +
                              " contacts; this server allows " +
                              std::to_string(limits.max_contacts) + " per world (max_contacts)");
  }
  return records;
}

Status Session::restore(const WorldSnapshot& records, v1::RestoreSnapshotReply* reply) {
  {
    Hold hold(this);
    if (recorder_) {
      return failed_precondition("world " + std::to_string(id_) + " is recording replay " +
                                 recorder_->name() +
                                 ": a replay cannot hold a rollback; stop recording first");
    }
    if (game_) {
      return failed_precondition("world " + std::to_string(id_) +
                                 " is a multiplayer session: its players follow its ticks, so "
                                 "it cannot be rolled back (fork it into a new world instead)");
    }
    FULCRUM_RETURN_IF_ERROR(world_.restore(records));  // its messages start "snapshot: "
    ++epoch_;
    ++counters().worlds_restored;
    log_event("world_restored", {{"world", id_}, {"tick", world_.tick()}});
    reply->set_world_id(id_);
    reply->set_tick(world_.tick());
    reply->set_state_hash(world_.state_hash());
    refresh_summary_locked(reply->state_hash());
    publish_all_locked();
  }
  return {};
}

Status Session::query(const v1::QueryRequest& request, v1::QueryReply* reply) {
  QueryFilter filter;
  if (request.filter().has_category_bits()) filter.category_bits = request.filter().category_bits();
  if (request.filter().has_mask_bits()) filter.mask_bits = request.filter().mask_bits();
  switch (request.kind_case()) {
    case v1::QueryRequest::kRayCast: {
      const v1::RayCastQuery& q = request.ray_cast();
      FULCRUM_RETURN_IF_ERROR(check_vec(q.origin(), "ray_cast.origin"));
      FULCRUM_RETURN_IF_ERROR(check_vec(q.translation(), "ray_cast.translation"));
      if (q.translation().x() == 0.0 && q.translation().y() == 0.0) {
        return invalid_argument("ray_cast.translation: must not be zero");
      }
      break;
    }
    case v1::QueryRequest::kAabb: {
      const v1::AabbQuery& q = request.aabb();
      FULCRUM_RETURN_IF_ERROR(check_vec(q.lower(), "aabb.lower"));
      FULCRUM_RETURN_IF_ERROR(check_vec(q.upper(), "aabb.upper"));
      if (q.lower().x() > q.upper().x() || q.lower().y() > q.upper().y()) {
        return invalid_argument("aabb.upper: must be >= aabb.lower in x and y");
      }
      break;
    }
    case v1::QueryRequest::kPoint:
      FULCRUM_RETURN_IF_ERROR(check_vec(request.point().point(), "point.point"));
      break;
    case v1::QueryRequest::KIND_NOT_SET:
      return invalid_argument("kind: one of ray_cast, aabb, point is required");
  }

  Hold hold(this);
  reply->set_tick(world_.tick());
  auto add_shape_and_body = [&](ShapeId shape, v1::Handle* shape_out, v1::Handle* body_out) {
    handle_to_proto(shape.index, shape.generation, shape_out);
    Result<ShapeInfo> info = world_.shape_info(shape);
    if (info.ok()) handle_to_proto(info->body.index, info->body.generation, body_out);
  };
  auto add_hit = [&](const RayHit& hit) {
    v1::RayHit* out = reply->add_hits();
    add_shape_and_body(hit.shape, out->mutable_shape(), out->mutable_body());
    to_proto(hit.point, out->mutable_point());
    to_proto(hit.normal, out->mutable_normal());
    out->set_fraction(hit.fraction);
  };
  std::vector<ShapeId> shapes;
  switch (request.kind_case()) {
    case v1::QueryRequest::kRayCast: {
      const v1::RayCastQuery& q = request.ray_cast();
      if (q.all()) {
        for (const RayHit& hit :
             world_.ray_cast_all(to_vec(q.origin()), to_vec(q.translation()), filter)) {
          add_hit(hit);
        }
      } else if (auto hit =
                     world_.ray_cast_closest(to_vec(q.origin()), to_vec(q.translation()), filter)) {
        add_hit(*hit);
      }
      break;
    }
    case v1::QueryRequest::kAabb: {
      AABB box;
      box.lower = to_vec(request.aabb().lower());
      box.upper = to_vec(request.aabb().upper());
      shapes = world_.overlap_aabb(box, filter);
      break;
    }
    case v1::QueryRequest::kPoint:
      shapes = world_.overlap_point(to_vec(request.point().point()), filter);
      break;
    case v1::QueryRequest::KIND_NOT_SET:
      break;
  }
  for (ShapeId shape : shapes) {
    v1::ShapeHit* out = reply->add_shapes();
    add_shape_and_body(shape, out->mutable_shape(), out->mutable_body());
  }
  return {};
}

// --- Watchers ---------------------------------------------------------------------------------

void Session::subscribe(std::shared_ptr<FrameSink> sink) {
  {
    std::unique_lock<std::mutex> wl(watchers_mu_);
    if (closed_) {
      const Closed closed = *closed_;
      wl.unlock();
      sink->close(closed.status, closed.shutting_down);
      return;
    }
    Watcher w;
    w.key = sink.get();
    w.every = sink->every_ticks();
    w.sink = sink;
    watchers_.push_back(std::move(w));
    any_need_first_ = true;
  }
  deliver_first_frames();
}

void Session::unsubscribe(const FrameSink* sink) {
  std::lock_guard<std::mutex> wl(watchers_mu_);
  std::erase_if(watchers_, [&](const Watcher& w) { return w.key == sink; });
}

void Session::close_streams(const Status& status, bool shutting_down) {
  std::vector<std::shared_ptr<FrameSink>> sinks;
  {
    std::lock_guard<std::mutex> wl(watchers_mu_);
    closed_ = Closed{status, shutting_down};
    for (Watcher& w : watchers_) {
      if (auto s = w.sink.lock()) sinks.push_back(std::move(s));
    }
    watchers_.clear();
  }
  for (auto& s : sinks) s->close(status, shutting_down);
  const Status closed =
      shutting_down ? Status(StatusCode::kUnavailable, "the server is stopping") : status;
  std::vector<std::weak_ptr<SessionWatcher>> session_watchers;
  {
    std::lock_guard<std::mutex> wl(session_watchers_mu_);
    session_watchers_closed_ = closed;
    session_watchers.swap(session_watchers_);
  }
  for (auto& w : session_watchers) {
    if (auto watcher = w.lock()) watcher->close(closed);
  }
}

void Session::publish_tick_locked() {
  const int64_t tick = world_.tick();
  std::vector<std::shared_ptr<FrameSink>> due;
  {
    std::lock_guard<std::mutex> wl(watchers_mu_);
    if (watchers_.empty()) return;
    for (Watcher& w : watchers_) {
      if (!w.needs_first && tick % w.every != 0) continue;
      if (auto s = w.sink.lock()) {
        due.push_back(std::move(s));
        w.needs_first = false;
      }
    }
  }
  if (due.empty()) return;
  // Captured once per tick, shared by every reader; offer() only swaps a pointer.
  std::shared_ptr<const PublishedFrame> frame = capture_frame(world_, id_, epoch_, ++frame_seq_);
  for (auto& s : due) s->offer(frame);
}

void Session::publish_all_locked() {
  std::vector<std::shared_ptr<FrameSink>> all;
  {
    std::lock_guard<std::mutex> wl(watchers_mu_);
    for (Watcher& w : watchers_) {
      if (auto s = w.sink.lock()) {
        all.push_back(std::move(s));
        w.needs_first = false;
      }
    }
  }
  if (all.empty()) return;
  std::shared_ptr<const PublishedFrame> frame = capture_frame(world_, id_, epoch_, ++frame_seq_);
  for (auto& s : all) s->offer(frame);
}

// A watcher that subscribes while a Step holds the world must not wait for it (the subscribe
// call runs on a gRPC thread). It marks itself, then tries the world's lock; every holder of the
// lock tries again after releasing it. Whoever gets the lock after the mark delivers the frame,
// so none is lost.
void Session::deliver_first_frames() {
  if (!any_need_first_) return;
  std::unique_lock<std::mutex> lock(mu_, std::try_to_lock);
  if (!lock.owns_lock()) return;  // the holder delivers when it releases
  std::vector<std::shared_ptr<FrameSink>> waiting;
  {
    std::lock_guard<std::mutex> wl(watchers_mu_);
    any_need_first_ = false;
    for (Watcher& w : watchers_) {
      if (!w.needs_first) continue;
      if (auto s = w.sink.lock()) waiting.push_back(std::move(s));
      w.needs_first = false;
    }
  }
  if (waiting.empty()) return;
  std::shared_ptr<const PublishedFrame> frame = capture_frame(world_, id_, epoch_, ++frame_seq_);
  for (auto& s : waiting) s->offer(frame);
}

// --- Registry ---------------------------------------------------------------------------------

Result<std::shared_ptr<Session>> Registry::create(std::string name, World world) {
  if (world.body_count() > limits_.max_bodies) {
    return resource_exhausted("scene: " + std::to_string(world.body_count()) +
                              " bodies; this server allows " + std::to_string(limits_.max_bodies) +
                              " per world (max_bodies)");
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (static_cast<int>(worlds_.size()) >= limits_.max_worlds) {
    return resource_exhausted("this server holds at most " + std::to_string(limits_.max_worlds) +
                              " worlds (max_worlds); delete one first");
  }
  const uint64_t id = next_id_++;
  const int bodies = world.body_count();
  const int64_t tick = world.tick();
  log_event("world_created", {{"world", id}, {"name", name}, {"bodies", bodies}, {"tick", tick}});
  ++counters().worlds_created;
  auto session = std::make_shared<Session>(id, std::move(name), std::move(world), limits_);
  worlds_.emplace(id, session);
  return session;
}

Result<std::shared_ptr<Session>> Registry::find(uint64_t id, const char* field) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = worlds_.find(id);
  if (it == worlds_.end()) {
    return not_found(std::string(field) + ": no world " + std::to_string(id));
  }
  return it->second;
}

Status Registry::remove(uint64_t id) {
  std::shared_ptr<Session> session;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = worlds_.find(id);
    if (it == worlds_.end()) return not_found("world_id: no world " + std::to_string(id));
    session = std::move(it->second);
    worlds_.erase(it);
  }
  session->retire();
  if (pool_ != nullptr) pool_->stop(session.get());
  session->close_recording();
  log_event("world_deleted", {{"world", id}});
  ++counters().worlds_deleted;
  session->close_streams(not_found("world " + std::to_string(id) + " was deleted"), false);
  return {};
}

std::vector<std::shared_ptr<Session>> Registry::list() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::shared_ptr<Session>> out;
  out.reserve(worlds_.size());
  for (const auto& [id, s] : worlds_) out.push_back(s);
  return out;
}

void Registry::close_all_streams(const Status& status) {
  for (auto& s : list()) s->close_streams(status, true);
}

void Registry::close_all_recordings() {
  for (auto& s : list()) s->close_recording();
}

}  // namespace fulcrum::server
