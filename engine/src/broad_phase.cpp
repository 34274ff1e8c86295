// Broad phase: shapes' fattened boxes in two dynamic trees, one for static bodies' shapes and
// one for the others. Shapes whose boxes moved are buffered; once per step each buffered box is
// queried against the moving tree, and a moving shape's against the static tree too (two static
// shapes never collide), and new pairs become contacts. Pairs are sorted before creation, so
// contact ids never depend on either tree's shape.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

// How far past a shape (and its next tick's travel) its broad-phase box reaches: the
// speculative distance, so that two shapes near enough for contact points always have
// overlapping boxes, plus a margin that lets the shape move a little before its box must. The
// margin is an eighth of the shape's half-diagonal, at most settings.aabb_margin: a margin as
// large as a small shape pairs it with neighbours far beyond contact reach, and each pair is a
// contact the narrow phase visits every tick. Static shapes move only by edits: no margin.
//
// A shape travelling more than half its margin a tick (along x or y, `travel` = dt v) gets none
// either. Its box is swept by the travel, and the next tick's sweep reaches a travel further:
// the margin would keep it in its box for a tick or two at most, while every tick it widens the
// box and brings pairs beyond contact reach. In a tumbling pile nearly every box moves each
// tick whatever its margin (the tumbler's 1,923 of 2,029 at the margin by size alone).
double WorldImpl::box_reach(int si, BodyType body_type, const Vec2& travel) const {
  const double speculative = settings.speculative_distance;
  if (body_type == BodyType::kStatic) return speculative;
  constexpr double kMarginPerHalfDiagonal = 0.125;
  const double half_diagonal = shape_outlines[si].half_diagonal;
  const double margin = std::min(settings.aabb_margin, kMarginPerHalfDiagonal * half_diagonal);
  const double t = std::max(std::abs(travel.x()), std::abs(travel.y()));
  return speculative + (t > 0.5 * margin ? 0.0 : margin);
}

void WorldImpl::derive_shape(int si) {
  if (shape_thickness.size() < shapes.size()) shape_thickness.resize(shapes.size(), 0.0);
  if (shape_outlines.size() < shapes.size()) shape_outlines.resize(shapes.size());
  const Geometry& g = shapes[si].geometry;
  shape_thickness[si] = geometry_thickness(g);
  ShapeOutline& o = shape_outlines[si];
  o = ShapeOutline{};
  o.type = geometry_type(g);
  if (const auto* c = std::get_if<Circle>(&g)) {
    o.radius = c->radius;
    o.points[0] = c->center;
    o.count = 1;
  } else if (const auto* k = std::get_if<Capsule>(&g)) {
    o.radius = k->radius;
    o.points = {k->center1, k->center2};
    o.count = 2;
  } else if (const auto* e = std::get_if<Segment>(&g)) {
    o.points = {e->point1, e->point2};
    o.count = 2;
  } else if (const auto* p = std::get_if<Polygon>(&g)) {
    o.radius = p->radius;
    if (p->count >= 1 && p->count <= static_cast<int>(o.points.size())) {
      std::copy_n(p->vertices.begin(), p->count, o.points.begin());
      o.count = p->count;
    }
  }
  const AABB local = compute_aabb(g, Transform{});
  o.half_diagonal = 0.5 * length(local.upper - local.lower);
}

AABB WorldImpl::shape_box(int si, const Transform& xf) const {
  const ShapeOutline& o = shape_outlines[si];
  if (o.count == 0) return compute_aabb(shapes[si].geometry, xf);
  if (o.type == ShapeType::kSegment) {
    const Vec2 a = xf.apply(o.points[0]);
    const Vec2 b = xf.apply(o.points[1]);
    return AABB{a.cwiseMin(b), a.cwiseMax(b)};
  }
  return box_around(o.points.data(), o.count, o.radius, xf);
}

void WorldImpl::create_proxy(int si) {
  Shape& s = shapes[si];
  const Body& b = bodies[s.body];
  const AABB box = shape_box(si, b.xf);
  AABB fat = box.fattened(box_reach(si, b.type, settings.dt * b.v));
  s.proxy = tree_of(s).create_proxy(fat, static_cast<uint64_t>(si), s.filter.category_bits,
                                    s.filter.mask_bits);
  if (fat_boxes.size() < shapes.size()) fat_boxes.resize(shapes.size());
  fat_boxes[si] = fat;
  if (awake_boxes.size() < shapes.size()) awake_boxes.resize(shapes.size());
  place_box(si, box);
  if (!s.in_move_buffer) {
    s.in_move_buffer = true;
    move_buffer.push_back(si);
  }
}

void WorldImpl::destroy_proxy(int si) {
  Shape& s = shapes[si];
  if (s.in_move_buffer) {
    move_buffer.erase(std::find(move_buffer.begin(), move_buffer.end(), si));
    s.in_move_buffer = false;
  }
  if (s.proxy != kNullIndex) tree_of(s).destroy_proxy(s.proxy);
  s.proxy = kNullIndex;
}

// The new fat box of each of a body's shapes whose box, swept by the next tick's travel and
// widened by the speculative distance, left its old one; or nothing. A shape that stays inside
// its fat box costs one box computation and no tree work. Sweeping lets fast bodies meet what
// lies ahead of them before they get there. Writes only the body's own shapes' placed boxes:
// safe on several threads at once for different bodies.
template <class F>
void WorldImpl::find_moves(int bi, F&& moved) {
  const Body& b = bodies[bi];
  Vec2 travel = settings.dt * b.v;
  for (int si : b.shapes) {
    // The box now and where it will be after a tick at this velocity.
    AABB swept = shape_box(si, b.xf);
    place_box(si, swept);
    swept.lower += travel.cwiseMin(Vec2::Zero());
    swept.upper += travel.cwiseMax(Vec2::Zero());
    if (fat_boxes[si].contains(swept.fattened(settings.speculative_distance))) continue;
    moved(si, swept.fattened(box_reach(si, b.type, travel)));
  }
}

void WorldImpl::buffer_move(int si) {
  Shape& s = shapes[si];
  if (!s.in_move_buffer) {
    s.in_move_buffer = true;
    move_buffer.push_back(si);
  }
}

void WorldImpl::synchronize_shapes(int bi) {
  find_moves(bi, [&](int si, const AABB& fat) {
    tree_of(shapes[si]).move_proxy(shapes[si].proxy, fat);
    fat_boxes[si] = fat;
    buffer_move(si);
  });
}

void WorldImpl::synchronize_awake(const std::vector<int>& awake) {
  // The boxes are found in chunks of bodies (on the world's threads when there are many), each
  // chunk keeping its own list; the lists are then taken in chunk order, so the moves are
  // the same, in the same order, at any thread count.
  constexpr size_t kBodiesPerChunk = 256;
  const int chunks = static_cast<int>((awake.size() + kBodiesPerChunk - 1) / kBodiesPerChunk);
  if (static_cast<int>(scratch_moves.size()) < chunks) scratch_moves.resize(chunks);
  auto chunk = [&](int i) {
    std::vector<std::pair<int, AABB>>& out = scratch_moves[i];
    out.clear();
    const size_t lo = static_cast<size_t>(i) * kBodiesPerChunk;
    const size_t hi = std::min(lo + kBodiesPerChunk, awake.size());
    for (size_t k = lo; k < hi; ++k) {
      // The records are cold in a large world (the tick before walked them all): each is
      // fetched a few bodies ahead, the lines find_moves reads (transform, velocity, shapes).
      if (k + kFetchAhead < hi) {
        const Body& far = bodies[awake[k + kFetchAhead]];
        __builtin_prefetch(&far.xf);
        __builtin_prefetch(&far.v);
        __builtin_prefetch(&far.shapes);
      }
      find_moves(awake[k], [&](int si, const AABB& fat) { out.emplace_back(si, fat); });
    }
  };
  run_chunks(chunks >= 2 ? pool : nullptr, chunks, chunk, true);
  pending_moves.clear();
  for (int i = 0; i < chunks; ++i) {
    for (const auto& [si, fat] : scratch_moves[i]) {
      pending_moves.emplace_back(shapes[si].proxy, fat);
      fat_boxes[si] = fat;
      buffer_move(si);
    }
  }
  commit_moves();
}

// When many leaves moved (a pile in motion), setting their boxes and rebuilding the tree once
// costs less than re-inserting each. The tree's shape never reaches the results: pairs and
// query hits are sorted. Only awake bodies move here, and static bodies are never awake: the
// moves are all in the moving tree.
//
// Rebuilding costs O(n log n); refitting the boxes in place, O(n), but the tree grows worse for
// queries as leaves drift from the neighbours they were built with. So the boxes are refitted,
// and the tree rebuilt only once its cost (DynamicTree::cost) has grown by a quarter since the
// last rebuild.
void WorldImpl::commit_moves() {
  const size_t threshold = std::max<size_t>(64, static_cast<size_t>(tree.proxy_count()) / 16);
  if (pending_moves.size() >= threshold) {
    for (const auto& [proxy, box] : pending_moves) tree.set_leaf_box(proxy, box);
    constexpr double kRefitSlack = 1.25;
    if (!(tree.refit_all(pool) <= kRefitSlack * tree_built_cost)) {
      tree.rebuild(pool);
      tree_built_cost = tree.cost();
    }
  } else {
    for (const auto& [proxy, box] : pending_moves) tree.move_proxy(proxy, box);
  }
  pending_moves.clear();
}

bool WorldImpl::should_collide(int sa, int sb) const {
  const Shape& a = shapes[sa];
  const Shape& b = shapes[sb];
  if (a.body == b.body) return false;
  // The filter before the bodies and the joints: it reads only the shapes' first lines, and in
  // scenes of many jointed, filtered shapes (the joint grid, a ragdoll's parts) it is the test
  // that fails.
  const bool filter_passes =
      a.filter.group_index != 0 && a.filter.group_index == b.filter.group_index
          ? a.filter.group_index > 0
          : (a.filter.category_bits & b.filter.mask_bits) != 0 &&
                (b.filter.category_bits & a.filter.mask_bits) != 0;
  if (!filter_passes) return false;
  const Body& ba = bodies[a.body];
  const Body& bb = bodies[b.body];
  if (!ba.is_dynamic() && !bb.is_dynamic()) return false;
  return ba.joints.empty() || bb.joints.empty() || !joint_blocks_contact(a.body, b.body);
}

namespace {

// Candidate pairs as a walk finds them. Most already have their contact (a contact lives as long
// as its shapes' boxes overlap), so the pair set is asked first, before either shape is read.
// Its lookups are likely cache misses: each candidate's slot is fetched as it is found, and the
// candidates are looked at in batches, in the order found, so that the misses overlap. A pair
// that has no contact, is not skipped (`skip`) and may collide is kept; `found` counts the kept
// pairs across threads, and once it passes `room` nothing more is kept.
template <typename Skip>
class PairBatch {
 public:
  PairBatch(const WorldImpl& w, int64_t room, std::atomic<int64_t>& found,
            std::vector<std::pair<int, int>>* out, Skip skip)
      : w_(w),
        room_(room),
        found_(found),
        out_(out),
        skip_(skip),
        more_(found.load(std::memory_order_relaxed) <= room) {}
  // Returns false once the room is passed: the walk may stop.
  bool add(int sa, int sb) {
    w_.contact_pairs.prefetch(pair_key(sa, sb));
    batch_[batched_++] = {sa, sb};
    return batched_ < kBatch || flush();
  }
  bool flush() {
    for (int k = 0; k < batched_ && more_; ++k) {
      const auto [sa, sb] = batch_[k];
      if (w_.contact_pairs.contains(pair_key(sa, sb))) continue;
      if (skip_(sa, sb) || !w_.should_collide(sa, sb)) continue;
      out_->emplace_back(std::min(sa, sb), std::max(sa, sb));
      more_ = found_.fetch_add(1, std::memory_order_relaxed) < room_;
    }
    batched_ = 0;
    return more_;
  }
  bool more() const { return more_; }

 private:
  static constexpr int kBatch = 32;
  const WorldImpl& w_;
  const int64_t room_;
  std::atomic<int64_t>& found_;
  std::vector<std::pair<int, int>>* out_;
  Skip skip_;
  bool more_;
  std::pair<int, int> batch_[kBatch];
  int batched_ = 0;
};

}  // namespace

// When at least half the moving tree's leaves moved (a pile flying apart, a rain of bodies), the
// new pairs are found by walking each tree with the moving tree (DynamicTree::join) instead of
// querying it once per moved shape: each overlapping pair of leaves is met once, and kept when
// either leaf moved. The pairs are those the queries find: a pair enters neither way unless its
// boxes overlap and its filter bits pass both ways. A moved shape of a positive group meets its
// group whatever the bits, which the walk cannot see: then the queries are used. Returns false,
// having done nothing, when the queries are to be used; else fills scratch_pairs (or stops once
// `found` passes `room`, as the queries do).
bool WorldImpl::join_moves(int64_t room, std::atomic<int64_t>& found) {
  const size_t moved = move_buffer.size();
  if (2 * moved < static_cast<size_t>(tree.proxy_count()) || moved < 256) return false;
  for (int si : move_buffer) {
    if (shapes[si].filter.group_index > 0) return false;
  }
  // Which leaves moved, by proxy, in each tree, and which nodes have one below them: the walks
  // skip subtrees where nothing moved (a pile asleep beside a rain of bodies).
  std::vector<uint8_t>& moved_leaf = scratch_moved_leaf;
  std::vector<uint8_t>& moved_static_leaf = scratch_moved_static_leaf;
  moved_leaf.assign(tree.node_capacity(), 0);
  moved_static_leaf.assign(static_tree.node_capacity(), 0);
  for (int si : move_buffer) {
    const Shape& s = shapes[si];
    if (&tree_of(s) == &tree) {
      tree.mark_with_ancestors(s.proxy, moved_leaf.data());
    } else {
      static_tree.mark_with_ancestors(s.proxy, moved_static_leaf.data());
    }
  }
  // The moving tree with itself, then with the static tree; each task keeps its own list.
  constexpr int kTasks = 16;
  const std::vector<DynamicTree::JoinTask> self = tree.join_tasks(tree, pool ? kTasks : 1);
  const std::vector<DynamicTree::JoinTask> cross = tree.join_tasks(static_tree, pool ? kTasks : 1);
  const int tasks = static_cast<int>(self.size() + cross.size());
  if (static_cast<int>(scratch_chunk_pairs.size()) < tasks) scratch_chunk_pairs.resize(tasks);
  auto task = [&](int i) {
    std::vector<std::pair<int, int>>& out = scratch_chunk_pairs[i];
    out.clear();
    const bool is_self = i < static_cast<int>(self.size());
    const DynamicTree& other = is_self ? tree : static_tree;
    const std::vector<uint8_t>& other_moved = is_self ? moved_leaf : moved_static_leaf;
    // The walk meets each pair once: none is skipped.
    PairBatch batch(*this, room, found, &out, [](int, int) { return false; });
    const DynamicTree::JoinTask t = is_self ? self[i] : cross[i - self.size()];
    tree.join(other, t, moved_leaf.data(), other_moved.data(), [&](int a, int b) {
      return batch.add(static_cast<int>(tree.user_data(a)), static_cast<int>(other.user_data(b)));
    });
    batch.flush();
  };
  run_chunks(pool, tasks, task, true);
  if (found.load() <= room) {
    for (int i = 0; i < tasks; ++i) {
      scratch_pairs.insert(scratch_pairs.end(), scratch_chunk_pairs[i].begin(),
                           scratch_chunk_pairs[i].end());
    }
  }
  return true;
}

int64_t WorldImpl::update_pairs() {
  if (move_buffer.empty()) return 0;
  // Collect the new pairs that may collide (lower shape index first), sorted so that contacts
  // are created in an order that does not depend on the tree's shape. A pair of two moved
  // shapes is taken from one side only. Filtered pairs and pairs that already have a contact
  // are dropped as they are found: neither test depends on anything this loop changes, so the
  // sorted list is the one filtering after the sort would leave, and a scene of many
  // overlapping shapes does not sort pairs it will never use.
  // The queries only read (the tree, the shapes, their bodies and joints, the contact pairs),
  // so they run in chunks of moved shapes, on the world's threads when there are many; each
  // chunk keeps its own pairs, and the sort below makes the chunking invisible.
  // With a contact limit, `found` counts new pairs across the chunks and the queries stop once
  // it passes what the limit leaves: the step is then refused whatever the other chunks would
  // have found, so stopping early cannot change the outcome, and memory stays bounded.
  const int64_t live = static_cast<int64_t>(contacts.size() - free_contacts.size());
  const int64_t room = contact_limit > 0 ? std::max<int64_t>(contact_limit - live, 0)
                                         : std::numeric_limits<int64_t>::max();
  std::atomic<int64_t> found{0};
  std::vector<std::pair<int, int>>& pairs = scratch_pairs;
  pairs.clear();
  auto query_shape = [&](int si, std::vector<std::pair<int, int>>* out) {
    const Shape& s = shapes[si];
    const AABB& box = fat_boxes[si];
    // Outside a positive group (whose members meet whatever their bits), only shapes whose
    // bits pass both ways can collide with this one: the tree skips subtrees of others.
    const bool grouped = s.filter.group_index > 0;
    const uint64_t category = grouped ? ~0ull : s.filter.category_bits;
    const uint64_t mask = grouped ? ~0ull : s.filter.mask_bits;
    // A pair of two moved shapes is found from the lower index's side.
    PairBatch batch(*this, room, found, out,
                    [&](int, int other) { return shapes[other].in_move_buffer && other < si; });
    auto walk = [&](const DynamicTree& t) {
      t.query_filtered(box, category, mask, [&](int proxy) {
        const int other = static_cast<int>(t.user_data(proxy));
        return other == si || batch.add(si, other);
      });
      batch.flush();
    };
    walk(tree);
    if (batch.more() && bodies[s.body].type != BodyType::kStatic) walk(static_tree);
  };
  constexpr size_t kShapesPerChunk = 64;
  const size_t moved = move_buffer.size();
  if (join_moves(room, found)) {
    // Found by walking the trees together (join_moves), in pairs of moved shapes' lists.
  } else if (pool != nullptr && moved >= 4 * kShapesPerChunk) {
    const int chunks = static_cast<int>((moved + kShapesPerChunk - 1) / kShapesPerChunk);
    scratch_chunk_pairs.resize(chunks);
    auto chunk = [&](int i) {
      std::vector<std::pair<int, int>>& out = scratch_chunk_pairs[i];
      out.clear();
      const size_t lo = static_cast<size_t>(i) * kShapesPerChunk;
      const size_t hi = std::min(lo + kShapesPerChunk, moved);
      for (size_t k = lo; k < hi && found.load(std::memory_order_relaxed) <= room; ++k) {
        query_shape(move_buffer[k], &out);
      }
    };
    run_chunks(pool, chunks, chunk, true);
    if (found.load() <= room) {
      for (int i = 0; i < chunks; ++i) {
        pairs.insert(pairs.end(), scratch_chunk_pairs[i].begin(), scratch_chunk_pairs[i].end());
      }
    }
  } else {
    for (size_t k = 0; k < moved && found.load(std::memory_order_relaxed) <= room; ++k) {
      query_shape(move_buffer[k], &pairs);
    }
  }
  if (found.load() > room) {
    pairs.clear();
    for (auto& chunk_pairs : scratch_chunk_pairs) chunk_pairs.clear();
    return live + found.load();
  }
  for (int si : move_buffer) shapes[si].in_move_buffer = false;
  move_buffer.clear();

  std::sort(pairs.begin(), pairs.end());  // each pair was found once: no duplicates to remove
  for (const auto& [sa, sb] : pairs) create_contact(sa, sb);
  return 0;
}

}  // namespace fulcrum
