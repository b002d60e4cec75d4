#pragma once
// IMU samples from files: imu.txt beside a KITTI-layout sequence, and sensor_msgs/Imu topics of
// ROS bags. imu.txt: one sample a line, "stamp gx gy gz ax ay az" (s; rad/s; m/s^2), whitespace
// separated, stamps strictly increasing; '#' starts a comment line.
//
// The accelerometer's unit is taken from the median magnitude of the samples (gravity dominates
// it): about 1 is g (the Livox driver's IMU), about 9.8 is m/s^2; anything else is an Error.
// Samples come back in m/s^2 and in stamp order.
#include <string>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/io/bag_reader.hpp"

namespace gcmap {

enum class AccelUnit { meters_per_second2, g };
const char* accel_unit_name(AccelUnit unit);  // "m/s^2" or "g"

struct ImuStream {
  std::vector<ImuSample> samples;                  // stamp order, accelerations in m/s^2
  AccelUnit unit = AccelUnit::meters_per_second2;  // as found in the file
  double gravity = 0.0;                            // median |accel| in m/s^2 after conversion
  double rate = 0.0;                               // Hz: samples per second over the span
  size_t duplicates = 0;                           // samples dropped for repeating the stamp before them (bags)
  // One line saying what was read and which unit was taken, for the log and stats.json.
  std::string describe(const std::string& source) const;
};

// The unit from the median |accel| of `samples`; Error("<where>: ...") when it is neither.
AccelUnit detect_accel_unit(const std::vector<ImuSample>& samples, const std::string& where, double* median = nullptr);

// Throws Error("PATH:LINE: ...") for a malformed line, a stamp not after the one before, a
// non-finite value, or a file without samples.
ImuStream read_imu_txt(const std::string& path);
// Full double precision; written to a temporary name and renamed.
void write_imu_txt(const std::string& path, const std::vector<ImuSample>& samples);

// The topics of sensor_msgs/Imu type.
std::vector<std::string> imu_topics(const BagReader& bag);
// All samples of an IMU topic, by header stamp. Throws Error naming the bag when the topic is not
// an IMU topic, holds no message, or a message cannot be decoded.
ImuStream read_bag_imu(BagReader& bag, const std::string& topic);

}  // namespace gcmap
