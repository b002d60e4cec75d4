#include "gcmap/session/session.hpp"

#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <bit>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/mapper.hpp"

namespace gcmap {

namespace fs = std::filesystem;
static_assert(std::endian::native == std::endian::little, "the session format is little endian");

namespace {

constexpr char kMagic[8] = {'G', 'C', 'M', 'A', 'P', 'S', 'M', '1'};

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
void put_pose(std::string& out, const Eigen::Isometry3d& T) {
  double v[7];
  pose_to_xyz_quat(T, v);
  out.append(reinterpret_cast<const char*>(v), sizeof v);
}

// Bounds-checked reading: every count is checked against the bytes left before allocating.
class Reader {
 public:
  Reader(const std::string& bytes, std::string path) : bytes_(bytes), path_(std::move(path)) {}
  template <typename T>
  T get() {
    T v;
    std::memcpy(&v, take(sizeof(T)), sizeof(T));
    return v;
  }
  Eigen::Isometry3d pose() {
    double v[7];
    std::memcpy(v, take(sizeof v), sizeof v);
    for (double x : v)
      if (!std::isfinite(x)) fail("a pose is not finite");
    if (std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]) < 1e-6) fail("a pose has a zero quaternion");
    return pose_from_xyz_quat(v);
  }
  // A count of records of `record_bytes` each that must fit in what is left.
  uint32_t count(size_t record_bytes, const char* what) {
    const uint32_t n = get<uint32_t>();
    if (record_bytes && n > (bytes_.size() - pos_) / record_bytes)
      fail(std::to_string(n) + " " + what + " do not fit in the " + std::to_string(bytes_.size() - pos_) + " bytes left");
    return n;
  }
  // Fails unless n more bytes are left.
  void need(uint64_t n, const std::string& what) {
    if (n > bytes_.size() - pos_) fail(what + " do not fit in the " + std::to_string(bytes_.size() - pos_) + " bytes left");
  }
  template <typename T>
  void array(T* out, size_t n) {
    std::memcpy(out, take(n * sizeof(T)), n * sizeof(T));
  }
  bool done() const { return pos_ == bytes_.size(); }
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(path_ + ": " + what + " (byte " + std::to_string(pos_) + ")");
  }

 private:
  const char* take(size_t n) {
    if (n > bytes_.size() - pos_) fail("truncated");
    const char* p = bytes_.data() + pos_;
    pos_ += n;
    return p;
  }
  const std::string& bytes_;
  std::string path_;
  size_t pos_ = 0;
};

void put_submap(std::string& out, const Submap& s, const Eigen::Isometry3d& T_world_submap) {
  put<int32_t>(out, s.id);
  put_pose(out, T_world_submap);
  put_pose(out, s.T_odom);
  put<uint32_t>(out, static_cast<uint32_t>(s.keyframes.size()));
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    put<int32_t>(out, s.keyframes[k]);
    put_pose(out, s.T_submap_keyframe[k]);
  }
  const bool descriptors = !s.descriptors.empty();
  put<uint32_t>(out, descriptors ? s.descriptors[0].rings : 0);
  put<uint32_t>(out, descriptors ? s.descriptors[0].sectors : 0);
  for (const ScanContext& d : s.descriptors) {
    out.append(reinterpret_cast<const char*>(d.cells.data()), d.cells.size() * sizeof(float));
    out.append(reinterpret_cast<const char*>(d.ring_key.data()), d.ring_key.size() * sizeof(float));
  }
  const PointCloud& c = *s.cloud;
  put<uint32_t>(out, static_cast<uint32_t>(c.size()));
  for (const Eigen::Vector3f& p : c.points) out.append(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
  for (const Eigen::Matrix3f& m : c.covs) {
    const float v[6] = {m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)};
    out.append(reinterpret_cast<const char*>(v), sizeof v);
  }
  put<uint8_t>(out, c.has_intensities() ? 1 : 0);
  out.append(reinterpret_cast<const char*>(c.intensities.data()), c.intensities.size() * sizeof(float));
}

// Version 2: a flag, then a float per point when the submap had intensities.
void get_intensities(Reader& in, int id, PointCloud& cloud) {
  const uint8_t flag = in.get<uint8_t>();
  if (flag > 1) in.fail("submap " + std::to_string(id) + ": intensity flag " + std::to_string(flag) + " is neither 0 nor 1");
  if (!flag) return;
  in.need(uint64_t(cloud.size()) * sizeof(float), std::to_string(cloud.size()) + " intensities");
  cloud.intensities.resize(cloud.size());
  in.array(cloud.intensities.data(), cloud.intensities.size());
}

Submap get_submap(Reader& in, uint32_t version, Eigen::Isometry3d* T_world_submap) {
  Submap s;
  s.id = in.get<int32_t>();
  *T_world_submap = in.pose();
  s.T_odom = in.pose();
  const uint32_t keyframes = in.count(4 + 56, "keyframes");
  for (uint32_t k = 0; k < keyframes; ++k) {
    s.keyframes.push_back(in.get<int32_t>());
    s.T_submap_keyframe.push_back(in.pose());
  }
  const uint32_t rings = in.get<uint32_t>(), sectors = in.get<uint32_t>();
  if (rings > 1000 || sectors > 10000)
    in.fail("implausible descriptor size " + std::to_string(rings) + " x " + std::to_string(sectors));
  if (rings && sectors) {
    in.need(uint64_t(keyframes) * (rings * sectors + rings) * sizeof(float), "descriptors");
    for (uint32_t k = 0; k < keyframes; ++k) {
      ScanContext d;
      d.rings = static_cast<int>(rings);
      d.sectors = static_cast<int>(sectors);
      d.cells.resize(size_t(rings) * sectors);
      d.ring_key.resize(rings);
      in.array(d.cells.data(), d.cells.size());
      in.array(d.ring_key.data(), d.ring_key.size());
      s.descriptors.push_back(std::move(d));
    }
  }
  auto cloud = std::make_shared<PointCloud>();
  const uint32_t n = in.count(9 * sizeof(float), "points");
  cloud->points.resize(n);
  cloud->covs.resize(n);
  for (auto& p : cloud->points) in.array(p.data(), 3);
  for (auto& m : cloud->covs) {
    float v[6];
    in.array(v, 6);
    m << v[0], v[1], v[2], v[1], v[3], v[4], v[2], v[4], v[5];
  }
  if (version >= 2) get_intensities(in, s.id, *cloud);
  if (!cloud->points.empty() && remove_non_finite(*cloud) > 0)
    in.fail("submap " + std::to_string(s.id) + " has non-finite points");
  s.cloud = std::move(cloud);
  return s;
}

// What a run leaves besides the clouds, readable by people and by yaml-cpp.
std::string manifest_yaml(const Session& s) {
  std::ostringstream m;
  m << "format: gcmap-session\nversion: " << kSessionVersion << "\ncreated_by: gcmap " << GCMAP_VERSION
    << "\nframes: " << s.trajectory.size() << "\nsubmaps: " << s.submaps.size() << "\nfactors:\n";
  for (const SessionFactor& f : s.factors)
    m << "  - [" << to_string(f.kind) << ", " << f.source << ", " << f.target << ", " << f.overlap << "]\n";
  return m.str();
}

FactorKind parse_factor_kind(const std::string& text, const std::string& path) {
  for (FactorKind k : kFactorKinds)
    if (text == to_string(k)) return k;
  throw Error(path + ": unknown factor kind '" + text + "'");
}

void read_manifest(const std::string& path, Session& s, size_t* frames, size_t* submaps) {
  YAML::Node m;
  try {
    m = YAML::Load(read_file(path));
    if (!m.IsMap() || m["format"].as<std::string>("") != "gcmap-session") throw Error(path + ": not a gcmap session manifest");
    s.version = m["version"].as<int>();
    if (s.version > kSessionVersion)
      throw Error(path + ": session version " + std::to_string(s.version) + " is newer than this gcmap reads (" +
                  std::to_string(kSessionVersion) + "): use a newer gcmap");
    if (s.version < 1) throw Error(path + ": bad session version " + std::to_string(s.version));
    s.created_by = m["created_by"].as<std::string>("");
    *frames = m["frames"].as<size_t>();
    *submaps = m["submaps"].as<size_t>();
    for (const auto& f : m["factors"]) {
      if (!f.IsSequence() || f.size() != 4) throw Error(path + ": a factor must be [kind, source, target, overlap]");
      s.factors.push_back({parse_factor_kind(f[0].as<std::string>(), path), f[1].as<int>(), f[2].as<int>(), f[3].as<double>()});
    }
  } catch (const YAML::Exception& e) { throw Error(path + ": unreadable manifest (" + std::string(e.what()) + ")"); }
}

// Voxel maps and factor sources, as the run that wrote the session made them.
void rebuild(Submap& s, const MappingConfig& config) {
  auto voxels = std::make_shared<GaussianVoxelMap>(config.global.voxel_resolution);
  voxels->insert(*s.cloud);
  voxels->finalize();
  s.voxels = voxels;
  PointCloud source = evenly_subsampled(*s.cloud, config.global.factor_source_points);
  std::vector<float>().swap(source.intensities);  // the factors read points and covariances only
  s.factor_source = std::make_shared<const PointCloud>(std::move(source));
}

// The reader takes a covariance (and an intensity, when any) per point: anything else would be
// written as a file that does not read back.
void check_channels(const std::string& dir, const Submap& m) {
  const PointCloud& c = *m.cloud;
  if (c.covs.size() != c.size() || (c.has_intensities() && c.intensities.size() != c.size()))
    throw Error(dir + ": submap " + std::to_string(m.id) + " has " + std::to_string(c.size()) + " points, " +
                std::to_string(c.covs.size()) + " covariances and " + std::to_string(c.intensities.size()) + " intensities");
}

// Writes into a fresh folder beside DIR, then swaps it in.
void write_folder(const fs::path& dir, const std::function<void(const fs::path&)>& write) {
  const fs::path tmp = dir.string() + ".tmp." + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(tmp, ec);
  if (!fs::create_directories(tmp, ec) || ec) throw Error(tmp.string() + ": cannot create (" + ec.message() + ")");
  try {
    write(tmp);
    gcmap::replace_folder(tmp.string(), dir.string());  // no instant without a session
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(tmp, ec);
    throw Error(dir.string() + ": cannot replace (" + e.code().message() + ")");
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace

Session make_session(const MappingPipeline& p, const std::vector<double>& stamps) {
  Session s;
  s.config = p.config();
  s.submaps = p.submaps();
  const Eigen::Isometry3d T_out_world = p.mapper().output_from_world();
  for (const Submap& m : p.submaps()) s.T_world_submap.push_back(T_out_world * p.mapper().submap_pose(m.id));
  for (const GlobalFactor& f : p.factors()) s.factors.push_back({f.kind, f.source, f.target, f.overlap});
  s.trajectory = p.trajectory();
  s.stamps = stamps;
  s.stamps.resize(s.trajectory.size(), 0.0);
  return s;
}

void write_session(const std::string& dir, const MappingPipeline& p, const std::vector<double>& stamps) {
  write_session(dir, make_session(p, stamps));
}

void write_session(const std::string& dir, const Session& s) {
  if (s.submaps.size() != s.T_world_submap.size() || s.stamps.size() != s.trajectory.size())
    throw Error(dir + ": inconsistent session (submaps and poses, or frames and stamps, differ in number)");
  for (const Submap& m : s.submaps) check_channels(dir, m);
  write_folder(dir, [&](const fs::path& tmp) {
    write_file_atomic((tmp / "submaps.bin").string(), [&](std::ostream& o) {
      // A submap at a time: the whole file in memory would be the largest buffer of a run.
      std::string bin(kMagic, sizeof kMagic);
      put<uint32_t>(bin, kSessionVersion);
      put<uint32_t>(bin, static_cast<uint32_t>(s.submaps.size()));
      for (size_t k = 0; k < s.submaps.size(); ++k) {
        put_submap(bin, s.submaps[k], s.T_world_submap[k]);
        o.write(bin.data(), static_cast<std::streamsize>(bin.size()));
        bin.clear();
      }
      o.write(bin.data(), static_cast<std::streamsize>(bin.size()));
    });
    Trajectory t;
    t.poses = s.trajectory;
    t.stamps = s.stamps;
    t.format = TrajectoryFormat::tum;
    write_trajectory((tmp / "trajectory.tum").string(), t);
    write_file_atomic((tmp / "config.yaml").string(), [&](std::ostream& o) { o << s.config.to_yaml(); });
    write_file_atomic((tmp / "manifest.yaml").string(), [&](std::ostream& o) { o << manifest_yaml(s); });
  });
}

Session read_session(const std::string& dir, const std::function<void(size_t done, size_t total)>& progress) {
  const fs::path root(dir);
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw Error(dir + ": no session folder");
  Session s;
  size_t frames = 0, submaps = 0;
  read_manifest((root / "manifest.yaml").string(), s, &frames, &submaps);
  s.config = MappingConfig::load((root / "config.yaml").string());
  const Trajectory t = read_trajectory((root / "trajectory.tum").string());
  if (t.size() != frames)
    throw Error((root / "trajectory.tum").string() + ": " + std::to_string(t.size()) + " poses, the manifest says " +
                std::to_string(frames) + " frames");
  s.trajectory = t.poses;
  s.stamps = t.stamps;
  const std::string path = (root / "submaps.bin").string();
  const std::string bytes = read_file(path);
  Reader in(bytes, path);
  char magic[8];
  in.array(magic, 8);
  if (std::memcmp(magic, kMagic, 8) != 0) in.fail("not a gcmap submap file");
  const uint32_t version = in.get<uint32_t>();
  if (static_cast<int>(version) != s.version) in.fail("version " + std::to_string(version) + " differs from the manifest's");
  const uint32_t count = in.count(4 + 2 * 56 + 4 + 8 + 4, "submaps");
  if (count != submaps) in.fail(std::to_string(count) + " submaps, the manifest says " + std::to_string(submaps));
  for (uint32_t k = 0; k < count; ++k) {
    Eigen::Isometry3d T;
    s.submaps.push_back(get_submap(in, version, &T));
    if (s.submaps.back().id != static_cast<int>(k)) in.fail("submap ids out of order");
    for (int f : s.submaps.back().keyframes)
      if (f < 0 || static_cast<size_t>(f) >= frames) in.fail("keyframe " + std::to_string(f) + " is not a frame of the session");
    s.T_world_submap.push_back(T);
  }
  if (!in.done()) in.fail("unexpected bytes after the last submap");
  for (const SessionFactor& f : s.factors)
    if (f.source < 0 || f.target < 0 || static_cast<size_t>(std::max(f.source, f.target)) >= count)
      throw Error((root / "manifest.yaml").string() + ": a factor names a submap that does not exist");
  for (size_t k = 0; k < s.submaps.size(); ++k) {
    rebuild(s.submaps[k], s.config);
    if (progress) progress(k + 1, s.submaps.size());
  }
  return s;
}

SessionInfo session_info(const Session& s, const std::string& dir) {
  SessionInfo info;
  info.version = s.version;
  info.created_by = s.created_by;
  info.frames = s.trajectory.size();
  info.submaps = s.submaps.size();
  info.factors = s.factors.size();
  info.intensities = have_intensities(s.submaps);
  for (size_t k = 0; k < s.submaps.size(); ++k) {
    info.keyframes += s.submaps[k].keyframes.size();
    info.points += s.submaps[k].cloud->size();
    for (const Eigen::Vector3f& p : s.submaps[k].cloud->points) info.extent.extend(s.T_world_submap[k] * p.cast<double>());
  }
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.is_regular_file()) info.bytes += e.file_size();
  return info;
}

}  // namespace gcmap
