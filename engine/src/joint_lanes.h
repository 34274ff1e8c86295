// Plain revolute points (JointRow::plain_point: a pin with no limit, motor or spring) solved
// colour by colour, several joints per instruction, as contact_lanes.h does for contacts.
//
// Each solve_group call colours its plain points in row (joint id) order, each the lowest
// colour in which neither of its movable bodies is used yet; points that fit no colour go to an
// overflow set solved one lane at a time in row order after the colours. Within a colour no two
// points share a body the solver writes, so lanes and threads give the same bits. The other
// joint rows (every other type, and revolute joints with a limit, motor or spring) are solved
// after the points, one by one in row order.
#pragma once

#include <cstdint>
#include <vector>

#include "contact_lanes.h"

namespace fulcrum {

struct Joint;
struct JointRow;

// Eight plain points, structure of arrays: what joint_frame and solve_revolute_point read.
struct alignas(64) PointBlock {
  int32_t ia[kBlockLanes], ib[kBlockLanes];  // solver body slots (0: the static body)
  uint8_t write_a[kBlockLanes], write_b[kBlockLanes];
  double inv_inertia_a[kBlockLanes], inv_inertia_b[kBlockLanes];
  double rax[kBlockLanes], ray[kBlockLanes];  // anchors relative to the centres, tick start
  double rbx[kBlockLanes], rby[kBlockLanes];
  double dcx[kBlockLanes], dcy[kBlockLanes];  // centre of B minus centre of A, tick start
  double ix[kBlockLanes], iy[kBlockLanes];    // accumulated point impulse
};

// One pass's feedback, shared by every point of the group (their softness is the world's).
struct PointRule {
  bool use_bias = true;
  double rate = 0.0;  // bias rate: the soft rate, or baumgarte / h for rigid joints
  double mass_scale = 1.0;
  double impulse_scale = 0.0;
  double max_speed = 0.0;  // cap on the feedback's speed (capped_point_correction)
};

struct ColouredPoints {
  std::vector<PointBlock> blocks;
  std::vector<int> colour_start;  // as ColouredContacts: colours, then the overflow
  int colours = 0;
  int points = 0;                  // plain point rows packed
  std::vector<int> lane_of_row;    // joint row -> block * kBlockLanes + lane (-1: not a point)
  std::vector<int> other_rows;     // the rows that are not plain points, in row order
  std::vector<uint32_t> body_use;  // scratch: colours used per solver body
};

// Colours the plain point rows of `rows` (joints[row.joint] their joints) and packs them into
// blocks, each lane starting from its joint's accumulated point impulse.
void colour_points(const std::vector<JointRow>& rows, const std::vector<Joint>& joints,
                   const std::vector<SolverBody>& bodies, ColouredPoints* out);
// Writes the lanes' point impulses back to their joints.
void unpack_points(const ColouredPoints& cp, const std::vector<JointRow>& rows,
                   std::vector<Joint>* joints);

void warm_start_points(ColouredPoints& cp, SolverBody* bodies, WorkerPool* pool);
void solve_points(ColouredPoints& cp, SolverBody* bodies, const PointRule& rule, WorkerPool* pool);

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
}  // namespace lanes

}  // namespace fulcrum
