// `fulcrum sim --trace FILE`: the run's figures every k ticks, and the states of the bodies
// named, as CSV (one row per sample) or, when FILE ends in .jsonl, as JSON lines (one object
// per sample). Doubles carry 17 significant digits, so they read back to the same bits.
#pragma once

#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "fulcrum/status.h"
#include "fulcrum/world.h"

namespace fulcrum::cli {

class TraceWriter {
 public:
  // Opens (truncates) `path` and writes the CSV header. `bodies` are the handles traced.
  static Result<std::unique_ptr<TraceWriter>> open(const std::string& path,
                                                   std::vector<BodyId> bodies);

  // One sample of the world as it is now, with its metrics (taken by the caller).
  void write(const World& world, const WorldMetrics& metrics);
  // Flushes and closes; an error if any write failed (full disk, closed pipe).
  Status close();

 private:
  TraceWriter(const std::string& path, std::vector<BodyId> bodies, bool jsonl);

  std::string path_;
  std::vector<BodyId> bodies_;
  bool jsonl_ = false;
  std::ofstream out_;
};

}  // namespace fulcrum::cli
