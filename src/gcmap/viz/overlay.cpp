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

// In the legend panel's bottom-left corner, at most `max_len` pixels long.
void draw_scale_bar(Canvas& c, const TopDown& v, double s, double x, double bottom, double max_len) {
  const double metres = nice_floor(max_len / v.pixels_per_m), len = metres * v.pixels_per_m, y = bottom - 24 * s;
  char label[32];
  std::snprintf(label, sizeof(label), "scale: %g m", metres);
  c.colour(palette::text);
  c.rect(x, y - 6 * s, len, 6 * s);
  c.rect(x, y - 14 * s, 2 * s, 14 * s);
  c.rect(x + len - 2 * s, y - 14 * s, 2 * s, 14 * s);
  c.text(x, y - 22 * s, label, 20 * s);
}

struct LegendLayout {
  double s, fs, row, swatch, text_w;
  double width() const { return swatch + text_w + 2.5 * fs; }
  // Entries, the colour scale and the scale bar below them.
  double height(size_t entries, bool scale) const { return (entries + (scale ? 2.0 : 0.0) + 3.0) * row + 2 * fs; }
};

std::string scale_range(const ColourScale& scale) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.3g .. %.3g", scale.lo, scale.hi);
  return buf;
}

LegendLayout legend_layout(const std::vector<LegendEntry>& legend, const ColourScale* scale, double s) {
  Image scratch(1, 1, palette::background);
  Canvas c(scratch);
  LegendLayout l{s, 20 * s, 32 * s, 44 * s, 0.0};
  if (scale) l.text_w = c.text_width(scale->label + "  " + scale_range(*scale), l.fs) - l.swatch + 0.5 * l.fs;
  for (const LegendEntry& e : legend) l.text_w = std::max(l.text_w, c.text_width(e.label, l.fs));
  return l;
}

void draw_legend(Canvas& c, const LegendLayout& l, const std::vector<LegendEntry>& legend, const ColourScale* scale, double x) {
  double y = l.fs + 0.5 * l.row;
  for (const LegendEntry& e : legend) {
    c.colour(e.colour);
    const Eigen::Vector2d a(x, y), b(x + l.swatch - 0.5 * l.fs, y);
    if (e.dot) c.dot(0.5 * (a + b), 0.35 * l.fs);
    else c.line(a, b, e.factor == FactorKind::loop ? 4 * l.s : 3 * l.s);
    c.colour(palette::text);
    c.text(x + l.swatch, y + 0.35 * l.fs, e.label, l.fs);
    y += l.row;
  }
  if (!scale) return;
  c.colour(palette::text);
  c.text(x, y + 0.35 * l.fs, scale->label + "  " + scale_range(*scale), l.fs);
  const double gw = l.swatch + l.text_w - 0.5 * l.fs, gy = y + 0.6 * l.row;
  cairo_pattern_t* grad = cairo_pattern_create_linear(x, 0, x + gw, 0);
  for (int i = 0; i <= 10; ++i) {
    const Rgb k = colormap(i / 10.0);
    cairo_pattern_add_color_stop_rgb(grad, i / 10.0, k.r / 255.0, k.g / 255.0, k.b / 255.0);
  }
  cairo_set_source(c.cr(), grad);
  cairo_rectangle(c.cr(), x, gy, gw, 0.5 * l.fs);
  cairo_fill(c.cr());
  cairo_pattern_destroy(grad);
}

}  // namespace

Image compose_picture(const Image& raster, const RunData& run, const TopDown& view, const RenderOptions& options,
                      const std::vector<LegendEntry>& legend, const ColourScale* scale, const std::string& note) {
  const double s = std::max(0.6, std::max(raster.width, raster.height) / 2000.0);
  const LegendLayout layout = legend_layout(legend, scale, s);
  const int height = std::max(raster.height, static_cast<int>(std::ceil(layout.height(legend.size(), scale))));
  Image pic(raster.width + static_cast<int>(std::ceil(layout.width())), height, palette::panel);
  for (int y = 0; y < raster.height; ++y)
    std::copy_n(raster.pixels.begin() + static_cast<size_t>(y) * raster.width, raster.width,
                pic.pixels.begin() + static_cast<size_t>(y) * pic.width);
  Canvas c(pic);
  cairo_rectangle(c.cr(), 0, 0, raster.width, raster.height);
  cairo_clip(c.cr());
  if (options.graph) draw_factors(c, run.graph, view, s);
  draw_trajectory(c, run.trajectory, view, s);
  if (options.graph) draw_nodes(c, run.graph, view, s);
  if (!note.empty()) {
    c.colour(palette::text);
    c.text(0.5 * raster.width, 0.5 * raster.height, note, 32 * s, Align::center);
  }
  cairo_reset_clip(c.cr());
  draw_legend(c, layout, legend, scale, raster.width + layout.fs);
  draw_scale_bar(c, view, s, raster.width + layout.fs, pic.height, layout.width() - 2 * layout.fs);
  return pic;
}

}  // namespace gcmap::viz
