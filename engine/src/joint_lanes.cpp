// Colouring and packing of the revolute joints' lanes, and their passes on the chosen path.
#include "joint_lanes.h"

#include <algorithm>

#include "fulcrum/simd.h"
#include "fulcrum/state.h"
#include "joint_solver.h"
#include "union_find.h"
#include "worker_pool.h"

namespace fulcrum {

namespace {

// A body the point rows change: the static body (slot 0), kinematic bodies and bodies of
// infinite mass and inertia are only read.
bool movable(const LargeVector<SolverBody>& bodies, const std::vector<SolverBodyExtra>& extras,
             int slot) {
  return bodies[slot].inv_mass > 0.0 || extras[slot].inv_inertia > 0.0;
}

PointKey point_key(int joint, const SolverScratch::RowSlots& r,
                   const LargeVector<SolverBody>& bodies,
                   const std::vector<SolverBodyExtra>& extras) {
  PointKey key;
  key.joint = joint;
  key.ia = r.ia;
  key.ib = r.ib;
  key.kind = (r.plain_point ? kPlainKey : 0) | (r.revolute ? kRevoluteKey : 0) |
             (movable(bodies, extras, r.ia) ? kMovableAKey : 0) |
             (movable(bodies, extras, r.ib) ? kMovableBKey : 0);
  return key;
}

void clear_lane(PointBlock* b, int l) {
  b->ia[l] = b->ib[l] = 0;
  b->write_a[l] = b->write_b[l] = 0;
  b->inv_inertia_a[l] = b->inv_inertia_b[l] = 0.0;
  b->rax[l] = b->ray[l] = b->rbx[l] = b->rby[l] = 0.0;
  b->dcx[l] = b->dcy[l] = 0.0;
  b->ix[l] = b->iy[l] = 0.0;
}

// Row r's lane, `key` its key (point_key).
void write_lane(const JointRow& r, const PointKey& key, const std::vector<SolverBodyExtra>& extras,
                PointBlock* b, int l) {
  b->ia[l] = r.ia;
  b->ib[l] = r.ib;
  b->write_a[l] = (key.kind & kMovableAKey) != 0;
  b->write_b[l] = (key.kind & kMovableBKey) != 0;
  b->inv_inertia_a[l] = extras[r.ia].inv_inertia;
  b->inv_inertia_b[l] = extras[r.ib].inv_inertia;
  b->rax[l] = r.rax;
  b->ray[l] = r.ray;
  b->rbx[l] = r.rbx;
  b->rby[l] = r.rby;
  b->dcx[l] = r.dcx;
  b->dcy[l] = r.dcy;
  b->ix[l] = r.ix;
  b->iy[l] = r.iy;
}

void clear_revolute_lane(RevoluteBlock* b, int l) {
  clear_lane(b, l);
  for (double* field :
       {b->angle, b->axial_mass, b->spring_rate, b->spring_mass_scale, b->spring_impulse_scale,
        b->target_angle, b->motor_speed, b->max_motor_torque, b->lower_angle, b->upper_angle,
        b->spring_on, b->motor_on, b->limit_on, b->spring_impulse, b->motor_impulse,
        b->lower_impulse, b->upper_impulse}) {
    field[l] = 0.0;
  }
}

// Row r's lane: the point's fields, then its angle rows. A row is on only where the joint has it
// and one of its bodies turns.
void write_revolute_lane(const JointRow& r, const PointKey& key,
                         const std::vector<SolverBodyExtra>& extras, RevoluteBlock* b, int l) {
  write_lane(r, key, extras, b, l);
  const RevoluteRow& v = r.revolute;
  const bool turns = extras[r.ia].inv_inertia + extras[r.ib].inv_inertia > 0.0;
  b->angle[l] = r.angle;
  b->axial_mass[l] = r.axial_mass;
  b->spring_rate[l] = r.spring.bias_rate;
  b->spring_mass_scale[l] = r.spring.mass_scale;
  b->spring_impulse_scale[l] = r.spring.impulse_scale;
  b->target_angle[l] = v.target_angle;
  b->motor_speed[l] = v.motor_speed;
  b->max_motor_torque[l] = v.max_motor_torque;
  b->lower_angle[l] = v.lower_angle;
  b->upper_angle[l] = v.upper_angle;
  b->spring_on[l] = v.spring && turns ? 1.0 : 0.0;
  b->motor_on[l] = v.motor && turns ? 1.0 : 0.0;
  b->limit_on[l] = v.limit && turns ? 1.0 : 0.0;
  b->spring_impulse[l] = v.spring_impulse;
  b->motor_impulse[l] = v.motor_impulse;
  b->lower_impulse[l] = v.lower_impulse;
  b->upper_impulse[l] = v.upper_impulse;
}

struct PathFns {
  lanes::PointSolveFn solve;
  lanes::PointWarmFn warm;
  lanes::RevoluteSolveFn solve_revolutes;
  lanes::RevoluteWarmFn warm_revolutes;
};

PathFns path_fns() {
  switch (active_simd_path()) {
    case SimdPath::kAvx512:
      return {lanes::solve_points_x4e, lanes::warm_points_x4e, lanes::solve_revolutes_x4e,
              lanes::warm_revolutes_x4e};
    case SimdPath::kLanes4:
      return {lanes::solve_points_x4, lanes::warm_points_x4, lanes::solve_revolutes_x4,
              lanes::warm_revolutes_x4};
    case SimdPath::kLanes2:
      return {lanes::solve_points_x2, lanes::warm_points_x2, lanes::solve_revolutes_x2,
              lanes::warm_revolutes_x2};
    default:
      return {lanes::solve_points_scalar, lanes::warm_points_scalar, lanes::solve_revolutes_scalar,
              lanes::warm_revolutes_scalar};
  }
}

// Each colour's blocks in chunks of kBlocksPerChunk (shared among the pool's threads when there
// are two or more), then the overflow one lane at a time in row order. Lanes: ColouredPoints
// or ColouredRevolutes, for their blocks and colours.
template <class Lanes, class ColourFn, class OverflowFn>
void each_colour(Lanes& cp, WorkerPool* pool, ColourFn colour_fn, OverflowFn overflow_fn) {
  if (cp.colour_start.empty()) return;  // never laid out
  for (int c = 0; c < cp.colours; ++c) {
    const int first = cp.colour_start[c], end = cp.colour_start[c + 1];
    const int chunks = (end - first + kBlocksPerChunk - 1) / kBlocksPerChunk;
    if (pool == nullptr || chunks < 2) {
      colour_fn(first, end);
      continue;
    }
    auto chunk = [&](int i) {
      const int b = first + i * kBlocksPerChunk;
      colour_fn(b, std::min(b + kBlocksPerChunk, end));
    };
    pool->run(chunks, chunk);
  }
  const int end = static_cast<int>(cp.blocks.size());
  if (cp.colour_start[cp.colours] < end) overflow_fn(cp.colour_start[cp.colours], end);
}

// Fills grouped_rows and chunk_start from other_rows (see ColouredPoints).
void group_other_rows(const LargeVector<JointRow>& rows, size_t slots, ColouredPoints* out) {
  const std::vector<int>& other = out->other_rows;
  if (other.size() < 2 * static_cast<size_t>(kRowsPerJointChunk)) return;
  std::vector<int>& parent = out->slot_parent;
  std::vector<int>& group = out->slot_group;
  if (parent.size() < slots) {
    parent.resize(slots);
    group.resize(slots);
  }
  // Only the slots these rows name are read, so only they are reset.
  for (int k : other) parent[rows[k].ia] = rows[k].ia, parent[rows[k].ib] = rows[k].ib;
  for (int k : other) unite(parent, rows[k].ia, rows[k].ib);
  // Groups numbered in the order of their first rows; each row's group is kept in
  // grouped_rows for the counting sort below.
  for (int k : other) group[find_root(parent, rows[k].ia)] = -1;
  std::vector<int>& place = out->group_place;  // first each group's size, then its next place
  place.clear();
  std::vector<int>& row_group = out->grouped_rows;
  for (int k : other) {
    int& g = group[find_root(parent, rows[k].ia)];
    if (g < 0) {
      g = static_cast<int>(place.size());
      place.push_back(0);
    }
    ++place[g];
    row_group.push_back(g);
  }
  // Chunks of whole groups, at least kRowsPerJointChunk rows each.
  int at = 0;
  for (int& p : place) {
    if (out->chunk_start.empty() || at - out->chunk_start.back() >= kRowsPerJointChunk) {
      out->chunk_start.push_back(at);
    }
    const int n = p;
    p = at;
    at += n;
  }
  out->chunk_start.push_back(at);
  if (out->chunk_start.size() < 3) {  // one chunk: nothing to share
    out->grouped_rows.clear();
    out->chunk_start.clear();
    return;
  }
  std::vector<int>& sorted = out->group_sorted;
  sorted.resize(other.size());
  for (size_t i = 0; i < other.size(); ++i) sorted[place[row_group[i]]++] = other[i];
  out->grouped_rows.swap(sorted);
}

}  // namespace

void colour_points(const LargeVector<JointRow>& rows,
                   const std::vector<SolverScratch::RowSlots>& slots,
                   const LargeVector<SolverBody>& bodies,
                   const std::vector<SolverBodyExtra>& extras, WorkerPool* pool,
                   ColouredPoints* out) {
  const size_t n_rows = rows.size();
  std::vector<uint32_t>& use = out->body_use;
  use.assign(bodies.size(), 0);
  std::vector<uint32_t>& revolute_use = out->revolute_use;
  revolute_use.assign(bodies.size(), 0);
  std::vector<int>& lane_of_row = out->lane_of_row;
  lane_of_row.assign(n_rows, -1);
  out->other_rows.clear();
  out->keys.resize(n_rows);
  out->keyed_with_pool = pool != nullptr;
  ++out->layouts;
  // Each row's colour in lane_of_row first, then its lane.
  int count[kMaxColours + 1] = {};
  int revolute_count[kMaxColours + 1] = {};
  for (size_t k = 0; k < n_rows; ++k) {
    const SolverScratch::RowSlots& r = slots[k];
    const PointKey key = point_key(rows[k].joint, r, bodies, extras);
    out->keys[k] = key;
    if (!r.plain_point && !r.revolute) {
      out->other_rows.push_back(static_cast<int>(k));
      continue;
    }
    const int colour =
        take_colour(r.plain_point ? use : revolute_use, r.ia, (key.kind & kMovableAKey) != 0, r.ib,
                    (key.kind & kMovableBKey) != 0, false);
    lane_of_row[k] = colour;
    ++(r.plain_point ? count : revolute_count)[colour];
  }
  ColourLayout layout = lay_out_colours(count, &out->colour_start);
  out->colours = layout.colours;
  out->blocks.resize(layout.blocks);
  ColouredRevolutes& rv = out->revolutes;
  ColourLayout revolute_layout = lay_out_colours(revolute_count, &rv.colour_start);
  rv.colours = revolute_layout.colours;
  rv.blocks.resize(revolute_layout.blocks);
  out->points = 0;
  rv.joints = 0;
  for (size_t k = 0; k < n_rows; ++k) {
    if (lane_of_row[k] < 0) continue;
    if (slots[k].plain_point) {
      lane_of_row[k] = layout.next_lane[lane_of_row[k]]++;
      ++out->points;
    } else {
      lane_of_row[k] = revolute_layout.next_lane[lane_of_row[k]]++;
      ++rv.joints;
    }
  }
  out->lane_joint.assign(static_cast<size_t>(layout.blocks) * kBlockLanes, -1);
  rv.lane_joint.assign(static_cast<size_t>(revolute_layout.blocks) * kBlockLanes, -1);
  // Each row writes its own lane.
  const size_t per_chunk = 512;
  const int chunks = static_cast<int>((n_rows + per_chunk - 1) / per_chunk);
  auto pack = [&](int c) {
    for (size_t k = c * per_chunk; k < std::min((c + 1) * per_chunk, n_rows); ++k) {
      const int lane = lane_of_row[k];
      if (lane < 0) continue;
      if (slots[k].plain_point) {
        write_lane(rows[k], out->keys[k], extras, &out->blocks[lane / kBlockLanes],
                   lane % kBlockLanes);
        out->lane_joint[lane] = rows[k].joint;
      } else {
        write_revolute_lane(rows[k], out->keys[k], extras, &rv.blocks[lane / kBlockLanes],
                            lane % kBlockLanes);
        rv.lane_joint[lane] = rows[k].joint;
      }
    }
  };
  run_chunks(chunks > 1 ? pool : nullptr, chunks, pack, true);
  // Padding lanes: the static body on both sides, a singular K, no change.
  pad_colours(layout, &out->blocks, clear_lane);
  pad_colours(revolute_layout, &rv.blocks, clear_revolute_lane);
  out->grouped_rows.clear();
  out->chunk_start.clear();
  if (pool != nullptr) group_other_rows(rows, bodies.size(), out);
}

bool layout_fits(const ColouredPoints& cp, const std::vector<int>& row_joints, bool with_pool) {
  if (row_joints.empty() || cp.keys.size() != row_joints.size()) return false;
  if (cp.keyed_with_pool != with_pool) return false;
  for (size_t k = 0; k < row_joints.size(); ++k) {
    if (cp.keys[k].joint != row_joints[k]) return false;
  }
  return true;
}

bool place_point(ColouredPoints* cp, size_t k, const JointRow& r,
                 const LargeVector<SolverBody>& bodies,
                 const std::vector<SolverBodyExtra>& extras) {
  const bool revolute = r.type == JointType::kRevolute && !r.plain_point;
  const PointKey key = point_key(r.joint, {r.ia, r.ib, r.plain_point, revolute}, bodies, extras);
  if (!(key == cp->keys[k])) return false;
  const int lane = cp->lane_of_row[k];
  if (r.plain_point) {
    write_lane(r, key, extras, &cp->blocks[lane / kBlockLanes], lane % kBlockLanes);
  } else if (revolute) {
    write_revolute_lane(r, key, extras, &cp->revolutes.blocks[lane / kBlockLanes],
                        lane % kBlockLanes);
  }
  return true;
}

void unpack_points(const ColouredPoints& cp, LargeVector<Joint>* joints, WorkerPool* pool) {
  // Lane by lane, in block order: the blocks and lane_joint are read in memory order, and the
  // joint pool (it may be larger than the caches) is fetched 8 lanes ahead.
  constexpr int kAhead = 8;
  constexpr int kBlocksPerUnpack = 64;
  const int n_blocks = static_cast<int>(cp.blocks.size());
  const int chunks = (n_blocks + kBlocksPerUnpack - 1) / kBlocksPerUnpack;
  auto chunk = [&](int c) {
    const int lo = c * kBlocksPerUnpack * kBlockLanes;
    const int hi = std::min((c + 1) * kBlocksPerUnpack, n_blocks) * kBlockLanes;
    for (int lane = lo; lane < hi; ++lane) {
      if (lane + kAhead < hi && cp.lane_joint[lane + kAhead] >= 0) {
        __builtin_prefetch(&(*joints)[cp.lane_joint[lane + kAhead]].linear_impulse, 1);
      }
      const int ji = cp.lane_joint[lane];
      if (ji < 0) continue;
      const PointBlock& b = cp.blocks[lane / kBlockLanes];
      (*joints)[ji].linear_impulse = Vec2(b.ix[lane % kBlockLanes], b.iy[lane % kBlockLanes]);
    }
  };
  run_chunks(chunks > 1 ? pool : nullptr, chunks, chunk);
  const ColouredRevolutes& rv = cp.revolutes;
  for (size_t lane = 0; lane < rv.lane_joint.size(); ++lane) {
    const int ji = rv.lane_joint[lane];
    if (ji < 0) continue;
    const RevoluteBlock& b = rv.blocks[lane / kBlockLanes];
    const size_t l = lane % kBlockLanes;
    Joint& j = (*joints)[ji];
    j.linear_impulse = Vec2(b.ix[l], b.iy[l]);
    j.spring_impulse = b.spring_impulse[l];
    j.motor_impulse = b.motor_impulse[l];
    j.lower_impulse = b.lower_impulse[l];
    j.upper_impulse = b.upper_impulse[l];
  }
}

void warm_start_points(ColouredPoints& cp, SolverBody* bodies, WorkerPool* pool) {
  const PathFns fns = path_fns();
  PointBlock* blocks = cp.blocks.data();
  each_colour(
      cp, pool, [&](int first, int end) { fns.warm(blocks, first, end, bodies); },
      [&](int first, int end) { lanes::warm_points_scalar(blocks, first, end, bodies); });
  RevoluteBlock* revolutes = cp.revolutes.blocks.data();
  each_colour(
      cp.revolutes, pool,
      [&](int first, int end) { fns.warm_revolutes(revolutes, first, end, bodies); },
      [&](int first, int end) { lanes::warm_revolutes_scalar(revolutes, first, end, bodies); });
}

void solve_points(ColouredPoints& cp, SolverBody* bodies, const SolverBodyExtra* extras,
                  const PointRule& rule, WorkerPool* pool) {
  const PathFns fns = path_fns();
  PointBlock* blocks = cp.blocks.data();
  each_colour(
      cp, pool, [&](int first, int end) { fns.solve(blocks, first, end, bodies, rule); },
      [&](int first, int end) { lanes::solve_points_scalar(blocks, first, end, bodies, rule); });
  RevoluteBlock* revolutes = cp.revolutes.blocks.data();
  each_colour(
      cp.revolutes, pool,
      [&](int first, int end) { fns.solve_revolutes(revolutes, first, end, bodies, extras, rule); },
      [&](int first, int end) {
        lanes::solve_revolutes_scalar(revolutes, first, end, bodies, extras, rule);
      });
}

}  // namespace fulcrum
