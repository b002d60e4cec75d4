#include <algorithm>
#include <ctime>
#include <iomanip>
#include <optional>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/imu_io.hpp"

namespace gcmap::cli {

namespace {

// "2023-01-10 17:27:51.837 UTC"
std::string utc(int64_t ns) {
  const std::time_t s = std::time_t(ns / 1000000000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  std::ostringstream o;
  o << std::put_time(&tm, "%Y-%m-%d %H:%M:%S") << "." << std::setw(3) << std::setfill('0') << (ns % 1000000000) / 1000000
    << " UTC";
  return o.str();
}

std::string field_list(const CloudTopicInfo& c) {
  std::string out;
  for (const PointField& f : c.fields) out += (out.empty() ? "" : ", ") + f.name + " " + point_field_type_name(f.datatype);
  return out;
}

// An IMU topic's rate and measured gravity, or why they cannot be had.
struct ImuTopicInfo {
  std::optional<ImuStream> stream;
  std::string error;
};
ImuTopicInfo describe_imu_topic(BagReader& bag, const std::string& topic) {
  try {
    return {read_bag_imu(bag, topic), ""};
  } catch (const Error& e) { return {std::nullopt, e.what()}; }
}

std::string imu_line(const ImuTopicInfo& info) {
  if (!info.stream) return "    imu: " + info.error;
  const ImuStream& s = *info.stream;
  std::ostringstream o;
  o << std::fixed << std::setprecision(1) << "    imu: " << s.rate << " Hz; gravity " << std::setprecision(3) << s.gravity
    << " m/s^2 measured (median |acceleration|); acceleration in " << accel_unit_name(s.unit);
  if (s.duplicates) o << "; " << s.duplicates << " repeated stamps dropped";
  return o.str();
}

Json bag_json(BagReader& bag) {
  Json j = Json::object();
  j["path"] = bag.path();
  j["format"] = bag_format_name(bag.format());
  // As strings: %.10g numbers would round nanoseconds since the epoch.
  j["start_ns"] = std::to_string(bag.start_ns());
  j["end_ns"] = std::to_string(bag.end_ns());
  j["start_utc"] = utc(bag.start_ns());
  j["duration_s"] = double(bag.end_ns() - bag.start_ns()) * 1e-9;
  Json topics = Json::array();
  const auto clouds = point_cloud_topics(bag);
  for (const BagTopic& t : bag.topics()) {
    Json tj = Json::object();
    tj["name"] = t.name;
    tj["type"] = t.type;
    tj["messages"] = double(t.message_count);
    if (std::find(clouds.begin(), clouds.end(), t.name) != clouds.end()) {
      const CloudTopicInfo c = describe_cloud_topic(bag, t.name);
      Json fields = Json::array();
      for (const PointField& f : c.fields) {
        Json fj = Json::object();
        fj["name"] = f.name;
        fj["type"] = point_field_type_name(f.datatype);
        fj["offset"] = f.offset;
        fields.push_back(fj);
      }
      tj["fields"] = fields;
      tj["width"] = c.width;
      tj["height"] = c.height;
      tj["point_time"] = c.time_field;
    }
    if (is_imu_type(t.type) && t.message_count > 0) {
      const ImuTopicInfo info = describe_imu_topic(bag, t.name);
      if (info.stream) {
        tj["imu_rate_hz"] = info.stream->rate;
        tj["imu_gravity_m_s2"] = info.stream->gravity;
        tj["imu_accel_unit"] = accel_unit_name(info.stream->unit);
      } else {
        tj["imu_error"] = info.error;
      }
    }
    topics.push_back(tj);
  }
  j["topics"] = topics;
  Json warnings = Json::array();
  for (const std::string& w : bag.warnings()) warnings.push_back(w);
  j["warnings"] = warnings;
  return j;
}

void print_table(BagReader& bag) {
  uint64_t total = 0;
  size_t name_w = 5, type_w = 4;
  for (const BagTopic& t : bag.topics()) {
    total += t.message_count;
    name_w = std::max(name_w, t.name.size());
    type_w = std::max(type_w, t.type.size());
  }
  std::cout << bag.path() << ": " << bag_format_name(bag.format()) << " bag, " << bag.topics().size() << " topics, " << total
            << " messages\n";
  if (total > 0)
    std::cout << "time: " << utc(bag.start_ns()) << " to " << utc(bag.end_ns()) << " (" << std::fixed << std::setprecision(3)
              << double(bag.end_ns() - bag.start_ns()) * 1e-9 << " s)\n";
  std::cout << "\n"
            << std::left << std::setw(int(name_w) + 2) << "topic" << std::setw(int(type_w) + 2) << "type"
            << "messages\n";
  const auto clouds = point_cloud_topics(bag);
  for (const BagTopic& t : bag.topics()) {
    std::cout << std::left << std::setw(int(name_w) + 2) << t.name << std::setw(int(type_w) + 2) << t.type << t.message_count
              << "\n";
    if (is_imu_type(t.type) && t.message_count > 0) std::cout << imu_line(describe_imu_topic(bag, t.name)) << "\n";
    if (std::find(clouds.begin(), clouds.end(), t.name) == clouds.end() || t.message_count == 0) continue;
    const CloudTopicInfo c = describe_cloud_topic(bag, t.name);
    std::cout << "    points: " << c.width << " x " << c.height << "; fields: " << field_list(c) << "\n"
              << "    per-point time: " << c.time_field << "\n";
  }
  for (const std::string& w : bag.warnings()) std::cout << "warning: " << w << "\n";
}

}  // namespace

void add_bag_info(CLI::App& app, Runner& run) {
  struct Options {
    std::string path;
    bool json = false;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand(
      "bag-info", "Topics, types, message counts, time span and point fields of a ROS bag (.mcap, .db3 or its folder, .bag)");
  cmd->add_option("FILE", opt->path, "The bag: .mcap, .bag (ROS 1 v2.0), .db3 or a rosbag2 folder")->required();
  cmd->add_flag("--json", opt->json, "Print JSON instead of a table");
  cmd->callback([opt, &run] {
    run = [opt] {
      auto bag = open_bag(opt->path);
      if (opt->json) {
        std::cout << bag_json(*bag).dump() << std::endl;
      } else {
        print_table(*bag);
      }
      return 0;
    };
  });
}

}  // namespace gcmap::cli
