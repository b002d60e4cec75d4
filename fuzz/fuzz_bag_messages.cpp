// libFuzzer target: PointCloud2 and Livox CustomMsg deserialization (ROS 1 and CDR) and their
// conversion to scans, without a container. The first byte picks the message type and encoding.
#include "fuzz_bag_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (spdlog::set_level(spdlog::level::off), true);
  (void)quiet;
  if (size == 0) return 0;
  gcmap::BagTopic topic;
  topic.type = data[0] & 1 ? "livox_ros_driver2/msg/CustomMsg" : "sensor_msgs/msg/PointCloud2";
  topic.encoding = data[0] & 2 ? gcmap::MessageEncoding::cdr : gcmap::MessageEncoding::ros1;
  try {
    gcmap::fuzz::check_scan(
        gcmap::decode_scan(topic, std::string_view(reinterpret_cast<const char*>(data) + 1, size - 1), "fuzz message"));
  } catch (const gcmap::Error&) {}
  return 0;
}
