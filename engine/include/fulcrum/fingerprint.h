// The engine's determinism fingerprint. Fulcrum steps a world to the same bits on every build
// of the same engine (any compiler, optimisation level, instruction path, thread count or
// machine), so what can make two copies of a world differ is a change to the engine itself.
// The fingerprint names the results a build gives: it changes whenever the results do (the
// golden hashes of tests/golden are re-pinned in the same commit, and golden_test checks the
// two together). Clients state it when they join a multiplayer session; a mismatch is refused
// up front instead of desynchronising later.
#pragma once

namespace fulcrum {

// "fulcrum-results-N": N counts the changes to the engine's results.
inline constexpr const char kDeterminismFingerprint[] = "fulcrum-results-18";

}  // namespace fulcrum
