#pragma once
// The GPU linearization backend (paper Section III-D): every matching-cost factor of an LM
// iteration is evaluated in one device batch; other factors stay on the CPU. Clouds and voxel maps
// are uploaded once and kept on the device while their host objects live.
#include <memory>
#include <string>

#include "gcmap/graph/backend.hpp"

namespace gcmap::cuda {

// True when this binary has the CUDA backend and a device answers; otherwise `why` says why not.
bool device_available(std::string* why = nullptr);

struct DeviceMemory {
  size_t num_clouds = 0, num_points = 0, cloud_bytes = 0;
  size_t num_maps = 0, num_voxels = 0, num_slots = 0, map_bytes = 0;
  size_t batch_bytes = 0;  // per-iteration buffers of the current batch
};

class CudaBackend : public LinearizationBackend {
 public:
  CudaBackend();  // throws Error when the binary has no CUDA or no device answers
  ~CudaBackend() override;

  void linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                 std::span<FactorLinearization> out) override;
  void trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) override;
  void overlaps(const std::shared_ptr<const PointCloud>& source, std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                std::span<const Eigen::Isometry3d> T_target_source, std::span<double> out) override;
  RegistrationResult align(const PointCloud& source, const std::shared_ptr<const GaussianVoxelMap>& target,
                           const Eigen::Isometry3d& init_T_target_source, const RegistrationConfig& config) override;
  // Brute-force k nearest neighbours on the device (device::point_covariances).
  void estimate_covariances(PointCloud& cloud, const CovarianceConfig& config) override;

  // Frees the device copies of clouds and maps whose host objects are gone (also done whenever the
  // set of factors changes).
  void release_unused();
  DeviceMemory memory() const;
  Device device() const override { return Device::cuda; }
  std::string name() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// auto picks the GPU when one answers and otherwise logs one line and uses the CPU; cuda without a
// usable GPU is an error.
std::shared_ptr<LinearizationBackend> make_backend(Device device);

}  // namespace gcmap::cuda
