// The run-quality report (quality.json, report.html) against the simulator's ground truth: the
// frames it flags as degenerate are those whose true frame-to-frame error grows, an unclosed
// revisit shows as disagreeing submaps only while it is not closed.
#include <algorithm>
#include <cstdlib>
#include <regex>
#include <sstream>

#include "gcmap/io/file.hpp"
#include "gcmap/mapping/quality.hpp"
#include "gcmap/sim/simulator.hpp"
#include "gcmap/viz/report_html.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

struct MappedDrive {
  std::vector<Eigen::Isometry3d> truth;
  std::unique_ptr<MappingPipeline> pipeline;
  QualityReport report;
};

MappedDrive map_drive(const std::string& scenario, int frames, MappingConfig config = {},
                      sim::RealismConfig realism = sim::RealismConfig::none(), uint64_t seed = 1) {
  sim::SimulationConfig cfg;
  cfg.seed = seed;
  cfg.scenario = scenario;
  cfg.frames = frames;
  cfg.realism = realism;
  sim::Simulator simulator(cfg);
  MappedDrive d;
  d.truth = simulator.poses();
  d.pipeline = std::make_unique<MappingPipeline>(config);
  for (size_t f = 0; f < simulator.num_frames(); ++f) d.pipeline->add_scan(simulator.scan(f), 0.1 * f);
  d.pipeline->finish();
  d.report = assess_quality(*d.pipeline);
  return d;
}

// The odometry's frame-to-frame translation error against the truth (m), 0 for frame 0.
std::vector<double> frame_to_frame_errors(const MappedDrive& d) {
  const auto& odom = d.pipeline->odometry();
  std::vector<double> e(odom.size(), 0.0);
  for (size_t i = 1; i < odom.size(); ++i)
    e[i] = test::translation_error(d.truth[i - 1].inverse() * d.truth[i], odom[i - 1].inverse() * odom[i]);
  return e;
}

TEST(Quality, DegenerateFramesAreThoseWhoseTrueErrorGrowsInATunnel) {
  const MappedDrive d = map_drive("tunnel", 150);
  const std::vector<double> error = frame_to_frame_errors(d);
  // A frame is bad at 4x the typical (median) error outside the canyon, whatever the odometry's
  // accuracy there, and above the worst outside (where it is millimetres, single frames reach 4x).
  std::vector<double> outside;
  for (size_t i = 1; i < error.size(); ++i)
    if (d.truth[i].translation().x() < 50.0) outside.push_back(error[i]);
  ASSERT_GE(outside.size(), 20u);
  std::nth_element(outside.begin(), outside.begin() + outside.size() / 2, outside.end());
  const double typical = outside[outside.size() / 2];
  const double bad_error = std::max(4.0 * typical, *std::max_element(outside.begin(), outside.end()));
  int flagged = 0, bad = 0, both = 0;
  double flagged_sum = 0.0, other_sum = 0.0;
  for (const FrameQualityRecord& f : d.report.frames) {
    if (f.index == 0) continue;
    const double x = d.truth[f.index].translation().x();
    if (f.degenerate) EXPECT_GT(x, 50.0) << "frame " << f.index << " flagged outside the canyon (from 50 m on)";
    if (f.degenerate) EXPECT_EQ(f.weak_axis, WeakAxis::along_travel) << "frame " << f.index;
    flagged += f.degenerate, bad += error[f.index] > bad_error, both += f.degenerate && error[f.index] > bad_error;
    (f.degenerate ? flagged_sum : other_sum) += error[f.index];
  }
  std::printf("typical error outside %.4f m; %d flagged, %d over %.4f m, %d both\n", typical, flagged, bad, bad_error, both);
  ASSERT_GE(flagged, 20);
  ASSERT_GE(bad, 10);
  const double precision = static_cast<double>(both) / flagged, recall = static_cast<double>(both) / bad;
  EXPECT_GE(recall, 0.9) << both << " of " << bad << " frames over " << bad_error << " m flagged";
  EXPECT_GE(precision, 0.4) << both << " of " << flagged << " flagged frames over " << bad_error << " m";
  EXPECT_GT(flagged_sum / flagged, 3.0 * other_sum / (d.report.frames.size() - 1 - flagged));
  ASSERT_FALSE(d.report.verdict.empty());
  EXPECT_NE(d.report.verdict[0].find("degenerate (weak along the direction of travel)"), std::string::npos)
      << d.report.verdict[0];
}

// The small scenario's revisit of the start, with the realistic sensor (drift of a few cm). Open:
// without explicit loops and with a sliding window of global factors nothing ties the last submap
// to the first. Closed: the default mapping (explicit loops on, a factor to every overlapping submap).
MappedDrive map_revisit(bool closed) {
  MappingConfig config;
  if (!closed) config.global.mode = GlobalMode::sliding_window, config.loop.enabled = false;
  // Seed 2 on ten neighbours per covariance: its open revisit drifts apart enough to flag. Seed 1's
  // no longer does since the simulated walk and drive lost their jolts (e574af8), nor does seed 3's,
  // nor seed 2's on the default twenty neighbours, whose odometry drifts less.
  config.preprocess.num_neighbors = 10;
  return map_drive("small", 0, config, sim::RealismConfig::all(), 2);
}

// Pairs of submaps flagged as disagreeing.
std::vector<std::pair<int, int>> disagreeing(const QualityReport& r) {
  std::vector<std::pair<int, int>> out;
  for (const SubmapPairRecord& p : r.pairs)
    if (p.inconsistent) out.emplace_back(p.target, p.source);
  return out;
}

// The truth says each flagged pair passes the same place, far apart in time.
void expect_revisits(const MappedDrive& open, const std::vector<std::pair<int, int>>& flagged) {
  for (const auto& [a, b] : flagged) {
    double closest = 1e9;  // between the keyframes of the two submaps
    for (const int ka : open.pipeline->submaps()[a].keyframes)
      for (const int kb : open.pipeline->submaps()[b].keyframes)
        closest = std::min(closest, (open.truth[ka].translation() - open.truth[kb].translation()).norm());
    EXPECT_LT(closest, 5.0) << a << "-" << b;
    EXPECT_GT(b - a, 3) << a << "-" << b;
  }
}

// The quality: section of the config reaches the flags: the same drive judged with a larger
// factor flags no pair, with a higher conditioning threshold more frames.
void expect_config_keys_change_the_flags(const MappedDrive& open) {
  const MappingConfig lenient = MappingConfig::parse("quality:\n  inconsistent_factor: 1000\n", "test");
  EXPECT_TRUE(disagreeing(assess_quality(*open.pipeline, lenient.quality)).empty());
  const auto degenerate = [](const QualityReport& r) {
    return std::count_if(r.frames.begin(), r.frames.end(), [](const auto& f) { return f.degenerate; });
  };
  const MappingConfig strict = MappingConfig::parse("quality:\n  degenerate_conditioning: 0.9\n", "test");
  EXPECT_GT(degenerate(assess_quality(*open.pipeline, strict.quality)), degenerate(open.report) + 10);
}

// Every submap of more than one keyframe measures its keyframes' disagreement, and it is the
// baseline of its pairs: averaged over the keyframes, it predicts the shift of consecutive submaps.
// A noisier sensor (the realistic one) makes the keyframes disagree more than the ideal one.
void expect_noise_is_the_keyframes_disagreement(const MappedDrive& clean, const MappedDrive& noisy) {
  const auto mid = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  std::vector<double> noise[2];
  for (int k = 0; k < 2; ++k) {
    const MappedDrive& d = k == 0 ? clean : noisy;
    for (const SubmapQualityRecord& s : d.report.submaps) {
      const Submap& submap = d.pipeline->submaps()[s.id];
      ASSERT_EQ(submap.keyframe_noise.has_value(), submap.keyframes.size() > 1) << s.id;
      if (!submap.keyframe_noise) continue;
      EXPECT_EQ(s.baseline, NoiseBaseline::keyframes);
      EXPECT_DOUBLE_EQ(s.keyframe_noise, *submap.keyframe_noise);
      EXPECT_LT(s.keyframe_noise, 0.05) << s.id;  // m: far below the drift a revisit flags
      noise[k].push_back(s.keyframe_noise);
    }
    std::vector<double> predicted;
    for (const SubmapPairRecord& p : d.report.pairs) {
      EXPECT_NEAR(p.limit, std::max(0.02, 4.0 * p.noise), 1e-12);
      if (p.source == p.target + 1) predicted.push_back(p.noise);
    }
    ASSERT_FALSE(predicted.empty());
    EXPECT_GT(mid(predicted), d.report.consecutive_shift / 4.0);
    EXPECT_LT(mid(predicted), d.report.consecutive_shift * 4.0);
  }
  ASSERT_GT(noise[0].size(), 5u);
  ASSERT_GT(noise[1].size(), 5u);
  EXPECT_GT(mid(noise[1]), 1.5 * mid(noise[0]));
}

// One test for the three drives it needs (each mapping takes a while).
TEST(Quality, AnUnclosedRevisitIsFlaggedAgainstTheKeyframesNoiseAndAClosedOneIsNot) {
  const MappedDrive open = map_revisit(false);
  const auto flagged = disagreeing(open.report);
  ASSERT_FALSE(flagged.empty()) << "consecutive shift " << open.report.consecutive_shift;
  expect_revisits(open, flagged);
  const bool said = std::any_of(open.report.verdict.begin(), open.report.verdict.end(),
                                [](const std::string& s) { return s.find("a revisit that did not close") != std::string::npos; });
  EXPECT_TRUE(said) << open.report.verdict[0];
  expect_config_keys_change_the_flags(open);

  const MappedDrive closed = map_revisit(true);
  EXPECT_TRUE(disagreeing(closed.report).empty()) << closed.report.verdict[0];
  expect_noise_is_the_keyframes_disagreement(map_drive("small", 0), open);
}

// report.html in headless Chromium (as view.html in test_viewer_browser.cpp): it loads without a
// console error, draws the map, and shows the verdict and the flagged frames of the tunnel.
TEST(Quality, ReportPageLoadsInChromiumAndShowsTheVerdict) {
  std::string chromium;
  for (const char* name : {"chromium-headless-shell", "chromium"})
    if (chromium.empty() && std::system((std::string("command -v ") + name + " >/dev/null 2>&1").c_str()) == 0) chromium = name;
  if (chromium.empty()) GTEST_SKIP() << "no chromium-headless-shell or chromium on PATH";
  const MappedDrive d = map_drive("tunnel", 120);
  test::TempDir dir;
  write_file_atomic(dir / "report.html", [&](std::ostream& s) { s << viz::report_html(d.report, *d.pipeline); });
  const std::string cmd = "timeout 60 " + chromium + " --headless --no-sandbox --disable-gpu --enable-logging=stderr --v=0" +
                          " --no-first-run --user-data-dir='" + dir / "profile" + "' --dump-dom 'file://" + dir / "report.html" +
                          "' > '" + dir / "dom.out" + "' 2> '" + dir / "dom.log" + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << test::slurp(dir / "dom.log");
  const std::string dom = test::slurp(dir / "dom.out"), log = test::slurp(dir / "dom.log");
  std::vector<std::string> console;
  std::stringstream in(log);
  for (std::string line; std::getline(in, line);)
    if (line.find(":CONSOLE") != std::string::npos) console.push_back(line);
  ASSERT_EQ(console.size(), 1u) << log;  // only the page's own line: no error or exception
  std::smatch m;
  ASSERT_TRUE(std::regex_search(console[0], m, std::regex("gcmap report: drew ([0-9]+) map points"))) << console[0];
  EXPECT_GT(std::stoul(m[1]), 1000u);  // an empty map draws 0
  EXPECT_NE(console[0].find(" map points, 120 frames"), std::string::npos) << console[0];
  const size_t degenerate =
      std::count_if(d.report.frames.begin(), d.report.frames.end(), [](const auto& f) { return f.degenerate; });
  ASSERT_GT(degenerate, 0u);
  EXPECT_NE(dom.find("<title>gcmap report: 120 frames, " + std::to_string(degenerate) + " degenerate"), std::string::npos)
      << dom.substr(0, 400);
  EXPECT_NE(dom.find(d.report.verdict[0]), std::string::npos);
}

}  // namespace
}  // namespace gcmap
