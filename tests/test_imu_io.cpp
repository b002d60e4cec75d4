#include <filesystem>
#include <fstream>
#include <random>
#include <tuple>

#include "bag_test_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/graph/imu_preintegration.hpp"
#include "gcmap/io/bag_writer.hpp"
#include "gcmap/io/imu_io.hpp"
#include "gcmap/sim/imu.hpp"
#include "gcmap/sim/writer.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// A vehicle-like IMU stream: gravity plus a little motion, `scale` 1 for m/s^2, 1/g for g.
std::vector<ImuSample> random_samples(size_t n, double scale, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> u(0.0, 1.0);
  std::vector<ImuSample> out;
  for (size_t k = 0; k < n; ++k) {
    ImuSample s{1.7e9 + 0.005 * double(k), 0.1 * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                Eigen::Vector3d(0.5 * u(rng), 0.5 * u(rng), kStandardGravity + 0.3 * u(rng))};
    s.accel *= scale;
    out.push_back(s);
  }
  return out;
}

void expect_error(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one containing '" << needle << "'";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what(); }
}

TEST(ImuIo, ImuTxtRoundTrip) {
  test::TempDir dir;
  const auto samples = random_samples(300, 1.0, 1);
  write_imu_txt(dir / "imu.txt", samples);
  const ImuStream back = read_imu_txt(dir / "imu.txt");
  ASSERT_EQ(back.samples.size(), samples.size());
  for (size_t k = 0; k < samples.size(); ++k) {
    EXPECT_EQ(back.samples[k].stamp, samples[k].stamp);
    EXPECT_EQ(back.samples[k].gyro, samples[k].gyro);
    EXPECT_EQ(back.samples[k].accel, samples[k].accel);
  }
  EXPECT_EQ(back.unit, AccelUnit::meters_per_second2);
  EXPECT_NEAR(back.rate, 200.0, 1e-3);
  EXPECT_NEAR(back.gravity, kStandardGravity, 0.2);
}

TEST(ImuIo, ImuTxtErrorsNameTheFileAndLine) {
  test::TempDir dir;
  const auto write = [&](const std::string& text) {
    std::ofstream(dir / "imu.txt") << text;
    return dir / "imu.txt";
  };
  const std::string ok = "0.00 0 0 0 0 0 9.8\n";
  expect_error([&] { read_imu_txt(write(ok + "0.01 0 0 0 0 9.8\n")); }, "imu.txt:2: 6 values, expected 7");
  expect_error([&] { read_imu_txt(write(ok + "0.01 0 0 x 0 0 9.8\n")); }, "imu.txt:2: 'x' is not a finite number");
  expect_error([&] { read_imu_txt(write(ok + "0.01 0 0 nan 0 0 9.8\n")); }, "imu.txt:2: 'nan' is not a finite number");
  expect_error([&] { read_imu_txt(write("# header\n" + ok + ok)); }, "imu.txt:3: stamp 0.000000 is not after");
  expect_error([&] { read_imu_txt(write(ok + "0.01 0 0 0 0 0 9.8 1\n")); }, "imu.txt:2: more than 7 values");
  expect_error([&] { read_imu_txt(write("# nothing\n")); }, "imu.txt: no IMU samples");
  expect_error([&] { read_imu_txt(dir / "missing.txt"); }, "missing.txt");
  expect_error([&] { read_imu_txt(write(ok + "0.01 0 0 0 0 0 3.0\n0.02 0 0 0 0 0 3.0\n")); },
               "imu.txt: the median acceleration magnitude is 3.000");
}

TEST(ImuIo, DetectsTheAccelerationUnit) {
  double median = 0;
  EXPECT_EQ(detect_accel_unit(random_samples(100, 1.0, 2), "x", &median), AccelUnit::meters_per_second2);
  EXPECT_NEAR(median, kStandardGravity, 0.2);
  EXPECT_EQ(detect_accel_unit(random_samples(100, 1.0 / kStandardGravity, 2), "x", &median), AccelUnit::g);
  EXPECT_NEAR(median, 1.0, 0.02);
  expect_error([] { detect_accel_unit(random_samples(100, 0.3, 2), "where"); }, "where: the median acceleration");
  // imu.txt in g is converted, and says so.
  test::TempDir dir;
  write_imu_txt(dir / "imu.txt", random_samples(100, 1.0 / kStandardGravity, 3));
  const ImuStream s = read_imu_txt(dir / "imu.txt");
  EXPECT_EQ(s.unit, AccelUnit::g);
  EXPECT_NEAR(s.gravity, kStandardGravity, 0.2);
  EXPECT_NE(s.describe("imu.txt").find("acceleration in g, converted to m/s^2"), std::string::npos) << s.describe("imu.txt");
}

void write_imu_bag(const std::string& path, const test::Container& c, const std::vector<ImuSample>& samples,
                   bool reversed = false) {
  auto w = open_bag_writer(path, c.format, c.options);
  const uint32_t topic = w->add_topic("/imu", "sensor_msgs/msg/Imu");
  std::vector<ImuSample> order = samples;
  if (reversed) std::reverse(order.begin(), order.end());
  for (const ImuSample& s : order) {
    ImuMsg m;
    m.stamp_ns = std::llround(s.stamp * 1e9);
    m.frame_id = "imu_link";
    m.angular_velocity = {s.gyro.x(), s.gyro.y(), s.gyro.z()};
    m.linear_acceleration = {s.accel.x(), s.accel.y(), s.accel.z()};
    w->write(topic, m.stamp_ns, encode_imu(m, message_encoding(c.format)));
  }
  w->close();
}

TEST(ImuIo, BagRoundTripInEveryContainer) {
  const auto samples = random_samples(24, 1.0, 4);  // several chunks; db3-split: 12 files
  for (const test::Container& c : test::containers()) {
    test::TempDir dir;
    const std::string path = dir / test::bag_name(c);
    write_imu_bag(path, c, samples, c.name == "bag-lz4");  // one written out of stamp order
    auto bag = open_bag(path);
    ASSERT_EQ(imu_topics(*bag), std::vector<std::string>{"/imu"}) << c.name;
    const ImuStream back = read_bag_imu(*bag, "/imu");
    ASSERT_EQ(back.samples.size(), samples.size()) << c.name;
    for (size_t k = 0; k < samples.size(); ++k) {
      EXPECT_NEAR(back.samples[k].stamp, samples[k].stamp, 1e-6) << c.name << " sample " << k;
      EXPECT_EQ(back.samples[k].gyro, samples[k].gyro) << c.name;
      EXPECT_EQ(back.samples[k].accel, samples[k].accel) << c.name;
    }
    EXPECT_EQ(back.unit, AccelUnit::meters_per_second2);
  }
}

TEST(ImuIo, LivoxImuInGIsDetectedAndConverted) {
  const auto truth = random_samples(400, 1.0, 5);
  auto in_g = truth;
  for (ImuSample& s : in_g) s.accel /= kStandardGravity;
  test::TempDir dir;
  const test::Container c{"mcap", BagFormat::mcap, {}};
  write_imu_bag(dir / "livox.mcap", c, in_g);
  auto bag = open_bag(dir / "livox.mcap");
  const ImuStream s = read_bag_imu(*bag, "/imu");
  EXPECT_EQ(s.unit, AccelUnit::g);
  ASSERT_EQ(s.samples.size(), truth.size());
  for (size_t k = 0; k < truth.size(); ++k) EXPECT_LT((s.samples[k].accel - truth[k].accel).norm(), 1e-12);
  expect_error([&] { read_bag_imu(*bag, "/points"); }, "/points");
}

TEST(ImuIo, MalformedImuMessageNamesTheBag) {
  test::TempDir dir;
  auto w = open_bag_writer(dir / "bad.mcap", BagFormat::mcap);
  const uint32_t topic = w->add_topic("/imu", "sensor_msgs/msg/Imu");
  ImuMsg m;
  const std::string data = encode_imu(m, MessageEncoding::cdr);
  w->write(topic, 1, data.substr(0, data.size() - 20));
  w->close();
  auto bag = open_bag(dir / "bad.mcap");
  expect_error([&] { read_bag_imu(*bag, "/imu"); }, "bad.mcap: topic /imu, message at 1 ns");
}

// --- the simulated IMU ---

sim::SimulationConfig drive(const std::string& scenario, int frames) {
  sim::SimulationConfig cfg;
  cfg.scenario = scenario;
  cfg.frames = frames;
  cfg.sensor = "vlp16";
  return cfg;
}

TEST(SimulatedImu, NoiseFreeImuPreintegratesToTheFramePoses) {
  // The realistic city drive: stops, turns, slopes. Its poses are piecewise; the IMU comes from
  // the smooth trajectory through them, which is exact at its knots (the frame stamps among them).
  sim::SimulationConfig cfg;
  cfg.scenario = "city";
  cfg.frames = 150;
  const sim::Simulator simulator(cfg);
  sim::ImuSimConfig ic;
  ic.noise = false;
  ic.T_lidar_imu.linear() = so3_exp(Eigen::Vector3d(0.02, -0.03, 0.5));  // a rotated IMU too
  const sim::ImuTrajectory traj = sim::imu_trajectory(simulator, ic.T_lidar_imu);
  // The trapezoid steps are second order: over one 0.1 s frame of this drive they leave at most
  // 3e-5 m at 200 Hz (the default rate) and 3e-7 m at 2 kHz.
  for (const auto& [rate, bound_t, bound_r] : {std::tuple{200.0, 5e-5, 1e-8}, std::tuple{2000.0, 1e-6, 1e-9}}) {
    ic.rate = rate;
    const auto imu = sim::simulate_imu(traj, ic, cfg.seed);
    double worst_t = 0, worst_r = 0;
    for (size_t k = 0; k + 1 < simulator.num_frames(); ++k) {
      ImuPreintegration pre;
      pre.integrate(imu.samples, 0.1 * double(k), 0.1 * double(k + 1));
      const NavState end = pre.predict(traj.state(0.1 * double(k)));
      const Eigen::Isometry3d T_lidar = end.T_world_imu * ic.T_lidar_imu.inverse();
      // The relative LiDAR pose between the two frames, as poses.txt gives it.
      const Eigen::Isometry3d rel = simulator.poses()[k].inverse() * T_lidar;
      const Eigen::Isometry3d truth = simulator.poses()[k].inverse() * simulator.poses()[k + 1];
      worst_t = std::max(worst_t, (rel.translation() - truth.translation()).norm());
      worst_r = std::max(worst_r, so3_log(rel.linear().transpose() * truth.linear()).norm());
    }
    EXPECT_LT(worst_t, bound_t) << rate << " Hz";
    EXPECT_LT(worst_r, bound_r) << rate << " Hz";
  }
  // And the smooth trajectory follows the drive's own poses within the sweeps, where the IMU
  // deskews them.
  double worst_t = 0, worst_r = 0;
  for (size_t k = 0; k + 1 < simulator.num_frames(); ++k) {
    for (const double s : {0.005, 0.023, 0.05, 0.077}) {
      const Eigen::Isometry3d T = traj.state(0.1 * double(k) + s).T_world_imu * ic.T_lidar_imu.inverse();
      worst_t = std::max(worst_t, test::translation_error(T, simulator.pose_at(k, s)));
      worst_r = std::max(worst_r, test::rotation_error_deg(T, simulator.pose_at(k, s)));
    }
  }
  EXPECT_LT(worst_t, 5e-4);
  EXPECT_LT(worst_r, 1e-5);
}

TEST(SimulatedImu, WritesImuTxtAndBagTopicsThatReadBack) {
  for (const auto& [format, message] : std::vector<std::pair<std::optional<BagFormat>, sim::ScanMessage>>{
           {std::nullopt, sim::ScanMessage::pointcloud2},
           {BagFormat::mcap, sim::ScanMessage::pointcloud2},
           {BagFormat::db3, sim::ScanMessage::pointcloud2},
           {BagFormat::ros1, sim::ScanMessage::livox_custom_msg}}) {
    test::TempDir dir;
    sim::OutputOptions out;
    out.bag = format;
    out.message = message;
    out.imu = sim::ImuSimConfig{};
    out.imu->time_offset = 0.0125;
    // The city drive at its own speeds (small spreads its route over the frames asked for).
    sim::write_simulation(dir.path.string(), drive("city", 6), out);
    const ImuStream txt = read_imu_txt(dir / "imu.txt");
    ASSERT_EQ(txt.samples.size(), 101u);  // 0.5 s at 200 Hz, both ends
    EXPECT_DOUBLE_EQ(txt.samples.front().stamp, 0.0125);
    EXPECT_NEAR(txt.gravity, kStandardGravity, 0.5);
    const std::string scenario = test::slurp(dir / "scenario.json");
    EXPECT_NE(scenario.find("\"T_lidar_imu\""), std::string::npos);
    EXPECT_NE(scenario.find("\"gyro_noise_density\""), std::string::npos);
    if (!format) continue;
    auto bag = open_bag(sim::simulated_bag_path(dir.path.string(), *format));
    const ImuStream b = read_bag_imu(*bag, "/imu");
    EXPECT_EQ(b.unit, message == sim::ScanMessage::livox_custom_msg ? AccelUnit::g : AccelUnit::meters_per_second2);
    ASSERT_EQ(b.samples.size(), txt.samples.size());
    for (size_t k = 0; k < b.samples.size(); ++k) {
      EXPECT_NEAR(b.samples[k].stamp, txt.samples[k].stamp, 1e-9);
      EXPECT_EQ(b.samples[k].gyro, txt.samples[k].gyro);
      EXPECT_LT((b.samples[k].accel - txt.samples[k].accel).norm(), 1e-12);
    }
  }
}

TEST(SimulatedImu, LeavesTheScansAsTheyWere) {
  test::TempDir with, without;
  sim::OutputOptions out;
  sim::write_simulation(without.path.string(), drive("small", 3), out);
  out.imu = sim::ImuSimConfig{};
  sim::write_simulation(with.path.string(), drive("small", 3), out);
  for (const std::string f : {"velodyne/000000.bin", "velodyne/000002.bin", "poses.txt", "times.txt"})
    EXPECT_EQ(test::slurp(with / f), test::slurp(without / f)) << f;
  EXPECT_FALSE(std::filesystem::exists(without / "imu.txt"));
  EXPECT_EQ(test::slurp(without / "scenario.json").find("imu"), std::string::npos);
}

}  // namespace
}  // namespace gcmap
