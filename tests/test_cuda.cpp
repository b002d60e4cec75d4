// The CUDA backend: the device voxel table's probing and growth (shared with the kernels, checked
// here on the host), backend selection, and CPU/GPU parity on real clouds where a GPU answers.
#include <cmath>
#include <random>
#include <thread>
#include <vector>

#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>

#include "gcmap/core/error.hpp"
#include "gcmap/core/kdtree.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/cuda/voxel_hash.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/odometry/odometry.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

using cuda::VoxelSlot;

// The kernel's insertion with a host compare-and-swap, under the kernel's growth policy.
struct HostTable {
  std::vector<VoxelSlot> slots;
  uint32_t mask = 0;
  bool build(const std::vector<Eigen::Vector3i>& coords, uint32_t max_slots) {
    const uint32_t n = cuda::grow_voxel_table(coords.size(), max_slots, [&](uint32_t capacity) {
      slots.assign(capacity, VoxelSlot{-1, -1, -1, -1});
      mask = capacity - 1;
      const auto claim = [](int32_t* field, int32_t index) {
        if (*field != -1) return false;
        *field = index;
        return true;
      };
      for (size_t i = 0; i < coords.size(); ++i)
        if (!cuda::voxel_table_insert(slots.data(), mask, coords[i].x(), coords[i].y(), coords[i].z(), static_cast<int32_t>(i),
                                      claim))
          return false;
      return true;
    });
    return n != 0;
  }
  int32_t find(const Eigen::Vector3i& c) const { return cuda::voxel_table_find(slots.data(), mask, c.x(), c.y(), c.z()); }
};

TEST(VoxelTable, KeepsEveryVoxelOfADenseBlockAndFindsNoOther) {
  // 64 x 64 x 32 neighbouring voxels: the adjacent keys a real map has, 131072 of them.
  std::vector<Eigen::Vector3i> coords;
  for (int x = -32; x < 32; ++x)
    for (int y = -32; y < 32; ++y)
      for (int z = -4; z < 28; ++z) coords.emplace_back(x, y, z);
  HostTable t;
  ASSERT_TRUE(t.build(coords, 1u << 22));
  EXPECT_LE(coords.size() * 2, t.mask + 1);
  for (size_t i = 0; i < coords.size(); ++i) ASSERT_EQ(t.find(coords[i]), static_cast<int32_t>(i)) << i;
  EXPECT_EQ(t.find({32, 0, 0}), -1);
  EXPECT_EQ(t.find({0, 0, -5}), -1);
  EXPECT_EQ(t.find({1000000, -1000000, 7}), -1);
}

TEST(VoxelTable, GrowsPastAProbeOverflowAndFailsCleanlyAtTheCap) {
  // Keys chosen so that all share their home slot in tables of up to 1024 slots: more of them than
  // kMaxProbes overflow the probe window until the table is big enough to tell them apart.
  std::vector<Eigen::Vector3i> coords;
  const uint32_t home = cuda::voxel_slot_hash(0, 0, 0) & 1023u;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> u(-100000, 100000);
  while (coords.size() < 2 * cuda::kMaxProbes) {
    const Eigen::Vector3i c(u(rng), u(rng), u(rng));
    if ((cuda::voxel_slot_hash(c.x(), c.y(), c.z()) & 1023u) == home) coords.push_back(c);
  }
  HostTable t;
  EXPECT_FALSE(t.build(coords, 1024));  // every size up to the cap overflows
  ASSERT_TRUE(t.build(coords, 1u << 20));
  EXPECT_GT(t.mask + 1, 1024u);
  for (size_t i = 0; i < coords.size(); ++i) EXPECT_EQ(t.find(coords[i]), static_cast<int32_t>(i));
  EXPECT_EQ(cuda::grow_voxel_table(100, 64, [](uint32_t) { return true; }), 0u);  // cap below the first size
}

TEST(Device, BackendSelection) {
  EXPECT_EQ(cuda::make_backend(Device::cpu)->device(), Device::cpu);
  EXPECT_EQ(cuda::make_backend(Device::cpu)->name(), "cpu");
  EXPECT_THROW(parse_device("gpu", "--device"), Error);
  std::string why;
  if (cuda::device_available(&why)) {
    EXPECT_EQ(cuda::make_backend(Device::automatic)->device(), Device::cuda);
  } else {
    // A binary with or without CUDA runs here: auto falls back, cuda is refused with the reason.
    EXPECT_FALSE(why.empty());
    EXPECT_EQ(cuda::make_backend(Device::automatic)->device(), Device::cpu);
    try {
      cuda::make_backend(Device::cuda);
      ADD_FAILURE() << "--device cuda without a GPU must fail";
    } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("device cuda"), std::string::npos) << e.what(); }
  }
}

// Without a GPU backend, scans prepared through a backend are the plain preprocessing's, bit for bit.
TEST(Device, ScansPreparedThroughTheCpuBackendAreThePlainOnes) {
  const sim::Simulator simulator(sim::SimulationConfig{.scenario = "small"});
  PreprocessConfig config;
  config.elevation_sigma_deg = 0.1;
  CpuBackend cpu;
  const PointCloud plain = preprocess_scan(simulator.scan(2), config), through = preprocess_scan(simulator.scan(2), config, &cpu);
  ASSERT_EQ(through.size(), plain.size());
  ASSERT_GT(plain.size(), 1000u);
  for (size_t i = 0; i < plain.size(); ++i) {
    ASSERT_EQ(through.points[i], plain.points[i]) << i;
    ASSERT_EQ(through.covs[i], plain.covs[i]) << i;
  }
}

#define GCMAP_REQUIRE_GPU()                                                              \
  do {                                                                                   \
    std::string why;                                                                     \
    if (!cuda::device_available(&why)) GTEST_SKIP() << "no CUDA device (" << why << ")"; \
  } while (0)

class GpuParity : public ::testing::Test {
 protected:
  void SetUp() override {
    GCMAP_REQUIRE_GPU();
    GCMAP_REQUIRE_SHARED_DATA("kitti07_submaps");
    const std::string dir = test::shared_data() + "/kitti07_submaps";
    reference = read_trajectory(dir + "/graph.txt");
    for (int k = 0; k < 5; ++k) {
      nodes.push_back(make_scan_node(read_point_cloud(dir + "/00000" + std::to_string(k) + "/points.bin", BinFields::xyz), 1.0));
    }
    gpu = std::make_shared<cuda::CudaBackend>();
  }
  Trajectory reference;
  std::vector<ScanNode> nodes;
  std::shared_ptr<cuda::CudaBackend> gpu;
};

double relative_difference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / std::max(b.norm(), 1e-30);
}

TEST_F(GpuParity, LinearizationTrialErrorsAndOverlapMatchTheCpu) {
  // Every ordered pair at random poses near the reference (0.05 rad, 0.5 m); half of them with a
  // robust width, in the same batch.
  std::mt19937_64 rng(11);
  Values values;
  for (int k = 0; k < 5; ++k) values[k] = reference.poses[k] * test::random_pose(rng, 0.05, 0.5);
  FactorGraph graph;
  for (int j = 0; j < 5; ++j) {
    for (int i = 0; i < 5; ++i) {
      if (i == j) continue;
      auto f = std::make_shared<MatchingCostFactor>(j, i, nodes[j].cloud, nodes[i].voxels);
      f->set_robust_width((i + j) % 2 ? 0.25f : 0.f);
      graph.add(std::move(f));
    }
  }
  std::vector<Factor*> factors;
  std::vector<FactorPoses> poses;
  for (const auto& f : graph.factors) {
    factors.push_back(f.get());
    poses.push_back({&values.at(f->keys()[0]), &values.at(f->keys()[1])});
  }
  std::vector<FactorLinearization> on_cpu(factors.size()), on_gpu(factors.size());
  CpuBackend cpu;
  cpu.linearize(factors, poses, on_cpu);
  gpu->linearize(factors, poses, on_gpu);
  // Float per point on both sides, double across blocks: differences come from summation order.
  for (size_t f = 0; f < factors.size(); ++f) {
    for (int a = 0; a < 2; ++a) {
      for (int b = 0; b < 2; ++b)
        EXPECT_LT(relative_difference(on_gpu[f].H.block<6, 6>(6 * a, 6 * b), on_cpu[f].H.block<6, 6>(6 * a, 6 * b)), 1e-4) << f;
      EXPECT_LT(relative_difference(on_gpu[f].b.segment<6>(6 * a), on_cpu[f].b.segment<6>(6 * a)), 1e-4) << f;
    }
    EXPECT_NEAR(on_gpu[f].error, on_cpu[f].error, 1e-4 * on_cpu[f].error) << f;
  }
  // Trial errors at moved poses with the association of that linearization.
  Values moved = values;
  for (int k = 1; k < 5; ++k) moved[k] = values[k] * test::random_pose(rng, 0.01, 0.1);
  for (size_t f = 0; f < factors.size(); ++f) poses[f] = {&moved.at(factors[f]->keys()[0]), &moved.at(factors[f]->keys()[1])};
  std::vector<double> trial_cpu(factors.size()), trial_gpu(factors.size());
  cpu.trial_errors(factors, poses, trial_cpu);
  gpu->trial_errors(factors, poses, trial_gpu);
  for (size_t f = 0; f < factors.size(); ++f) EXPECT_NEAR(trial_gpu[f], trial_cpu[f], 1e-4 * trial_cpu[f]) << f;
  // Overlap: the same points in the same voxels, so identical values.
  for (int j = 0; j < 5; ++j) {
    std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
    std::vector<Eigen::Isometry3d> T;
    for (int i = 0; i < 5; ++i) {
      targets.push_back(nodes[i].voxels);
      T.push_back(values.at(i).inverse() * values.at(j));
    }
    std::vector<double> ov_cpu(5), ov_gpu(5);
    cpu.overlaps(nodes[j].cloud, targets, T, ov_cpu);
    gpu->overlaps(nodes[j].cloud, targets, T, ov_gpu);
    for (int i = 0; i < 5; ++i) EXPECT_EQ(ov_gpu[i], ov_cpu[i]) << j << " -> " << i;
  }
  const cuda::DeviceMemory m = gpu->memory();
  EXPECT_EQ(m.num_clouds, 5u);
  EXPECT_EQ(m.num_maps, 5u);
  // Released only once the host objects are gone.
  gpu->release_unused();
  EXPECT_EQ(gpu->memory().num_clouds, 5u);
}

TEST_F(GpuParity, OptimizeGivesTheSamePosesOnBothDevices) {
  std::mt19937_64 rng(3);
  Values start;
  for (int k = 0; k < 5; ++k) start[k] = k == 0 ? reference.poses[k] : reference.poses[k] * test::random_pose(rng, 0.05, 0.3);
  const auto solve = [&](std::shared_ptr<LinearizationBackend> backend) {
    Values values = start;
    FactorGraph graph;
    add_overlapping_pairs(graph, nodes, values, 0.025, backend.get());
    LevenbergMarquardt(LMConfig{}, backend).optimize(graph, values, {0});
    return values;
  };
  const Values cpu = solve(std::make_shared<CpuBackend>());
  const Values gpu_result = solve(gpu);
  for (int k = 0; k < 5; ++k) {
    EXPECT_LT(test::translation_error(gpu_result.at(k), cpu.at(k)), 1e-3) << k;
    EXPECT_LT(test::rotation_error_deg(gpu_result.at(k), cpu.at(k)), 0.01) << k;
  }
}

// Registrations on the device (the odometry's scan-to-model VGICP) land where the CPU's do: each of
// the first 45 frames of the `small` drive (about 1.1 m apart, one corner) onto the previous
// frame's 1 m voxels from a guess 0.2 m / 1 deg off. The odometry on either device follows the
// truth frame to frame within 2 cm, and the two trajectories stay within 1 cm of each other.
TEST(GpuParityOdometry, RegistrationsAndOdometryMatchTheCpu) {
  GCMAP_REQUIRE_GPU();
  const sim::Simulator simulator(sim::SimulationConfig{.scenario = "small"});
  const MappingConfig config;
  std::vector<std::shared_ptr<PointCloud>> frames;
  for (size_t f = 0; f < 45; ++f)
    frames.push_back(std::make_shared<PointCloud>(preprocess_scan(simulator.scan(f), config.preprocess)));
  const auto gpu = std::make_shared<cuda::CudaBackend>();
  CpuBackend cpu;
  std::mt19937_64 rng(5);
  const auto& truth = simulator.poses();
  RegistrationConfig reg;
  reg.max_iterations = config.odometry.max_iterations;
  for (size_t f = 1; f < frames.size(); ++f) {
    const ScanNode target = make_scan_node(*frames[f - 1], 1.0);
    const Eigen::Isometry3d guess = truth[f - 1].inverse() * truth[f] * test::random_pose(rng, 1.0 * M_PI / 180.0, 0.2);
    const RegistrationResult c = cpu.align(*frames[f], target.voxels, guess, reg);
    const RegistrationResult g = gpu->align(*frames[f], target.voxels, guess, reg);
    EXPECT_LT(test::translation_error(g.T_target_source, c.T_target_source), 1e-3) << f;
    EXPECT_LT(test::rotation_error_deg(g.T_target_source, c.T_target_source), 0.01) << f;
    EXPECT_NEAR(static_cast<double>(g.num_inliers), static_cast<double>(c.num_inliers), 0.001 * c.num_inliers) << f;
  }
  std::vector<std::vector<Eigen::Isometry3d>> runs;
  for (const auto& backend : std::vector<std::shared_ptr<LinearizationBackend>>{std::make_shared<CpuBackend>(), gpu}) {
    Odometry odometry(config.odometry, backend);
    std::vector<Eigen::Isometry3d>& poses = runs.emplace_back();
    for (size_t f = 0; f < frames.size(); ++f) poses.push_back(odometry.track(frames[f], 0.1 * f));
    for (size_t f = 1; f < frames.size(); ++f)
      EXPECT_LT(test::translation_error(poses[f - 1].inverse() * poses[f], truth[f - 1].inverse() * truth[f]), 0.02)
          << backend->name() << " frame " << f;
  }
  double apart = 0.0;
  for (size_t f = 0; f < frames.size(); ++f) apart = std::max(apart, test::translation_error(runs[1][f], runs[0][f]));
  EXPECT_LT(apart, 0.01);
  std::printf("odometry on the GPU and the CPU at most %.2g m apart over %zu frames\n", apart, frames.size());
}

// Covariances on the device (brute-force neighbours) equal the CPU's (kd-tree) within float
// tolerance wherever the neighbourhood's normal is well defined (its two smallest eigenvalues
// apart), with and without the beam-elevation term; whole scans of the `small` drive prepared
// either way register alike.
TEST(GpuParityPreprocessing, CovariancesMatchTheCpu) {
  GCMAP_REQUIRE_GPU();
  const sim::Simulator simulator(sim::SimulationConfig{.scenario = "small"});
  const MappingConfig config;
  const auto gpu = std::make_shared<cuda::CudaBackend>();
  for (const double elevation_sigma : {0.0, 0.002}) {
    const PointCloud base = voxel_downsample(
        range_filter(simulator.scan(3), config.preprocess.min_range, config.preprocess.max_range), config.preprocess.downsample);
    CovarianceConfig cc;
    cc.num_neighbors = config.preprocess.num_neighbors;
    cc.elevation_sigma = elevation_sigma;
    PointCloud on_cpu = base, on_gpu = base;
    estimate_covariances(on_cpu, cc);
    gpu->estimate_covariances(on_gpu, cc);
    ASSERT_EQ(on_gpu.covs.size(), on_cpu.covs.size());
    const KdTree tree(base.points);
    size_t compared = 0, differ = 0;
    for (size_t i = 0; i < base.size(); ++i) {
      uint32_t idx[32];
      float d2[32];
      const size_t found = tree.knn(base.points[i], cc.num_neighbors, idx, d2);
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (size_t j = 0; j < found; ++j) mean += base.points[idx[j]].cast<double>();
      mean /= found;
      Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
      for (size_t j = 0; j < found; ++j) {
        const Eigen::Vector3d d = base.points[idx[j]].cast<double>() - mean;
        C += d * d.transpose();
      }
      const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C).eigenvalues();
      if (ev[1] - ev[0] < 0.05 * ev[2]) continue;  // the normal is ill-defined: any in a plane will do
      ++compared;
      differ += (on_gpu.covs[i] - on_cpu.covs[i]).cwiseAbs().maxCoeff() > 1e-3f * on_cpu.covs[i].norm();
    }
    EXPECT_GT(compared, base.size() / 2);
    EXPECT_LE(differ, compared / 1000) << differ << " of " << compared << " covariances differ";
    std::printf("elevation sigma %.3f: %zu of %zu covariances compared, %zu differ\n", elevation_sigma, compared, base.size(),
                differ);
  }
  // Prepared through the backend, as the pipeline does: the registrations land where the CPU's do.
  const ScanNode target = make_scan_node(preprocess_scan(simulator.scan(10), config.preprocess), 1.0);
  const PointCloud source_cpu = preprocess_scan(simulator.scan(11), config.preprocess);
  const PointCloud source_gpu = preprocess_scan(simulator.scan(11), config.preprocess, gpu.get());
  const Eigen::Isometry3d guess = simulator.poses()[10].inverse() * simulator.poses()[11];
  CpuBackend cpu;
  const RegistrationResult c = cpu.align(source_cpu, target.voxels, guess, RegistrationConfig{});
  const RegistrationResult g = cpu.align(source_gpu, target.voxels, guess, RegistrationConfig{});
  EXPECT_LT(test::translation_error(g.T_target_source, c.T_target_source), 1e-3);
  EXPECT_LT(test::rotation_error_deg(g.T_target_source, c.T_target_source), 0.01);
}

// Threads share one backend as the pipeline does: scans prepared on several threads while another
// registers, each in its own stream. Every result equals the one computed alone, bit for bit (the
// kernels sum in a fixed order), so no call read another's buffers or an unfinished upload.
TEST(GpuParityConcurrency, ThreadsSharingTheBackendGetWhatEachGetsAlone) {
  GCMAP_REQUIRE_GPU();
  const sim::Simulator simulator(sim::SimulationConfig{.scenario = "small"});
  const MappingConfig config;
  const auto gpu = std::make_shared<cuda::CudaBackend>();
  std::vector<PointCloud> raw, alone;
  for (size_t f = 0; f < 8; ++f) {
    raw.push_back(simulator.scan(f));
    alone.push_back(preprocess_scan(raw.back(), config.preprocess, gpu.get()));
  }
  const ScanNode target = make_scan_node(alone[0], 1.0);
  const Eigen::Isometry3d guess = simulator.poses()[0].inverse() * simulator.poses()[1];
  const RegistrationResult reference = gpu->align(alone[1], target.voxels, guess, RegistrationConfig{});
  std::vector<RegistrationResult> registered(30);
  std::vector<PointCloud> together(raw.size());
  std::thread registering([&] {
    for (auto& r : registered) r = gpu->align(alone[1], target.voxels, guess, RegistrationConfig{});
  });
  for (int round = 0; round < 3; ++round)
    tbb::parallel_for(size_t{0}, raw.size(),
                      [&](size_t f) { together[f] = preprocess_scan(raw[f], config.preprocess, gpu.get()); });
  registering.join();
  for (size_t f = 0; f < raw.size(); ++f) {
    ASSERT_EQ(together[f].size(), alone[f].size()) << f;
    for (size_t i = 0; i < alone[f].size(); ++i) ASSERT_EQ(together[f].covs[i], alone[f].covs[i]) << f << " " << i;
  }
  for (const RegistrationResult& r : registered) {
    EXPECT_EQ(r.T_target_source.matrix(), reference.T_target_source.matrix());
    EXPECT_EQ(r.num_inliers, reference.num_inliers);
  }
}

}  // namespace
}  // namespace gcmap
