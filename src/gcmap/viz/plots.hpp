#pragma once
// The paper's figures from a run folder: Fig. 10 (global optimization time and factors against
// submaps), the per-module timings of Table III as bars, and with ground truth the top-down
// trajectories and the KITTI per-length errors.
#include <string>
#include <vector>

#include "gcmap/viz/canvas.hpp"
#include "gcmap/viz/run_data.hpp"

namespace gcmap::viz {

struct PlotOptions {
  FigureFormat format = FigureFormat::png;
  std::string ground_truth;  // poses file (KITTI or TUM), one per frame of trajectory.kitti; empty: none
  std::string calib;         // KITTI calib.txt: estimates are Velodyne-frame, ground truth camera-frame
};

// Reads DIR's stats.json (and trajectory.kitti, odometry.kitti with ground truth), writes the
// figures into out_dir (created if needed).
std::vector<WrittenFile> write_plots(const std::string& run_dir, const std::string& out_dir, const PlotOptions& options);

}  // namespace gcmap::viz
