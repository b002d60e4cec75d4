#include "gcmap/viz/report_html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace gcmap::viz {

namespace {

std::string escaped(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else out += c;
  }
  return out;
}

double rounded(double v) { return std::round(v * 100.0) / 100.0; }

// Map points from above, [x, y, submap] flattened, in the output frame; the trajectory [x, y].
Json map_points(const MappingPipeline& p, size_t max_points) {
  const Mapper& m = p.mapper();
  size_t total = 0;
  for (const Submap& s : m.submaps()) total += s.factor_source->size();
  const size_t stride = std::max<size_t>(1, (total + max_points - 1) / std::max<size_t>(max_points, 1));
  Json a = Json::array();
  const Eigen::Isometry3d T_out_world = m.output_from_world();
  for (const Submap& s : m.submaps()) {
    const Eigen::Isometry3d T = T_out_world * m.submap_pose(s.id);
    for (size_t i = 0; i < s.factor_source->size(); i += stride) {
      const Eigen::Vector3d q = T * s.factor_source->points[i].cast<double>();
      a.push_back(rounded(q.x())), a.push_back(rounded(q.y())), a.push_back(s.id);
    }
  }
  return a;
}

Json trajectory_xy(const MappingPipeline& p) {
  Json a = Json::array();
  for (const Eigen::Isometry3d& T : p.trajectory())
    a.push_back(rounded(T.translation().x())), a.push_back(rounded(T.translation().y()));
  return a;
}

std::string row(std::initializer_list<std::string> cells) {
  std::string r = "<tr>";
  for (const std::string& c : cells) r += "<td>" + escaped(c) + "</td>";
  return r + "</tr>\n";
}

std::string num(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string flagged_frames_table(const QualityReport& r) {
  std::string t =
      "<table id=\"frames\"><tr><th>frame</th><th>conditioning</th><th>weak</th><th>inliers</th><th>deskew shift "
      "(m)</th><th>odometry</th></tr>\n";
  for (const FrameQualityRecord& f : r.frames) {
    if (!f.degenerate && !f.failed) continue;
    const RegistrationQuality& q = f.figures.registration;
    t += row({std::to_string(f.index), num("%.4f", q.conditioning()), to_string(f.weak_axis), num("%.2f", q.inlier_fraction),
              num("%.3f", f.figures.deskew_shift), f.failed ? to_string(q.failure) : "ok"});
  }
  return t + "</table>\n";
}

std::string pairs_table(const QualityReport& r) {
  std::string t =
      "<table id=\"pairs\"><tr><th>submaps</th><th>shift (m)</th><th>limit (m)</th><th>rotation "
      "(deg)</th><th>inliers</th><th>coarse</th><th>consistent</th></tr>\n";
  for (const SubmapPairRecord& p : r.pairs)
    if (p.source > p.target + 1)
      t += row({std::to_string(p.target) + "-" + std::to_string(p.source), num("%.3f", p.shift), num("%.3f", p.limit),
                num("%.2f", p.rotation_deg), num("%.2f", p.inlier_fraction), p.coarse ? "yes" : "no",
                p.inconsistent ? "no" : "yes"});
  return t + "</table>\n";
}

std::string loops_table(const QualityReport& r) {
  std::string t =
      "<table id=\"loops\"><tr><th>submaps</th><th>descriptor distance</th><th>inliers</th><th>rmse "
      "(m)</th><th>decision</th></tr>\n";
  for (const LoopRecord& l : r.loops)
    t += row({std::to_string(l.target) + "-" + std::to_string(l.source), num("%.3f", l.descriptor_distance),
              num("%.2f", l.inlier_fraction), num("%.3f", l.inlier_rmse), l.accepted ? "accepted" : "rejected"});
  return t + "</table>\n";
}

std::string stamps_table(const QualityReport& r) {
  std::string t = "<table id=\"stamps\"><tr><th>frame</th><th>interval (s)</th></tr>\n";
  for (const StampAnomaly& a : r.stamp_anomalies) t += row({std::to_string(a.frame), num("%.4f", a.interval)});
  return t + "</table>\n";
}

// Draws from the embedded data; logs one line, which the browser test checks.
constexpr const char* kScript = R"JS(
const D = JSON.parse(document.getElementById('data').textContent);
function fit(c, xs, ys) {
  const x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
  const s = 0.95 * Math.min(c.width / Math.max(x1 - x0, 1e-3), c.height / Math.max(y1 - y0, 1e-3));
  return [(x) => (c.width - s * (x1 - x0)) / 2 + s * (x - x0), (y) => (c.height + s * (y1 - y0)) / 2 - s * (y - y0)];
}
function drawMap() {
  const c = document.getElementById('map'), g = c.getContext('2d'), P = D.points, T = D.trajectory;
  g.fillStyle = '#fff'; g.fillRect(0, 0, c.width, c.height);
  const xs = [], ys = [];
  for (let i = 0; i < T.length; i += 2) { xs.push(T[i]); ys.push(T[i + 1]); }
  for (let i = 0; i < P.length; i += 3 * 50) { xs.push(P[i]); ys.push(P[i + 1]); }
  if (!xs.length) return 0;
  const [fx, fy] = fit(c, xs, ys), S = D.quality.submaps;
  for (let i = 0; i < P.length; i += 3) {
    const s = S[P[i + 2]], w = s.worst_ratio;
    g.fillStyle = s.inconsistent ? '#d62728' : w > 0.5 ? '#ff9f1c' : '#7f9f7f';
    g.fillRect(fx(P[i]), fy(P[i + 1]), 1.5, 1.5);
  }
  const F = D.quality.frames;
  for (let k = 1; k < T.length / 2; ++k) {
    g.strokeStyle = F[k].odometry_failed ? '#d62728' : F[k].degenerate ? '#c000c0' : '#1f4fbf';
    g.lineWidth = F[k].degenerate || F[k].odometry_failed ? 4 : 2;
    g.beginPath(); g.moveTo(fx(T[2 * k - 2]), fy(T[2 * k - 1])); g.lineTo(fx(T[2 * k]), fy(T[2 * k + 1])); g.stroke();
  }
  return P.length / 3;
}
function drawConditioning() {
  const c = document.getElementById('conditioning'), g = c.getContext('2d'), F = D.quality.frames;
  g.fillStyle = '#fff'; g.fillRect(0, 0, c.width, c.height);
  const y = (v) => c.height * (1 - (Math.log10(Math.max(v, 1e-4)) + 4) / 4), x = (k) => c.width * k / Math.max(F.length - 1, 1);
  g.strokeStyle = '#d62728'; g.beginPath(); g.moveTo(0, y(D.quality.thresholds.degenerate_conditioning));
  g.lineTo(c.width, y(D.quality.thresholds.degenerate_conditioning)); g.stroke();
  g.strokeStyle = '#1f4fbf'; g.beginPath();
  F.forEach((f, k) => { if (f.registered) g.lineTo(x(k), y(f.conditioning)); });
  g.stroke();
}
const drawn = drawMap();
drawConditioning();
console.log('gcmap report: drew ' + drawn + ' map points, ' + D.quality.frames.length + ' frames');
)JS";

}  // namespace

std::string report_html(const QualityReport& r, const MappingPipeline& pipeline, size_t max_points) {
  const size_t degenerate = std::count_if(r.frames.begin(), r.frames.end(), [](const auto& f) { return f.degenerate; });
  const size_t inconsistent = std::count_if(r.pairs.begin(), r.pairs.end(), [](const auto& p) { return p.inconsistent; });
  Json data = Json::object();
  data["quality"] = quality_json(r);
  data["points"] = map_points(pipeline, max_points);
  data["trajectory"] = trajectory_xy(pipeline);
  std::string json = data.dump();
  for (size_t at = json.find("</"); at != std::string::npos; at = json.find("</", at)) json.replace(at, 2, "<\\/");
  std::string verdict;
  for (const std::string& s : r.verdict) verdict += "<li>" + escaped(s) + "</li>\n";
  const std::string title = "gcmap report: " + std::to_string(r.frames.size()) + " frames, " + std::to_string(degenerate) +
                            " degenerate, " + std::to_string(inconsistent) + " disagreeing submap pairs";
  return "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>" + title +
         "</title>\n<style>body{font-family:sans-serif;margin:1em 2em}table{border-collapse:collapse}"
         "td,th{border:1px solid #ccc;padding:2px 6px;font-size:90%}canvas{border:1px solid #ccc}</style></head><body>\n"
         "<h1>Run quality</h1>\n<h2>Verdict</h2>\n<ul id=\"verdict\">\n" +
         verdict +
         "</ul>\n<h2>Map from above</h2>\n<p>Submaps: grey consistent, orange over half the limit, red disagreeing with a "
         "submap they overlap. Trajectory: blue, magenta degenerate registration, red odometry failure.</p>\n"
         "<canvas id=\"map\" width=\"800\" height=\"600\"></canvas>\n"
         "<h2>Translation conditioning per frame</h2>\n<p>Smallest over largest eigenvalue of the registration's "
         "translation information (log scale, 1e-4 to 1); red: the degeneracy threshold.</p>\n"
         "<canvas id=\"conditioning\" width=\"800\" height=\"150\"></canvas>\n"
         "<h2>Flagged frames</h2>\n" +
         flagged_frames_table(r) + "<h2>Overlapping submaps (not consecutive)</h2>\n" + pairs_table(r) +
         "<h2>Loop candidates</h2>\n" + loops_table(r) + "<h2>Stamp anomalies</h2>\n" + stamps_table(r) +
         "<script id=\"data\" type=\"application/json\">" + json + "</script>\n<script>" + kScript +
         "</script>\n</body></html>\n";
}

}  // namespace gcmap::viz
