// Small text helpers shared by the benchmark binaries that write reports (fulcrum_sweep,
// fulcrum_box2d_compare): how figures are printed, how list flags are read, and the machine's
// load for a report's header.
#pragma once

#include <string>
#include <vector>

namespace fulcrum::bench {

// "%.3g" by default: how every figure in a report and a failure message is printed.
std::string num(double v, int digits = 3);

// "a,b,,c" -> {"a", "b", "c"}: a comma-separated flag value, empty items dropped.
std::vector<std::string> split_list(const std::string& list);

// The 1, 5 and 15 minute load averages ("0.12 0.3 0.25"), or "unknown" off Linux.
std::string load_average();

}  // namespace fulcrum::bench
