// libFuzzer target: the YAML mapping configuration (MappingConfig::parse).
#include <string>

#include "fuzz_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/mapping/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  gcmap::MappingConfig config;
  try {
    config = gcmap::MappingConfig::parse(std::string(gcmap::fuzz::bytes(data, size)), "fuzz.yaml");
  } catch (const gcmap::Error&) { return 0; }
  // What was accepted must reload from its own dump (runs write it as config.yaml) unchanged.
  const std::string yaml = config.to_yaml();
  if (gcmap::MappingConfig::parse(yaml, "dumped.yaml").to_yaml() != yaml) std::abort();
  return 0;
}
