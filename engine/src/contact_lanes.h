// Soft contacts solved colour by colour, several contacts per instruction.
//
// Graph colouring: each tick the touching contacts are given colours in contact id order, the
// lowest colour in which neither of the contact's dynamic bodies is used yet (static and
// kinematic bodies do not count: the solver never changes their velocity). Contacts of one
// colour share no body the solver writes, so they can be solved in any order, in lanes or on
// several threads, and the result is the same bits. Contacts that fit no colour go to an
// overflow set, solved one by one in id order after the colours.
//
// Layout: each colour's contacts (in id order) fill blocks of kBlockLanes lanes, structure of
// arrays inside a block; the last block of a colour is padded with empty lanes (static body on
// both sides, zero masses), which change nothing. The layout depends on neither the
// instruction path nor the thread count: a 2-lane path takes a block in two halves, the scalar
// path lane by lane.
#pragma once

#include <cstdint>
#include <memory>
#include <new>
#include <utility>
#include <vector>

#include "contact_solver.h"
#include "fulcrum/simd.h"
#include "large_pages.h"

namespace fulcrum {

inline constexpr int kBlockLanes = 8;
inline constexpr int kMaxColours = 24;

// The allocator of the lanes' blocks: the elements a vector grows by are left as they come
// (default-initialised; the blocks have no initialisers). Each time the blocks are laid out,
// every lane is written before any pass reads it: in full by prepare_lane (a row's) or
// pad_colours (padding), but for a row's separations, which the tick's first pass works out
// before it reads them (and bounce_separations before restitution does). A tick whose islands
// are solved in several groups (budget.cpp) grows the blocks back after each smaller group:
// zeroing them each time cost the spinner 1 % of its tick.
template <class T>
struct LaneAllocator : LargeAllocator<T> {
  LaneAllocator() = default;
  template <class U>
  explicit LaneAllocator(const LaneAllocator<U>&) noexcept {}
  template <class U>
  struct rebind {
    using other = LaneAllocator<U>;
  };
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

// One contact point's rows, one lane per contact; with 8 lanes each array is one cache line.
// What every pass reads comes first.
struct alignas(64) LanePoint {
  // The anchors at the tick's start (ra from A's centre, rb from B's) crossed with the normal n
  // and the tangent t = (ny, -nx): rna = ra x n, rnb = rb x n, rta = ra x t, rtb = rb x t. The
  // rows need the anchors only so (contact_kernel.h).
  double rna[kBlockLanes], rnb[kBlockLanes];
  double rta[kBlockLanes], rtb[kBlockLanes];
  double separation[kBlockLanes];  // now: refreshed whenever the bodies move (update_separations)
  double normal_mass[kBlockLanes];
  double tangent_mass[kBlockLanes];
  double normal_impulse[kBlockLanes];  // accumulated
  double tangent_impulse[kBlockLanes];
};

// The inverse masses are not here: the lanes read them with the bodies' velocities. Nor is the
// softness: it is one of two per tick (LaneRule), chosen by whether a body has infinite mass.
struct alignas(64) ContactBlock {
  int32_t ia[kBlockLanes], ib[kBlockLanes];  // solver body slots (0: the static body)
  // Whether the solver writes body A / B back (dynamic bodies only).
  uint8_t write_a[kBlockLanes], write_b[kBlockLanes];
  double inv_inertia_a[kBlockLanes], inv_inertia_b[kBlockLanes];
  double nx[kBlockLanes], ny[kBlockLanes];
  double friction[kBlockLanes];
  LanePoint points[2];  // a one-point manifold's second point has zero masses
};

// What few passes read of a block's points (index [point][lane]), kept beside the blocks
// (ColouredContacts::rests) so that the warm-start and solve passes stream six lines fewer per
// block. Field by field: a refreshing pass without restitution reads the first two lines alone,
// one aligned pair, which is what the processor fetches together.
struct alignas(128) ContactBlockRest {
  double base_separation[2][kBlockLanes];     // read where the separations are refreshed
  double max_normal_impulse[2][kBlockLanes];  // tracked only when restitution needs it
  // Restitution: the point's normal speed at impact, the least over the substeps
  // (track_approach_coloured); kept only for contacts with restitution.
  double approach_speed[2][kBlockLanes];
};

// What one pass needs besides the blocks.
struct LaneRule {
  double inv_h = 0.0;
  double max_speed = 0.0;     // cap on push-out speed
  bool use_bias = true;       // position feedback in this pass
  bool track_max = false;     // keep each point's largest normal impulse (for restitution)
  bool want_largest = false;  // return the largest corrective impulse (for early exit)
  // The bodies moved since the separations were computed: each lane refreshes its points'
  // separations before it is solved (what update_separations does, fused into the pass).
  bool refresh_separation = false;
  Softness soft;                      // between two dynamic bodies
  Softness static_soft;               // with a body of infinite mass (static, kinematic)
  ContactBlockRest* rests = nullptr;  // the blocks' rests (solve_coloured sets it)
  int block_count = 0;  // blocks (and rests) in all, every colour's and the overflow's
  // When set (the last relax pass of a substep with another after it), each lane also adds its
  // accumulated impulses, as a warm start applies them, to these rows (one per solver slot).
  VelocityBefore* warm_next = nullptr;
};

// One substep's position update (contact_kernel.h, integrate_lanes): its length, the speed
// cap and the turn-rate cap.
struct IntegrateRule {
  double h = 0.0;
  double max_speed = 0.0;
  double max_turn = 0.0;
  // When set (per solver slot, like the bodies), what a cap changes of a velocity is noted there
  // (note_cap).
  VelocityBefore* caps = nullptr;
};

// The colours' block ranges (lay_out_colours, below).
struct ColourLayout {
  int colours = 0;
  int blocks = 0;
  int next_lane[kMaxColours + 1] = {};
};

// The coloured blocks of one tick. Blocks [colour_start[c], colour_start[c + 1]) hold colour
// c; blocks from colour_start[colours] on hold the overflow, `overflow` lanes in id order.
struct ColouredContacts {
  std::vector<ContactBlock, LaneAllocator<ContactBlock>> blocks;
  std::vector<ContactBlockRest, LaneAllocator<ContactBlockRest>> rests;  // block for block
  std::vector<int> colour_start;
  int colours = 0;
  int overflow = 0;
  std::vector<int> lane_of_row;       // row -> block * kBlockLanes + lane
  std::vector<int> row_of_lane;       // block * kBlockLanes + lane -> row (-1: padding)
  std::vector<int> bounce_blocks;     // blocks holding a contact with restitution, ascending
  std::vector<uint8_t> bounce_marks;  // scratch: per block, whether it is a bounce block
  std::vector<uint32_t> body_use;     // scratch: colours used per solver body
  std::vector<double> chunk_largest;  // scratch: each chunk's largest impulse
  // What the layout was made from: the rows' slots and whether each slot's body is dynamic.
  // A tick with the same rows and slots gets the same colours, so colour_contacts keeps the
  // layout (lanes and colours) and pads it again. `layouts` counts the layouts made.
  std::vector<RowBodies> keyed_rows;
  std::vector<uint8_t> keyed_dynamic;
  ColourLayout padding;  // the layout's ends of lanes placed, for padding it again
  int64_t layouts = 0;
};

class WorkerPool;

// Graph colouring's two shared steps (contacts here, revolute pins in joint_lanes.cpp).
// The colour of a row between solver slots a and b, given which of them the row writes: the
// lowest colour neither uses yet, or the highest with `highest`; kMaxColours (the overflow)
// when none is free. The colour is marked used for the bodies written.
int take_colour(std::vector<uint32_t>& use, int a, bool write_a, int b, bool write_b, bool highest);
// Block ranges from the rows counted per colour (count[kMaxColours]: the overflow): each colour
// padded to whole blocks, in colour order, the overflow last. Sets colour_start (colours + 1
// entries) and next_lane[c], the first lane of colour c (the overflow's at kMaxColours); returns
// the number of blocks (ColourLayout, above).
ColourLayout lay_out_colours(const int count[kMaxColours + 1], std::vector<int>* colour_start);
// Fills the rest of each colour's last block, and the overflow's, with empty lanes:
// clear(block, lane) for each lane from layout.next_lane[c] (advanced past the rows placed) to
// the block's end.
template <class Blocks, class Clear>
void pad_colours(const ColourLayout& layout, Blocks* blocks, Clear clear) {
  auto tail = [&](int lane_end) {
    for (int lane = lane_end; lane % kBlockLanes != 0; ++lane) {
      clear(&(*blocks)[lane / kBlockLanes], lane % kBlockLanes);
    }
  };
  for (int c = 0; c < layout.colours; ++c) tail(layout.next_lane[c]);
  tail(layout.next_lane[kMaxColours]);
}

// Colours the rows (in id order) by their bodies and lays out the blocks: each row's lane
// (lane_of_row, and row_of_lane back), the colours' ranges, the padding. The rows' lanes are
// left for their preparation (contact_solver.cpp, prepare_lane), which may write the lanes of
// one block on different threads. slot_dynamic: for each solver slot, whether its body is
// dynamic (SolverScratch::slot_dynamic). Rows and slots as at the last layout keep that layout
// (the colouring is a function of them alone), padded again.
void colour_contacts(const std::vector<RowBodies>& rows, const std::vector<uint8_t>& slot_dynamic,
                     ColouredContacts* out);
// Point `point` of a lane whose manifold has fewer points: zero masses and impulses, so that it
// changes nothing.
void clear_lane_point(ContactBlock* block, ContactBlockRest* rest, int point, int lane);

// Lanes [first, first + count) of blocks, for each path. Each returns the largest corrective
// impulse (0 unless the rule asks for it). Declared per path so that the 4-lane path can live in a
// file built for AVX2.
namespace lanes {
using SolveFn = double (*)(ContactBlock* blocks, int first_block, int end_block, SolverBody* bodies,
                           const LaneRule& rule);
using WarmFn = void (*)(ContactBlock* blocks, int first_block, int end_block, SolverBody* bodies);
using SeparationFn = void (*)(ContactBlock* blocks, const ContactBlockRest* rests, int first_block,
                              int end_block, const SolverBody* bodies);
// The blocks listed in which[first, end).
using ApproachFn = void (*)(const ContactBlock* blocks, ContactBlockRest* rests, const int* which,
                            int first, int end, const SolverBody* bodies,
                            const VelocityBefore* before, double inv_h);
double solve_scalar(ContactBlock*, int, int, SolverBody*, const LaneRule&);
void warm_scalar(ContactBlock*, int, int, SolverBody*);
void separation_scalar(ContactBlock*, const ContactBlockRest*, int, int, const SolverBody*);
void approach_scalar(const ContactBlock*, ContactBlockRest*, const int*, int, int,
                     const SolverBody*, const VelocityBefore*, double);
double solve_x2(ContactBlock*, int, int, SolverBody*, const LaneRule&);
void warm_x2(ContactBlock*, int, int, SolverBody*);
void separation_x2(ContactBlock*, const ContactBlockRest*, int, int, const SolverBody*);
void approach_x2(const ContactBlock*, ContactBlockRest*, const int*, int, int, const SolverBody*,
                 const VelocityBefore*, double);
double solve_x4(ContactBlock*, int, int, SolverBody*, const LaneRule&);
void warm_x4(ContactBlock*, int, int, SolverBody*);
void separation_x4(ContactBlock*, const ContactBlockRest*, int, int, const SolverBody*);
void approach_x4(const ContactBlock*, ContactBlockRest*, const int*, int, int, const SolverBody*,
                 const VelocityBefore*, double);
double solve_x4e(ContactBlock*, int, int, SolverBody*, const LaneRule&);  // AVX-512F and VL
void warm_x4e(ContactBlock*, int, int, SolverBody*);
void separation_x4e(ContactBlock*, const ContactBlockRest*, int, int, const SolverBody*);
void approach_x4e(const ContactBlock*, ContactBlockRest*, const int*, int, int, const SolverBody*,
                  const VelocityBefore*, double);
// Solver bodies [first, end) (IntegrateRule); extras null unless the turns are added up.
using IntegrateFn = void (*)(SolverBody* bodies, SolverBodyExtra* extras, const IntegrateRule& rule,
                             int first, int end);
void integrate_x2(SolverBody*, SolverBodyExtra*, const IntegrateRule&, int, int);
void integrate_x4(SolverBody*, SolverBodyExtra*, const IntegrateRule&, int, int);
void integrate_x4e(SolverBody*, SolverBodyExtra*, const IntegrateRule&, int, int);
}  // namespace lanes

// The 2- or 4-lane position update of the active path; null on the scalar path (the caller's
// own loop).
lanes::IntegrateFn integrate_fn();

// Blocks per chunk when a colour is shared out among threads: a constant, so that which
// blocks form a chunk never depends on the thread count.
inline constexpr int kBlocksPerChunk = 4;

// The current separation of every lane's points, from the bodies' motion since the tick began;
// needed after a position update that no relax pass follows (LaneRule::refresh_separation).
void update_separations(ColouredContacts& cc, const SolverBody* bodies, WorkerPool* pool);

// The separations of the bounce blocks' lanes (what update_separations gives for all): at the
// tick's start, restitution reads them before the first pass works out the others.
void bounce_separations(ColouredContacts& cc, const SolverBody* bodies, WorkerPool* pool);

// Restitution's speeds of approach (contact_solver.cpp, track_approach), for the lanes of the
// bounce blocks: each point's normal speed now and before the substep's forces (`before`, per
// solver slot), its current separation, and so its speed at impact; the least is kept. Reads
// the bodies, writes only the rests: any order gives the same bits.
void track_approach_coloured(ColouredContacts& cc, const SolverBody* bodies,
                             const VelocityBefore* before, double inv_h, WorkerPool* pool);

// One pass (solve or warm start) over every colour, then the overflow one lane at a time.
// With a pool, each colour's chunks are shared among its threads.
double solve_coloured(ColouredContacts& cc, SolverBody* bodies, const LaneRule& rule,
                      WorkerPool* pool);
void warm_start_coloured(ColouredContacts& cc, SolverBody* bodies, WorkerPool* pool);

}  // namespace fulcrum
