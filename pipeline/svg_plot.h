// Small line plots as inline SVG for the run report (pipeline/report.h):
// crisp at any zoom, no network, no plotting library.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace hmc {

struct PlotSeries {
  std::string name;
  std::vector<std::pair<double, double>> points;  // (x, y); non-finite y breaks the line
};

struct PlotOptions {
  std::string title;
  std::string x_label = "frame";
  std::string y_label;
  int width = 640;   // px
  int height = 220;  // px
  bool y_from_zero = false;  // include 0 in the y range
};

// `text` with <, >, & and " escaped, for HTML text and attribute values.
std::string HtmlEscape(const std::string& text);

// An <svg> element: axes with ticks, one polyline per series (a fixed
// colour-blind-safe palette), a legend. Empty series are skipped; with no
// points at all, a note saying so.
std::string SvgLinePlot(const std::vector<PlotSeries>& series, const PlotOptions& options);

}  // namespace hmc
