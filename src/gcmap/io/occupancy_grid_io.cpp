#include "gcmap/io/occupancy_grid_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

namespace fs = std::filesystem;

bool OccupancyGrid::cell_of(double x, double y, int& cx, int& cy) const {
  cx = static_cast<int>(std::floor((x - origin.x()) / resolution));
  cy = static_cast<int>(std::floor((y - origin.y()) / resolution));
  return cx >= 0 && cy >= 0 && cx < width && cy < height;
}

size_t OccupancyGrid::count(Occupancy state) const { return static_cast<size_t>(std::count(cells.begin(), cells.end(), state)); }

namespace {

// map_saver's values: p = (255 - v) / 255 is 1 (occupied), 0.004 (free) and 0.196 (unknown), which
// the thresholds below sort into the three classes again.
constexpr uint8_t kOccupiedPixel = 0, kFreePixel = 254, kUnknownPixel = 205;
constexpr double kOccupiedThresh = 0.65, kFreeThresh = 0.196;

uint8_t pixel(Occupancy c) {
  return c == Occupancy::occupied ? kOccupiedPixel : c == Occupancy::free ? kFreePixel : kUnknownPixel;
}

std::string yaml_text(const std::string& image, const OccupancyGrid& g) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "image: %s\nmode: trinary\nresolution: %.6f\norigin: [%.6f, %.6f, 0.0]\nnegate: 0\n"
                "occupied_thresh: %.2f\nfree_thresh: %.3f\n",
                image.c_str(), g.resolution, g.origin.x(), g.origin.y(), kOccupiedThresh, kFreeThresh);
  return buf;
}

}  // namespace

void write_map_server(const std::string& dir, const std::string& stem, const OccupancyGrid& g) {
  const std::string image = stem + ".pgm";
  write_file_atomic((fs::path(dir) / image).string(), [&](std::ostream& out) {
    out << "P5\n# gcmap occupancy grid\n" << g.width << " " << g.height << "\n255\n";
    std::string row(static_cast<size_t>(g.width), '\0');
    for (int y = g.height - 1; y >= 0; --y) {  // PGM rows run top down
      for (int x = 0; x < g.width; ++x) row[x] = static_cast<char>(pixel(g.at(x, y)));
      out.write(row.data(), static_cast<std::streamsize>(row.size()));
    }
  });
  write_file_atomic((fs::path(dir) / (stem + ".yaml")).string(), [&](std::ostream& out) { out << yaml_text(image, g); });
}

namespace {

std::map<std::string, std::string> yaml_keys(const std::string& path) {
  std::map<std::string, std::string> keys;
  std::istringstream in(read_file(path));
  for (std::string line; std::getline(in, line);) {
    const size_t colon = line.find(':');
    if (line.empty() || line[0] == '#' || colon == std::string::npos) continue;
    std::string value = line.substr(colon + 1);
    value.erase(0, value.find_first_not_of(" \t"));
    value.erase(value.find_last_not_of(" \t\r") + 1);
    keys[line.substr(0, colon)] = value;
  }
  return keys;
}

double number(const std::string& path, const std::map<std::string, std::string>& keys, const std::string& key) {
  const auto it = keys.find(key);
  if (it == keys.end()) throw Error(path + ": no key '" + key + "'");
  try {
    return std::stod(it->second);
  } catch (const std::exception&) { throw Error(path + ": '" + key + "' is not a number: " + it->second); }
}

Eigen::Vector3d origin_of(const std::string& path, const std::map<std::string, std::string>& keys) {
  const auto it = keys.find("origin");
  Eigen::Vector3d o;
  if (it == keys.end() || std::sscanf(it->second.c_str(), "[%lf , %lf , %lf]", &o.x(), &o.y(), &o.z()) != 3)
    throw Error(path + ": 'origin' must be [x, y, yaw]");
  return o;
}

// The header's next whitespace-separated token, skipping comments.
std::string pgm_token(const std::string& path, const std::string& bytes, size_t& pos) {
  while (pos < bytes.size()) {
    if (bytes[pos] == '#') pos = bytes.find('\n', pos);
    else if (std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
    else break;
    if (pos == std::string::npos) break;
  }
  if (pos == std::string::npos || pos >= bytes.size()) throw Error(path + ": truncated PGM header");
  const size_t end = std::min(bytes.size(), bytes.find_first_of(" \t\r\n#", pos));
  std::string token = bytes.substr(pos, end - pos);
  pos = end;
  return token;
}

Occupancy classify(uint8_t v, bool negate, double occupied, double free) {
  const double p = negate ? v / 255.0 : (255.0 - v) / 255.0;
  return p > occupied ? Occupancy::occupied : p < free ? Occupancy::free : Occupancy::unknown;
}

}  // namespace

OccupancyGrid read_map_server(const std::string& yaml_path) {
  const auto keys = yaml_keys(yaml_path);
  if (keys.count("mode") && keys.at("mode") != "trinary") throw Error(yaml_path + ": only mode trinary is read");
  const Eigen::Vector3d origin = origin_of(yaml_path, keys);
  if (origin.z() != 0.0) throw Error(yaml_path + ": a rotated origin (yaw != 0) is not read");
  if (!keys.count("image")) throw Error(yaml_path + ": no key 'image'");
  const std::string image = (fs::path(yaml_path).parent_path() / keys.at("image")).string();
  const std::string bytes = read_file(image);
  size_t pos = 0;
  if (pgm_token(image, bytes, pos) != "P5") throw Error(image + ": not a binary PGM (P5)");
  OccupancyGrid g;
  g.width = std::stoi(pgm_token(image, bytes, pos));
  g.height = std::stoi(pgm_token(image, bytes, pos));
  if (pgm_token(image, bytes, pos) != "255" || g.width <= 0 || g.height <= 0) throw Error(image + ": not an 8-bit PGM");
  ++pos;  // the single whitespace before the pixels
  if (bytes.size() - pos != static_cast<size_t>(g.width) * g.height) throw Error(image + ": pixel data of the wrong size");
  g.resolution = number(yaml_path, keys, "resolution");
  g.origin = origin.head<2>();
  const bool negate = number(yaml_path, keys, "negate") != 0;
  const double occupied = number(yaml_path, keys, "occupied_thresh"), free = number(yaml_path, keys, "free_thresh");
  g.cells.resize(static_cast<size_t>(g.width) * g.height);
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x)
      g.cells[static_cast<size_t>(y) * g.width + x] = classify(
          static_cast<uint8_t>(bytes[pos + static_cast<size_t>(g.height - 1 - y) * g.width + x]), negate, occupied, free);
  return g;
}

}  // namespace gcmap
