#include "gcmap/viz/chart.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace gcmap::viz {

namespace {

constexpr Rgb kInk{30, 30, 30}, kGrid{225, 225, 225}, kFrame{120, 120, 120};
constexpr double kFont = 15.0;

std::string tick_label(double v, double step) {
  char buf[32];
  const int decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
  std::snprintf(buf, sizeof(buf), "%.*f", std::min(decimals, 6), std::abs(v) < 1e-12 * step ? 0.0 : v);
  return buf;
}

struct Range {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  void finish(bool from_zero) {
    if (lo > hi) lo = 0, hi = 1;
    if (from_zero) lo = std::min(lo, 0.0), hi = std::max(hi, 0.0);
    if (hi - lo < 1e-12) hi = lo + 1.0;
    const double pad = 0.04 * (hi - lo);
    if (!(from_zero && lo == 0.0)) lo -= pad;
    hi += pad;
  }
  void widen_to(double span) {
    const double c = 0.5 * (lo + hi);
    lo = c - 0.5 * span, hi = c + 0.5 * span;
  }
};

void draw_title(Canvas& c, const std::string& title, const Rect& a) {
  c.colour(kInk);
  c.text(a.x + 0.5 * a.w, a.y + 22, title, kFont + 3, Align::center);
}

// One row of legend items between the title and the plot, outside the data.
void draw_legend(Canvas& c, const std::vector<Series>& series, const Rect& plot) {
  double width = 0;
  for (const auto& s : series) width += 50 + c.text_width(s.label, kFont);
  double x = plot.x + 0.5 * (plot.w - width);
  const double y = plot.y - 14;
  for (const auto& s : series) {
    c.colour(s.colour);
    c.line({x + 4, y}, {x + 32, y}, 3.0);
    c.colour(kInk);
    c.text(x + 38, y + 0.35 * kFont, s.label, kFont);
    x += 50 + c.text_width(s.label, kFont);
  }
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  const double raw = (hi - lo) / std::max(1, target), p = std::pow(10.0, std::floor(std::log10(raw)));
  double step = 10 * p;
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) {
      step = m * p;
      break;
    }
  std::vector<double> out;
  for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; k += 1.0) out.push_back(k * step);
  return out;
}

void draw_line_chart(Canvas& c, const LineChart& chart, const Rect& a) {
  const double legend_h = chart.series.size() > 1 ? 28 : 0;
  const Rect plot{a.x + 80, a.y + 40 + legend_h, a.w - 100, a.h - 95 - legend_h};
  Range rx, ry;
  for (const auto& s : chart.series) {
    for (double v : s.x) rx.add(v);
    for (double v : s.y) ry.add(v);
  }
  rx.finish(false);
  if (std::isfinite(chart.x_min) && std::isfinite(chart.x_max)) rx.lo = chart.x_min, rx.hi = chart.x_max;
  ry.finish(chart.y_from_zero);
  if (chart.equal_aspect) {
    const double m_per_px = std::max((rx.hi - rx.lo) / plot.w, (ry.hi - ry.lo) / plot.h);
    rx.widen_to(m_per_px * plot.w);
    ry.widen_to(m_per_px * plot.h);
  }
  auto px = [&](double x, double y) {
    return Eigen::Vector2d(plot.x + (x - rx.lo) / (rx.hi - rx.lo) * plot.w,
                           plot.y + plot.h - (y - ry.lo) / (ry.hi - ry.lo) * plot.h);
  };
  draw_title(c, chart.title, a);
  const auto xt = nice_ticks(rx.lo, rx.hi, 6), yt = nice_ticks(ry.lo, ry.hi, 5);
  for (double t : xt) {
    c.colour(kGrid);
    c.line(px(t, ry.lo), px(t, ry.hi), 1.0);
    c.colour(kInk);
    c.text(px(t, ry.lo).x(), plot.y + plot.h + 20, tick_label(t, xt.size() > 1 ? xt[1] - xt[0] : 1.0), kFont, Align::center);
  }
  for (double t : yt) {
    c.colour(kGrid);
    c.line(px(rx.lo, t), px(rx.hi, t), 1.0);
    c.colour(kInk);
    c.text(plot.x - 8, px(rx.lo, t).y() + 5, tick_label(t, yt.size() > 1 ? yt[1] - yt[0] : 1.0), kFont, Align::right);
  }
  c.colour(kInk);
  c.text(plot.x + 0.5 * plot.w, plot.y + plot.h + 45, chart.x_label, kFont + 1, Align::center);
  c.text(a.x + 20, plot.y + 0.5 * plot.h, chart.y_label, kFont + 1, Align::center, true);
  cairo_t* cr = c.cr();
  cairo_save(cr);
  cairo_rectangle(cr, plot.x, plot.y, plot.w, plot.h);
  cairo_clip(cr);
  for (const auto& s : chart.series) {
    c.colour(s.colour);
    cairo_set_line_width(cr, s.width);
    cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      const Eigen::Vector2d p = px(s.x[i], s.y[i]);
      if (i == 0) cairo_move_to(cr, p.x(), p.y());
      else cairo_line_to(cr, p.x(), p.y());
    }
    cairo_stroke(cr);
    if (s.markers)
      for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) c.dot(px(s.x[i], s.y[i]), 3.5);
  }
  cairo_restore(cr);
  c.colour(kFrame);
  cairo_set_line_width(cr, 1.0);
  cairo_rectangle(cr, plot.x, plot.y, plot.w, plot.h);
  cairo_stroke(cr);
  if (chart.series.size() > 1) draw_legend(c, chart.series, plot);
}

void draw_bar_chart(Canvas& c, const BarChart& chart, const Rect& a) {
  double label_w = 0, note_w = 0, hi = 0;
  for (const Bar& b : chart.bars) {
    label_w = std::max(label_w, c.text_width(b.label, kFont));
    note_w = std::max(note_w, c.text_width(b.annotation, kFont - 2));
    hi = std::max(hi, b.value + b.error);
  }
  const Rect plot{a.x + label_w + 20, a.y + 40, a.w - label_w - note_w - 50, a.h - 95};
  const auto ticks = nice_ticks(0.0, hi > 0 ? hi : 1.0, 5);
  const double top = std::max(ticks.back(), hi > 0 ? hi : 1.0);
  auto vx = [&](double v) { return plot.x + v / top * plot.w; };
  draw_title(c, chart.title, a);
  for (double t : ticks) {
    c.colour(kGrid);
    c.line({vx(t), plot.y}, {vx(t), plot.y + plot.h}, 1.0);
    c.colour(kInk);
    c.text(vx(t), plot.y + plot.h + 20, tick_label(t, ticks.size() > 1 ? ticks[1] - ticks[0] : 1.0), kFont, Align::center);
  }
  c.text(plot.x + 0.5 * plot.w, plot.y + plot.h + 45, chart.value_label, kFont + 1, Align::center);
  const double row = plot.h / std::max<size_t>(1, chart.bars.size());
  for (size_t i = 0; i < chart.bars.size(); ++i) {
    const Bar& b = chart.bars[i];
    const double y = plot.y + row * (i + 0.5);
    c.colour(chart_colours::odometry);
    c.rect(plot.x, y - 0.3 * row, vx(b.value) - plot.x, 0.6 * row);
    if (b.error > 0) {
      c.colour(kInk);
      c.line({vx(std::max(0.0, b.value - b.error)), y}, {vx(b.value + b.error), y}, 1.5);
    }
    c.colour(kInk);
    c.text(plot.x - 10, y + 5, b.label, kFont, Align::right);
    c.text(vx(std::max(b.value + b.error, b.value)) + 8, y + 5, b.annotation, kFont - 2);
  }
}

void draw_message(Canvas& c, const std::string& title, const std::string& message, const Rect& a) {
  draw_title(c, title, a);
  c.colour(kFrame);
  c.text(a.x + 0.5 * a.w, a.y + 0.5 * a.h, message, kFont + 1, Align::center);
}

}  // namespace gcmap::viz
