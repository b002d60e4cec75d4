#pragma once
// Internal to render.cpp: what is drawn over the rasterized map.
#include <string>
#include <vector>

#include "gcmap/viz/render.hpp"

namespace gcmap::viz {

// The range behind the map's colours, shown as a gradient in the legend (absent for submap colours).
struct ColourScale {
  std::string label;  // "height [m]"
  double lo = 0.0, hi = 1.0;
};

// Factors, trajectory, nodes, loop weights, scale bar, legend and an optional centred note.
void draw_overlays(Image& image, const RunData& run, const TopDown& view, const RenderOptions& options,
                   const std::vector<LegendEntry>& legend, const ColourScale* scale, const std::string& note);

}  // namespace gcmap::viz
