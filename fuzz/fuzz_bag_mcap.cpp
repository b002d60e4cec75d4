// libFuzzer target: MCAP (chunks none/zstd/lz4, summary or linear scan), with the
// PointCloud2 / Livox decoding of every message.
#include "fuzz_bag_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  gcmap::fuzz::read_bag_bytes(gcmap::BagFormat::mcap, data, size);
  return 0;
}
