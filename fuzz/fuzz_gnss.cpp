// libFuzzer target: GNSS fixes from gnss.txt text and from sensor_msgs/NavSatFix messages (ROS 1
// and CDR). The first byte picks the reader.
#include <cmath>

#include "fuzz_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/io/gnss_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view rest = gcmap::fuzz::bytes(data + 1, size - 1);
  try {
    if (data[0] % 3 == 0) {
      for (const gcmap::GnssFix& f : gcmap::parse_gnss_txt(rest, "gnss.txt"))  // the reader promises checked fixes
        if (!std::isfinite(f.stamp) || std::abs(f.position.lat_deg) > 90 || !(f.sigma_enu.minCoeff() > 0)) std::abort();
    } else {
      gcmap::decode_navsatfix(rest, data[0] % 3 == 1 ? gcmap::MessageEncoding::ros1 : gcmap::MessageEncoding::cdr,
                              "fuzz message");
    }
  } catch (const gcmap::Error&) {}
  return 0;
}
