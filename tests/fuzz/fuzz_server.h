// What the fuzz targets that drive the server share (requests, sessions, snapshot_stream).
#pragma once

#include <cstdint>
#include <map>
#include <utility>

#include "session.h"

namespace fulcrum::fuzz {

// Every world's id -> (tick, state hash): what a refused call must leave as it was.
inline std::map<uint64_t, std::pair<int64_t, uint64_t>> worlds(server::Registry& registry) {
  std::map<uint64_t, std::pair<int64_t, uint64_t>> out;
  for (const auto& session : registry.list()) {
    v1::WorldInfo info;
    session->info(&info);
    out[session->id()] = {info.tick(), info.state_hash()};
  }
  return out;
}

}  // namespace fulcrum::fuzz
