#include "gcmap/cuda/cuda_backend.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <map>
#include <mutex>

#include "gcmap/core/error.hpp"
#include "gcmap/registration/align.hpp"
#include "gcmap/registration/vgicp.hpp"

#ifdef GCMAP_WITH_CUDA
#include "gcmap/cuda/kernels.hpp"
#endif

namespace gcmap::cuda {

#ifdef GCMAP_WITH_CUDA

bool device_available(std::string* why) {
  const char* reason = nullptr;
  const int n = device::device_count(&reason);
  if (n == 0 && why) *why = reason ? reason : "no CUDA device";
  return n > 0;
}

namespace {

// Row-major 3x4 of T_target_source in float, cast exactly as the CPU path's PointTransform.
void pose_rows(const Eigen::Isometry3d& T, float* out) {
  const PointTransform X(T);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out[4 * r + c] = X.R(r, c);
    out[4 * r + 3] = X.t[r];
  }
}

void cov_upper(const Eigen::Matrix3f& C, float* out) {
  out[0] = C(0, 0), out[1] = C(0, 1), out[2] = C(0, 2), out[3] = C(1, 1), out[4] = C(1, 2), out[5] = C(2, 2);
}

Eigen::Matrix3d sym_from_upper(const double* u) {
  Eigen::Matrix3d m;
  m << u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5];
  return m;
}

TargetFrameSums unpack(const double* s) {
  TargetFrameSums t;
  t.H.block<3, 3>(0, 0) = sym_from_upper(s);
  t.H.block<3, 3>(0, 3) = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(s + 6);
  t.H.block<3, 3>(3, 0) = t.H.block<3, 3>(0, 3).transpose();
  t.H.block<3, 3>(3, 3) = sym_from_upper(s + 15);
  t.b << s[21], s[22], s[23], s[24], s[25], s[26];
  t.error = s[27];
  t.num_inliers = static_cast<size_t>(s[28]);
  return t;
}

device::Cloud upload(const PointCloud& host) {
  if (!host.has_covs()) throw Error("CUDA backend: a matching-cost source cloud has no covariances");
  const size_t n = host.size();
  std::vector<float> xyz(3 * n), cov(6 * n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) xyz[3 * i + k] = host.points[i][k];
    cov_upper(host.covs[i], cov.data() + 6 * i);
  }
  return device::upload_cloud(xyz.data(), cov.data(), static_cast<uint32_t>(n));
}

device::VoxelMap upload(const GaussianVoxelMap& host) {
  const size_t n = host.num_voxels();
  std::vector<int32_t> coords(3 * n);
  std::vector<float> means(3 * n), cov(6 * n);
  for (size_t v = 0; v < n; ++v) {
    const Eigen::Vector3i c = host.coord(static_cast<int>(v));
    for (int k = 0; k < 3; ++k) coords[3 * v + k] = c[k], means[3 * v + k] = host.mean(static_cast<int>(v))[k];
    cov_upper(host.cov(static_cast<int>(v)), cov.data() + 6 * v);
  }
  // Hard cap: a table 8x its initial size (load 1/16) that still overflows is a broken hash.
  const uint32_t max_slots = 8 * voxel_table_capacity(n);
  return device::upload_voxel_map(coords.data(), means.data(), cov.data(), static_cast<uint32_t>(n), host.inv_resolution(),
                                  max_slots);
}

// One registration's cost on the device for align() (registration/align.hpp): the batch holds the
// single (source, target) pair.
struct DeviceVgicpProblem {
  device::Batch& batch;
  VgicpLinearization linearize(const Eigen::Isometry3d& T) {
    float rows[12];
    double sums[device::kSums];
    pose_rows(T, rows);
    batch.linearize(rows, sums);
    return expand_to_both_poses(unpack(sums), T);
  }
  VgicpError evaluate(const Eigen::Isometry3d& T) {
    float rows[12];
    double sums[2];
    pose_rows(T, rows);
    batch.trial_errors(rows, sums);
    return {sums[0], static_cast<size_t>(sums[1])};
  }
};

}  // namespace

struct CudaBackend::Impl {
  template <class Host, class Device>
  struct Resident {
    std::weak_ptr<const Host> host;
    Device device;
  };
  // Keyed by host address; a stale entry (expired host) at a reused address is replaced. Touched per
  // factor-set change, never per point.
  std::map<const void*, Resident<PointCloud, device::Cloud>> clouds;
  std::map<const void*, Resident<GaussianVoxelMap, device::VoxelMap>> maps;

  device::Batch batch;
  std::vector<std::pair<const void*, const void*>> batch_pairs;
  std::vector<float> batch_widths;  // their factors' robust widths
  device::OverlapScratch overlap_scratch;
  std::vector<float> poses;
  std::vector<double> sums;

  ~Impl() {
    for (auto& [k, c] : clouds) device::free_cloud(c.device);
    for (auto& [k, m] : maps) device::free_voxel_map(m.device);
  }

  const device::Cloud& cloud(const std::shared_ptr<const PointCloud>& host) {
    auto it = clouds.find(host.get());
    if (it != clouds.end() && !it->second.host.expired()) return it->second.device;
    if (it != clouds.end()) device::free_cloud(it->second.device), clouds.erase(it);
    return clouds.emplace(host.get(), Resident<PointCloud, device::Cloud>{host, upload(*host)}).first->second.device;
  }

  const device::VoxelMap& map(const std::shared_ptr<const GaussianVoxelMap>& host) {
    auto it = maps.find(host.get());
    if (it != maps.end() && !it->second.host.expired()) return it->second.device;
    if (it != maps.end()) device::free_voxel_map(it->second.device), maps.erase(it);
    return maps.emplace(host.get(), Resident<GaussianVoxelMap, device::VoxelMap>{host, upload(*host)}).first->second.device;
  }

  // align(): the source is uploaded by every call (the odometry deskews a frame in place between
  // registrations); the target is kept while the same map comes back (the odometry's model lives
  // until the next keyframe); holding it keeps its address from being reused. One at a time.
  std::mutex registration_mutex;
  struct Registration {
    device::Cloud source;
    std::shared_ptr<const GaussianVoxelMap> target;
    device::VoxelMap target_device;
    device::Batch batch;
    ~Registration() {
      device::free_cloud(source);
      device::free_voxel_map(target_device);
    }
  } registration;

  // estimate_covariances() is called by the threads that prepare scans, each in its own stream
  // (kernels.cu): each call takes a set of buffers from this pool, so scans are prepared side by side.
  struct CovarianceBuffers {
    device::CovarianceScratch scratch;
    std::vector<float> xyz, out;
  };
  std::mutex covariance_mutex;
  std::vector<std::unique_ptr<CovarianceBuffers>> covariance_pool;

  std::unique_ptr<CovarianceBuffers> take_covariance_buffers() {
    std::lock_guard lock(covariance_mutex);
    if (covariance_pool.empty()) return std::make_unique<CovarianceBuffers>();
    auto b = std::move(covariance_pool.back());
    covariance_pool.pop_back();
    return b;
  }
  void give_back(std::unique_ptr<CovarianceBuffers> b) {
    std::lock_guard lock(covariance_mutex);
    covariance_pool.push_back(std::move(b));
  }

  void release_unused() {
    for (auto it = clouds.begin(); it != clouds.end();) {
      if (it->second.host.expired()) device::free_cloud(it->second.device), it = clouds.erase(it);
      else ++it;
    }
    for (auto it = maps.begin(); it != maps.end();) {
      if (it->second.host.expired()) device::free_voxel_map(it->second.device), it = maps.erase(it);
      else ++it;
    }
  }

  // Splits the factors into the device batch (matching costs) and the rest; rebuilds the batch when
  // the set of pairs changed.
  void prepare(std::span<Factor* const> factors, std::vector<size_t>& on_device, std::vector<size_t>& on_host) {
    std::vector<std::pair<const void*, const void*>> pairs;
    std::vector<float> widths;
    for (size_t f = 0; f < factors.size(); ++f) {
      if (const auto* m = dynamic_cast<const MatchingCostFactor*>(factors[f])) {
        on_device.push_back(f);
        pairs.emplace_back(m->source_ptr().get(), m->target_ptr().get());
        widths.push_back(m->robust_width());
      } else {
        on_host.push_back(f);
      }
    }
    if (pairs == batch_pairs && widths == batch_widths && batch.num_pairs() == pairs.size()) return;
    release_unused();
    std::vector<device::Cloud> sources;
    std::vector<device::VoxelMap> targets;
    for (const size_t f : on_device) {
      const auto* m = static_cast<const MatchingCostFactor*>(factors[f]);
      sources.push_back(cloud(m->source_ptr()));
      targets.push_back(map(m->target_ptr()));
    }
    batch.set_pairs(sources, targets, widths);
    batch_pairs = std::move(pairs);
    batch_widths = std::move(widths);
  }

  void upload_poses(std::span<const FactorPoses> factor_poses, const std::vector<size_t>& on_device,
                    std::vector<Eigen::Isometry3d>* T_out) {
    poses.resize(12 * on_device.size());
    for (size_t k = 0; k < on_device.size(); ++k) {
      const FactorPoses& p = factor_poses[on_device[k]];
      const Eigen::Isometry3d T = p[1]->inverse() * *p[0];  // as MatchingCostFactor::linearize
      pose_rows(T, poses.data() + 12 * k);
      if (T_out) T_out->push_back(T);
    }
  }
};

CudaBackend::CudaBackend() {
  std::string why;
  if (!device_available(&why)) throw Error("device cuda: no usable CUDA device (" + why + ")");
  device::select_device(0);
  impl_ = std::make_unique<Impl>();
}

CudaBackend::~CudaBackend() = default;

void CudaBackend::linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                            std::span<FactorLinearization> out) {
  std::vector<size_t> on_device, on_host;
  impl_->prepare(factors, on_device, on_host);
  std::vector<Eigen::Isometry3d> T;
  impl_->upload_poses(poses, on_device, &T);
  impl_->sums.resize(device::kSums * on_device.size());
  tbb::parallel_for(size_t{0}, on_host.size(),
                    [&](size_t k) { factors[on_host[k]]->linearize(poses[on_host[k]].data(), out[on_host[k]]); });
  impl_->batch.linearize(impl_->poses.data(), impl_->sums.data());
  tbb::parallel_for(size_t{0}, on_device.size(), [&](size_t k) {
    const auto* m = static_cast<const MatchingCostFactor*>(factors[on_device[k]]);
    to_factor_linearization(m->conditioned(expand_to_both_poses(unpack(impl_->sums.data() + device::kSums * k), T[k]), T[k]),
                            out[on_device[k]]);
  });
}

void CudaBackend::trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) {
  std::vector<size_t> on_device, on_host;
  impl_->prepare(factors, on_device, on_host);
  impl_->upload_poses(poses, on_device, nullptr);
  impl_->sums.resize(2 * on_device.size());
  tbb::parallel_for(size_t{0}, on_host.size(),
                    [&](size_t k) { out[on_host[k]] = factors[on_host[k]]->trial_error(poses[on_host[k]].data()); });
  impl_->batch.trial_errors(impl_->poses.data(), impl_->sums.data());
  for (size_t k = 0; k < on_device.size(); ++k) out[on_device[k]] = impl_->sums[2 * k];
}

void CudaBackend::overlaps(const std::shared_ptr<const PointCloud>& source,
                           std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                           std::span<const Eigen::Isometry3d> T_target_source, std::span<double> out) {
  if (targets.empty()) return;
  if (source->empty()) {
    std::fill(out.begin(), out.end(), 0.0);
    return;
  }
  const device::Cloud& s = impl_->cloud(source);
  std::vector<device::VoxelMap> maps;
  std::vector<float> rows(12 * targets.size());
  for (size_t k = 0; k < targets.size(); ++k) {
    maps.push_back(impl_->map(targets[k]));
    pose_rows(T_target_source[k], rows.data() + 12 * k);
  }
  std::vector<uint32_t> hits(targets.size());
  device::overlap_counts(s, maps, rows.data(), hits.data(), impl_->overlap_scratch);
  for (size_t k = 0; k < targets.size(); ++k) out[k] = static_cast<double>(hits[k]) / static_cast<double>(source->size());
}

RegistrationResult CudaBackend::align(const PointCloud& source, const std::shared_ptr<const GaussianVoxelMap>& target,
                                      const Eigen::Isometry3d& init_T_target_source, const RegistrationConfig& config) {
  if (source.empty() || target->num_voxels() == 0)
    return LinearizationBackend::align(source, target, init_T_target_source, config);
  std::lock_guard lock(impl_->registration_mutex);
  Impl::Registration& r = impl_->registration;
  device::free_cloud(r.source);
  r.source = upload(source);
  if (r.target != target) {
    device::free_voxel_map(r.target_device);
    r.target.reset();
    r.target_device = upload(*target);
    r.target = target;
  }
  r.batch.set_pairs({r.source}, {r.target_device}, {0.f});
  DeviceVgicpProblem problem{r.batch};
  return gcmap::align(problem, init_T_target_source, config);
}

void CudaBackend::estimate_covariances(PointCloud& cloud, const CovarianceConfig& config) {
  // Brute force is quadratic in the points: past a dense scan's size the CPU's kd-tree wins.
  constexpr size_t kMaxPoints = 150000;
  if (config.num_neighbors < 1 || config.num_neighbors > device::kMaxNeighbors || cloud.size() > kMaxPoints)
    return LinearizationBackend::estimate_covariances(cloud, config);
  const size_t n = cloud.size();
  std::unique_ptr<Impl::CovarianceBuffers> buffers = impl_->take_covariance_buffers();
  std::vector<float>& xyz = buffers->xyz;
  std::vector<float>& out = buffers->out;
  xyz.resize(3 * n);
  out.resize(6 * n);
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) xyz[3 * i + k] = cloud.points[i][k];
  device::point_covariances(xyz.data(), static_cast<uint32_t>(n), config.num_neighbors, config.epsilon, config.elevation_sigma,
                            out.data(), buffers->scratch);
  cloud.covs.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const float* c = &out[6 * i];
    cloud.covs[i] << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  }
  impl_->give_back(std::move(buffers));
}

void CudaBackend::release_unused() { impl_->release_unused(); }

DeviceMemory CudaBackend::memory() const {
  DeviceMemory m;
  for (const auto& [k, c] : impl_->clouds) {
    ++m.num_clouds;
    m.num_points += c.device.size;
    m.cloud_bytes += c.device.size * 10 * sizeof(float);
  }
  for (const auto& [k, v] : impl_->maps) {
    ++m.num_maps;
    m.num_voxels += v.device.num_voxels;
    m.num_slots += v.device.mask + 1;
    m.map_bytes += v.device.num_voxels * 10 * sizeof(float) + (v.device.mask + 1) * sizeof(VoxelSlot);
  }
  m.batch_bytes = impl_->batch.device_bytes() + impl_->registration.batch.device_bytes();
  return m;
}

std::string CudaBackend::name() const { return std::string("cuda: ") + device::device_name(); }

#else  // no CUDA in this build

bool device_available(std::string* why) {
  if (why) *why = "this gcmap was built without CUDA";
  return false;
}

struct CudaBackend::Impl {};
CudaBackend::CudaBackend() { throw Error("device cuda: this gcmap was built without CUDA (GCMAP_CUDA=OFF or no nvcc)"); }
CudaBackend::~CudaBackend() = default;
void CudaBackend::linearize(std::span<Factor* const>, std::span<const FactorPoses>, std::span<FactorLinearization>) {}
void CudaBackend::trial_errors(std::span<Factor* const>, std::span<const FactorPoses>, std::span<double>) {}
void CudaBackend::overlaps(const std::shared_ptr<const PointCloud>&, std::span<const std::shared_ptr<const GaussianVoxelMap>>,
                           std::span<const Eigen::Isometry3d>, std::span<double>) {}
RegistrationResult CudaBackend::align(const PointCloud& source, const std::shared_ptr<const GaussianVoxelMap>& target,
                                      const Eigen::Isometry3d& init, const RegistrationConfig& config) {
  return LinearizationBackend::align(source, target, init, config);
}
void CudaBackend::estimate_covariances(PointCloud& cloud, const CovarianceConfig& config) {
  LinearizationBackend::estimate_covariances(cloud, config);
}
void CudaBackend::release_unused() {}
DeviceMemory CudaBackend::memory() const { return {}; }
std::string CudaBackend::name() const { return "cuda"; }

#endif

std::shared_ptr<LinearizationBackend> make_backend(Device device) {
  if (device == Device::cpu) return std::make_shared<CpuBackend>();
  if (device == Device::cuda) return std::make_shared<CudaBackend>();
  std::string why;
  if (device_available(&why)) return std::make_shared<CudaBackend>();
#ifdef GCMAP_WITH_CUDA
  spdlog::info("--device auto: no usable GPU, using the CPU ({})", why);
#endif
  return std::make_shared<CpuBackend>();
}

}  // namespace gcmap::cuda
