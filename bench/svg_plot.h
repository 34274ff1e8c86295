// A small SVG writer for the speed-against-error plots of fulcrum_sweep: one scatter plot on
// log-log axes with labelled points, a polyline (the Pareto front) and a horizontal limit line.
// Written by hand rather than pulled from a plotting library: the plots are a few hundred
// lines of SVG, and a dependency would have to be installed on every machine that runs the
// benchmarks.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace fulcrum::bench {

struct SvgPoint {
  double x = 0.0;  // data units, > 0 (log axis)
  double y = 0.0;  // data units; values <= 0 are drawn on a "0" row under the lowest tick
  std::string label;
  int group = 0;        // index into SvgScatter::groups: the marker colour
  bool filled = true;   // filled marker (for example: passes), hollow otherwise
  bool ringed = false;  // a ring around the marker (for example: the cheapest passing point)
};

struct SvgScatter {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<std::string> groups;  // legend entries, by SvgPoint::group
  std::vector<SvgPoint> points;
  // A polyline through these data points, in order (for example: the Pareto front).
  std::vector<std::pair<double, double>> line;
  std::string line_label;
  // A dashed horizontal line at this y (for example: the pass limit).
  std::optional<double> y_limit;
  std::string y_limit_label;
  std::string filled_label;  // legend text for filled markers ("" leaves it out)
  std::string hollow_label;  // legend text for hollow markers
  std::string ring_label;    // legend text for the ring
  std::string note;          // one line of small print under the plot
};

// The whole SVG document. Both axes are log10, each spanning at least one decade.
std::string to_svg(const SvgScatter& plot);

}  // namespace fulcrum::bench
