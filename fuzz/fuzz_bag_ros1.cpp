// libFuzzer target: ROS 1 bag v2.0 (chunks none/bz2/lz4, index or linear scan), with the
// PointCloud2 / Livox decoding of every message.
#include "fuzz_bag_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  gcmap::fuzz::read_bag_bytes(gcmap::BagFormat::ros1, data, size);
  return 0;
}
