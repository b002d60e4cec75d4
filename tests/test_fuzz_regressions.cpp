// Replays the inputs that once crashed a reader (found by the fuzz/ targets) and the seed corpora.
// A regression input must give a one-line gcmap::Error naming the input, or, when its name starts
// with "valid", a sound result; the seeds must parse. Any other exception fails; a crash or
// sanitizer report kills the test (scripts/sanitize.sh runs it under ASan+UBSan).
#include <algorithm>
#include <filesystem>
#include <functional>
#include <map>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/gnss_io.hpp"
#include "gcmap/io/labels.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/config.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

namespace fs = std::filesystem;

void check_cloud(const PointCloud& c) { EXPECT_TRUE(c.intensities.empty() || c.intensities.size() == c.points.size()); }

// Every message of a bag, point clouds decoded, as the bag fuzz targets read it.
void read_bag(BagFormat format, const std::string& d, const std::string& n) {
  auto bag = open_bag_bytes(format, d, n);
  for (const BagTopic& topic : bag->topics()) {
    auto cursor = bag->read(topic.name);
    for (BagMessage m; cursor->next(m);)
      if (is_pointcloud2_type(topic.type) || is_livox_type(topic.type)) check_cloud(decode_scan(topic, m.data, n).cloud);
  }
}

// Each fuzz target's parser on one input; throws what the parser throws.
const std::map<std::string, std::function<void(const std::string&, const std::string&)>>& parsers() {
  static const std::map<std::string, std::function<void(const std::string&, const std::string&)>> table = {
      {"fuzz_kitti_bin",
       [](const std::string& d, const std::string& n) {
         try {
           check_cloud(parse_bin(d, BinFields::xyzi, n));
         } catch (const Error&) { check_cloud(parse_bin(d, BinFields::xyz, n)); }
       }},
      {"fuzz_pcd", [](const std::string& d, const std::string& n) { check_cloud(parse_pcd(d, n)); }},
      {"fuzz_ply", [](const std::string& d, const std::string& n) { check_cloud(parse_ply(d, n)); }},
      {"fuzz_trajectory",
       [](const std::string& d, const std::string& n) {
         // calib.txt seeds hold no poses and trajectories no Tr line: either parser may accept it.
         bool any = false;
         try {
           for (const auto& T : parse_trajectory(d, n).poses) EXPECT_TRUE(T.matrix().allFinite()) << n;
           any = true;
         } catch (const Error&) {}
         try {
           EXPECT_TRUE(parse_kitti_calib_tr(d, n).matrix().allFinite()) << n;
           any = true;
         } catch (const Error&) {}
         if (!any) parse_trajectory(d, n);  // rethrows its Error
       }},
      {"fuzz_labels",
       [](const std::string& d, const std::string& n) {
         // As the fuzz target: the first byte picks one label less, as many, or one more.
         if (d.empty()) throw Error(n + ": empty");
         const std::string_view body(d.data() + 1, d.size() - 1);
         const size_t expected = body.size() / 4 + static_cast<unsigned char>(d[0]) % 3 - 1;
         EXPECT_EQ(parse_labels(body, expected, n).size(), expected);
       }},
      {"fuzz_bag_mcap", [](const std::string& d, const std::string& n) { read_bag(BagFormat::mcap, d, n); }},
      {"fuzz_bag_ros1", [](const std::string& d, const std::string& n) { read_bag(BagFormat::ros1, d, n); }},
      {"fuzz_bag_db3", [](const std::string& d, const std::string& n) { read_bag(BagFormat::db3, d, n); }},
      {"fuzz_bag_messages",
       [](const std::string& d, const std::string& n) {
         // As the fuzz target: the first byte picks the message type and encoding.
         if (d.empty()) throw Error(n + ": empty");
         BagTopic topic;
         topic.type = d[0] & 1 ? "livox_ros_driver2/msg/CustomMsg" : "sensor_msgs/msg/PointCloud2";
         topic.encoding = d[0] & 2 ? MessageEncoding::cdr : MessageEncoding::ros1;
         check_cloud(decode_scan(topic, std::string_view(d).substr(1), n).cloud);
       }},
      {"fuzz_gnss",
       [](const std::string& d, const std::string& n) {
         // As the fuzz target: the first byte picks gnss.txt text or a NavSatFix encoding.
         if (d.empty()) throw Error(n + ": empty");
         const std::string_view rest = std::string_view(d).substr(1);
         const int kind = static_cast<uint8_t>(d[0]) % 3;
         if (kind == 0) EXPECT_FALSE(parse_gnss_txt(rest, n).empty());
         else decode_navsatfix(rest, kind == 1 ? MessageEncoding::ros1 : MessageEncoding::cdr, n);
       }},
      {"fuzz_config",
       [](const std::string& d, const std::string& n) {
         const std::string yaml = MappingConfig::parse(d, n).to_yaml();
         EXPECT_EQ(MappingConfig::parse(yaml, n).to_yaml(), yaml) << n << ": the dump does not reload to itself";
       }},
  };
  return table;
}

// Runs every file under root/<target>/ through its parser.
void replay(const fs::path& root, bool seeds) {
  ASSERT_TRUE(fs::is_directory(root)) << root;
  size_t files = 0;
  for (const auto& dir : fs::directory_iterator(root)) {
    const std::string target = dir.path().filename().string();
    ASSERT_TRUE(parsers().count(target)) << "no parser for " << dir.path();
    for (const auto& file : fs::directory_iterator(dir.path())) {
      const std::string name = file.path().string(), data = read_file(name);
      const bool valid = seeds || file.path().filename().string().rfind("valid", 0) == 0;
      ++files;
      try {
        parsers().at(target)(data, name);
        EXPECT_TRUE(valid) << name << ": accepted";
      } catch (const Error& e) {
        const std::string msg = e.what();
        EXPECT_FALSE(valid) << name << ": " << msg;
        EXPECT_NE(msg.find(name), std::string::npos) << msg;
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
      }
    }
  }
  EXPECT_GT(files, 0u);
}

TEST(FuzzRegressions, SavedInputsGiveErrorsNotCrashes) {
  replay(fs::path(GCMAP_SOURCE_DIR) / "tests/data/fuzz_regressions", false);
}

TEST(FuzzRegressions, SeedCorporaParse) { replay(fs::path(GCMAP_SOURCE_DIR) / "fuzz/corpus", true); }

}  // namespace
}  // namespace gcmap
