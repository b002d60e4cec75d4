// libFuzzer target: rosbag2 sqlite3 database (one .db3, read in memory), with the
// PointCloud2 / Livox decoding of every message.
#include "fuzz_bag_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  gcmap::fuzz::read_bag_bytes(gcmap::BagFormat::db3, data, size);
  return 0;
}
