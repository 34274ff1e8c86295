// Which instruction path the contact solver's lanes run on. Every path performs the same IEEE
// operations in the same order for each contact (no fused multiply-add), so all paths give
// bit-identical results; they differ only in speed. The path is process-wide: the environment
// variable FULCRUM_SIMD (scalar, lanes2, lanes4, avx512 or auto) sets it at start, set_simd_path()
// changes it for tests and benchmarks.
#pragma once

#include <string>
#include <vector>

#include "fulcrum/status.h"

namespace fulcrum {

enum class SimdPath {
  kAuto = 0,    // the widest path this CPU runs
  kScalar = 1,  // one contact at a time
  kLanes2 = 2,  // two contacts per instruction: SSE2 on x86-64, NEON on aarch64
  kLanes4 = 3,  // four contacts per instruction: AVX2 on x86-64 (chosen when the CPU has it)
  // The 4-lane path built for AVX-512F and VL on x86-64 (chosen when the CPU has them): the same
  // operations on the same 4-double vectors, with 32 vector registers instead of 16.
  kAvx512 = 4,
};

const char* simd_path_name(SimdPath path);
// "auto", "scalar", "lanes2" (also "sse2", "neon"), "lanes4" (also "avx2") or "avx512".
Result<SimdPath> parse_simd_path(const std::string& name);
// The paths this CPU can run, narrowest first (never kAuto).
std::vector<SimdPath> supported_simd_paths();
// Forces a path (kAuto: the widest supported). Refused when the CPU cannot run it.
Status set_simd_path(SimdPath path);
// The path the solver uses now (never kAuto).
SimdPath active_simd_path();

}  // namespace fulcrum
