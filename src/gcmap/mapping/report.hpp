#pragma once
// The machine-readable record of a mapping run (graph.json, stats.json), built in one place for the
// CLI, the Python package and sessions.
#include "gcmap/io/json.hpp"
#include "gcmap/mapping/pipeline.hpp"

namespace gcmap {

// A verified loop candidate, the same in graph.json and quality.json.
Json loop_json(const LoopRecord& l);

// Submaps (pose in the output frame, frames, points), every factor with its final error and
// robust weight, every verified loop candidate. frame_offset is added to frame numbers (--start).
Json graph_json(const MappingPipeline& pipeline, int frame_offset = 0);

// What the map frame is: local ENU (GNSS), levelled by gravity (IMU), or the first frame.
std::string map_frame_description(const Mapper& mapper);
// Frames, rate, device and per-module timings (paper Table III), the global optimization per
// insertion (paper Fig. 10) and the final optimization.
Json stats_json(const MappingPipeline& pipeline);

}  // namespace gcmap
