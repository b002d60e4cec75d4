#include "gcmap/io/imu_io.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

namespace {

bool to_double(const std::string& s, double& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v);
}

double median_accel(const std::vector<ImuSample>& samples) {
  std::vector<double> m(samples.size());
  for (size_t k = 0; k < samples.size(); ++k) m[k] = samples[k].accel.norm();
  std::nth_element(m.begin(), m.begin() + m.size() / 2, m.end());
  return m[m.size() / 2];
}

// Converts to m/s^2 where the unit is g and fills in what ImuStream says about the samples.
ImuStream finish(std::vector<ImuSample> samples, const std::string& where, size_t duplicates) {
  if (samples.empty()) throw Error(where + ": no IMU samples");
  ImuStream s;
  s.unit = detect_accel_unit(samples, where);
  if (s.unit == AccelUnit::g)
    for (ImuSample& x : samples) x.accel *= kStandardGravity;
  s.gravity = median_accel(samples);
  const double span = samples.back().stamp - samples.front().stamp;
  s.rate = span > 0 ? double(samples.size() - 1) / span : 0.0;
  s.duplicates = duplicates;
  s.samples = std::move(samples);
  return s;
}

// One imu.txt line's seven numbers; Error naming the line otherwise.
ImuSample parse_line(const std::string& line, const std::string& where) {
  std::istringstream ss(line);
  std::string t;
  double v[7];
  int n = 0;
  while (ss >> t) {
    if (n == 7) throw Error(where + ": more than 7 values (expected: stamp gx gy gz ax ay az)");
    if (!to_double(t, v[n])) throw Error(where + ": '" + t + "' is not a finite number");
    ++n;
  }
  if (n != 7) throw Error(where + ": " + std::to_string(n) + " values, expected 7 (stamp gx gy gz ax ay az)");
  return {v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6]}};
}

}  // namespace

const char* accel_unit_name(AccelUnit unit) { return unit == AccelUnit::g ? "g" : "m/s^2"; }

std::string ImuStream::describe(const std::string& source) const {
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%zu IMU samples from %s at %.1f Hz; acceleration in %s%s (median |a| %.3f m/s^2)",
                samples.size(), source.c_str(), rate, accel_unit_name(unit), unit == AccelUnit::g ? ", converted to m/s^2" : "",
                gravity);
  return buf;
}

AccelUnit detect_accel_unit(const std::vector<ImuSample>& samples, const std::string& where, double* median) {
  if (samples.empty()) throw Error(where + ": no IMU samples");
  const double m = median_accel(samples);
  if (median) *median = m;
  if (m > 0.5 && m < 2.0) return AccelUnit::g;
  if (m > 5.0 && m < 15.0) return AccelUnit::meters_per_second2;
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.3f", m);
  throw Error(where + ": the median acceleration magnitude is " + buf +
              ", neither about 1 (g) nor about 9.8 (m/s^2): cannot tell the accelerometer's unit");
}

ImuStream read_imu_txt(const std::string& path) {
  std::istringstream in(read_file(path));
  std::vector<ImuSample> samples;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = path + ":" + std::to_string(number);
    samples.push_back(parse_line(line, where));
    if (samples.size() > 1 && !(samples.back().stamp > samples[samples.size() - 2].stamp))
      throw Error(where + ": stamp " + std::to_string(samples.back().stamp) + " is not after the line before");
  }
  return finish(std::move(samples), path, 0);
}

void write_imu_txt(const std::string& path, const std::vector<ImuSample>& samples) {
  write_file_atomic(path, [&](std::ostream& out) {
    out << "# stamp[s] gyro_x gyro_y gyro_z[rad/s] accel_x accel_y accel_z[m/s^2]\n";
    char buf[256];
    for (const ImuSample& s : samples) {
      std::snprintf(buf, sizeof(buf), "%.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", s.stamp, s.gyro.x(), s.gyro.y(), s.gyro.z(),
                    s.accel.x(), s.accel.y(), s.accel.z());
      out << buf;
    }
  });
}

std::vector<std::string> imu_topics(const BagReader& bag) {
  std::vector<std::string> names;
  for (const BagTopic& t : bag.topics())
    if (is_imu_type(t.type)) names.push_back(t.name);
  return names;
}

ImuStream read_bag_imu(BagReader& bag, const std::string& topic) {
  const BagTopic& t = bag.topic(topic);
  const std::string where = bag.path() + ": topic " + topic;
  if (!is_imu_type(t.type)) throw Error(where + " is " + t.type + ", not sensor_msgs/Imu");
  std::vector<ImuSample> samples;
  auto cursor = bag.read(topic);
  BagMessage msg;
  while (cursor->next(msg)) {
    const ImuMsg m = decode_imu(msg.data, t.encoding, where + ", message at " + std::to_string(msg.time_ns) + " ns");
    samples.push_back({double(m.stamp_ns) * 1e-9,
                       {m.angular_velocity[0], m.angular_velocity[1], m.angular_velocity[2]},
                       {m.linear_acceleration[0], m.linear_acceleration[1], m.linear_acceleration[2]}});
  }
  // Record order is not stamp order where drivers buffer; repeated stamps are duplicates.
  std::stable_sort(samples.begin(), samples.end(), [](const ImuSample& a, const ImuSample& b) { return a.stamp < b.stamp; });
  const size_t before = samples.size();
  samples.erase(
      std::unique(samples.begin(), samples.end(), [](const ImuSample& a, const ImuSample& b) { return a.stamp == b.stamp; }),
      samples.end());
  return finish(std::move(samples), where, before - samples.size());
}

}  // namespace gcmap
