#pragma once
// Line and bar charts on a Canvas: nice ticks, grid, axis labels with units, a legend.
#include <cmath>
#include <string>
#include <vector>

#include "gcmap/viz/canvas.hpp"

namespace gcmap::viz {

struct Series {
  std::string label;
  std::vector<double> x, y;
  Rgb colour;
  bool markers = false;
  double width = 2.0;  // line width in pixels
};

struct LineChart {
  std::string title, x_label, y_label;  // labels with units: "submaps", "time [ms]"
  std::vector<Series> series;
  bool equal_aspect = false;  // metres on both axes
  bool y_from_zero = true;
  double x_min = NAN, x_max = NAN;  // fixed x range where finite
};

struct Bar {
  std::string label;
  double value = 0.0, error = 0.0;  // error: half-length of the whisker
  std::string annotation;           // printed after the bar
};

struct BarChart {
  std::string title, value_label;  // value_label with its unit
  std::vector<Bar> bars;           // drawn top to bottom, horizontally
};

struct Rect {
  double x = 0, y = 0, w = 0, h = 0;
};

void draw_line_chart(Canvas& c, const LineChart& chart, const Rect& area);
void draw_bar_chart(Canvas& c, const BarChart& chart, const Rect& area);
// A chart-sized message where there is nothing to plot.
void draw_message(Canvas& c, const std::string& title, const std::string& message, const Rect& area);

// Ticks at 1, 2 or 5 times a power of ten covering [lo, hi] with about `target` intervals.
std::vector<double> nice_ticks(double lo, double hi, int target = 5);

// Colours the figures share.
namespace chart_colours {
inline constexpr Rgb estimate{214, 39, 40};
inline constexpr Rgb odometry{31, 119, 180};
inline constexpr Rgb ground_truth{170, 170, 170};
inline constexpr Rgb accent{44, 160, 44};
}  // namespace chart_colours

}  // namespace gcmap::viz
