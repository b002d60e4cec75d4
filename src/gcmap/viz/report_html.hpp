#pragma once
// report.html: the run-quality report (mapping/quality.hpp) as one self-contained page that opens
// from disk: the verdict first, the map from above coloured by submap consistency and the
// trajectory by registration degeneracy (canvas), the per-frame conditioning, the flagged frames,
// submap pairs, loop candidates and stamp anomalies.
#include <string>

#include "gcmap/mapping/quality.hpp"

namespace gcmap::viz {

// The page; at most max_points map points (each submap's factor source, evenly decimated).
std::string report_html(const QualityReport& report, const MappingPipeline& pipeline, size_t max_points = 100'000);

}  // namespace gcmap::viz
