#pragma once
#include <string>

#include "gcmap/io/json.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap::cli {

struct MapRunOptions {
  std::string input, output, initial_trajectory;
  MappingConfig config;
  int start = 0, max_frames = 0;
  std::string device = "auto";  // cpu, cuda or auto
  bool quiet = false;
};

struct MapRunResult {
  size_t frames = 0, submaps = 0, factors = 0;
  double seconds = 0.0, fps = 0.0;
  Json stats;
};

// Runs the whole pipeline on a sequence folder and writes every output into options.output.
MapRunResult run_mapping(const MapRunOptions& options);

}  // namespace gcmap::cli
