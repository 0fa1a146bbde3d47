#include "pipeline/svg_plot.h"

#include <cmath>

#include <gtest/gtest.h>

namespace hmc {
namespace {

size_t Count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

TEST(SvgPlotTest, OnePathPerSeriesAndGapsAtNonFiniteValues) {
  PlotSeries a{"a <b>", {{1, 0.5}, {2, 0.7}, {3, std::nan("")}, {4, 0.2}}};
  PlotSeries b{"b", {{1, 1}, {4, 2}}};
  PlotSeries empty{"empty", {}};
  const std::string svg = SvgLinePlot({a, b, empty}, {"t", "frame", "mm", 400, 200, true});
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_EQ(Count(svg, "<path"), 2u);
  // The NaN breaks series a into two pieces: two moves, two line-tos.
  const size_t start = svg.find("<path d=\"");
  const std::string d = svg.substr(start, svg.find('"', start + 9) - start);
  EXPECT_EQ(Count(d, "M"), 2u);
  EXPECT_EQ(Count(d, "L"), 1u);
  EXPECT_NE(svg.find("a &lt;b&gt;"), std::string::npos);  // escaped legend
  EXPECT_EQ(svg.find("a <b>"), std::string::npos);
}

TEST(SvgPlotTest, NoPointsSaysSo) {
  const std::string svg = SvgLinePlot({{"x", {}}}, {});
  EXPECT_NE(svg.find("no data"), std::string::npos);
  EXPECT_EQ(Count(svg, "<path"), 0u);
}

}  // namespace
}  // namespace hmc
