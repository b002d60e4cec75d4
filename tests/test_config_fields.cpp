// MappingConfig fields by "section.key" name (what the Python package's attributes use).
#include <gtest/gtest.h>

#include "gcmap/core/error.hpp"
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
  c.set("loop.rings", 30.0);  // an integral number is an integer
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
    } catch (const Error& e) {
      return std::string(e.what());
    }
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

}  // namespace
}  // namespace gcmap
