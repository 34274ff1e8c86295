// Revolute joints solved colour by colour, several joints per instruction, as contact_lanes.h
// does for contacts: the plain points (JointRow::plain_point: a pin with no limit, motor or
// spring) in blocks of their own, then the other revolute joints (a ragdoll's limited, braked
// joints) in blocks that add the angle rows.
//
// Each solve_group call colours its plain points in row (joint id) order, each the lowest
// colour in which neither of its movable bodies is used yet; points that fit no colour go to an
// overflow set solved one lane at a time in row order after the colours. The other revolute
// joints are coloured the same way, on their own. Within a colour no two joints share a body
// the solver writes, so lanes and threads give the same bits. The other joint rows (every other
// type) are solved after the revolute joints, one by one in row order.
#pragma once

#include <cstdint>
#include <vector>

#include "contact_lanes.h"
#include "worker_pool.h"

namespace fulcrum {

struct Joint;
struct JointRow;

// Eight plain points, structure of arrays: what joint_frame and the point rows read. Each field
// fills one cache line, and the lines only the biased passes read (dcx, dcy) come after the
// others, so that a relax pass fetches none of them (fetch_ahead).
struct alignas(64) PointBlock {
  int32_t ia[kBlockLanes], ib[kBlockLanes];  // solver body slots (0: the static body)
  double inv_inertia_a[kBlockLanes], inv_inertia_b[kBlockLanes];
  double rax[kBlockLanes], ray[kBlockLanes];  // anchors relative to the centres, tick start
  double rbx[kBlockLanes], rby[kBlockLanes];
  double ix[kBlockLanes], iy[kBlockLanes];  // accumulated point impulse
  // 1 / det K of the point rows, as the first pass since the bodies last moved worked it out
  // (PointRule::mass), for the passes after it: K depends only on where
  // the bodies are, and the division is the pass's costliest instruction.
  double inv_det[kBlockLanes];
  uint8_t write_a[kBlockLanes], write_b[kBlockLanes];
  alignas(64) double dcx[kBlockLanes];  // centre of B minus centre of A, tick start
  double dcy[kBlockLanes];
};

// Eight revolute joints with angle rows: the point's fields, then what the spring, motor and
// limit rows read and accumulate (revolute_joint.cpp). A row a lane does not have (its flag 0, or
// neither body turns) leaves the bodies and its impulse as they are.
struct alignas(64) RevoluteBlock : PointBlock {
  double angle[kBlockLanes];  // joint angle at tick start
  double axial_mass[kBlockLanes];
  double spring_rate[kBlockLanes], spring_mass_scale[kBlockLanes];  // the joint's spring
  double spring_impulse_scale[kBlockLanes];
  double target_angle[kBlockLanes], motor_speed[kBlockLanes], max_motor_torque[kBlockLanes];
  double lower_angle[kBlockLanes], upper_angle[kBlockLanes];
  double spring_on[kBlockLanes], motor_on[kBlockLanes], limit_on[kBlockLanes];  // 1 or 0
  double spring_impulse[kBlockLanes], motor_impulse[kBlockLanes];               // accumulated
  double lower_impulse[kBlockLanes], upper_impulse[kBlockLanes];
};

// What the layout of a tick's points reads of one joint row: its joint, its slots, whether it is
// a plain point or another revolute joint and whether each of its bodies moves. Rows with the
// same keys, row for row, are coloured, grouped and laid out the same.
struct PointKey {
  int joint = -1;
  int ia = 0, ib = 0;
  uint8_t kind = 0;  // kPlainKey or kRevoluteKey | kMovableAKey | kMovableBKey
  bool operator==(const PointKey&) const = default;
};
inline constexpr uint8_t kPlainKey = 1, kMovableAKey = 2, kMovableBKey = 4, kRevoluteKey = 8;

// Which passes work out the point rows' 1 / det K and which read it (PointRule::mass): a pass reads
// it when an earlier pass has kept it since the bodies last moved, and keeps it when a later
// pass will read it before they move again. For solve_group's passes: `sub` and `it` the
// substep and the iteration, the counts the world's.
struct PointMassUse {
  bool keep = false, read = false;
  // Velocity pass `it` of substep `sub`: the bodies moved before it unless it follows another
  // velocity pass, or the relax passes of the substep before (no motion in between).
  static PointMassUse velocity(int sub, int it, int velocity_iterations, int relax_iterations) {
    PointMassUse u;
    u.read = it > 0 || (sub > 0 && relax_iterations > 0);
    u.keep = !u.read && velocity_iterations > 1;
    return u;
  }
  // Relax pass `it` of substep `sub`: the bodies moved before the first; the later relax passes
  // and the next substep's velocity passes read what it works out.
  static PointMassUse relax(int sub, int it, int substeps, int velocity_iterations,
                            int relax_iterations) {
    PointMassUse u;
    u.read = it > 0;
    u.keep = !u.read && (relax_iterations > 1 || (sub + 1 < substeps && velocity_iterations > 0));
    return u;
  }
};

// One pass's feedback, shared by every point of the group (their softness is the world's).
struct PointRule {
  bool use_bias = true;
  double rate = 0.0;  // bias rate: the soft rate, or baumgarte / h for rigid joints
  double mass_scale = 1.0;
  double impulse_scale = 0.0;
  double max_speed = 0.0;  // cap on the feedback's speed (capped_point_correction)
  // When set (the last relax pass of a substep with another after it), each lane also adds its
  // accumulated impulse, as a warm start applies it, to these rows (one per solver slot).
  VelocityBefore* warm_next = nullptr;
  double h = 0.0, inv_h = 0.0;  // the substep: the revolute joints' motors and limits
  // Whether the pass keeps each lane's 1 / det K in its block, or reads it from there instead
  // (no body has moved since a pass kept it).
  PointMassUse mass;
};

// The revolute joints with angle rows, laid out as the points are (ColouredPoints, below).
struct ColouredRevolutes {
  LargeVector<RevoluteBlock> blocks;
  std::vector<int> colour_start;
  int colours = 0;
  int joints = 0;               // rows packed
  std::vector<int> lane_joint;  // block * kBlockLanes + lane -> its joint (-1: padding)
};

struct ColouredPoints {
  LargeVector<PointBlock> blocks;
  std::vector<int> colour_start;  // as ColouredContacts: colours, then the overflow
  int colours = 0;
  int points = 0;  // plain point rows packed
  // Joint row -> block * kBlockLanes + lane, in `blocks` for a plain point, in revolutes.blocks
  // for another revolute joint (-1: neither).
  std::vector<int> lane_of_row;
  std::vector<int> lane_joint;  // block * kBlockLanes + lane -> its joint (-1: padding)
  ColouredRevolutes revolutes;  // solved after the points
  std::vector<int> other_rows;  // the rows that are not revolute joints, in row order
  // The other rows in groups, for threads: rows that share a solver body (any slot, the static
  // body's too, since their functions write both bodies, one of infinite mass unchanged) are
  // in one group, in row order, and groups follow in the order of their first rows. Chunk c
  // is grouped_rows[chunk_start[c], chunk_start[c + 1]), whole groups of at least
  // kRowsPerJointChunk rows (the last may have fewer). Rows of different groups write no
  // memory in common, so chunks on any number of threads give the bits of other_rows solved in
  // order. Empty (no chunks) without threads, or with fewer than two chunks' rows.
  std::vector<int> grouped_rows;
  std::vector<int> chunk_start;
  // Each row's key when colour_points laid the points out, and whether it grouped the other
  // rows (it had a pool): a tick with the same keys has this layout (place_point). `layouts`
  // counts the layouts made.
  std::vector<PointKey> keys;
  bool keyed_with_pool = false;
  int64_t layouts = 0;
  std::vector<uint8_t> chunk_differs;  // scratch: prepare_joints' chunks, a row not placed
  std::vector<uint32_t> body_use;      // scratch: colours used per solver body (points)
  std::vector<uint32_t> revolute_use;  // scratch: the same for the other revolute joints
  std::vector<int> slot_parent;        // scratch: union-find over solver slots
  std::vector<int> slot_group;         // scratch: group of a root slot
  std::vector<int> group_place;        // scratch: each group's size, then its place
  std::vector<int> group_sorted;       // scratch: grouped_rows in the making
};

// Rows per chunk of grouped_rows: a constant, so that chunks never depend on the thread count.
inline constexpr int kRowsPerJointChunk = 32;

// Runs row_fn(k) for every other row k: in row order without a pool (or with fewer than two
// chunks), else chunk by chunk among the pool's threads.
template <class F>
void each_other_row(const ColouredPoints& cp, WorkerPool* pool, F row_fn) {
  const int chunks = static_cast<int>(cp.chunk_start.size()) - 1;
  if (pool == nullptr || chunks < 2) {
    for (int k : cp.other_rows) row_fn(k);
    return;
  }
  auto chunk = [&](int c) {
    for (int i = cp.chunk_start[c]; i < cp.chunk_start[c + 1]; ++i) row_fn(cp.grouped_rows[i]);
  };
  pool->run(chunks, chunk);
}

// Colours the plain point rows of `rows` (read from `slots`, row for row) and, apart, the other
// revolute rows, and packs them into blocks, each lane starting from its row's accumulated
// impulses (JointRow::ix, iy, revolute), sharing the packing among the pool's threads. With a
// pool it also groups the other rows; without, they have no chunks. It keeps every row's key
// for place_point.
void colour_points(const LargeVector<JointRow>& rows,
                   const std::vector<SolverScratch::RowSlots>& slots,
                   const LargeVector<SolverBody>& bodies,
                   const std::vector<SolverBodyExtra>& extras, WorkerPool* pool,
                   ColouredPoints* out);
// Whether the last layout (colour_points) was made for rows of these joints, row for row, and
// grouped as `with_pool` asks: then place_point may be tried row by row. (A tick that solves its
// islands in groups of different joints lays each group out anew.)
bool layout_fits(const ColouredPoints& cp, const std::vector<int>& row_joints, bool with_pool);
// Row k of a tick whose rows fit the last layout: true when it has row k's key there, a
// revolute joint then written from `r` into the lane it had (the rest of the layout is
// unchanged, so the row itself need not be kept); false when it differs, and the tick's rows
// must be coloured anew (colour_points, from every row).
bool place_point(ColouredPoints* cp, size_t k, const JointRow& r,
                 const LargeVector<SolverBody>& bodies, const std::vector<SolverBodyExtra>& extras);
// Writes the lanes' impulses back to their joints, sharing the blocks among the pool's threads
// (each lane has its own joint).
void unpack_points(const ColouredPoints& cp, LargeVector<Joint>* joints, WorkerPool* pool);

// The passes over the plain points, then over the other revolute joints (which read the angles
// the bodies turned, in `extras`).
void warm_start_points(ColouredPoints& cp, SolverBody* bodies, WorkerPool* pool);
void solve_points(ColouredPoints& cp, SolverBody* bodies, const SolverBodyExtra* extras,
                  const PointRule& rule, WorkerPool* pool);

namespace lanes {
using PointSolveFn = void (*)(PointBlock* blocks, int first_block, int end_block,
                              SolverBody* bodies, const PointRule& rule);
using PointWarmFn = void (*)(PointBlock* blocks, int first_block, int end_block,
                             SolverBody* bodies);
void solve_points_scalar(PointBlock*, int, int, SolverBody*, const PointRule&);
void warm_points_scalar(PointBlock*, int, int, SolverBody*);
void solve_points_x2(PointBlock*, int, int, SolverBody*, const PointRule&);
void warm_points_x2(PointBlock*, int, int, SolverBody*);
void solve_points_x4(PointBlock*, int, int, SolverBody*, const PointRule&);
void warm_points_x4(PointBlock*, int, int, SolverBody*);
void solve_points_x4e(PointBlock*, int, int, SolverBody*, const PointRule&);  // AVX-512F and VL
void warm_points_x4e(PointBlock*, int, int, SolverBody*);
using RevoluteSolveFn = void (*)(RevoluteBlock* blocks, int first_block, int end_block,
                                 SolverBody* bodies, const SolverBodyExtra* extras,
                                 const PointRule& rule);
using RevoluteWarmFn = void (*)(RevoluteBlock* blocks, int first_block, int end_block,
                                SolverBody* bodies);
void solve_revolutes_scalar(RevoluteBlock*, int, int, SolverBody*, const SolverBodyExtra*,
                            const PointRule&);
void warm_revolutes_scalar(RevoluteBlock*, int, int, SolverBody*);
void solve_revolutes_x2(RevoluteBlock*, int, int, SolverBody*, const SolverBodyExtra*,
                        const PointRule&);
void warm_revolutes_x2(RevoluteBlock*, int, int, SolverBody*);
void solve_revolutes_x4(RevoluteBlock*, int, int, SolverBody*, const SolverBodyExtra*,
                        const PointRule&);
void warm_revolutes_x4(RevoluteBlock*, int, int, SolverBody*);
void solve_revolutes_x4e(RevoluteBlock*, int, int, SolverBody*, const SolverBodyExtra*,
                         const PointRule&);
void warm_revolutes_x4e(RevoluteBlock*, int, int, SolverBody*);
}  // namespace lanes

}  // namespace fulcrum
