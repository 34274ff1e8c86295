#include "frames.h"

#include <cstring>

#include "quantize.h"

namespace fulcrum::server {

namespace {

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// Bit-for-bit equality: a body whose state did not change at all is not re-sent.
bool same_motion(const BodyMotion& a, const BodyMotion& b) {
  return a.id == b.id && a.awake == b.awake && same_bits(a.position.x(), b.position.x()) &&
         same_bits(a.position.y(), b.position.y()) && same_bits(a.angle, b.angle) &&
         same_bits(a.linear_velocity.x(), b.linear_velocity.x()) &&
         same_bits(a.linear_velocity.y(), b.linear_velocity.y()) &&
         same_bits(a.angular_velocity, b.angular_velocity);
}

// Whether the reader's copy of a body must be replaced: any bit changed, or, for quantized
// frames, any quantized value (a body outside the quantized ranges compares bit for bit).
bool changed(const BodyMotion& a, const BodyMotion& b, bool quantized) {
  if (!quantized) return !same_motion(a, b);
  QuantizedMotion qa, qb;
  const bool fa = quantize(a, &qa);
  const bool fb = quantize(b, &qb);
  if (fa && fb) return a.id != b.id || !(qa == qb);
  if (!fa && !fb) return !same_motion(a, b);
  return true;
}

void add_body(const BodyMotion& m, bool quantized, v1::Frame* out) {
  QuantizedMotion q;
  if (quantized && quantize(m, &q)) {
    quantized_to_proto(m, q, out->add_quantized_bodies());
  } else {
    motion_to_proto(m, out->add_bodies());
  }
}

}  // namespace

BodyMotion motion_of(BodyId id, const BodyState& state) {
  BodyMotion m;
  m.id = id;
  m.position = state.transform.p;
  m.angle = state.transform.q.angle();
  m.linear_velocity = state.linear_velocity;
  m.angular_velocity = state.angular_velocity;
  m.awake = state.awake;
  return m;
}

void motion_to_proto(const BodyMotion& m, v1::BodyFrame* out) {
  out->mutable_body()->set_index(m.id.index);
  out->mutable_body()->set_generation(m.id.generation);
  out->mutable_position()->set_x(m.position.x());
  out->mutable_position()->set_y(m.position.y());
  out->set_angle(m.angle);
  out->mutable_linear_velocity()->set_x(m.linear_velocity.x());
  out->mutable_linear_velocity()->set_y(m.linear_velocity.y());
  out->set_angular_velocity(m.angular_velocity);
  out->set_awake(m.awake);
}

std::shared_ptr<const PublishedFrame> capture_frame(const World& world, uint64_t world_id,
                                                    uint64_t epoch, uint64_t seq) {
  auto frame = std::make_shared<PublishedFrame>();
  frame->seq = seq;
  frame->world_id = world_id;
  frame->tick = world.tick();
  frame->state_hash = world.state_hash();
  frame->budgets = world.budgets();
  frame->epoch = epoch;
  const std::vector<BodyId> ids = world.bodies();
  frame->bodies.reserve(ids.size());
  for (BodyId id : ids) {
    Result<BodyState> s = world.body_state(id);
    if (!s.ok()) continue;  // cannot happen for a live id; skip rather than abort
    const BodyMotion m = motion_of(id, *s);
    if (m.awake) ++frame->awake_body_count;
    frame->bodies.push_back(m);
  }
  return frame;
}

void frame_to_proto(const PublishedFrame& next, const PublishedFrame* previous,
                    v1::FrameBodies mode, uint64_t skipped_frames, uint32_t every_ticks,
                    v1::Frame* out, bool quantized) {
  out->Clear();
  out->set_world_id(next.world_id);
  out->set_tick(next.tick);
  out->set_state_hash(next.state_hash);
  out->set_skipped_frames(skipped_frames);
  out->set_skipped_ticks(static_cast<int64_t>(skipped_frames) * every_ticks);
  out->set_body_count(static_cast<int32_t>(next.bodies.size()));
  out->set_awake_body_count(next.awake_body_count);
  out->set_budget_islands(next.budgets.islands);
  out->set_max_substeps(next.budgets.max_substeps);
  out->set_max_relax_iterations(next.budgets.max_relax_iterations);
  const bool restored = previous != nullptr && previous->epoch != next.epoch;
  out->set_restored(restored);
  if (mode == v1::FRAME_BODIES_NONE) return;

  if (mode == v1::FRAME_BODIES_ALL || previous == nullptr || restored) {
    out->set_full(true);
    for (const BodyMotion& m : next.bodies) add_body(m, quantized, out);
    return;
  }
  // Both lists are in index order: one merge finds changed, new and destroyed bodies.
  const std::vector<BodyMotion>& a = previous->bodies;
  const std::vector<BodyMotion>& b = next.bodies;
  size_t i = 0, j = 0;
  while (i < a.size() || j < b.size()) {
    if (j == b.size() || (i < a.size() && a[i].id.index < b[j].id.index)) {
      v1::Handle* h = out->add_destroyed();
      h->set_index(a[i].id.index);
      h->set_generation(a[i].id.generation);
      ++i;
    } else if (i == a.size() || b[j].id.index < a[i].id.index) {
      add_body(b[j++], quantized, out);
    } else {
      if (a[i].id.generation != b[j].id.generation) {
        v1::Handle* h = out->add_destroyed();  // the slot was reused by a new body
        h->set_index(a[i].id.index);
        h->set_generation(a[i].id.generation);
      }
      if (changed(a[i], b[j], quantized)) add_body(b[j], quantized, out);
      ++i;
      ++j;
    }
  }
}

std::shared_ptr<const std::string> encode_shared(const PublishedFrame& next,
                                                 const PublishedFrame* previous,
                                                 v1::FrameBodies mode, bool quantized,
                                                 bool* built) {
  // The same cases as frame_to_proto, reduced to what the bytes depend on.
  const bool restored = previous != nullptr && previous->epoch != next.epoch;
  FrameMemo::Entry key;
  key.kind = mode == v1::FRAME_BODIES_NONE                                     ? 2
             : mode == v1::FRAME_BODIES_ALL || previous == nullptr || restored ? 0
                                                                               : 1;
  key.base_seq = key.kind == 1 ? previous->seq : 0;
  key.quantized = quantized && key.kind != 2;
  key.restored = restored;
  // A frame without a sequence number (or a base without one) is never shared.
  const bool memoize =
      next.memo != nullptr && next.seq != 0 && (key.kind != 1 || key.base_seq != 0);
  auto same = [&](const FrameMemo::Entry& e) {
    return e.kind == key.kind && e.base_seq == key.base_seq && e.quantized == key.quantized &&
           e.restored == key.restored;
  };
  if (memoize) {
    std::lock_guard<std::mutex> lock(next.memo->mu);
    for (const FrameMemo::Entry& e : next.memo->entries) {
      if (same(e)) {
        if (built != nullptr) *built = false;
        return e.bytes;
      }
    }
  }
  // Encoded outside the lock; two readers racing on the same new entry both encode it, and the
  // first one stored is kept (same bytes).
  v1::Frame frame;
  frame_to_proto(next, previous, mode, 0, 1, &frame, quantized);
  auto bytes = std::make_shared<std::string>();
  frame.SerializeToString(bytes.get());
  if (built != nullptr) *built = true;
  if (!memoize) return bytes;
  std::lock_guard<std::mutex> lock(next.memo->mu);
  for (const FrameMemo::Entry& e : next.memo->entries) {
    if (same(e)) return e.bytes;
  }
  key.bytes = bytes;
  next.memo->entries.push_back(key);
  return bytes;
}

std::string encode_reader_part(uint64_t skipped_frames, uint32_t every_ticks) {
  v1::Frame part;
  part.set_skipped_frames(skipped_frames);
  part.set_skipped_ticks(static_cast<int64_t>(skipped_frames) * every_ticks);
  return part.SerializeAsString();
}

}  // namespace fulcrum::server
