#pragma once
// What gcmap assumes about a recording, and the evidence for each assumption: decided here only, so
// that `gcmap map` (its first lines, stats.json "assumptions") and `gcmap inspect` never disagree.
#include <string>
#include <vector>

#include "gcmap/io/gnss_io.hpp"
#include "gcmap/io/imu_io.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/point_cloud_io.hpp"

namespace gcmap {

enum class InputLayout { kitti, folder, bag };
// Where the scans' stamps come from.
enum class StampSource { times_file, bag_header, point_times, assumed_rate };

const char* layout_name(InputLayout layout);
const char* stamp_source_name(StampSource source);

// What the user and the configuration say (the decision does not read the config table itself).
struct InputOptions {
  std::string times_file;  // --times: the stamps file, instead of the search beside the scans
  BinFields bin_fields = BinFields::xyzi;
  std::string topic;                      // bags: empty for the only point-cloud topic
  bool kitti_vertical_correction = true;  // preprocess.kitti_vertical_correction
  bool deskew = true;                     // preprocess.deskew
  bool deskew_from_azimuth = false;       // preprocess.deskew_from_azimuth
  std::string elevation_calibration;      // preprocess.elevation_calibration
  int estimate_elevation_frames = 0;      // calibration.frames when calibration.estimate_elevation, else 0
  std::string gnss_file;                  // --gnss: the fixes file, instead of gnss.txt beside the scans
  std::string gnss_topic;                 // --gnss-topic: a bag's NavSatFix topic (default: its only one)
  bool use_imu = true;                    // imu.use (--no-imu: false)
  bool imu_levels_map = true;             // imu.level_map
  bool imu_inertial_odometry = true;      // imu.inertial_odometry
  std::string imu_file;                   // --imu: the IMU samples file, instead of imu.txt beside the scans
  std::string imu_topic;                  // --imu-topic: a bag's sensor_msgs/Imu topic (default: its only one)
};

// One assumption: what is assumed and why, in words.
struct Assumed {
  std::string value, evidence;
};

struct InputAssumptions {
  std::string input;
  InputLayout layout = InputLayout::folder;
  std::string scans_dir;           // folders: where the scans are
  std::string root;                // folders: where labels/ and point_times/ are looked for
  std::vector<std::string> files;  // folders: the scans in file-name order
  size_t scans = 0;
  std::string topic;  // bags
  StampSource stamp_source = StampSource::assumed_rate;
  std::string times_path;      // StampSource::times_file
  std::vector<double> stamps;  // folders: one per scan (read, or at the assumed rate)
  double assumed_rate_hz = 10.0;
  bool point_times = false;  // the scans carry per-point times
  bool kitti_correction = false;
  std::string gnss_path;            // gnss.txt, --gnss, or "BAG: topic T"; empty: no GNSS
  std::vector<GnssFix> gnss_fixes;  // as read (io/gnss_io.hpp)
  std::string imu_path;             // imu.txt, --imu, or "BAG: topic T"; empty: no IMU used
  std::vector<ImuSample> imu_samples;
  Assumed layout_text, stamps_text, point_times_text, deskew, elevation_correction, beam_calibration, labels, gnss, imu;
  std::vector<std::string> warnings;  // stated in the first lines and in stats.json

  // "assumption: value (evidence)" lines for the start of a run.
  std::vector<std::string> lines() const;
  Json to_json() const;
};

// Looks at the recording (a sequence folder, a folder of scans, a bag) and decides. Folders: the
// KITTI layout is DIR/velodyne/ (or DIR itself named velodyne); stamps from options.times_file,
// else the first of times.txt in the sequence folder, in the scans folder, beside the scans
// folder; none: options' rate is assumed, with a warning. Throws Error naming the file for a times
// file whose count does not match the scans, a line that is not a number, or a stamp before the
// previous one. KITTI's 0.22 deg elevation correction only with all of KITTI's evidence (see
// kitti_evidence in the .cpp). Reads the first scan (sensor evidence, per-point times). GNSS:
// options.gnss_file, else a bag's options.gnss_topic, else gnss.txt where times.txt is looked for
// (bags: beside the bag), else a bag's only sensor_msgs/NavSatFix topic; read whole
// (Error("PATH:LINE: ...") for a bad line, Error naming the bag for a bad message).
InputAssumptions decide_input(const std::string& input, const InputOptions& options);

}  // namespace gcmap
