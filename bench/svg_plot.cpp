#include "svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace fulcrum::bench {

namespace {

constexpr double kWidth = 680.0, kHeight = 440.0;
// The plot area; the legend sits to its right.
constexpr double kLeft = 78.0, kRight = 530.0, kTop = 38.0, kBottom = 372.0;
// Height of the "0" row under the y axis, for points whose error is exactly zero.
constexpr double kZeroRow = 16.0;
constexpr double kCharWidth = 5.4, kFontHeight = 9.0;  // 9 px sans-serif, estimated
const char* const kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// A log10 axis over [lo, hi] (decades), mapped onto pixels [p0, p1].
struct LogAxis {
  double lo = 0.0, hi = 1.0, p0 = 0.0, p1 = 1.0;
  double map(double v) const { return p0 + (std::log10(v) - lo) / (hi - lo) * (p1 - p0); }
};

// Padded decades around the positive values; at least one decade wide.
LogAxis make_axis(const std::vector<double>& values, double p0, double p1) {
  double lo = 1e300, hi = -1e300;
  for (double v : values) {
    if (!(v > 0.0) || !std::isfinite(v)) continue;
    lo = std::min(lo, std::log10(v));
    hi = std::max(hi, std::log10(v));
  }
  if (lo > hi) lo = -3.0, hi = 0.0;
  if (hi - lo < 1.0) {
    double mid = 0.5 * (lo + hi);
    lo = mid - 0.5, hi = mid + 0.5;
  }
  double pad = 0.06 * (hi - lo);
  return LogAxis{lo - pad, hi + pad, p0, p1};
}

// Tick values inside the axis: 1, 2, 5 per decade on short axes, decades on long ones.
std::vector<double> ticks(const LogAxis& a) {
  std::vector<double> out;
  double span = a.hi - a.lo;
  std::vector<double> mantissas =
      span <= 2.5 ? std::vector<double>{1, 2, 5} : std::vector<double>{1};
  int step = span > 7.0 ? 2 : 1;
  for (int k = static_cast<int>(std::floor(a.lo)); k <= static_cast<int>(std::ceil(a.hi)); ++k) {
    if (step > 1 && k % step != 0) continue;
    for (double m : mantissas) {
      double v = m * std::pow(10.0, k);
      double l = std::log10(v);
      if (l >= a.lo && l <= a.hi) out.push_back(v);
    }
  }
  return out;
}

std::string tick_label(double v) {
  double e = std::log10(v);
  if (v >= 1e-3 && v < 1e4) return fmt("%g", v);
  if (std::abs(e - std::round(e)) < 1e-9) return fmt("1e%.0f", std::round(e));
  return fmt("%.0e", v);
}

struct Box {
  double x0, y0, x1, y1;
  bool overlaps(const Box& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
};

}  // namespace

std::string to_svg(const SvgScatter& plot) {
  std::vector<double> xs, ys;
  bool has_zero = false;
  for (const SvgPoint& p : plot.points) {
    xs.push_back(p.x);
    ys.push_back(p.y);
    has_zero = has_zero || !(p.y > 0.0);
  }
  if (plot.y_limit) ys.push_back(*plot.y_limit);
  const double bottom = has_zero ? kBottom - kZeroRow : kBottom;
  const LogAxis ax = make_axis(xs, kLeft, kRight);
  const LogAxis ay = make_axis(ys, bottom, kTop);
  auto px = [&](double x) { return ax.map(x); };
  auto py = [&](double y) { return y > 0.0 ? ay.map(y) : kBottom - 0.5 * kZeroRow; };

  std::string s;
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + fmt("%.0f", kWidth) + "\" height=\"" +
       fmt("%.0f", kHeight) + "\" viewBox=\"0 0 " + fmt("%.0f", kWidth) + " " +
       fmt("%.0f", kHeight) + "\" font-family=\"sans-serif\" font-size=\"9\">\n";
  s += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s += "<text x=\"" + fmt("%.1f", 0.5 * (kLeft + kRight)) +
       "\" y=\"20\" text-anchor=\"middle\" font-size=\"13\">" + escape(plot.title) + "</text>\n";

  // Grid and tick labels.
  s += "<g stroke=\"#e4e4e4\">\n";
  for (double t : ticks(ax)) {
    s += "<line x1=\"" + fmt("%.1f", px(t)) + "\" y1=\"" + fmt("%.1f", kTop) + "\" x2=\"" +
         fmt("%.1f", px(t)) + "\" y2=\"" + fmt("%.1f", kBottom) + "\"/>\n";
  }
  for (double t : ticks(ay)) {
    s += "<line x1=\"" + fmt("%.1f", kLeft) + "\" y1=\"" + fmt("%.1f", py(t)) + "\" x2=\"" +
         fmt("%.1f", kRight) + "\" y2=\"" + fmt("%.1f", py(t)) + "\"/>\n";
  }
  s += "</g>\n<g fill=\"#333\">\n";
  for (double t : ticks(ax)) {
    s += "<text x=\"" + fmt("%.1f", px(t)) + "\" y=\"" + fmt("%.1f", kBottom + 13.0) +
         "\" text-anchor=\"middle\">" + tick_label(t) + "</text>\n";
  }
  for (double t : ticks(ay)) {
    s += "<text x=\"" + fmt("%.1f", kLeft - 5.0) + "\" y=\"" + fmt("%.1f", py(t) + 3.0) +
         "\" text-anchor=\"end\">" + tick_label(t) + "</text>\n";
  }
  if (has_zero) {
    s += "<text x=\"" + fmt("%.1f", kLeft - 5.0) + "\" y=\"" + fmt("%.1f", py(0.0) + 3.0) +
         "\" text-anchor=\"end\">0</text>\n";
  }
  s += "</g>\n";
  s += "<rect x=\"" + fmt("%.1f", kLeft) + "\" y=\"" + fmt("%.1f", kTop) + "\" width=\"" +
       fmt("%.1f", kRight - kLeft) + "\" height=\"" + fmt("%.1f", kBottom - kTop) +
       "\" fill=\"none\" stroke=\"#666\"/>\n";
  if (has_zero) {
    s += "<line x1=\"" + fmt("%.1f", kLeft) + "\" y1=\"" + fmt("%.1f", bottom) + "\" x2=\"" +
         fmt("%.1f", kRight) + "\" y2=\"" + fmt("%.1f", bottom) +
         "\" stroke=\"#999\" stroke-dasharray=\"2 2\"/>\n";
  }
  s += "<text x=\"" + fmt("%.1f", 0.5 * (kLeft + kRight)) + "\" y=\"" +
       fmt("%.1f", kBottom + 30.0) + "\" text-anchor=\"middle\" font-size=\"11\">" +
       escape(plot.x_label) + "</text>\n";
  s += "<text transform=\"translate(16 " + fmt("%.1f", 0.5 * (kTop + kBottom)) +
       ") rotate(-90)\" text-anchor=\"middle\" font-size=\"11\">" + escape(plot.y_label) +
       "</text>\n";

  if (plot.y_limit && *plot.y_limit > 0.0) {
    double y = py(*plot.y_limit);
    s += "<line x1=\"" + fmt("%.1f", kLeft) + "\" y1=\"" + fmt("%.1f", y) + "\" x2=\"" +
         fmt("%.1f", kRight) + "\" y2=\"" + fmt("%.1f", y) +
         "\" stroke=\"#c00\" stroke-dasharray=\"6 4\"/>\n";
    s += "<text x=\"" + fmt("%.1f", kRight - 4.0) + "\" y=\"" + fmt("%.1f", y - 4.0) +
         "\" text-anchor=\"end\" fill=\"#c00\">" + escape(plot.y_limit_label) + "</text>\n";
  }

  if (plot.line.size() >= 2) {
    s += "<polyline fill=\"none\" stroke=\"#222\" stroke-width=\"1.5\" points=\"";
    for (size_t i = 0; i < plot.line.size(); ++i) {
      s += (i ? " " : "") + fmt("%.1f", px(plot.line[i].first)) + "," +
           fmt("%.1f", py(plot.line[i].second));
    }
    s += "\"/>\n";
  }

  // Markers, then labels placed where they collide with no marker and no earlier label.
  std::vector<Box> taken;
  for (const SvgPoint& p : plot.points) {
    double x = px(p.x), y = py(p.y);
    double r = p.ringed ? 8.5 : 4.5;
    taken.push_back(Box{x - r, y - r, x + r, y + r});
    const char* colour = kPalette[static_cast<size_t>(p.group) % std::size(kPalette)];
    if (p.ringed) {
      s += "<circle cx=\"" + fmt("%.1f", x) + "\" cy=\"" + fmt("%.1f", y) +
           "\" r=\"8\" fill=\"none\" stroke=\"#111\" stroke-width=\"1.5\"/>\n";
    }
    s += "<circle cx=\"" + fmt("%.1f", x) + "\" cy=\"" + fmt("%.1f", y) + "\" r=\"4\" fill=\"" +
         (p.filled ? colour : "white") + "\" stroke=\"" + colour + "\" stroke-width=\"1.5\"/>\n";
  }
  struct Spot {
    double dx, dy;
    const char* anchor;
  };
  const Spot spots[] = {{7, 3, "start"},  {-7, 3, "end"},   {0, -8, "middle"},  {0, 13, "middle"},
                        {6, -6, "start"}, {6, 12, "start"}, {-6, -6, "end"},    {-6, 12, "end"},
                        {12, 3, "start"}, {-12, 3, "end"},  {0, -17, "middle"}, {0, 22, "middle"}};
  for (const SvgPoint& p : plot.points) {
    double x = px(p.x), y = py(p.y);
    double w = kCharWidth * static_cast<double>(p.label.size());
    Spot chosen = spots[0];
    for (const Spot& spot : spots) {
      double lx = x + spot.dx, ly = y + spot.dy;
      double x0 = std::string(spot.anchor) == "start" ? lx
                  : std::string(spot.anchor) == "end" ? lx - w
                                                      : lx - 0.5 * w;
      Box b{x0, ly - kFontHeight + 1.0, x0 + w, ly + 1.0};
      bool inside = b.x0 >= kLeft && b.x1 <= kRight && b.y0 >= kTop && b.y1 <= kBottom;
      bool clear =
          std::none_of(taken.begin(), taken.end(), [&](const Box& t) { return t.overlaps(b); });
      if (inside && clear) {
        chosen = spot;
        taken.push_back(b);
        break;
      }
    }
    s += "<text x=\"" + fmt("%.1f", x + chosen.dx) + "\" y=\"" + fmt("%.1f", y + chosen.dy) +
         "\" text-anchor=\"" + chosen.anchor + "\">" + escape(p.label) + "</text>\n";
  }

  // Legend.
  double ly = kTop + 6.0;
  const double lx = kRight + 14.0;
  auto legend_text = [&](const std::string& text) {
    s += "<text x=\"" + fmt("%.1f", lx + 14.0) + "\" y=\"" + fmt("%.1f", ly + 3.0) + "\">" +
         escape(text) + "</text>\n";
    ly += 15.0;
  };
  for (size_t g = 0; g < plot.groups.size(); ++g) {
    const char* colour = kPalette[g % std::size(kPalette)];
    s += "<circle cx=\"" + fmt("%.1f", lx + 4.0) + "\" cy=\"" + fmt("%.1f", ly) +
         "\" r=\"4\" fill=\"" + colour + "\"/>\n";
    legend_text(plot.groups[g]);
  }
  ly += 4.0;
  if (!plot.filled_label.empty()) {
    s += "<circle cx=\"" + fmt("%.1f", lx + 4.0) + "\" cy=\"" + fmt("%.1f", ly) +
         "\" r=\"4\" fill=\"#777\" stroke=\"#777\" stroke-width=\"1.5\"/>\n";
    legend_text(plot.filled_label);
  }
  if (!plot.hollow_label.empty()) {
    s += "<circle cx=\"" + fmt("%.1f", lx + 4.0) + "\" cy=\"" + fmt("%.1f", ly) +
         "\" r=\"4\" fill=\"white\" stroke=\"#777\" stroke-width=\"1.5\"/>\n";
    legend_text(plot.hollow_label);
  }
  if (!plot.ring_label.empty()) {
    s += "<circle cx=\"" + fmt("%.1f", lx + 4.0) + "\" cy=\"" + fmt("%.1f", ly) +
         "\" r=\"7\" fill=\"none\" stroke=\"#111\" stroke-width=\"1.5\"/>\n";
    legend_text(plot.ring_label);
  }
  if (!plot.line_label.empty()) {
    s += "<line x1=\"" + fmt("%.1f", lx - 2.0) + "\" y1=\"" + fmt("%.1f", ly) + "\" x2=\"" +
         fmt("%.1f", lx + 10.0) + "\" y2=\"" + fmt("%.1f", ly) +
         "\" stroke=\"#222\" stroke-width=\"1.5\"/>\n";
    legend_text(plot.line_label);
  }
  if (plot.y_limit && !plot.y_limit_label.empty()) {
    s += "<line x1=\"" + fmt("%.1f", lx - 2.0) + "\" y1=\"" + fmt("%.1f", ly) + "\" x2=\"" +
         fmt("%.1f", lx + 10.0) + "\" y2=\"" + fmt("%.1f", ly) +
         "\" stroke=\"#c00\" stroke-dasharray=\"4 2\"/>\n";
    legend_text(plot.y_limit_label);
  }
  if (!plot.note.empty()) {
    s += "<text x=\"" + fmt("%.1f", kLeft) + "\" y=\"" + fmt("%.1f", kHeight - 10.0) +
         "\" fill=\"#555\">" + escape(plot.note) + "</text>\n";
  }
  s += "</svg>\n";
  return s;
}

}  // namespace fulcrum::bench
