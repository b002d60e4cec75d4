#pragma once
#include <memory>
#include <string>

#include "gcmap/core/scan_source.hpp"
#include "gcmap/graph/backend.hpp"
#include "gcmap/io/input_assumptions.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap::cli {

struct MapRunOptions {
  std::string input, output, initial_trajectory;
  MappingConfig config;
  int start = 0, max_frames = 0;
  std::string topic;                        // bags: the point-cloud topic (empty: the only one)
  std::string times_file;                   // folders: --times, the stamps file (empty: looked for beside the scans)
  std::string gnss_file;                    // --gnss: GNSS fixes (empty: gnss.txt beside the scans, if any)
  std::string gnss_topic;                   // --gnss-topic: a bag's NavSatFix topic (empty: its only one, if any)
  std::string imu_file;                     // --imu: IMU samples (empty: imu.txt beside the scans, if any)
  std::string imu_topic;                    // --imu-topic: a bag's sensor_msgs/Imu topic (empty: its only one, if any)
  BinFields bin_fields = BinFields::xyzi;   // folders: layout of .bin scans
  double start_time = 0.0, duration = 0.0;  // bags: s after the first message; duration 0: to the end
  Device device = Device::automatic;
  bool quiet = false;
};

struct MapRunResult {
  size_t frames = 0, submaps = 0, factors = 0;
  double seconds = 0.0, fps = 0.0;
  int signal = 0;       // SIGINT or SIGTERM when interrupted (outputs are then partial)
  std::string failure;  // why the run failed although it wrote its outputs (most scans unusable), else empty
  std::string gnss;     // a line on the GNSS fixes used and rejected; empty without GNSS
  std::string imu;      // a line on what the IMU did; empty without one
  bool nothing_written = false;        // interrupted before mapping began (while estimating the beam elevations)
  bool elevation_calibration = false;  // elevation_calibration.txt written
};

// A sequence folder or a ROS bag.
struct Input {
  std::unique_ptr<ScanSource> source;
  bool kitti_hdl64 = false;
  int frame_offset = 0;          // added to frame numbers in graph.json and quality.json
  InputAssumptions assumptions;  // what the run assumes about the input, and why
};

// Opens options.input from options.start for options.max_frames (bags: topic and time window).
Input open_input(const MapRunOptions& options);

// Reads the input, runs the mapping pipeline and writes every output into options.output.
MapRunResult run_mapping(const MapRunOptions& options);

}  // namespace gcmap::cli
