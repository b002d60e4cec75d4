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

// The picture: `raster` (the map seen from above, in view's pixels) with the factors, trajectory,
// nodes, loop weights, scale bar and an optional centred note drawn over it, and the legend in a
// panel on its right, where it hides nothing.
Image compose_picture(const Image& raster, const RunData& run, const TopDown& view, const RenderOptions& options,
                      const std::vector<LegendEntry>& legend, const ColourScale* scale, const std::string& note);

}  // namespace gcmap::viz
