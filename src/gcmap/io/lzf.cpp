// LZF decompression (liblzf's format), as used by PCD binary_compressed.
#include <cstring>

#include "gcmap/core/error.hpp"
#include "gcmap/io/point_cloud_io.hpp"

namespace gcmap {

namespace {
// LZF turns at most 3 input bytes (a long back reference) into 264 output bytes.
constexpr size_t kLzfMaxRatio = 88;
}  // namespace

std::string lzf_decompress(std::string_view in, size_t expected_size) {
  if (expected_size / kLzfMaxRatio > in.size())
    throw Error("corrupt LZF data (" + std::to_string(in.size()) + " bytes cannot expand to " + std::to_string(expected_size) +
                ")");
  std::string out(expected_size, '\0');
  const auto* ip = reinterpret_cast<const unsigned char*>(in.data());
  const auto* in_end = ip + in.size();
  size_t op = 0;
  while (ip < in_end) {
    unsigned ctrl = *ip++;
    if (ctrl < 32) {
      const size_t len = ctrl + 1;
      if (static_cast<size_t>(in_end - ip) < len || op + len > expected_size) throw Error("corrupt LZF data (literal run)");
      std::memcpy(&out[op], ip, len);
      ip += len;
      op += len;
    } else {
      size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_end) throw Error("corrupt LZF data");
        len += *ip++;
      }
      if (ip >= in_end) throw Error("corrupt LZF data");
      const size_t back = ((ctrl & 0x1f) << 8) + *ip++ + 1;
      len += 2;
      if (back > op || op + len > expected_size) throw Error("corrupt LZF data (back reference)");
      for (size_t k = 0; k < len; ++k, ++op) out[op] = out[op - back];  // may overlap on purpose
    }
  }
  if (op != expected_size) throw Error("corrupt LZF data (short output)");
  return out;
}

}  // namespace gcmap
