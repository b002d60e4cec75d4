// libFuzzer target: raw float32 .bin scans, KITTI x y z intensity and plain x y z.
#include "fuzz_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/io/point_cloud_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  for (const gcmap::BinFields fields : {gcmap::BinFields::xyzi, gcmap::BinFields::xyz}) {
    try {
      gcmap::PointCloud cloud = gcmap::parse_bin(gcmap::fuzz::bytes(data, size), fields, "fuzz.bin");
      gcmap::remove_non_finite(cloud);
      gcmap::fuzz::check_cloud(cloud);
    } catch (const gcmap::Error&) {}
  }
  return 0;
}
