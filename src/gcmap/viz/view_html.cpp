#include "gcmap/viz/view_html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/viz/image.hpp"
#include "gcmap/viz/render.hpp"

namespace gcmap::viz {

namespace {

// One of the libjs-three files, checked so that the page cannot end its <script> early.
std::string three_file(const std::string& dir, const std::vector<std::string>& candidates) {
  for (const std::string& rel : candidates) {
    const std::string path = (std::filesystem::path(dir) / rel).string();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) continue;
    std::string js = read_file(path);
    std::string lower = js;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char ch) { return std::tolower(ch); });
    if (lower.find("</script") != std::string::npos) throw Error(path + ": contains \"</script\", cannot be inlined");
    return js;
  }
  throw Error((std::filesystem::path(dir) / candidates.front()).string() +
              ": not found (install Debian's libjs-three, or give the folder that holds three.js)");
}

std::string base64(const std::string& in) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  for (size_t i = 0; i < in.size(); i += 3) {
    uint32_t v = static_cast<uint8_t>(in[i]) << 16;
    if (i + 1 < in.size()) v |= static_cast<uint8_t>(in[i + 1]) << 8;
    if (i + 2 < in.size()) v |= static_cast<uint8_t>(in[i + 2]);
    out += abc[(v >> 18) & 63];
    out += abc[(v >> 12) & 63];
    out += i + 1 < in.size() ? abc[(v >> 6) & 63] : '=';
    out += i + 2 < in.size() ? abc[v & 63] : '=';
  }
  return out;
}

// Evenly spaced indices, at most `max` of them.
std::vector<size_t> decimate(size_t n, size_t max) {
  std::vector<size_t> keep;
  const size_t m = std::min(n, max);
  keep.reserve(m);
  for (size_t k = 0; k < m; ++k) keep.push_back(static_cast<size_t>(static_cast<double>(k) * n / m));
  return keep;
}

void xyz_array(const Eigen::Vector3d& p, Json& arr) {
  for (int k = 0; k < 3; ++k) arr.push_back(std::round(p[k] * 1000.0) / 1000.0);
}

// Bounds, quantization step, colours, trajectory and factor segments.
Json page_meta(const RunData& run, const std::vector<size_t>& keep, const Eigen::Vector3d& lo, const Eigen::Vector3d& step) {
  Json meta = Json::object();
  Json jmin = Json::array(), jmax = Json::array(), jstep = Json::array(), heights = Json::array();
  std::vector<float> z;
  for (size_t i : keep) z.push_back(run.map.points[i].z());
  std::sort(z.begin(), z.end());
  const double zlo = z.empty() ? 0.0 : z[z.size() / 50], zhi = z.empty() ? 1.0 : z[z.size() - 1 - z.size() / 50];
  for (int k = 0; k < 3; ++k) {
    jmin.push_back(lo[k]);
    jmax.push_back(lo[k] + 65535.0 * step[k]);
    jstep.push_back(step[k]);
  }
  meta["min"] = jmin;
  meta["max"] = jmax;
  meta["step"] = jstep;
  heights.push_back(zlo);
  heights.push_back(zhi > zlo ? zhi : zlo + 1.0);
  meta["height_range"] = heights;
  meta["map_points"] = run.map.size();
  Json lut = Json::array();
  for (int i = 0; i < 256; ++i) {
    const Rgb c = colormap(i / 255.0);
    lut.push_back(c.r), lut.push_back(c.g), lut.push_back(c.b);
  }
  meta["colormap"] = lut;
  Json colours = Json::object();
  colours["trajectory"] = palette::trajectory.hex();
  colours["node"] = palette::node.hex();
  meta["colours"] = colours;
  Json traj = Json::array(), nodes = Json::array();
  for (const auto& T : run.trajectory) xyz_array(T.translation(), traj);
  for (const auto& n : run.graph.nodes) xyz_array(n.T_out_submap.translation(), nodes);
  meta["trajectory"] = traj;
  meta["nodes"] = nodes;
  RenderOptions with_graph;
  Json factors = Json::array();
  for (const LegendEntry& e : legend_entries(run, with_graph)) {
    if (!e.factor) continue;
    Json f = Json::object(), seg = Json::array();
    f["label"] = std::to_string(run.graph.count(*e.factor)) + " " + factor_kind_label(*e.factor);
    f["colour"] = e.colour.hex();
    f["opacity"] = *e.factor == FactorKind::matching_cost ? 0.45 : 1.0;
    for (const GraphEdge& g : run.graph.edges)
      if (g.kind == *e.factor) {
        xyz_array(run.graph.nodes[g.source].T_out_submap.translation(), seg);
        xyz_array(run.graph.nodes[g.target].T_out_submap.translation(), seg);
      }
    f["segments"] = seg;
    factors.push_back(f);
  }
  meta["factors"] = factors;
  return meta;
}

// Filled last placeholder first, so that no inserted text is searched for a later placeholder.
void replace_once(std::string& page, const std::string& key, const std::string& value) {
  const size_t at = page.find(key);
  page.replace(at, key.size(), value);
}

}  // namespace

std::string default_three_dir() { return GCMAP_THREE_JS_DIR; }

void ViewOptions::validate() const {
  if (max_points < 1) throw Error("view max_points: must be at least 1");
  if (three_dir.empty()) throw Error("view three_dir: empty (the folder of Debian's libjs-three)");
}

ViewSummary write_view_html(const RunData& run, const std::string& path, const ViewOptions& options) {
  options.validate();
  const std::string three = three_file(options.three_dir, {"build/three.min.js", "three.min.js"});
  const std::string orbit = three_file(options.three_dir, {"examples/js/controls/OrbitControls.js"});
  const std::vector<size_t> keep = decimate(run.map.size(), options.max_points);
  Eigen::AlignedBox3d box;
  for (size_t i : keep) box.extend(run.map.points[i].cast<double>());
  if (box.isEmpty()) box = Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
  const Eigen::Vector3d lo = box.min(), step = (box.sizes() / 65535.0).cwiseMax(1e-6);
  std::string packed(6 * keep.size(), '\0');
  for (size_t j = 0; j < keep.size(); ++j)
    for (int k = 0; k < 3; ++k) {
      const double q = std::round((run.map.points[keep[j]][k] - lo[k]) / step[k]);
      const uint16_t v = static_cast<uint16_t>(std::clamp(q, 0.0, 65535.0));
      packed[6 * j + 2 * k] = static_cast<char>(v & 0xff);
      packed[6 * j + 2 * k + 1] = static_cast<char>(v >> 8);
    }
  std::string page = kViewPageTemplate;
  replace_once(page, "@POINTS@", base64(packed));
  replace_once(page, "@META@", page_meta(run, keep, lo, step).dump());
  replace_once(page, "@ORBIT@", orbit);
  replace_once(page, "@THREE@", three);
  write_file_atomic(path, [&](std::ostream& out) { out.write(page.data(), static_cast<std::streamsize>(page.size())); });
  return {run.map.size(), keep.size(), page.size()};
}

WrittenFile view_run(const std::string& dir, const std::string& path, const ViewOptions& options) {
  options.validate();
  const RunData run = read_run(dir, true);
  const ViewSummary s = write_view_html(run, path, options);
  char mb[32];
  std::snprintf(mb, sizeof(mb), "%.1f MB", s.bytes / 1e6);
  return {path, std::string("3D viewer page (") + mb + ", " + std::to_string(s.points_written) + " of " +
                    std::to_string(s.map_points) + " map points, trajectory and factor graph layers)"};
}

}  // namespace gcmap::viz
