#include "gcmap/mapping/mapper.hpp"

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

namespace {
const MappingConfig& validated(const MappingConfig& config) {
  config.validate();
  return config;
}
}  // namespace

Mapper::Mapper(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend)
    : config_(validated(config)),
      backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      local_(config_, backend_),
      loops_(config_.loop),
      global_(config_, backend_) {}

FrameStatus Mapper::add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom) {
  if (frame != static_cast<int>(frames_.size())) throw Error("Mapper: frames must be numbered consecutively from 0");
  frames_.push_back({-1, T_odom});
  SubmapBuilder::Result r = local_.add_frame(frame, cloud, T_odom);
  frames_.back().anchor = r.anchor;
  if (r.closed) insert(std::move(*r.closed));
  return r.status;
}

void Mapper::insert(Submap submap) {
  for (size_t k = 0; k < submap.keyframes.size(); ++k) {
    frames_[submap.keyframes[k]].submap = submap.id;
    frames_[submap.keyframes[k]].index = static_cast<int>(k);
  }
  loops_.add_submap(submap);
  global_.insert(std::move(submap), &loops_);
}

void Mapper::finish(std::optional<int> max_final_iterations) {
  if (auto s = local_.close()) insert(std::move(*s));
  global_.optimize_final(max_final_iterations);
}

Eigen::Isometry3d Mapper::keyframe_world(int kf) const {
  const FrameRecord& r = frames_[kf];
  if (r.submap >= 0) return global_.pose(r.submap) * submaps()[r.submap].T_submap_keyframe[r.index];
  // A keyframe of the open submap (only before finish()): placed from the last submap by odometry.
  if (submaps().empty()) return r.T_odom;
  const Submap& last = submaps().back();
  return global_.pose(last.id) * last.T_odom.inverse() * r.T_odom;
}

Eigen::Isometry3d Mapper::world_pose(int f) const {
  const int anchor = frames_[f].anchor;
  if (anchor < 0) return frames_[f].T_odom;
  return keyframe_world(anchor) * frames_[anchor].T_odom.inverse() * frames_[f].T_odom;
}

Eigen::Isometry3d Mapper::output_from_world() const {
  return frames_.empty() ? Eigen::Isometry3d::Identity() : world_pose(0).inverse();
}

Eigen::Isometry3d Mapper::frame_pose(int frame) const { return normalized(output_from_world() * world_pose(frame)); }

std::vector<Eigen::Isometry3d> Mapper::trajectory() const {
  const Eigen::Isometry3d T0_inv = output_from_world();
  std::vector<Eigen::Isometry3d> out(frames_.size());
  for (size_t f = 0; f < frames_.size(); ++f) out[f] = normalized(T0_inv * world_pose(static_cast<int>(f)));
  return out;
}

PointCloud Mapper::assemble_map(double resolution) const {
  // Points only, placed straight into the output frame (first frame identity, like the
  // trajectory): the whole map exists once before downsampling, the peak of a run's memory.
  const Eigen::Isometry3d T_out_world =
      !frames_.empty() && frames_[0].submap >= 0 ? keyframe_world(0).inverse() : Eigen::Isometry3d::Identity();
  size_t total = 0;
  for (const Submap& s : submaps()) total += s.cloud->size();
  PointCloud map;
  map.points.resize(total);
  size_t offset = 0;
  for (const Submap& s : submaps()) {
    const Eigen::Isometry3d T = T_out_world * global_.pose(s.id);
    const Eigen::Matrix3f R = T.linear().cast<float>();
    const Eigen::Vector3f t = T.translation().cast<float>();
    for (const Eigen::Vector3f& p : s.cloud->points) map.points[offset++] = R * p + t;
  }
  return voxel_downsample(map, resolution);
}

}  // namespace gcmap
