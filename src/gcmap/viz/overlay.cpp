#include "gcmap/viz/overlay.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "gcmap/viz/canvas.hpp"

namespace gcmap::viz {

namespace {

Eigen::Vector2d node_px(const RunGraph& g, const TopDown& v, int i) { return v.pixel(g.nodes[i].T_out_submap.translation()); }

// Dense matching-cost factors faint and below, the few loops bold and on top.
void draw_factors(Canvas& c, const RunGraph& g, const TopDown& v, double s) {
  for (FactorKind kind : kFactorKinds) {
    for (const GraphEdge& e : g.edges) {
      if (e.kind != kind) continue;
      const double w = std::clamp(e.weight, 0.0, 1.0);
      switch (kind) {
        case FactorKind::matching_cost: c.colour(palette::factor(kind), 0.45); break;
        case FactorKind::odometry: c.colour(palette::factor(kind), 0.9); break;
        case FactorKind::se3: c.colour(palette::factor(kind), 0.3 + 0.6 * w); break;
        case FactorKind::loop: c.colour(palette::factor(kind), 0.35 + 0.65 * w); break;
      }
      const double width = kind == FactorKind::loop ? 4.0 * s : kind == FactorKind::matching_cost ? 1.3 * s : 2.0 * s;
      c.line(node_px(g, v, e.source), node_px(g, v, e.target), width);
    }
  }
}

void draw_trajectory(Canvas& c, const Poses& traj, const TopDown& v, double s) {
  if (traj.empty()) return;
  cairo_t* cr = c.cr();
  c.colour(palette::trajectory);
  cairo_set_line_width(cr, std::max(3.0, 2.5 * s));  // >= 3 px: the pixel under a pose is fully covered
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  const Eigen::Vector2d p0 = v.pixel(traj.front().translation());
  cairo_move_to(cr, p0.x(), p0.y());
  for (const auto& T : traj) {
    const Eigen::Vector2d p = v.pixel(T.translation());
    cairo_line_to(cr, p.x(), p.y());
  }
  cairo_stroke(cr);
}

// Submap nodes, and the final kernel weight beside each explicit loop.
void draw_nodes(Canvas& c, const RunGraph& g, const TopDown& v, double s) {
  for (size_t i = 0; i < g.nodes.size(); ++i) {
    c.colour(palette::background);
    c.dot(node_px(g, v, static_cast<int>(i)), 5.5 * s);
    c.colour(palette::node);
    c.dot(node_px(g, v, static_cast<int>(i)), 4.0 * s);
  }
  for (const GraphEdge& e : g.edges) {
    if (e.kind != FactorKind::loop) continue;
    char label[32];
    std::snprintf(label, sizeof(label), "w %.2f", e.weight);
    const Eigen::Vector2d m = 0.5 * (node_px(g, v, e.source) + node_px(g, v, e.target)) + Eigen::Vector2d(8 * s, -8 * s);
    c.colour(palette::background, 0.75);
    c.rect(m.x() - 3 * s, m.y() - 17 * s, c.text_width(label, 17 * s) + 6 * s, 22 * s);
    c.colour(palette::factor(FactorKind::loop));
    c.text(m.x(), m.y(), label, 17 * s);
  }
}

// 1, 2 or 5 times a power of ten, at most `x`.
double nice_floor(double x) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * p <= x) return m * p;
  return p;
}

void draw_scale_bar(Canvas& c, const TopDown& v, double s) {
  const double metres = nice_floor(0.2 * v.width / v.pixels_per_m), len = metres * v.pixels_per_m;
  const double x = 24 * s, y = v.height - 24 * s;
  char label[32];
  std::snprintf(label, sizeof(label), "%g m", metres);
  c.colour(palette::background, 0.75);
  c.rect(x - 10 * s, y - 40 * s, len + 20 * s, 52 * s);
  c.colour(palette::text);
  c.rect(x, y - 6 * s, len, 6 * s);
  c.text(x + 0.5 * len, y - 14 * s, label, 20 * s, Align::center);
}

void draw_legend(Canvas& c, const std::vector<LegendEntry>& legend, const ColourScale* scale, double s) {
  const double fs = 20 * s, row = 1.6 * fs, swatch = 2.2 * fs, x = 24 * s, y = 24 * s;
  double text_w = scale ? c.text_width(scale->label, fs) + 4 * fs : 0.0;
  for (const LegendEntry& e : legend) text_w = std::max(text_w, c.text_width(e.label, fs));
  const double rows = legend.size() + (scale ? 2.0 : 0.0);
  c.colour(palette::background, 0.8);
  c.rect(x, y, swatch + text_w + 1.5 * fs, rows * row + fs);
  double yy = y + 0.5 * fs + 0.5 * row;
  for (const LegendEntry& e : legend) {
    c.colour(e.colour);
    const Eigen::Vector2d a(x + 0.5 * fs, yy), b(x + swatch, yy);
    if (e.dot) c.dot(0.5 * (a + b), 0.35 * fs);
    else c.line(a, b, e.factor == FactorKind::loop ? 4 * s : 3 * s);
    c.colour(palette::text);
    c.text(x + swatch + 0.5 * fs, yy + 0.35 * fs, e.label, fs);
    yy += row;
  }
  if (!scale) return;
  c.colour(palette::text);
  c.text(x + 0.5 * fs, yy + 0.35 * fs, scale->label, fs);
  const double gx = x + 0.5 * fs, gw = swatch + text_w, gy = yy + 0.6 * row;
  cairo_pattern_t* grad = cairo_pattern_create_linear(gx, 0, gx + gw, 0);
  for (int i = 0; i <= 10; ++i) {
    const Rgb k = colormap(i / 10.0);
    cairo_pattern_add_color_stop_rgb(grad, i / 10.0, k.r / 255.0, k.g / 255.0, k.b / 255.0);
  }
  cairo_set_source(c.cr(), grad);
  cairo_rectangle(c.cr(), gx, gy, gw, 0.5 * fs);
  cairo_fill(c.cr());
  cairo_pattern_destroy(grad);
  char lo[32], hi[32];
  std::snprintf(lo, sizeof(lo), "%.3g", scale->lo);
  std::snprintf(hi, sizeof(hi), "%.3g", scale->hi);
  c.colour(palette::text);
  c.text(x + c.text_width(scale->label, fs) + 1.5 * fs, yy + 0.35 * fs, std::string(lo) + " .. " + hi, fs);
}

}  // namespace

void draw_overlays(Image& image, const RunData& run, const TopDown& view, const RenderOptions& options,
                   const std::vector<LegendEntry>& legend, const ColourScale* scale, const std::string& note) {
  Canvas c(image);
  const double s = std::max(0.6, std::max(image.width, image.height) / 2000.0);
  if (options.graph) draw_factors(c, run.graph, view, s);
  draw_trajectory(c, run.trajectory, view, s);
  if (options.graph) draw_nodes(c, run.graph, view, s);
  draw_scale_bar(c, view, s);
  draw_legend(c, legend, scale, s);
  if (!note.empty()) {
    c.colour(palette::text);
    c.text(0.5 * image.width, 0.5 * image.height, note, 32 * s, Align::center);
  }
}

}  // namespace gcmap::viz
