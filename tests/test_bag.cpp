#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "bag_test_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

struct Layout {
  std::string name;
  CloudLayout layout;
  size_t nan_every = 0;
};

std::vector<Layout> layouts() {
  using C = PointTimeConvention;
  auto L = [](C time, bool f64 = false, uint32_t height = 1, bool be_data = false, bool be_cdr = false) {
    CloudLayout l;
    l.time = time;
    l.xyz_float64 = f64;
    l.height = height;
    l.big_endian_data = be_data;
    l.big_endian_cdr = be_cdr;
    return l;
  };
  return {{"ouster-t", L(C::ouster_t)},
          {"velodyne-time-f64", L(C::velodyne_time, true)},
          {"hesai-timestamp", L(C::hesai_timestamp)},
          {"livox-offset-time", L(C::livox_offset_time)},
          {"luminar-sec-nsec", L(C::sec_nsec)},
          {"no-times", L(C::none)},
          {"organized-nan-bigendian", L(C::ouster_t, false, 4, true), 7},
          {"cdr-bigendian-f64", L(C::velodyne_time, true, 1, false, true)},
          {"livox-custom-msg", L(C::livox_custom_msg)}};
}

// Every container x layout: points, intensities, times and stamps come back.
TEST(Bag, RoundTripEveryContainerAndLayout) {
  TempDir dir;
  const double t0 = 1700000000.0;
  for (const Container& c : containers()) {
    for (const Layout& l : layouts()) {
      SCOPED_TRACE(c.name + " / " + l.name);
      const std::string path = dir / (l.name + "_" + bag_name(c));
      std::vector<PointCloud> scans;
      {
        ScanBagWriter w(path, c.format, l.layout, c.options);
        for (int k = 0; k < 5; ++k) {
          scans.push_back(make_scan(120, 10 * k + 1, l.nan_every));
          w.write(scans.back(), t0 + 0.1 * k);
        }
        w.close();
      }
      BagScanSource src(path);
      EXPECT_EQ(src.topic(), "/points");
      EXPECT_EQ(src.message_count(), 5u);
      BagScan s;
      for (int k = 0; k < 5; ++k) {
        ASSERT_TRUE(src.next(s));
        const PointCloud want = finite_points(scans[k]);
        ASSERT_EQ(s.cloud.size(), want.size());
        EXPECT_NEAR(s.stamp, t0 + 0.1 * k, 1e-6);
        for (size_t i = 0; i < want.size(); ++i) {
          ASSERT_EQ(s.cloud.points[i], want.points[i]) << i;
          ASSERT_EQ(s.cloud.intensities[i], want.intensities[i]) << i;
        }
        if (l.layout.time == PointTimeConvention::none) {
          EXPECT_FALSE(s.cloud.has_times());
          continue;
        }
        ASSERT_EQ(s.cloud.times.size(), want.size());
        for (size_t i = 0; i < want.size(); ++i) ASSERT_NEAR(s.cloud.times[i], want.times[i], 1e-6) << i;
      }
      EXPECT_FALSE(src.next(s));
      EXPECT_EQ(src.skipped(), 0u);
    }
  }
}

// Messages written out of order, over several chunks and two topics, come back in time order.
TEST(Bag, MessagesInTimeOrderPerTopic) {
  TempDir dir;
  const std::vector<int64_t> times = {50, 10, 40, 20, 30, 90, 60, 80, 70, 15};
  for (const Container& c : containers()) {
    SCOPED_TRACE(c.name);
    const std::string path = dir / bag_name(c);
    BagWriterOptions o = c.options;
    o.chunk_bytes = 3 * 20;
    auto w = open_bag_writer(path, c.format, o);
    const uint32_t a = w->add_topic("/a", "std_msgs/msg/String"), b = w->add_topic("/b", "std_msgs/msg/String");
    for (int64_t t : times) w->write(t % 20 == 0 ? a : b, t * 1000000000, "msg" + std::to_string(t) + std::string(16, 'x'));
    w->close();
    auto bag = open_bag(path);
    ASSERT_EQ(bag->topics().size(), 2u);
    EXPECT_EQ(bag->topic("/a").message_count, 4u);
    EXPECT_EQ(bag->topic("/b").message_count, 6u);
    EXPECT_EQ(bag->start_ns(), 10'000'000'000);
    EXPECT_EQ(bag->end_ns(), 90'000'000'000);
    for (const char* topic : {"/a", "/b"}) {
      std::vector<int64_t> want;
      for (int64_t t : times)
        if ((t % 20 == 0) == (topic[1] == 'a')) want.push_back(t);
      std::sort(want.begin(), want.end());
      auto cur = bag->read(topic);
      BagMessage m;
      for (int64_t t : want) {
        ASSERT_TRUE(cur->next(m));
        EXPECT_EQ(m.time_ns, t * 1000000000);
        EXPECT_EQ(m.data, "msg" + std::to_string(t) + std::string(16, 'x'));
      }
      EXPECT_FALSE(cur->next(m));
    }
  }
}

TEST(Bag, TimeWindowSelectsScans) {
  TempDir dir;
  for (const Container& c : containers()) {
    SCOPED_TRACE(c.name);
    const std::string path = dir / bag_name(c);
    ScanBagWriter w(path, c.format, CloudLayout{}, c.options);
    for (int k = 0; k < 10; ++k) w.write(make_scan(30, k), 1000.0 + 0.1 * k);  // recorded at 1000.05 + 0.1 k
    w.close();
    BagScanOptions o;
    o.start_time = 0.25;
    o.duration = 0.3;
    BagScanSource src(path, o);
    std::vector<double> stamps;
    for (BagScan s; src.next(s);) stamps.push_back(s.stamp);
    ASSERT_EQ(stamps.size(), 3u);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(stamps[k], 1000.0 + 0.1 * (k + 3), 1e-6);
    o.start_time = -1;
    EXPECT_THROW([&] { BagScanSource s(path, o); }(), Error);
  }
}

void expect_error(const std::function<void()>& f, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one containing '" << part << "'";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what(); }
}

TEST(Bag, TopicSelection) {
  TempDir dir;
  for (const Container& c : containers()) {
    SCOPED_TRACE(c.name);
    const std::string two = dir / ("two_" + bag_name(c)), none = dir / ("none_" + bag_name(c));
    {
      auto w = open_bag_writer(two, c.format, c.options);
      const uint32_t a = w->add_topic("/lidar_front", "sensor_msgs/msg/PointCloud2");
      const uint32_t b = w->add_topic("/lidar_rear", "sensor_msgs/msg/PointCloud2");
      w->add_topic("/chatter", "std_msgs/msg/String");
      const std::string msg = encode_scan(make_scan(20, 1), 5.0, CloudLayout{}, message_encoding(c.format));
      w->write(a, 5'000'000'000, msg);
      w->write(b, 6'000'000'000, msg);
      w->close();
      auto n = open_bag_writer(none, c.format, c.options);
      n->write(n->add_topic("/chatter", "std_msgs/msg/String"), 1, "hello");
      n->close();
    }
    expect_error([&] { BagScanSource s(two); }, "/lidar_front, /lidar_rear");
    expect_error([&] { BagScanSource s(two, {"/missing"}); }, "no topic /missing");
    expect_error([&] { BagScanSource s(two, {"/chatter"}); }, "not sensor_msgs/PointCloud2");
    expect_error([&] { BagScanSource s(none); }, "no point-cloud topic");
    BagScanSource rear(two, {"/lidar_rear"});
    BagScan s;
    ASSERT_TRUE(rear.next(s));
    EXPECT_EQ(s.record_time_ns, 6'000'000'000);
    EXPECT_FALSE(rear.next(s));
  }
}

// A message whose point_step/row_step disagree with its data, or without x/y/z, is skipped.
TEST(Bag, InconsistentCloudsAreSkipped) {
  TempDir dir;
  const std::string path = dir / "bad.mcap";
  auto w = open_bag_writer(path, BagFormat::mcap);
  const uint32_t t = w->add_topic("/points", "sensor_msgs/msg/PointCloud2");
  const PointCloud scan = make_scan(40, 3);
  const std::string good = encode_scan(scan, 1.0, CloudLayout{}, MessageEncoding::cdr);
  PointCloud2Msg m = decode_pointcloud2(good, MessageEncoding::cdr, "test");
  std::string data(m.data);
  PointCloud2Msg bad_step = m;
  bad_step.row_step = m.point_step;  // < width * point_step
  PointCloud2Msg short_data = m;
  short_data.data = std::string_view(data).substr(0, data.size() / 2);
  PointCloud2Msg no_z = m;
  no_z.fields[2].name = "w";
  PointCloud2Msg outside = m;
  outside.fields[0].offset = m.point_step;
  w->write(t, 1, encode_pointcloud2(bad_step, MessageEncoding::cdr));
  w->write(t, 2, good);
  w->write(t, 3, encode_pointcloud2(short_data, MessageEncoding::cdr));
  w->write(t, 4, encode_pointcloud2(no_z, MessageEncoding::cdr));
  w->write(t, 5, encode_pointcloud2(outside, MessageEncoding::cdr));
  w->write(t, 6, good.substr(0, good.size() - 9));
  w->close();
  BagScanSource src(path);
  BagScan s;
  ASSERT_TRUE(src.next(s));
  EXPECT_EQ(s.cloud.size(), 40u);
  EXPECT_FALSE(src.next(s));
  EXPECT_EQ(src.skipped(), 5u);
}

TEST(Bag, EmptyBagsAndNonBags) {
  TempDir dir;
  for (const Container& c : containers()) {
    SCOPED_TRACE(c.name);
    const std::string path = dir / ("empty_" + bag_name(c));
    ScanBagWriter(path, c.format, CloudLayout{}, c.options).close();
    EXPECT_TRUE(is_bag_path(path));
    auto bag = open_bag(path);
    ASSERT_EQ(bag->topics().size(), 1u);
    EXPECT_EQ(bag->topics()[0].message_count, 0u);
    BagScanSource src(path);
    BagScan s;
    EXPECT_FALSE(src.next(s));
  }
  EXPECT_FALSE(is_bag_path(dir / "scan.pcd"));
  EXPECT_FALSE(is_bag_path(dir.path.string()));
  write_file_atomic(dir / "zero.mcap", [](std::ostream&) {});
  expect_error([&] { open_bag(dir / "zero.mcap"); }, "zero.mcap");
  write_file_atomic(dir / "text.bag", [](std::ostream& o) { o << "hello world, not a bag"; });
  expect_error([&] { open_bag(dir / "text.bag"); }, "not a bag");
  expect_error([&] { open_bag(dir / "missing.db3"); }, "missing.db3");
  expect_error([&] { open_bag(dir.path.string()); }, "not a ROS 2 bag");
}

TEST(Bag, RealLuminarRos1Lz4) {
  GCMAP_REQUIRE_SHARED_DATA("bags/luminar_5scans_lz4.bag");
  const std::string path = shared_data() + "/bags/luminar_5scans_lz4.bag";
  BagScanSource src(path);
  EXPECT_EQ(src.topic(), "/luminar_pointcloud");
  EXPECT_EQ(src.message_count(), 5u);
  int n = 0;
  for (BagScan s; src.next(s); ++n) {
    EXPECT_GT(s.cloud.size(), 30000u);
    EXPECT_LT(s.cloud.size(), 45000u);
    ASSERT_TRUE(s.cloud.has_times());
    const float span = *std::max_element(s.cloud.times.begin(), s.cloud.times.end());
    EXPECT_GT(span, 0.05f);
    EXPECT_LT(span, 0.2f);
    EXPECT_EQ(*std::min_element(s.cloud.times.begin(), s.cloud.times.end()), 0.f);
    EXPECT_NEAR(s.header_stamp - s.stamp, span, 0.02);  // Luminar stamps the end of the sweep
  }
  EXPECT_EQ(n, 5);
  EXPECT_EQ(src.skipped(), 0u);
}

TEST(Bag, RealPacketBagsHaveNoPointCloudTopic) {
  GCMAP_REQUIRE_SHARED_DATA("bags/packets_ouster.bag");
  for (const char* name : {"packets_ouster.bag", "packets_vlp16_db3"}) {
    const std::string path = shared_data() + "/bags/" + name;
    auto bag = open_bag(path);
    EXPECT_FALSE(bag->topics().empty()) << name;
    for (const BagTopic& t : bag->topics()) EXPECT_GT(t.message_count, 0u) << t.name;
    EXPECT_TRUE(point_cloud_topics(*bag).empty());
    expect_error([&] { BagScanSource s(path); }, "no point-cloud topic");
  }
  EXPECT_EQ(open_bag(shared_data() + "/bags/packets_vlp16_db3")->topic("/velodyne_packets").message_count, 4u);
}

}  // namespace
}  // namespace gcmap::test
