// The replay side of `fulcrum view` (view.h, ReplayPlayer): a replay file re-stepped locally,
// checked tick by tick against the hashes it holds, and seekable.
#include <algorithm>

#include "describe_convert.h"
#include "edit_convert.h"
#include "snapshot_convert.h"
#include "view.h"

namespace fulcrum::cli {

Result<std::unique_ptr<ReplayPlayer>> ReplayPlayer::open(const std::string& path) {
  Result<ReplayContents> contents = read_replay(path);
  if (!contents.ok()) return contents.status();
  std::unique_ptr<ReplayPlayer> p(new ReplayPlayer());
  p->path_ = path;
  p->replay_ = std::move(contents).value();
  Result<v1::Snapshot> initial = unwrap_snapshot(p->replay_.header.initial());
  if (!initial.ok()) return initial.status().with_prefix(path + ": initial snapshot: ");
  Result<WorldSnapshot> records = snapshot_from_proto(*initial);
  if (!records.ok()) return records.status().with_prefix(path + ": initial snapshot: ");
  FULCRUM_RETURN_IF_ERROR(p->world_.restore(*records));
  p->start_tick_ = p->world_.tick();
  p->end_tick_ = p->start_tick_;
  p->restepped_hashes_.push_back(p->world_.state_hash());
  p->checkpoints_.push_back(p->world_.snapshot());
  for (size_t i = 0; i < p->replay_.ticks.size(); ++i) {
    const v1::ReplayTick& t = p->replay_.ticks[i];
    if (t.tick() != p->world_.tick() + 1) {
      return data_loss(path + ": tick records out of order: expected tick " +
                       std::to_string(p->world_.tick() + 1) + ", found " +
                       std::to_string(t.tick()));
    }
    for (int b = 0; b < t.edits_size(); ++b) {
      Result<EditOutcome> applied = apply_edit_batch(&p->world_, t.edits(b));
      if (!applied.ok() && p->first_divergent_tick_ < 0) {
        p->first_divergent_tick_ = t.tick();
        p->detail_ = "edit batch " + std::to_string(b) + " before tick " +
                     std::to_string(t.tick()) +
                     " was refused on replay: " + applied.status().message();
      }
    }
    p->world_.step();
    const uint64_t hash = p->world_.state_hash();
    p->restepped_hashes_.push_back(hash);
    if (hash != t.state_hash() && p->first_divergent_tick_ < 0) {
      p->first_divergent_tick_ = t.tick();
      p->detail_ = "tick " + std::to_string(t.tick()) + ": state hash " + World::hash_text(hash) +
                   " re-stepped, " + World::hash_text(t.state_hash()) + " in the file";
    }
    p->end_tick_ = p->world_.tick();
    if ((p->end_tick_ - p->start_tick_) % kCheckpointTicks == 0) {
      p->checkpoints_.push_back(p->world_.snapshot());
    }
  }
  return p;
}

std::string ReplayPlayer::info_json() const {
  std::string out =
      "{\"path\":" + json_string(path_) + ",\"scene\":" + json_string(replay_.header.scene()) +
      ",\"startTick\":" + std::to_string(start_tick_) +
      ",\"endTick\":" + std::to_string(end_tick_) + ",\"dt\":" + json_number(world_.settings().dt) +
      ",\"ok\":" + (first_divergent_tick_ < 0 ? "true" : "false") + ",\"firstDivergentTick\":" +
      (first_divergent_tick_ < 0 ? "null" : std::to_string(first_divergent_tick_)) +
      ",\"detail\":" + json_string(detail_) + "}";
  return out;
}

void ReplayPlayer::step_once() {
  const int64_t next = world_.tick() + 1;
  const v1::ReplayTick& t = replay_.ticks[static_cast<size_t>(next - start_tick_ - 1)];
  // Refused batches were found when the file was opened; re-stepping refuses them the same way.
  for (const v1::EditBatch& batch : t.edits()) (void)apply_edit_batch(&world_, batch);
  world_.step();
}

void ReplayPlayer::seek(int64_t tick) {
  const int64_t now = world_.tick();
  const int64_t k = (tick - start_tick_) / kCheckpointTicks;
  const int64_t checkpoint_tick = start_tick_ + k * kCheckpointTicks;
  // Step on from where the world is when that is no further than from the checkpoint.
  if (tick < now || checkpoint_tick > now) {
    Status restored = world_.restore(checkpoints_[static_cast<size_t>(k)]);
    (void)restored;  // a snapshot this process took restores
  }
  while (world_.tick() < tick) step_once();
}

std::string ReplayPlayer::frame_json_at(int64_t tick) {
  std::lock_guard<std::mutex> lock(mu_);
  seek(std::clamp(tick, start_tick_, end_tick_));
  FrameJson f;
  f.tick = world_.tick();
  f.hash = world_.state_hash();
  f.full = true;
  for (BodyId id : world_.bodies()) {
    Result<BodyState> s = world_.body_state(id);
    if (!s.ok()) continue;
    client::BodyFrame b;
    b.id = id;
    b.position = s->transform.p;
    b.angle = s->transform.q.angle();
    b.awake = s->awake;
    if (b.awake) ++f.awake_count;
    f.bodies.push_back(b);
  }
  f.body_count = static_cast<int>(f.bodies.size());
  const bool at_start = f.tick == start_tick_;
  const uint64_t recorded =
      at_start ? f.hash : replay_.ticks[static_cast<size_t>(f.tick - start_tick_ - 1)].state_hash();
  f.extra = ",\"recordedHash\":\"" + (at_start ? std::string() : World::hash_text(recorded)) +
            "\",\"diverged\":" + (recorded != f.hash ? "true" : "false");
  return frame_json(f);
}

std::string ReplayPlayer::describe_json() {
  std::lock_guard<std::mutex> lock(mu_);
  v1::DescribeWorldReply reply;
  describe_world_to_proto(world_, &reply);
  return description_json(reply);
}

}  // namespace fulcrum::cli
