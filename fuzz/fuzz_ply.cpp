// libFuzzer target: PLY (ascii, binary little and big endian).
#include "fuzz_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/io/point_cloud_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    gcmap::PointCloud cloud = gcmap::parse_ply(gcmap::fuzz::bytes(data, size), "fuzz.ply");
    gcmap::remove_non_finite(cloud);
    gcmap::fuzz::check_cloud(cloud);
  } catch (const gcmap::Error&) {}
  return 0;
}
