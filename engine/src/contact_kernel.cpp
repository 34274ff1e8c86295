// Graph colouring, block packing, the scalar and 2-lane contact paths, and the choice of path.
#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <mutex>

#include "contact_kernel.h"
#include "joint_kernel.h"
#include "worker_pool.h"

namespace fulcrum {

namespace lanes {

double solve_scalar(ContactBlock* blocks, int first, int end, SolverBody* bodies,
                    const LaneRule& rule) {
  return solve_blocks<double>(blocks, first, end, bodies, rule);
}
void warm_scalar(ContactBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_blocks<double>(blocks, first, end, bodies);
}
void separation_scalar(ContactBlock* blocks, const ContactBlockRest* rests, int first, int end,
                       const SolverBody* bodies) {
  separation_blocks<double>(blocks, rests, first, end, bodies);
}
void approach_scalar(const ContactBlock* blocks, ContactBlockRest* rests, const int* which,
                     int first, int end, const SolverBody* bodies, const VelocityBefore* before,
                     double inv_h) {
  approach_blocks<double>(blocks, rests, which, first, end, bodies, before, inv_h);
}
double solve_x2(ContactBlock* blocks, int first, int end, SolverBody* bodies,
                const LaneRule& rule) {
  return solve_blocks<F64x2>(blocks, first, end, bodies, rule);
}
void warm_x2(ContactBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_blocks<F64x2>(blocks, first, end, bodies);
}
void separation_x2(ContactBlock* blocks, const ContactBlockRest* rests, int first, int end,
                   const SolverBody* bodies) {
  separation_blocks<F64x2>(blocks, rests, first, end, bodies);
}
void approach_x2(const ContactBlock* blocks, ContactBlockRest* rests, const int* which, int first,
                 int end, const SolverBody* bodies, const VelocityBefore* before, double inv_h) {
  approach_blocks<F64x2>(blocks, rests, which, first, end, bodies, before, inv_h);
}

void integrate_x2(SolverBody* bodies, SolverBodyExtra* extras, const IntegrateRule& rule, int first,
                  int end) {
  integrate_bodies<F64x2>(bodies, extras, rule, first, end);
}

void solve_points_scalar(PointBlock* blocks, int first, int end, SolverBody* bodies,
                         const PointRule& rule) {
  solve_point_blocks<double>(blocks, first, end, bodies, rule);
}
void warm_points_scalar(PointBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_point_blocks<double>(blocks, first, end, bodies);
}
void solve_points_x2(PointBlock* blocks, int first, int end, SolverBody* bodies,
                     const PointRule& rule) {
  solve_point_blocks<F64x2>(blocks, first, end, bodies, rule);
}
void warm_points_x2(PointBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_point_blocks<F64x2>(blocks, first, end, bodies);
}
void solve_revolutes_scalar(RevoluteBlock* blocks, int first, int end, SolverBody* bodies,
                            const SolverBodyExtra* extras, const PointRule& rule) {
  solve_revolute_blocks<double>(blocks, first, end, bodies, extras, rule);
}
void warm_revolutes_scalar(RevoluteBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_revolute_blocks<double>(blocks, first, end, bodies);
}
void solve_revolutes_x2(RevoluteBlock* blocks, int first, int end, SolverBody* bodies,
                        const SolverBodyExtra* extras, const PointRule& rule) {
  solve_revolute_blocks<F64x2>(blocks, first, end, bodies, extras, rule);
}
void warm_revolutes_x2(RevoluteBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_revolute_blocks<F64x2>(blocks, first, end, bodies);
}

}  // namespace lanes

// --- The path ------------------------------------------------------------------------------

namespace {

bool cpu_runs(SimdPath path) {
#if defined(__x86_64__) || defined(__i386__)
  if (path == SimdPath::kLanes4) return __builtin_cpu_supports("avx2");
  if (path == SimdPath::kAvx512) {
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("avx512f") &&
           __builtin_cpu_supports("avx512vl");
  }
  return true;
#else
  return path != SimdPath::kAvx512;  // the generic 4-lane build runs anywhere
#endif
}

SimdPath widest() {
#if defined(__x86_64__) || defined(__i386__)
  if (cpu_runs(SimdPath::kAvx512)) return SimdPath::kAvx512;
  return cpu_runs(SimdPath::kLanes4) ? SimdPath::kLanes4 : SimdPath::kLanes2;
#else
  return SimdPath::kLanes2;          // NEON holds two doubles; 4 lanes would only split in two
#endif
}

std::atomic<int> g_path{-1};

SimdPath path_from_environment() {
  const char* text = std::getenv("FULCRUM_SIMD");
  if (text == nullptr || *text == '\0') return widest();
  Result<SimdPath> parsed = parse_simd_path(text);
  if (!parsed.ok() || !cpu_runs(*parsed)) return widest();
  return *parsed == SimdPath::kAuto ? widest() : *parsed;
}

}  // namespace

const char* simd_path_name(SimdPath path) {
  switch (path) {
    case SimdPath::kAuto:
      return "auto";
    case SimdPath::kScalar:
      return "scalar";
    case SimdPath::kLanes2:
      return "lanes2";
    case SimdPath::kLanes4:
      return "lanes4";
    case SimdPath::kAvx512:
      return "avx512";
  }
  return "unknown";
}

Result<SimdPath> parse_simd_path(const std::string& name) {
  if (name == "auto") return SimdPath::kAuto;
  if (name == "scalar") return SimdPath::kScalar;
  if (name == "lanes2" || name == "sse2" || name == "neon") return SimdPath::kLanes2;
  if (name == "lanes4" || name == "avx2") return SimdPath::kLanes4;
  if (name == "avx512") return SimdPath::kAvx512;
  return invalid_argument("simd path '" + name +
                          "': expected auto, scalar, lanes2 (sse2, neon), lanes4 (avx2) or avx512");
}

std::vector<SimdPath> supported_simd_paths() {
  std::vector<SimdPath> out;
  for (SimdPath p : {SimdPath::kScalar, SimdPath::kLanes2, SimdPath::kLanes4, SimdPath::kAvx512}) {
    if (cpu_runs(p)) out.push_back(p);
  }
  return out;
}

Status set_simd_path(SimdPath path) {
  if (path == SimdPath::kAuto) path = widest();
  if (!cpu_runs(path)) {
    return invalid_argument(std::string("simd path ") + simd_path_name(path) +
                            ": this CPU cannot run it");
  }
  g_path.store(static_cast<int>(path), std::memory_order_relaxed);
  return {};
}

SimdPath active_simd_path() {
  int p = g_path.load(std::memory_order_relaxed);
  if (p < 0) {
    static std::once_flag once;
    std::call_once(once, [] {
      int expected = -1;
      g_path.compare_exchange_strong(expected, static_cast<int>(path_from_environment()));
    });
    p = g_path.load(std::memory_order_relaxed);
  }
  return static_cast<SimdPath>(p);
}

// --- Colouring and packing -----------------------------------------------------------------

static_assert(kMaxColours <= 32, "colours are bits of a uint32_t");

namespace {

void clear_point(LanePoint* q, ContactBlockRest* r, int i, int l) {
  q->rna[l] = q->rnb[l] = q->rta[l] = q->rtb[l] = 0.0;
  q->separation[l] = r->base_separation[i][l] = 0.0;
  q->normal_mass[l] = q->tangent_mass[l] = 0.0;
  q->normal_impulse[l] = q->tangent_impulse[l] = r->max_normal_impulse[i][l] = 0.0;
  r->approach_speed[i][l] = 0.0;
}

void clear_lane(ContactBlock* b, ContactBlockRest* r, int l) {
  b->ia[l] = b->ib[l] = 0;
  b->write_a[l] = b->write_b[l] = 0;
  b->inv_inertia_a[l] = b->inv_inertia_b[l] = 0.0;
  b->nx[l] = b->ny[l] = b->friction[l] = 0.0;
  clear_point(&b->points[0], r, 0, l);
  clear_point(&b->points[1], r, 1, l);
}

}  // namespace

int take_colour(std::vector<uint32_t>& use, int a, bool write_a, int b, bool write_b,
                bool highest) {
  constexpr uint32_t kAll = kMaxColours == 32 ? ~0u : (1u << kMaxColours) - 1u;
  const uint32_t used = (write_a ? use[a] : 0u) | (write_b ? use[b] : 0u);
  const uint32_t free = ~used & kAll;
  if (free == 0) return kMaxColours;
  const int colour = highest ? 31 - __builtin_clz(free) : __builtin_ctz(free);
  if (write_a) use[a] |= 1u << colour;
  if (write_b) use[b] |= 1u << colour;
  return colour;
}

ColourLayout lay_out_colours(const int count[kMaxColours + 1], std::vector<int>* colour_start) {
  ColourLayout out;
  for (int c = 0; c < kMaxColours; ++c) {
    if (count[c] > 0) out.colours = c + 1;
  }
  colour_start->resize(out.colours + 1);
  for (int c = 0; c < out.colours; ++c) {
    (*colour_start)[c] = out.blocks;
    out.next_lane[c] = out.blocks * kBlockLanes;
    out.blocks += (count[c] + kBlockLanes - 1) / kBlockLanes;
  }
  (*colour_start)[out.colours] = out.blocks;
  out.next_lane[kMaxColours] = out.blocks * kBlockLanes;
  out.blocks += (count[kMaxColours] + kBlockLanes - 1) / kBlockLanes;
  return out;
}

namespace {

// The padding of colour_contacts: the static body on both sides, zero masses, nothing written.
void pad_contact_colours(const ColourLayout& layout, ColouredContacts* out) {
  pad_colours(layout, &out->blocks, [out](ContactBlock* b, int l) {
    clear_lane(b, &out->rests[b - out->blocks.data()], l);
  });
}

// Whether `rows` and the slots' kinds are those the layout was made from.
bool same_layout(const std::vector<RowBodies>& rows, const std::vector<uint8_t>& slot_dynamic,
                 const ColouredContacts& cc) {
  return !rows.empty() && rows == cc.keyed_rows && slot_dynamic == cc.keyed_dynamic;
}

}  // namespace

void colour_contacts(const std::vector<RowBodies>& rows, const std::vector<uint8_t>& slot_dynamic,
                     ColouredContacts* out) {
  if (same_layout(rows, slot_dynamic, *out)) {
    pad_contact_colours(out->padding, out);
    return;
  }
  ++out->layouts;
  out->keyed_rows = rows;
  out->keyed_dynamic = slot_dynamic;
  const size_t n_rows = rows.size();
  std::vector<uint32_t>& use = out->body_use;
  use.assign(slot_dynamic.size(), 0);
  // Pass 1: each row's colour (kMaxColours: overflow), counted per colour.
  std::vector<int>& lane_of_row = out->lane_of_row;
  lane_of_row.resize(n_rows);
  int count[kMaxColours + 1] = {};
  for (size_t k = 0; k < n_rows; ++k) {
    const RowBodies& row = rows[k];
    const bool dyn_a = slot_dynamic[row.ia] != 0;
    const bool dyn_b = slot_dynamic[row.ib] != 0;
    // Contacts between two dynamic bodies take the lowest free colour, contacts with a static
    // or kinematic body the highest: each pass solves them last, so the ground has the last
    // word (a pyramid created overlapping then leaves no faster than 3 m/s, where lowest-first
    // reached 3.15 m/s).
    const int colour = take_colour(use, row.ia, dyn_a, row.ib, dyn_b, !(dyn_a && dyn_b));
    lane_of_row[k] = colour;
    ++count[colour];
  }
  ColourLayout layout = lay_out_colours(count, &out->colour_start);
  int* next_lane = layout.next_lane;  // advanced as rows take their lanes
  out->colours = layout.colours;
  out->overflow = count[kMaxColours];
  // Lanes in id order within each colour; prepare_lane then fills each row's lane.
  out->row_of_lane.assign(static_cast<size_t>(layout.blocks) * kBlockLanes, -1);
  for (size_t k = 0; k < n_rows; ++k) {
    lane_of_row[k] = next_lane[lane_of_row[k]]++;
    out->row_of_lane[lane_of_row[k]] = static_cast<int>(k);
  }
  out->blocks.resize(layout.blocks);
  out->rests.resize(layout.blocks);
  // Empty lanes at the end of each colour and of the overflow.
  out->padding = layout;
  pad_contact_colours(layout, out);
}

void clear_lane_point(ContactBlock* block, ContactBlockRest* rest, int point, int lane) {
  clear_point(&block->points[point], rest, point, lane);
}

// --- Passes ----------------------------------------------------------------------------------

namespace {

struct PathFns {
  lanes::SolveFn solve;
  lanes::WarmFn warm;
  lanes::SeparationFn separation;
  lanes::ApproachFn approach;
};

PathFns path_fns() {
  switch (active_simd_path()) {
    case SimdPath::kAvx512:
      return {lanes::solve_x4e, lanes::warm_x4e, lanes::separation_x4e, lanes::approach_x4e};
    case SimdPath::kLanes4:
      return {lanes::solve_x4, lanes::warm_x4, lanes::separation_x4, lanes::approach_x4};
    case SimdPath::kLanes2:
      return {lanes::solve_x2, lanes::warm_x2, lanes::separation_x2, lanes::approach_x2};
    default:
      return {lanes::solve_scalar, lanes::warm_scalar, lanes::separation_scalar,
              lanes::approach_scalar};
  }
}

}  // namespace

lanes::IntegrateFn integrate_fn() {
  switch (active_simd_path()) {
    case SimdPath::kAvx512:
      return lanes::integrate_x4e;
    case SimdPath::kLanes4:
      return lanes::integrate_x4;
    case SimdPath::kLanes2:
      return lanes::integrate_x2;
    default:
      return nullptr;
  }
}

namespace {

int chunk_count(int first, int end) {
  return (end - first + kBlocksPerChunk - 1) / kBlocksPerChunk;
}

}  // namespace

double solve_coloured(ColouredContacts& cc, SolverBody* bodies, const LaneRule& pass_rule,
                      WorkerPool* pool) {
  const PathFns fns = path_fns();
  LaneRule rule = pass_rule;
  rule.rests = cc.rests.data();
  rule.block_count = static_cast<int>(cc.blocks.size());
  ContactBlock* blocks = cc.blocks.data();
  double largest = 0.0;
  for (int c = 0; c < cc.colours; ++c) {
    const int first = cc.colour_start[c], end = cc.colour_start[c + 1];
    const int chunks = chunk_count(first, end);
    if (pool == nullptr || chunks < 2) {
      largest = lane_max(largest, fns.solve(blocks, first, end, bodies, rule));
      continue;
    }
    // Each chunk's largest impulse into its own slot, reduced in chunk order.
    cc.chunk_largest.assign(chunks, 0.0);
    auto chunk = [&](int i) {
      const int b = first + i * kBlocksPerChunk;
      cc.chunk_largest[i] = fns.solve(blocks, b, std::min(b + kBlocksPerChunk, end), bodies, rule);
    };
    pool->run(chunks, chunk);
    for (double x : cc.chunk_largest) largest = lane_max(largest, x);
  }
  const int end = static_cast<int>(cc.blocks.size());
  if (cc.colour_start[cc.colours] < end) {
    largest = lane_max(largest,
                       lanes::solve_scalar(blocks, cc.colour_start[cc.colours], end, bodies, rule));
  }
  return largest;
}

void update_separations(ColouredContacts& cc, const SolverBody* bodies, WorkerPool* pool) {
  const PathFns fns = path_fns();
  ContactBlock* blocks = cc.blocks.data();
  const int end = static_cast<int>(cc.blocks.size());
  const int chunks = chunk_count(0, end);
  if (pool == nullptr || chunks < 2) {
    fns.separation(blocks, cc.rests.data(), 0, end, bodies);
    return;
  }
  auto chunk = [&](int i) {
    const int b = i * kBlocksPerChunk;
    fns.separation(blocks, cc.rests.data(), b, std::min(b + kBlocksPerChunk, end), bodies);
  };
  pool->run(chunks, chunk);
}

void bounce_separations(ColouredContacts& cc, const SolverBody* bodies, WorkerPool* pool) {
  const PathFns fns = path_fns();
  ContactBlock* blocks = cc.blocks.data();
  const std::vector<int>& which = cc.bounce_blocks;
  auto range = [&](size_t lo, size_t hi) {
    for (size_t j = lo; j < hi; ++j) {
      fns.separation(blocks, cc.rests.data(), which[j], which[j] + 1, bodies);
    }
  };
  const int chunks = chunk_count(0, static_cast<int>(which.size()));
  if (pool == nullptr || chunks < 2) {
    range(0, which.size());
    return;
  }
  auto chunk = [&](int i) {
    const size_t lo = static_cast<size_t>(i) * kBlocksPerChunk;
    range(lo, std::min(lo + kBlocksPerChunk, which.size()));
  };
  pool->run(chunks, chunk);
}

void track_approach_coloured(ColouredContacts& cc, const SolverBody* bodies,
                             const VelocityBefore* before, double inv_h, WorkerPool* pool) {
  const PathFns fns = path_fns();
  const int* which = cc.bounce_blocks.data();
  const int end = static_cast<int>(cc.bounce_blocks.size());
  const int chunks = chunk_count(0, end);
  if (pool == nullptr || chunks < 2) {
    fns.approach(cc.blocks.data(), cc.rests.data(), which, 0, end, bodies, before, inv_h);
    return;
  }
  auto chunk = [&](int i) {
    const int b = i * kBlocksPerChunk;
    fns.approach(cc.blocks.data(), cc.rests.data(), which, b, std::min(b + kBlocksPerChunk, end),
                 bodies, before, inv_h);
  };
  pool->run(chunks, chunk);
}

void warm_start_coloured(ColouredContacts& cc, SolverBody* bodies, WorkerPool* pool) {
  const PathFns fns = path_fns();
  ContactBlock* blocks = cc.blocks.data();
  for (int c = 0; c < cc.colours; ++c) {
    const int first = cc.colour_start[c], end = cc.colour_start[c + 1];
    const int chunks = chunk_count(first, end);
    if (pool == nullptr || chunks < 2) {
      fns.warm(blocks, first, end, bodies);
      continue;
    }
    auto chunk = [&](int i) {
      const int b = first + i * kBlocksPerChunk;
      fns.warm(blocks, b, std::min(b + kBlocksPerChunk, end), bodies);
    };
    pool->run(chunks, chunk);
  }
  const int end = static_cast<int>(cc.blocks.size());
  if (cc.colour_start[cc.colours] < end) {
    lanes::warm_scalar(blocks, cc.colour_start[cc.colours], end, bodies);
  }
}

}  // namespace fulcrum
