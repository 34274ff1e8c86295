// Shared by Fulcrum's fuzz targets (docs/fuzzing.md): the limits worlds are built under, and the
// checks every input must pass. A failed check prints what is wrong and aborts, which libFuzzer
// (or the standalone driver, standalone_main.cpp) reports as a crash with the input saved.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>

#include "edit_convert.h"
#include "fulcrum/scene.h"
#include "fulcrum/world.h"
#include "world_checks.h"

namespace fulcrum::fuzz {

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

inline void check(bool ok, const std::string& what) {
  if (!ok) fail(what);
}

// A refusal must say what it refused: a code and a message.
inline void check_refusal(const Status& s, const char* where) {
  check(!s.ok(), std::string(where) + ": not a refusal");
  check(!s.message().empty(), std::string(where) + ": a refusal without a message");
}

// Small limits, so that one input stays cheap (a fuzzer runs thousands a second): the server's
// limits work the same way at their larger defaults (tests/server/hardening_test.cpp).
inline EditLimits limits() {
  EditLimits l;
  l.max_bodies = 512;
  l.max_shapes = 2048;
  l.max_shapes_per_body = 64;
  l.max_work = 200000;
  l.max_edits = 256;
  return l;
}

// world_checks.h, aborting with `where` on a problem.
inline void check_world(const World& w, const std::string& where) {
  const std::string problem = checks::world_problem(w);
  if (!problem.empty()) fail(where + ": " + problem);
}

// Steps an accepted world a few ticks, checking it after each.
inline void step_and_check(World& w, int ticks, const std::string& where) {
  check_world(w, where + ", as accepted");
  for (int t = 0; t < ticks; ++t) {
    Status s = w.try_step();
    if (!s.ok()) {
      // Only the contact limit may refuse a tick, and a refused tick changes nothing.
      check(s.code() == StatusCode::kResourceExhausted, where + ": try_step: " + s.message());
      return;
    }
    check_world(w, where + ", after tick " + std::to_string(w.tick()));
  }
}

// Builds a decoded scene under limits(): a refusal says why; an accepted world passes
// check_world before and after each of a few ticks. Returns the initial state hash, none when
// refused.
inline std::optional<uint64_t> run_scene(const SceneDef& scene, const std::string& where) {
  Result<World> built = build_world(scene, limits());
  if (!built.ok()) {
    check_refusal(built.status(), (where + ": build_world").c_str());
    return std::nullopt;
  }
  World w = std::move(built).value();
  const uint64_t initial = w.state_hash();
  check(w.set_contact_limit(4096).ok(), "set_contact_limit");
  step_and_check(w, 3, where);
  return initial;
}

// FULCRUM_FUZZ_PRINT=1: print each decoded message in text format (to read a finding).
inline void print(const google::protobuf::Message& m) {
  if (std::getenv("FULCRUM_FUZZ_PRINT") != nullptr) {
    std::fprintf(stderr, "%s: %s\n", m.GetTypeName().c_str(), m.DebugString().c_str());
  }
}

inline std::string_view bytes(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

}  // namespace fulcrum::fuzz
