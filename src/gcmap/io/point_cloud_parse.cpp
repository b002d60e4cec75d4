// The PCD, PLY and raw .bin parsers behind read_point_cloud. Every size a header declares is checked
// against the bytes that follow it before anything is allocated from it.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <vector>

#include "gcmap/core/error.hpp"
#include "gcmap/io/point_cloud_io.hpp"

namespace gcmap {

namespace {

// One scalar field of a record: type 'F' float, 'I' signed, 'U' unsigned; size in bytes.
struct Field {
  std::string name;
  char type = 'F';
  int size = 4;
  int count = 1;
  size_t offset = 0;  // within a record (interleaved layouts)
};

// A PCD field's COUNT above this is taken for garbage (real files use 1, or a few hundred at most).
constexpr size_t kMaxFieldCount = 1 << 16;

double read_scalar(const char* p, char type, int size, bool big_endian) {
  if (type == 'F' && size == 4 && big_endian == (std::endian::native == std::endian::big)) {  // the common case
    float v;
    std::memcpy(&v, p, 4);
    return v;
  }
  unsigned char b[8];
  std::memcpy(b, p, size);
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + size);
  switch (type) {
    case 'F':
      if (size == 4) {
        float v;
        std::memcpy(&v, b, 4);
        return v;
      }
      if (size == 8) {
        double v;
        std::memcpy(&v, b, 8);
        return v;
      }
      break;
    case 'I':
      if (size == 1) {
        int8_t v;
        std::memcpy(&v, b, 1);
        return v;
      }
      if (size == 2) {
        int16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      if (size == 4) {
        int32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      if (size == 8) {
        int64_t v;
        std::memcpy(&v, b, 8);
        return static_cast<double>(v);
      }
      break;
    case 'U':
      if (size == 1) {
        uint8_t v;
        std::memcpy(&v, b, 1);
        return v;
      }
      if (size == 2) {
        uint16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      if (size == 4) {
        uint32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      if (size == 8) {
        uint64_t v;
        std::memcpy(&v, b, 8);
        return static_cast<double>(v);
      }
      break;
  }
  return std::nan("");
}

bool valid_scalar(char type, int size) {
  if (type == 'F') return size == 4 || size == 8;
  if (type == 'I' || type == 'U') return size == 1 || size == 2 || size == 4 || size == 8;
  return false;
}

std::vector<std::string> split_ws(std::string_view line) {
  std::vector<std::string> out;
  size_t i = 0;
  while (true) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i == line.size()) return out;
    const size_t j = std::min(line.find_first_of(" \t", i), line.size());
    out.emplace_back(line.substr(i, j - i));
    i = j;
  }
}

bool parse_double(const char* b, const char* e, double& v) {
  while (b < e && (*b == ' ' || *b == '\t' || *b == '+')) ++b;
  const auto r = std::from_chars(b, e, v);
  if (r.ec == std::errc()) return true;
  // from_chars rejects "nan"/"inf" spellings in some forms; keep them as non-finite points.
  std::string s(b, e);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (s.rfind("nan", 0) == 0 || s.rfind("-nan", 0) == 0) {
    v = std::nan("");
    return true;
  }
  if (s.rfind("inf", 0) == 0) {
    v = INFINITY;
    return true;
  }
  if (s.rfind("-inf", 0) == 0) {
    v = -INFINITY;
    return true;
  }
  return false;
}

size_t parse_count(const std::string& path, const std::string& what, const std::string& s) {
  unsigned long long v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) throw Error(path + ": bad " + what + " '" + s + "'");
  return static_cast<size_t>(v);
}

// Throws unless `count` items of at least `min_bytes` each fit in `available` bytes.
void require_bytes(const std::string& path, size_t count, size_t min_bytes, size_t available, const char* items) {
  if (min_bytes > 0 && count > available / min_bytes)
    throw Error(path + ": truncated (the header declares " + std::to_string(count) + " " + items + ", the data holds at most " +
                std::to_string(available / min_bytes) + ")");
}

// Reads the next header line; throws when the file ends inside the header.
std::string next_line(const std::string& path, std::string_view data, size_t& pos) {
  if (pos >= data.size()) throw Error(path + ": truncated header");
  size_t end = data.find('\n', pos);
  if (end == std::string::npos) end = data.size();
  std::string line(data.substr(pos, end - pos));
  pos = end + 1;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return line;
}

int find_field(const std::vector<Field>& fields, const std::string& name) {
  for (size_t i = 0; i < fields.size(); ++i)
    if (fields[i].name == name) return static_cast<int>(i);
  return -1;
}

void require_xyz(const std::string& path, const std::vector<Field>& fields) {
  for (const char* n : {"x", "y", "z"})
    if (find_field(fields, n) < 0) throw Error(path + ": no field '" + n + "'");
}

// Fills the cloud from a getter value(point, field) over x, y, z and optional intensity.
template <typename Getter>
PointCloud assemble(const std::vector<Field>& fields, size_t n, Getter value) {
  const int fx = find_field(fields, "x"), fy = find_field(fields, "y"), fz = find_field(fields, "z");
  const int fi = find_field(fields, "intensity");
  PointCloud cloud;
  cloud.points.resize(n);
  if (fi >= 0) cloud.intensities.resize(n);
  // Each point on its own: parallel and the same bytes for any thread count.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      cloud.points[i] = Eigen::Vector3f(value(i, fx), value(i, fy), value(i, fz));
      if (fi >= 0) cloud.intensities[i] = static_cast<float>(value(i, fi));
    }
  });
  return cloud;
}

// Whitespace-separated numbers, `cols` per line, `n` lines (blank lines skipped); row-major.
std::vector<double> parse_ascii_rows(const std::string& path, std::string_view data, size_t& pos, size_t n, size_t cols,
                                     const char* items) {
  // Each row takes at least 2 bytes per value ("0 " ... "0\n"), the last one without its newline.
  require_bytes(path, n, 2 * cols, data.size() - std::min(pos, data.size()) + 1, items);
  std::vector<double> values(n * cols);
  size_t i = 0;
  while (i < n && pos < data.size()) {
    const std::string line = next_line(path, data, pos);
    const char* p = line.data();
    const char* end = p + line.size();
    size_t c = 0;
    while (p < end && c < cols) {
      while (p < end && (*p == ' ' || *p == '\t')) ++p;
      if (p == end) break;
      const char* q = p;
      while (q < end && *q != ' ' && *q != '\t') ++q;
      if (!parse_double(p, q, values[i * cols + c])) throw Error(path + ": bad number on data line " + std::to_string(i + 1));
      ++c;
      p = q;
    }
    if (c == 0) continue;  // blank line
    if (c != cols)
      throw Error(path + ": data line " + std::to_string(i + 1) + " has " + std::to_string(c) + " values, expected " +
                  std::to_string(cols));
    ++i;
  }
  if (i != n) throw Error(path + ": truncated (" + std::to_string(i) + " of " + std::to_string(n) + " " + items + ")");
  return values;
}

struct PcdHeader {
  std::vector<Field> fields;
  size_t points = 0;
  size_t record = 0;  // bytes per point (binary layouts)
  std::string format;
};

// The header as written, before it is checked.
struct RawPcdHeader {
  std::vector<std::string> fields;
  std::vector<size_t> sizes, counts;
  std::vector<char> types;
  std::optional<size_t> width, points;
  size_t height = 1;
  std::string format;
};

RawPcdHeader read_pcd_header(const std::string& path, std::string_view data, size_t& pos) {
  RawPcdHeader h;
  while (h.format.empty()) {
    const std::string line = next_line(path, data, pos);
    auto tok = split_ws(line);
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string key = tok[0];
    tok.erase(tok.begin());
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS") h.fields.insert(h.fields.end(), tok.begin(), tok.end());
    else if (key == "SIZE")
      for (auto& t : tok) h.sizes.push_back(parse_count(path, "SIZE", t));
    else if (key == "TYPE")
      for (auto& t : tok) h.types.push_back(t.size() == 1 ? t[0] : '?');
    else if (key == "COUNT")
      for (auto& t : tok) h.counts.push_back(parse_count(path, "COUNT", t));
    else if (key == "WIDTH" && tok.size() == 1) h.width = parse_count(path, "WIDTH", tok[0]);
    else if (key == "HEIGHT" && tok.size() == 1) h.height = parse_count(path, "HEIGHT", tok[0]);
    else if (key == "POINTS" && tok.size() == 1) h.points = parse_count(path, "POINTS", tok[0]);
    else if (key == "DATA" && tok.size() == 1) h.format = tok[0];
    else throw Error(path + ": not a PCD file (unexpected header line '" + line.substr(0, 40) + "')");
  }
  return h;
}

PcdHeader parse_pcd_header(const std::string& path, std::string_view data, size_t& pos) {
  RawPcdHeader raw = read_pcd_header(path, data, pos);
  const size_t nf = raw.fields.size();
  if (nf == 0) throw Error(path + ": PCD header has no FIELDS");
  if (raw.sizes.size() != nf || raw.types.size() != nf) throw Error(path + ": PCD header SIZE/TYPE do not match FIELDS");
  if (raw.counts.empty()) raw.counts.assign(nf, 1);
  if (raw.counts.size() != nf) throw Error(path + ": PCD header COUNT does not match FIELDS");
  PcdHeader h;
  for (size_t f = 0; f < nf; ++f) {
    if (raw.sizes[f] > 8 || !valid_scalar(raw.types[f], static_cast<int>(raw.sizes[f])) || raw.counts[f] < 1 ||
        raw.counts[f] > kMaxFieldCount)
      throw Error(path + ": PCD field '" + raw.fields[f] + "' has an unsupported TYPE/SIZE/COUNT");
    h.fields.push_back(
        Field{raw.fields[f], raw.types[f], static_cast<int>(raw.sizes[f]), static_cast<int>(raw.counts[f]), h.record});
    h.record += raw.sizes[f] * raw.counts[f];
  }
  require_xyz(path, h.fields);
  if (!raw.width && !raw.points) throw Error(path + ": PCD header has neither WIDTH nor POINTS");
  if (raw.width) {
    if (raw.height != 0 && *raw.width > SIZE_MAX / raw.height) throw Error(path + ": WIDTH*HEIGHT is too large");
    if (raw.points && *raw.points != *raw.width * raw.height) throw Error(path + ": POINTS does not equal WIDTH*HEIGHT");
    raw.points = *raw.width * raw.height;
  }
  h.points = *raw.points;
  h.format = raw.format;
  return h;
}

PointCloud pcd_binary(const std::string& path, std::string_view data, size_t pos, const PcdHeader& h) {
  const size_t n = h.points, available = data.size() - std::min(pos, data.size());
  if (n > available / h.record)
    throw Error(path + ": truncated (" + std::to_string(available / h.record) + " of " + std::to_string(n) + " points)");
  const char* base = data.data() + pos;
  return assemble(h.fields, n, [&](size_t k, int f) {
    return read_scalar(base + k * h.record + h.fields[f].offset, h.fields[f].type, h.fields[f].size, false);
  });
}

PointCloud pcd_compressed(const std::string& path, std::string_view data, size_t pos, const PcdHeader& h) {
  if (pos > data.size() || data.size() - pos < 8) throw Error(path + ": truncated compressed header");
  uint32_t compressed = 0, uncompressed = 0;
  std::memcpy(&compressed, data.data() + pos, 4);
  std::memcpy(&uncompressed, data.data() + pos + 4, 4);
  if (data.size() - pos - 8 < compressed) throw Error(path + ": truncated compressed data");
  const size_t n = h.points;
  if (n > SIZE_MAX / h.record || uncompressed != n * h.record) throw Error(path + ": compressed size does not match the header");
  std::string raw;
  try {
    raw = lzf_decompress(data.substr(pos + 8, compressed), uncompressed);
  } catch (const Error& e) { throw Error(path + ": " + e.what()); }
  // Column-major: each field's values for all points are contiguous.
  std::vector<size_t> column(h.fields.size());
  size_t off = 0;
  for (size_t f = 0; f < h.fields.size(); ++f) {
    column[f] = off;
    off += n * static_cast<size_t>(h.fields[f].size) * h.fields[f].count;
  }
  return assemble(h.fields, n, [&](size_t k, int f) {
    const Field& field = h.fields[f];
    return read_scalar(raw.data() + column[f] + k * static_cast<size_t>(field.size) * field.count, field.type, field.size, false);
  });
}

}  // namespace

PointCloud parse_pcd(std::string_view data, const std::string& path) {
  if (data.empty()) throw Error(path + ": empty file");
  size_t pos = 0;
  const PcdHeader h = parse_pcd_header(path, data, pos);
  if (h.format == "ascii") {
    // Offsets count scalars, not bytes, in the ascii layout.
    std::vector<size_t> column(h.fields.size());
    size_t cols = 0;
    for (size_t f = 0; f < h.fields.size(); ++f) {
      column[f] = cols;
      cols += h.fields[f].count;
    }
    const std::vector<double> values = parse_ascii_rows(path, data, pos, h.points, cols, "points");
    return assemble(h.fields, h.points, [&](size_t k, int f) { return values[k * cols + column[f]]; });
  }
  if (h.format == "binary") return pcd_binary(path, data, pos, h);
  if (h.format == "binary_compressed") return pcd_compressed(path, data, pos, h);
  throw Error(path + ": unknown PCD DATA format '" + h.format + "'");
}

namespace {

bool ply_type(const std::string& name, char& type, int& size) {
  static const std::pair<const char*, std::pair<char, int>> table[] = {
      {"char", {'I', 1}},  {"int8", {'I', 1}},    {"uchar", {'U', 1}},  {"uint8", {'U', 1}},
      {"short", {'I', 2}}, {"int16", {'I', 2}},   {"ushort", {'U', 2}}, {"uint16", {'U', 2}},
      {"int", {'I', 4}},   {"int32", {'I', 4}},   {"uint", {'U', 4}},   {"uint32", {'U', 4}},
      {"float", {'F', 4}}, {"float32", {'F', 4}}, {"double", {'F', 8}}, {"float64", {'F', 8}}};
  for (const auto& [n, ts] : table) {
    if (name == n) {
      type = ts.first;
      size = ts.second;
      return true;
    }
  }
  return false;
}

struct PlyElement {
  std::string name;
  size_t count = 0;
  std::vector<Field> props;
  bool has_list = false;
  size_t record = 0;
};

// Reads the header after the magic line; returns the elements and sets `format`.
std::vector<PlyElement> read_ply_header(const std::string& path, std::string_view data, size_t& pos, std::string& format) {
  std::vector<PlyElement> elements;
  while (true) {
    const std::string line = next_line(path, data, pos);
    auto tok = split_ws(line);
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") return elements;
    if (tok[0] == "format" && tok.size() >= 2) {
      format = tok[1];
    } else if (tok[0] == "element" && tok.size() == 3) {
      elements.emplace_back();
      elements.back().name = tok[1];
      elements.back().count = parse_count(path, "element count", tok[2]);
    } else if (tok[0] == "property" && !elements.empty()) {
      PlyElement& el = elements.back();
      if (tok.size() >= 2 && tok[1] == "list") {
        el.has_list = true;
        continue;
      }
      Field f;
      if (tok.size() != 3 || !ply_type(tok[1], f.type, f.size))
        throw Error(path + ": bad PLY property line '" + line.substr(0, 40) + "'");
      f.name = tok[2];
      f.offset = el.record;
      el.record += f.size;
      el.props.push_back(f);
    } else {
      throw Error(path + ": bad PLY header line '" + line.substr(0, 40) + "'");
    }
  }
}

// Steps over an element before the vertices; only fixed-size ones can be skipped.
void skip_ply_element(const std::string& path, std::string_view data, size_t& pos, const PlyElement& el, bool ascii) {
  if (el.has_list) throw Error(path + ": PLY element '" + el.name + "' with a list precedes the vertices (unsupported)");
  if (ascii) {
    for (size_t i = 0; i < el.count; ++i) next_line(path, data, pos);
    return;
  }
  const size_t available = data.size() - std::min(pos, data.size());
  if (el.record > 0 && el.count > available / el.record) throw Error(path + ": truncated (element '" + el.name + "')");
  pos += el.count * el.record;
}

}  // namespace

PointCloud parse_ply(std::string_view data, const std::string& path) {
  if (data.empty()) throw Error(path + ": empty file");
  size_t pos = 0;
  if (next_line(path, data, pos) != "ply") throw Error(path + ": not a PLY file (missing 'ply' magic)");
  std::string format;
  const std::vector<PlyElement> elements = read_ply_header(path, data, pos, format);
  const bool ascii = format == "ascii";
  const bool big = format == "binary_big_endian";
  if (!ascii && !big && format != "binary_little_endian") throw Error(path + ": unknown PLY format '" + format + "'");

  for (const PlyElement& el : elements) {
    if (el.name != "vertex") {
      skip_ply_element(path, data, pos, el, ascii);
      continue;
    }
    if (el.has_list) throw Error(path + ": PLY vertex element with a list property (unsupported)");
    require_xyz(path, el.props);
    const size_t n = el.count, cols = el.props.size();
    if (ascii) {
      const std::vector<double> values = parse_ascii_rows(path, data, pos, n, cols, "vertices");
      return assemble(el.props, n, [&](size_t k, int f) { return values[k * cols + f]; });
    }
    const size_t available = data.size() - std::min(pos, data.size());
    if (n > available / el.record)
      throw Error(path + ": truncated (" + std::to_string(available / el.record) + " of " + std::to_string(n) + " vertices)");
    const char* base = data.data() + pos;
    return assemble(el.props, n, [&](size_t k, int f) {
      return read_scalar(base + k * el.record + el.props[f].offset, el.props[f].type, el.props[f].size, big);
    });
  }
  throw Error(path + ": PLY file has no vertex element");
}

}  // namespace gcmap
