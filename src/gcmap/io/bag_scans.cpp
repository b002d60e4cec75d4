#include "gcmap/io/bag_scans.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_bytes.hpp"

namespace gcmap {

namespace {

int64_t to_ns(double s) { return std::llround(s * 1e9); }

struct FieldWriter {
  std::vector<PointField>& fields;
  uint32_t offset = 0;
  uint32_t add(const char* name, PointFieldType type) {
    fields.push_back({name, offset, uint8_t(type), 1});
    offset += uint32_t(point_field_size(uint8_t(type)));
    return fields.back().offset;
  }
};

template <typename T>
void store(char* p, T v, bool swap) {
  if (swap) v = byteswap(v);
  std::memcpy(p, &v, sizeof(T));
}

// As the Livox drivers write it: timebase = header stamp, offset_time in ns after it.
std::string encode_livox_scan(const PointCloud& cloud, int64_t stamp_ns, float reflectivity_scale, MessageEncoding enc) {
  LivoxMsg m;
  m.stamp_ns = stamp_ns;
  m.timebase = uint64_t(stamp_ns);
  m.frame_id = "livox_frame";
  m.points.resize(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    LivoxPoint& p = m.points[i];
    p.x = cloud.points[i].x();
    p.y = cloud.points[i].y();
    p.z = cloud.points[i].z();
    const float r = cloud.has_intensities() ? cloud.intensities[i] * reflectivity_scale : 0.f;
    p.reflectivity = r > 0 ? uint8_t(std::lround(std::min(r, 255.f))) : 0;  // NaN: 0
    p.offset_time = cloud.has_times() ? uint32_t(to_ns(cloud.times[i])) : 0;
  }
  return encode_livox(m, enc);
}

}  // namespace

std::string encode_scan(const PointCloud& cloud, double stamp, const CloudLayout& L, MessageEncoding enc) {
  const int64_t stamp_ns = to_ns(stamp);
  if (L.time == PointTimeConvention::livox_custom_msg) return encode_livox_scan(cloud, stamp_ns, L.reflectivity_scale, enc);
  if (L.height == 0 || cloud.size() % L.height) throw Error("encode_scan: cloud size is not a multiple of height");
  PointCloud2Msg m;
  m.frame_id = "lidar";
  FieldWriter fw{m.fields};
  const PointFieldType xyz = L.xyz_float64 ? PointFieldType::float64 : PointFieldType::float32;
  fw.add("x", xyz), fw.add("y", xyz), fw.add("z", xyz);
  const bool intensity = L.intensity && cloud.has_intensities();
  const uint32_t oi = intensity ? fw.add("intensity", PointFieldType::float32) : 0;
  uint32_t ot = 0, ot2 = 0;
  using C = PointTimeConvention;
  if (L.time == C::ouster_t) ot = fw.add("t", PointFieldType::uint32);
  if (L.time == C::velodyne_time) ot = fw.add("time", PointFieldType::float32);
  if (L.time == C::hesai_timestamp) ot = fw.add("timestamp", PointFieldType::float64);
  if (L.time == C::livox_offset_time) ot = fw.add("offset_time", PointFieldType::uint32);
  if (L.time == C::sec_nsec) ot = fw.add("time_sec", PointFieldType::uint32), ot2 = fw.add("time_nsec", PointFieldType::uint32);
  const bool organized = L.height > 1;
  m.height = L.height;
  m.width = uint32_t(cloud.size() / L.height);
  m.point_step = fw.offset + (organized ? 4 : 0);  // organized: padding as real drivers have
  m.row_step = m.width * m.point_step + (organized ? 8 : 0);
  m.is_bigendian = L.big_endian_data;
  m.is_dense = !organized;
  std::string data(size_t(m.height) * m.row_step, '\0');
  const bool sw = L.big_endian_data;
  float t_max = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    char* p = data.data() + (i / m.width) * m.row_step + (i % m.width) * m.point_step;
    const Eigen::Vector3f& q = cloud.points[i];
    for (int k = 0; k < 3; ++k) {
      if (L.xyz_float64) store<double>(p + m.fields[k].offset, q[k], sw);
      else store<float>(p + m.fields[k].offset, q[k], sw);
    }
    if (intensity) store<float>(p + oi, cloud.intensities[i], sw);
    const float t = cloud.has_times() ? cloud.times[i] : 0.f;
    t_max = std::max(t_max, t);
    if (L.time == C::ouster_t || L.time == C::livox_offset_time) store<uint32_t>(p + ot, uint32_t(to_ns(t)), sw);
    if (L.time == C::velodyne_time) store<float>(p + ot, t, sw);
    if (L.time == C::hesai_timestamp) store<double>(p + ot, stamp + double(t), sw);
    if (L.time == C::sec_nsec) {
      const int64_t abs_ns = stamp_ns + to_ns(t);
      store<uint32_t>(p + ot, uint32_t(abs_ns / 1000000000), sw);
      store<uint32_t>(p + ot2, uint32_t(abs_ns % 1000000000), sw);
    }
  }
  m.stamp_ns = L.time == C::sec_nsec ? stamp_ns + to_ns(t_max) : stamp_ns;
  m.data = data;
  return encode_pointcloud2(m, enc, L.big_endian_cdr);
}

std::vector<std::string> point_cloud_topics(const BagReader& bag) {
  std::vector<std::string> names;
  for (const BagTopic& t : bag.topics())
    if (is_pointcloud2_type(t.type) || is_livox_type(t.type)) names.push_back(t.name);
  return names;
}

std::string choose_point_cloud_topic(const BagReader& bag, const std::string& topic) {
  const std::vector<std::string> clouds = point_cloud_topics(bag);
  if (!topic.empty()) {
    const BagTopic& t = bag.topic(topic);
    if (std::find(clouds.begin(), clouds.end(), topic) == clouds.end())
      throw Error(bag.path() + ": topic " + topic + " has type " + t.type + ", not sensor_msgs/PointCloud2 or Livox CustomMsg");
    return topic;
  }
  if (clouds.size() == 1) return clouds[0];
  std::string list;
  for (const std::string& c : clouds) list += (list.empty() ? "" : ", ") + c;
  if (!clouds.empty()) throw Error(bag.path() + ": several point-cloud topics (" + list + "): choose one with --topic");
  for (const BagTopic& t : bag.topics()) list += (list.empty() ? "" : ", ") + t.name + " (" + t.type + ")";
  throw Error(bag.path() +
              ": no point-cloud topic (sensor_msgs/PointCloud2 or Livox CustomMsg); topics: " + (list.empty() ? "none" : list));
}

BagScanSource::BagScanSource(const std::string& path, const BagScanOptions& options) : BagScanSource(open_bag(path), options) {}

BagScanSource::BagScanSource(std::unique_ptr<BagReader> bag, const BagScanOptions& options) : bag_(std::move(bag)) {
  if (!(options.start_time >= 0) || !std::isfinite(options.start_time))
    throw Error(bag_->path() + ": start time must be a finite number >= 0 (s after the first message)");
  if (!(options.duration > 0)) throw Error(bag_->path() + ": duration must be > 0 s");
  topic_ = choose_point_cloud_topic(*bag_, options.topic);
  // base + s, saturated at the end of the int64 range instead of overflowing.
  auto add_s = [](int64_t base, double s) {
    const double ns = s * 1e9, room = double(std::numeric_limits<int64_t>::max()) - double(base) - 1e6;
    return ns >= room ? std::numeric_limits<int64_t>::max() : base + int64_t(ns);
  };
  const int64_t begin = add_s(bag_->start_ns(), options.start_time);
  cursor_ = bag_->read(topic_, begin, add_s(begin, options.duration));
}

uint64_t BagScanSource::message_count() const { return bag_->topic(topic_).message_count; }

bool BagScanSource::next(BagScan& scan) {
  const BagTopic& topic = bag_->topic(topic_);
  BagMessage msg;
  while (cursor_->next(msg)) {
    const std::string where = bag_->path() + ": " + topic_ + " message at " + std::to_string(msg.time_ns) + " ns";
    try {
      scan = decode_scan(topic, msg.data, where);
      scan.record_time_ns = msg.time_ns;
      return true;
    } catch (const Error& e) {
      if (skipped_++ < 10) spdlog::warn("{} (message skipped)", e.what());
    }
  }
  return false;
}

ScanBagWriter::ScanBagWriter(const std::string& path, BagFormat format, const CloudLayout& layout,
                             const BagWriterOptions& options, const std::string& topic)
    : writer_(open_bag_writer(path, format, options)), layout_(layout), encoding_(message_encoding(format)) {
  const bool livox = layout.time == PointTimeConvention::livox_custom_msg;
  const char* livox_type = format == BagFormat::ros1 ? "livox_ros_driver/msg/CustomMsg" : "livox_ros_driver2/msg/CustomMsg";
  topic_ = writer_->add_topic(topic, livox ? livox_type : "sensor_msgs/msg/PointCloud2");
}

void ScanBagWriter::write(const PointCloud& cloud, double stamp) {
  float t_max = 0;
  for (float t : cloud.times) t_max = std::max(t_max, t);
  writer_->write(topic_, to_ns(stamp + t_max), encode_scan(cloud, stamp, layout_, encoding_));
}

BagScanRecords::BagScanRecords(const std::string& path, const BagScanOptions& options, size_t skip, size_t limit)
    : source_(path, options), skip_(skip), limit_(limit) {}

std::optional<ScanRecord> BagScanRecords::next() {
  if (limit_ && given_ == limit_) return std::nullopt;
  BagScan scan;
  for (; skip_ > 0; --skip_)
    if (!source_.next(scan)) return std::nullopt;
  if (!source_.next(scan)) return std::nullopt;
  ++given_;
  auto cloud = std::make_shared<PointCloud>(std::move(scan.cloud));
  return ScanRecord{scan.stamp, [cloud] { return std::move(*cloud); }};
}

size_t BagScanRecords::size_hint() const {
  // The whole topic: an upper bound when a time window or a limit applies.
  const size_t n = source_.message_count();
  return limit_ ? std::min(n, limit_) : n;
}

std::vector<std::string> BagScanRecords::warnings() const {
  std::vector<std::string> w = source_.bag().warnings();
  if (source_.skipped())
    w.push_back(source_.bag().path() + ": " + std::to_string(source_.skipped()) + " messages of " + source_.topic() +
                " could not be decoded and were skipped");
  return w;
}

}  // namespace gcmap
