// MappingConfig fields by "section.key" name (what the Python package's attributes use).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap {
namespace {

TEST(ConfigFields, GetAndSetEveryKeyByName) {
  const std::vector<std::string> keys = MappingConfig::keys();
  ASSERT_GT(keys.size(), 40u);
  EXPECT_EQ(keys.front(), "preprocess.min_range");
  MappingConfig c;
  for (const std::string& key : keys) c.set(key, c.get(key));  // every value goes back in as it came out
  EXPECT_EQ(c.to_yaml(), MappingConfig{}.to_yaml());

  c.set("preprocess.downsample", 0.5);
  c.set("local.max_keyframes", 7);
  c.set("loop.rings", 30.0);              // an integral number is an integer
  c.set("odometry.voxel_resolution", 2);  // an integer is a number
  c.set("loop.enabled", false);
  c.set("global.mode", std::string("sliding-window"));
  EXPECT_EQ(c.preprocess.downsample, 0.5);
  EXPECT_EQ(c.local.max_keyframes, 7);
  EXPECT_EQ(c.loop.scan_context.rings, 30);
  EXPECT_EQ(c.odometry.voxel_resolution, 2.0);
  EXPECT_FALSE(c.loop.enabled);
  EXPECT_EQ(c.global.mode, GlobalMode::sliding_window);
  EXPECT_EQ(std::get<std::string>(c.get("global.mode")), "sliding-window");
  EXPECT_EQ(MappingConfig::parse(c.to_yaml(), "test").to_yaml(), c.to_yaml());
}

TEST(ConfigFields, ErrorsNameTheKey) {
  MappingConfig c;
  auto message = [&](const std::string& key, const MappingConfig::Value& v) {
    try {
      c.set(key, v);
    } catch (const Error& e) { return std::string(e.what()); }
    return std::string("no error");
  };
  EXPECT_EQ(message("local.nope", 1), "unknown key 'local.nope'");
  EXPECT_EQ(message("local.max_keyframes", 2.5), "local.max_keyframes must be an integer, got 2.5");
  EXPECT_EQ(message("preprocess.downsample", std::string("x")), "preprocess.downsample must be a number, got 'x'");
  EXPECT_EQ(message("loop.enabled", 1), "loop.enabled must be true or false, got 1");
  EXPECT_EQ(message("global.factor", true), "global.factor must be a name, got true");
  EXPECT_EQ(message("global.factor", std::string("icp")), "global.factor must be one of vgicp, se3, got 'icp'");
  EXPECT_THROW(c.get("preprocess"), Error);
  EXPECT_EQ(c.to_yaml(), MappingConfig{}.to_yaml());  // nothing was changed by the failures
}

// What `key: value` in a YAML file is refused with ("no error" when it loads).
std::string yaml_error(const std::string& key, const std::string& value) {
  const size_t dot = key.find('.');
  try {
    MappingConfig::parse(key.substr(0, dot) + ":\n  " + key.substr(dot + 1) + ": " + value + "\n", "hostile.yaml");
  } catch (const Error& e) { return e.what(); }
  return "no error";
}

// What validate() says once `key` is set to `value` ("no error" when valid).
std::string set_error(const std::string& key, const MappingConfig::Value& value) {
  MappingConfig c;
  try {
    c.set(key, value);
    c.validate();
  } catch (const Error& e) { return e.what(); }
  return "no error";
}

// Values that once loaded and later failed without naming the key, or mapped meaninglessly.
TEST(ConfigRanges, HostileValuesNameTheKeyAndTheFile) {
  const std::vector<std::pair<std::string, std::string>> hostile = {
      {"preprocess.downsample", "1e-300"},   {"odometry.voxel_resolution", "1e-300"},
      {"local.voxel_resolution", "1e-300"},  {"local.submap_downsample", "1e-300"},
      {"global.voxel_resolution", "1e-300"}, {"loop.verification_downsample", "1e-300"},
      {"output.map_resolution", "1e-300"},   {"loop.rings", "2000000000"},
      {"loop.sectors", "2000000000"},        {"preprocess.num_neighbors", "2000000000"},
      {"loop.num_candidates", "2000000000"}, {"loop.max_radius", "1e300"},
      {"preprocess.max_range", "1e300"},     {"loop.lidar_height", "-1e300"},
      {"loop.tukey_width", "1e-300"},        {"local.max_keyframes", "2000000000"},
      {"preprocess.sweep_period", "1e-300"}, {"preprocess.min_range", "-1"},
  };
  for (const auto& [key, value] : hostile) {
    const std::string message = yaml_error(key, value);
    EXPECT_EQ(message.rfind("hostile.yaml: " + key + " must be in [", 0), 0u) << key << ": " << message;
    const bool integer = value.find_first_of(".e") == std::string::npos;
    const MappingConfig::Value v = integer ? MappingConfig::Value(std::stoi(value)) : MappingConfig::Value(std::stod(value));
    EXPECT_EQ(set_error(key, v).rfind(key + " must be in [", 0), 0u) << key << ": " << set_error(key, v);
  }
  EXPECT_EQ(yaml_error("preprocess.downsample", "1e-300"),
            "hostile.yaml: preprocess.downsample must be in [0.01, 100] m, got 1e-300");
  EXPECT_EQ(yaml_error("loop.rings", "2000000000"), "hostile.yaml: loop.rings must be in [1, 200], got 2000000000");
  EXPECT_EQ(yaml_error("preprocess.num_neighbors", "3"), "hostile.yaml: preprocess.num_neighbors must be in [4, 100], got 3");
  EXPECT_EQ(yaml_error("loop.sectors", "360"), "no error");  // the bounds are valid values
  EXPECT_EQ(yaml_error("preprocess.downsample", "0.01"), "no error");
}

// Every number key refuses values just beyond either end of its documented range.
TEST(ConfigRanges, EveryNumberHasARange) {
  int numbers = 0;
  for (const ConfigKeyDoc& d : MappingConfig::documentation()) {
    if (d.type != "number" && d.type != "integer") continue;
    ++numbers;
    const std::string key = d.section + "." + d.key;
    const size_t comma = d.range.find(", ");
    ASSERT_EQ(d.range.front(), '[') << key;
    const double min = std::stod(d.range.substr(1, comma - 1)), max = std::stod(d.range.substr(comma + 2));
    const double above = max * 10 + 1, below = d.type == "integer" || min <= 0 ? min - 1 : min / 2;
    EXPECT_EQ(set_error(key, above).rfind(key + " must be in " + d.range, 0), 0u) << key;
    EXPECT_EQ(set_error(key, below).rfind(key + " must be in " + d.range, 0), 0u) << key;
    if (d.type == "number") EXPECT_EQ(set_error(key, std::nan("")).rfind(key + " must be in " + d.range, 0), 0u) << key;
  }
  EXPECT_GT(numbers, 50);
}

TEST(ConfigDocs, EveryKeyIsDocumented) {
  const std::vector<ConfigKeyDoc> docs = MappingConfig::documentation();
  ASSERT_EQ(docs.size(), MappingConfig::keys().size());
  for (const ConfigKeyDoc& d : docs) {
    const std::string key = d.section + "." + d.key;
    EXPECT_GT(d.meaning.size(), 20u) << key << " has no description";
    EXPECT_EQ(d.meaning.find_first_of("|\n"), std::string::npos) << key;  // one Markdown table cell
    EXPECT_FALSE(d.unit.empty()) << key;
    EXPECT_FALSE(d.range.empty()) << key;
    EXPECT_EQ(yaml_error(key, d.default_value), "no error") << key;  // the default, as written, loads
    ASSERT_FALSE(d.module.empty()) << key;
    const std::string folder = std::string(GCMAP_SOURCE_DIR) + (d.module == "apps/gcmap/" ? "/" : "/src/gcmap/") + d.module;
    EXPECT_TRUE(std::filesystem::is_directory(folder)) << key << ": no module " << d.module;
    EXPECT_NE(config_reference_text().find(key), std::string::npos) << key;
  }
}

// docs/config.md is what the table generates (`gcmap config --describe --markdown > docs/config.md`).
TEST(ConfigDocs, DocsFileIsGenerated) {
  EXPECT_EQ(read_file(std::string(GCMAP_SOURCE_DIR) + "/docs/config.md"), config_reference_markdown())
      << "regenerate: build/gcmap config --describe --markdown > docs/config.md";
}

}  // namespace
}  // namespace gcmap
