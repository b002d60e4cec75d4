#pragma once
// Top-down picture of a run: the map rasterized from above, the factor graph, the trajectory, a
// scale bar and a legend.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "gcmap/viz/image.hpp"
#include "gcmap/viz/run_data.hpp"

namespace gcmap::viz {

enum class ColorMode { height, intensity, submap };
ColorMode parse_color_mode(const std::string& name);  // throws Error naming the value

// A colour per point, for exports that carry one (LAS point format 7): height (z) or intensity
// mapped over their 2-98 % range, or per submap (`submap_of`: the submap of each point).
std::vector<Rgb> point_colours(const PointCloud& cloud, ColorMode mode, const std::vector<uint16_t>& submap_of);

struct RenderOptions {
  ColorMode color = ColorMode::height;
  int size = 2000;    // pixels along the longer side
  bool graph = true;  // submap nodes and factors
  void validate() const;
};

// World (x, y) to pixel coordinates, x to the right and y up, square pixels.
struct TopDown {
  double min_x = 0.0, max_y = 0.0, pixels_per_m = 1.0;
  int width = 0, height = 0;
  Eigen::Vector2d pixel(const Eigen::Vector3d& p) const {
    return {(p.x() - min_x) * pixels_per_m, (max_y - p.y()) * pixels_per_m};
  }
};
// Fits the map, trajectory and nodes into `size` pixels along the longer side with a margin.
TopDown fit_top_down(const RunData& run, int size);

// Fixed colours of the overlays (the map's colours are darker than these).
namespace palette {
inline constexpr Rgb background{20, 22, 26};
inline constexpr Rgb trajectory{255, 255, 255};
inline constexpr Rgb node{255, 225, 77};
inline constexpr Rgb text{235, 235, 235};
inline constexpr Rgb panel{34, 37, 43};  // behind the legend
Rgb factor(FactorKind kind);
}  // namespace palette

const char* factor_kind_label(FactorKind kind);  // "matching-cost factors", ...

struct LegendEntry {
  std::string label;
  Rgb colour;
  std::optional<FactorKind> factor;  // set for the factor-graph entries
  bool dot = false;                  // drawn as a dot (nodes) rather than a line
};
// One entry for the trajectory, and with options.graph one for the nodes and one per factor kind
// present in the graph (none for the kinds absent).
std::vector<LegendEntry> legend_entries(const RunData& run, const RenderOptions& options);

struct MapPicture {
  Image image;  // the map area (view) on the left, the legend panel on the right
  TopDown view;
  std::vector<LegendEntry> legend;
  std::string note;  // printed across the picture ("empty map ..."), empty when none
};
// Throws Error when options.color is intensity and the map has none (naming the mode).
MapPicture render_map(const RunData& run, const RenderOptions& options);

// Reads DIR's map.ply, trajectory.kitti and (with the graph or submap colours) graph.json, renders,
// writes `png_path`.
WrittenFile render_run(const std::string& dir, const std::string& png_path, const RenderOptions& options);

}  // namespace gcmap::viz
