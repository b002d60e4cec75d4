// libFuzzer target: SemanticKITTI .label files. The first byte picks the expected point count
// (the scan's size) relative to the bytes that follow, so matching and mismatching sizes are both hit.
#include "fuzz_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/io/labels.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view body = gcmap::fuzz::bytes(data + 1, size - 1);
  const size_t expected = body.size() / 4 + (data[0] % 3) - 1;  // one less, equal, one more
  try {
    const auto labels = gcmap::parse_labels(body, expected, "fuzz.label");
    if (labels.size() != expected) std::abort();
  } catch (const gcmap::Error&) {}
  return 0;
}
