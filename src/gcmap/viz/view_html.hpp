#pragma once
// A self-contained 3D viewer page: three.js and its OrbitControls (Debian's libjs-three) inlined,
// the map decimated and packed as 16-bit coordinates, the trajectory and the factor graph as
// layers that can be switched on and off. Opens from disk without a server or network.
#include <string>

#include "gcmap/viz/run_data.hpp"

namespace gcmap::viz {

// The compile-time libjs-three folder (CMake GCMAP_THREE_JS_DIR, /usr/share/javascript/three).
std::string default_three_dir();

struct ViewOptions {
  size_t max_points = 2'000'000;  // the map is evenly decimated to at most this
  std::string three_dir = default_three_dir();
  void validate() const;
};

struct ViewSummary {
  size_t map_points = 0, points_written = 0;
  size_t bytes = 0;
};

// Throws Error naming the missing three.js file (with a hint to install libjs-three).
ViewSummary write_view_html(const RunData& run, const std::string& path, const ViewOptions& options);

// Reads DIR's map.ply, trajectory.kitti and graph.json and writes the page to `path`.
WrittenFile view_run(const std::string& dir, const std::string& path, const ViewOptions& options);

// The page's template (view_page.cpp), with the @NAME@ placeholders write_view_html fills.
extern const char* const kViewPageTemplate;

}  // namespace gcmap::viz
