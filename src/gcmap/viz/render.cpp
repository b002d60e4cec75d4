#include "gcmap/viz/render.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "gcmap/core/error.hpp"
#include "gcmap/core/kdtree.hpp"
#include "gcmap/viz/overlay.hpp"

namespace gcmap::viz {

namespace {

constexpr double kMargin = 0.04;  // of the longer side, around the content

// The points seen from above, per pixel.
struct Grid {
  std::vector<float> top;    // highest z, -inf where empty
  std::vector<float> value;  // intensity sum
  std::vector<uint32_t> count;
};

// Pixel of every point (kNone outside the picture), in parallel.
constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
std::vector<uint32_t> pixel_of_points(const PointCloud& map, const TopDown& v) {
  std::vector<uint32_t> pixel(map.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, map.size(), 1 << 15), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const Eigen::Vector3f& p = map.points[i];
      const double px = (p.x() - v.min_x) * v.pixels_per_m, py = (v.max_y - p.y()) * v.pixels_per_m;
      pixel[i] = px >= 0 && py >= 0 && px < v.width && py < v.height
                     ? static_cast<uint32_t>(static_cast<size_t>(py) * v.width + static_cast<size_t>(px))
                     : kNone;
    }
  });
  return pixel;
}

// Point indices grouped by band of kBandPixels pixels, in cloud order within each band (a stable
// counting sort over fixed chunks of points); `start` holds each band's first position.
constexpr size_t kBandPixels = 1 << 18;  // 2 MB of top + count: a band's grid stays in cache
std::vector<uint32_t> points_by_band(const std::vector<uint32_t>& pixel, size_t bands, std::vector<size_t>& start) {
  constexpr size_t kChunk = 1 << 16;
  const size_t chunks = (pixel.size() + kChunk - 1) / kChunk;
  std::vector<size_t> at(chunks * bands, 0);  // [chunk][band]: count, then write position
  const auto each_point = [&](size_t c, auto&& f) {
    for (size_t i = c * kChunk; i < std::min(pixel.size(), (c + 1) * kChunk); ++i)
      if (pixel[i] != kNone) f(i, pixel[i] / kBandPixels);
  };
  tbb::parallel_for(size_t{0}, chunks, [&](size_t c) { each_point(c, [&](size_t, size_t b) { ++at[c * bands + b]; }); });
  start.assign(bands + 1, 0);
  size_t pos = 0;
  for (size_t b = 0; b < bands; ++b) {
    start[b] = pos;
    for (size_t c = 0; c < chunks; ++c) pos += std::exchange(at[c * bands + b], pos);
  }
  start[bands] = pos;
  std::vector<uint32_t> order(pos);
  tbb::parallel_for(size_t{0}, chunks, [&](size_t c) {
    each_point(c, [&](size_t i, size_t b) { order[at[c * bands + b]++] = static_cast<uint32_t>(i); });
  });
  return order;
}

// Bands of pixels in parallel, each pixel seeing its points in cloud order: the intensity sums
// (and the PNG bytes) do not depend on the thread count.
Grid accumulate(const PointCloud& map, const TopDown& v, bool intensity) {
  const size_t n = static_cast<size_t>(v.width) * v.height;
  Grid g{std::vector<float>(n, -std::numeric_limits<float>::infinity()), std::vector<float>(intensity ? n : 0, 0.0f),
         std::vector<uint32_t>(n, 0)};
  if (map.size() >= kNone) throw Error("render: more than 4 billion map points");
  const std::vector<uint32_t> pixel = pixel_of_points(map, v);
  const size_t bands = (n + kBandPixels - 1) / kBandPixels;
  std::vector<size_t> start;
  const std::vector<uint32_t> order = points_by_band(pixel, bands, start);
  tbb::parallel_for(size_t{0}, bands, [&](size_t b) {
    for (size_t j = start[b]; j < start[b + 1]; ++j) {
      const uint32_t i = order[j], k = pixel[i];
      g.top[k] = std::max(g.top[k], map.points[i].z());
      ++g.count[k];
      if (intensity) g.value[k] += map.intensities[i];
    }
  });
  return g;
}

// [q, 1-q] quantiles, so that a few outliers do not flatten the colours.
std::pair<double, double> robust_range(std::vector<float> v, double q = 0.02) {
  if (v.empty()) return {0.0, 1.0};
  const auto at = [&](double f) {
    auto it = v.begin() + static_cast<std::ptrdiff_t>(f * (v.size() - 1));
    std::nth_element(v.begin(), it, v.end());
    return static_cast<double>(*it);
  };
  const double lo = at(q), hi = at(1.0 - q);
  return {lo, hi > lo ? hi : lo + 1.0};
}

// Submap of every trajectory frame: the last one whose first frame is not after it.
std::vector<int> frame_submaps(const RunData& run) {
  if (run.graph.nodes.empty()) throw Error("color submap: graph.json lists no submaps");
  const int f0 = run.graph.nodes.front().first_frame;
  std::vector<int> out(run.trajectory.size());
  size_t s = 0;
  for (size_t f = 0; f < out.size(); ++f) {
    while (s + 1 < run.graph.nodes.size() && run.graph.nodes[s + 1].first_frame - f0 <= static_cast<int>(f)) ++s;
    out[f] = static_cast<int>(s);
  }
  return out;
}

// Colour of each occupied pixel from the submap of the nearest trajectory frame (in x, y).
void colour_by_submap(Image& img, const Grid& g, const RunData& run, const TopDown& v, const std::vector<float>& shade) {
  const std::vector<int> submap_of = frame_submaps(run);
  std::vector<Eigen::Vector3f> xy;
  for (const auto& T : run.trajectory) xy.emplace_back(T.translation().x(), T.translation().y(), 0.0f);
  if (xy.empty()) throw Error("color submap: the trajectory is empty");
  const KdTree tree(xy);
  tbb::parallel_for(0, v.height, [&](int y) {
    for (int x = 0; x < v.width; ++x) {
      const size_t k = static_cast<size_t>(y) * v.width + x;
      if (!g.count[k]) continue;
      const Eigen::Vector3f q(v.min_x + (x + 0.5) / v.pixels_per_m, v.max_y - (y + 0.5) / v.pixels_per_m, 0.0f);
      uint32_t i;
      float d;
      tree.knn(q, 1, &i, &d);
      img.set(x, y, scaled(category_colour(submap_of[i]), shade[k]));
    }
  });
}

// Rasterizes the map onto the background; returns the colour scale used (none for submap colours).
std::optional<ColourScale> rasterize(Image& img, const RunData& run, const TopDown& v, ColorMode mode) {
  const bool intensity = mode == ColorMode::intensity;
  const Grid g = accumulate(run.map, v, intensity);
  std::vector<float> values, counts;
  for (size_t k = 0; k < g.count.size(); ++k) {
    if (!g.count[k]) continue;
    values.push_back(intensity ? g.value[k] / g.count[k] : g.top[k]);
    counts.push_back(static_cast<float>(g.count[k]));
  }
  // Denser pixels (walls, poles) brighter: a shade in [0.55, 1] from log(count).
  const double dense = std::log1p(std::max(1.0, robust_range(counts, 0.1).second));
  std::vector<float> shade(g.count.size(), 0.0f);
  for (size_t k = 0; k < g.count.size(); ++k)
    if (g.count[k]) shade[k] = static_cast<float>(0.55 + 0.45 * std::min(1.0, std::log1p(g.count[k]) / dense));
  if (values.empty()) return std::nullopt;  // an empty map has no colour scale
  if (mode == ColorMode::submap) {
    colour_by_submap(img, g, run, v, shade);
    return std::nullopt;
  }
  const auto [lo, hi] = robust_range(values);
  tbb::parallel_for(0, v.height, [&](int y) {
    for (int x = 0; x < v.width; ++x) {
      const size_t k = static_cast<size_t>(y) * v.width + x;
      if (!g.count[k]) continue;
      const double value = intensity ? g.value[k] / g.count[k] : g.top[k];
      img.set(x, y, scaled(colormap((value - lo) / (hi - lo)), shade[k]));
    }
  });
  return ColourScale{intensity ? "intensity" : "height [m]", lo, hi};
}

// x, y extent of the points (min and max are exact in any order: parallel).
Eigen::AlignedBox2d points_box(const PointCloud& map) {
  using Box = Eigen::AlignedBox2f;
  const Box box = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, map.size(), 1 << 15), Box(),
      [&](const tbb::blocked_range<size_t>& r, Box b) {
        for (size_t i = r.begin(); i < r.end(); ++i) b.extend(map.points[i].head<2>());
        return b;
      },
      [](Box a, const Box& b) { return a.extend(b); });
  return box.isEmpty() ? Eigen::AlignedBox2d() : Eigen::AlignedBox2d(box.min().cast<double>(), box.max().cast<double>());
}

}  // namespace

std::vector<Rgb> point_colours(const PointCloud& cloud, ColorMode mode, const std::vector<uint16_t>& submap_of) {
  std::vector<Rgb> out(cloud.size());
  if (mode == ColorMode::submap) {
    if (submap_of.size() != cloud.size()) throw Error("colour by submap: the points' submaps are not known");
    for (size_t i = 0; i < out.size(); ++i) out[i] = category_colour(submap_of[i]);
    return out;
  }
  if (mode == ColorMode::intensity && !cloud.has_intensities()) throw Error("colour by intensity: the points have none");
  std::vector<float> values(cloud.size());
  for (size_t i = 0; i < values.size(); ++i)
    values[i] = mode == ColorMode::intensity ? cloud.intensities[i] : cloud.points[i].z();
  if (values.empty()) return out;
  const auto [lo, hi] = robust_range(values);
  tbb::parallel_for(size_t(0), out.size(), [&](size_t i) { out[i] = colormap((values[i] - lo) / (hi - lo)); });
  return out;
}

ColorMode parse_color_mode(const std::string& name) {
  if (name == "height") return ColorMode::height;
  if (name == "intensity") return ColorMode::intensity;
  if (name == "submap") return ColorMode::submap;
  throw Error("color mode \"" + name + "\": expected height, intensity or submap");
}

void RenderOptions::validate() const {
  if (size < 200 || size > 16384) throw Error("render size " + std::to_string(size) + ": must be within 200..16384 pixels");
}

const char* factor_kind_label(FactorKind kind) {
  static const char* names[] = {"matching-cost factors", "odometry factors", "SE(3) factors", "explicit loops"};
  return names[static_cast<int>(kind)];
}

namespace palette {
Rgb factor(FactorKind kind) {
  switch (kind) {
    case FactorKind::matching_cost: return {255, 95, 210};
    case FactorKind::odometry: return {95, 170, 255};
    case FactorKind::se3: return {255, 150, 50};
    case FactorKind::loop: return {255, 40, 40};
  }
  return text;
}
}  // namespace palette

TopDown fit_top_down(const RunData& run, int size) {
  Eigen::AlignedBox2d box = points_box(run.map);
  for (const auto& T : run.trajectory) box.extend(T.translation().head<2>());
  for (const auto& n : run.graph.nodes) box.extend(n.T_out_submap.translation().head<2>());
  if (box.isEmpty()) box = Eigen::AlignedBox2d(Eigen::Vector2d(-50, -50), Eigen::Vector2d(50, 50));
  const Eigen::Vector2d c = box.center(), half = (0.5 * box.sizes()).cwiseMax(10.0);  // at least 20 m
  const double pad = kMargin * size, ppm = (size - 2.0 * pad) / (2.0 * half.maxCoeff());
  TopDown v;
  v.pixels_per_m = ppm;
  v.width = static_cast<int>(std::ceil(2.0 * half.x() * ppm + 2.0 * pad));
  v.height = static_cast<int>(std::ceil(2.0 * half.y() * ppm + 2.0 * pad));
  v.min_x = c.x() - 0.5 * v.width / ppm;
  v.max_y = c.y() + 0.5 * v.height / ppm;
  return v;
}

std::vector<LegendEntry> legend_entries(const RunData& run, const RenderOptions& options) {
  std::vector<LegendEntry> out;
  out.push_back({"trajectory (" + std::to_string(run.trajectory.size()) + " frames)", palette::trajectory, std::nullopt, false});
  if (!options.graph) return out;
  out.push_back({std::to_string(run.graph.nodes.size()) + " submaps", palette::node, std::nullopt, true});
  for (FactorKind k : kFactorKinds)
    if (run.graph.has(k))
      out.push_back({std::to_string(run.graph.count(k)) + " " + factor_kind_label(k) +
                         (k == FactorKind::loop ? " (w: final kernel weight)" : ""),
                     palette::factor(k), k, false});
  return out;
}

MapPicture render_map(const RunData& run, const RenderOptions& options) {
  options.validate();
  if (options.color == ColorMode::intensity && !run.map.empty() && !run.map.has_intensities())
    throw Error("color intensity: map.ply has no intensity field (use height or submap)");
  MapPicture pic;
  pic.view = fit_top_down(run, options.size);
  pic.legend = legend_entries(run, options);
  Image raster(pic.view.width, pic.view.height, palette::background);
  const std::optional<ColourScale> scale = rasterize(raster, run, pic.view, options.color);
  if (run.map.empty()) pic.note = "empty map: map.ply has no points";
  pic.image = compose_picture(raster, run, pic.view, options, pic.legend, scale ? &*scale : nullptr, pic.note);
  return pic;
}

WrittenFile render_run(const std::string& dir, const std::string& png_path, const RenderOptions& options) {
  options.validate();
  const RunData run = read_run(dir, options.graph || options.color == ColorMode::submap);
  const MapPicture pic = render_map(run, options);
  write_png(png_path, pic.image);
  return {png_path, "top-down map picture (" + std::to_string(pic.image.width) + "x" + std::to_string(pic.image.height) +
                        " pixels, " + std::to_string(run.map.size()) + " map points, " + std::to_string(run.trajectory.size()) +
                        " poses" +
                        (options.graph ? ", " + std::to_string(run.graph.nodes.size()) + " submaps and " +
                                             std::to_string(run.graph.edges.size()) + " factors"
                                       : std::string()) +
                        ")"};
}

}  // namespace gcmap::viz
