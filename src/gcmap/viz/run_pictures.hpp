#pragma once
// The pictures of a finished run, for `gcmap map` and `gcmap demo` to call at the end.
#include <string>
#include <vector>

#include "gcmap/viz/plots.hpp"
#include "gcmap/viz/render.hpp"
#include "gcmap/viz/view_html.hpp"

namespace gcmap::viz {

struct RunPicturesOptions {
  bool map_png = true;  // OUT/map.png
  RenderOptions render;
  bool view_html = false;  // OUT/view.html
  ViewOptions view;
  bool plots = false;  // OUT/plots/*: Fig. 10, timings (and with plot.ground_truth the accuracy figures)
  PlotOptions plot;
};

// Writes the chosen pictures into the run folder OUT (which holds map.ply, trajectory.kitti,
// graph.json, stats.json) and returns what it wrote, in order.
std::vector<WrittenFile> write_run_pictures(const std::string& out_dir, const RunPicturesOptions& options);

}  // namespace gcmap::viz
