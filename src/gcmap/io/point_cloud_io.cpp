#include "gcmap/io/point_cloud_io.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <vector>

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/io/file.hpp"

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

double read_scalar(const char* p, char type, int size, bool big_endian) {
  unsigned char b[8];
  std::memcpy(b, p, size);
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + size);
  switch (type) {
    case 'F':
      if (size == 4) { float v; std::memcpy(&v, b, 4); return v; }
      if (size == 8) { double v; std::memcpy(&v, b, 8); return v; }
      break;
    case 'I':
      if (size == 1) { int8_t v; std::memcpy(&v, b, 1); return v; }
      if (size == 2) { int16_t v; std::memcpy(&v, b, 2); return v; }
      if (size == 4) { int32_t v; std::memcpy(&v, b, 4); return v; }
      if (size == 8) { int64_t v; std::memcpy(&v, b, 8); return static_cast<double>(v); }
      break;
    case 'U':
      if (size == 1) { uint8_t v; std::memcpy(&v, b, 1); return v; }
      if (size == 2) { uint16_t v; std::memcpy(&v, b, 2); return v; }
      if (size == 4) { uint32_t v; std::memcpy(&v, b, 4); return v; }
      if (size == 8) { uint64_t v; std::memcpy(&v, b, 8); return static_cast<double>(v); }
      break;
  }
  return std::nan("");
}

bool valid_scalar(char type, int size) {
  if (type == 'F') return size == 4 || size == 8;
  if (type == 'I' || type == 'U') return size == 1 || size == 2 || size == 4 || size == 8;
  return false;
}

std::vector<std::string> split_ws(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream ss(line);
  std::string tok;
  while (ss >> tok) out.push_back(tok);
  return out;
}

bool parse_double(const char* b, const char* e, double& v) {
  while (b < e && (*b == ' ' || *b == '\t' || *b == '+')) ++b;
  const auto r = std::from_chars(b, e, v);
  if (r.ec == std::errc()) return true;
  // from_chars rejects "nan"/"inf" spellings in some forms; keep them as non-finite points.
  std::string s(b, e);
  std::transform(s.begin(), s.end(), s.begin(), ::tolower);
  if (s.rfind("nan", 0) == 0 || s.rfind("-nan", 0) == 0) { v = std::nan(""); return true; }
  if (s.rfind("inf", 0) == 0) { v = INFINITY; return true; }
  if (s.rfind("-inf", 0) == 0) { v = -INFINITY; return true; }
  return false;
}

long parse_long(const std::string& path, const std::string& what, const std::string& s) {
  long v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size() || v < 0) throw Error(path + ": bad " + what + " '" + s + "'");
  return v;
}

// Reads the next header line; throws when the file ends inside the header.
std::string next_line(const std::string& path, const std::string& data, size_t& pos) {
  if (pos >= data.size()) throw Error(path + ": truncated header");
  size_t end = data.find('\n', pos);
  if (end == std::string::npos) end = data.size();
  std::string line = data.substr(pos, end - pos);
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
  for (size_t i = 0; i < n; ++i) {
    cloud.points[i] = Eigen::Vector3f(value(i, fx), value(i, fy), value(i, fz));
    if (fi >= 0) cloud.intensities[i] = static_cast<float>(value(i, fi));
  }
  return cloud;
}

PointCloud read_bin(const std::string& path, BinFields fields) {
  const std::string data = read_file(path);
  const size_t stride = fields == BinFields::xyzi ? 16 : 12;
  if (data.empty()) throw Error(path + ": empty file");
  if (data.size() % stride != 0) {
    throw Error(path + ": size " + std::to_string(data.size()) + " is not a multiple of " + std::to_string(stride) +
                " bytes (truncated, or wrong --bin-fields?)");
  }
  const size_t n = data.size() / stride;
  PointCloud cloud;
  cloud.points.resize(n);
  if (fields == BinFields::xyzi) cloud.intensities.resize(n);
  for (size_t i = 0; i < n; ++i) {
    float v[4];
    std::memcpy(v, data.data() + i * stride, stride);
    cloud.points[i] = Eigen::Vector3f(v[0], v[1], v[2]);
    if (fields == BinFields::xyzi) cloud.intensities[i] = v[3];
  }
  return cloud;
}

PointCloud read_pcd(const std::string& path) {
  const std::string data = read_file(path);
  if (data.empty()) throw Error(path + ": empty file");
  size_t pos = 0;
  std::vector<Field> fields;
  std::vector<int> sizes, counts;
  std::vector<char> types;
  long width = -1, height = 1, points = -1;
  std::string format;
  while (format.empty()) {
    const std::string line = next_line(path, data, pos);
    auto tok = split_ws(line);
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string key = tok[0];
    tok.erase(tok.begin());
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS") {
      for (auto& t : tok) fields.push_back(Field{t});
    } else if (key == "SIZE") {
      for (auto& t : tok) sizes.push_back(static_cast<int>(parse_long(path, "SIZE", t)));
    } else if (key == "TYPE") {
      for (auto& t : tok) types.push_back(t.size() == 1 ? t[0] : '?');
    } else if (key == "COUNT") {
      for (auto& t : tok) counts.push_back(static_cast<int>(parse_long(path, "COUNT", t)));
    } else if (key == "WIDTH" && tok.size() == 1) {
      width = parse_long(path, "WIDTH", tok[0]);
    } else if (key == "HEIGHT" && tok.size() == 1) {
      height = parse_long(path, "HEIGHT", tok[0]);
    } else if (key == "POINTS" && tok.size() == 1) {
      points = parse_long(path, "POINTS", tok[0]);
    } else if (key == "DATA" && tok.size() == 1) {
      format = tok[0];
    } else {
      throw Error(path + ": not a PCD file (unexpected header line '" + line.substr(0, 40) + "')");
    }
  }
  if (fields.empty()) throw Error(path + ": PCD header has no FIELDS");
  if (sizes.size() != fields.size() || types.size() != fields.size())
    throw Error(path + ": PCD header SIZE/TYPE do not match FIELDS");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (counts.size() != fields.size()) throw Error(path + ": PCD header COUNT does not match FIELDS");
  size_t record = 0;
  for (size_t f = 0; f < fields.size(); ++f) {
    fields[f].size = sizes[f];
    fields[f].type = types[f];
    fields[f].count = counts[f];
    fields[f].offset = record;
    if (!valid_scalar(types[f], sizes[f]) || counts[f] < 1)
      throw Error(path + ": PCD field '" + fields[f].name + "' has an unsupported TYPE/SIZE");
    record += static_cast<size_t>(sizes[f]) * counts[f];
  }
  require_xyz(path, fields);
  if (points < 0) points = width * height;
  if (width >= 0 && points != width * height) throw Error(path + ": POINTS does not equal WIDTH*HEIGHT");
  const size_t n = static_cast<size_t>(points);

  if (format == "ascii") {
    // Offsets count scalars, not bytes, in the ascii layout.
    std::vector<size_t> column(fields.size());
    size_t cols = 0;
    for (size_t f = 0; f < fields.size(); ++f) { column[f] = cols; cols += fields[f].count; }
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
      if (c != cols) throw Error(path + ": data line " + std::to_string(i + 1) + " has " + std::to_string(c) + " values, expected " + std::to_string(cols));
      ++i;
    }
    if (i != n) throw Error(path + ": truncated (" + std::to_string(i) + " of " + std::to_string(n) + " points)");
    return assemble(fields, n, [&](size_t k, int f) { return values[k * cols + column[f]]; });
  }
  if (format == "binary") {
    if (data.size() - pos < n * record)
      throw Error(path + ": truncated (" + std::to_string((data.size() - pos) / std::max<size_t>(record, 1)) + " of " + std::to_string(n) + " points)");
    const char* base = data.data() + pos;
    return assemble(fields, n, [&](size_t k, int f) {
      return read_scalar(base + k * record + fields[f].offset, fields[f].type, fields[f].size, false);
    });
  }
  if (format == "binary_compressed") {
    if (data.size() - pos < 8) throw Error(path + ": truncated compressed header");
    uint32_t compressed = 0, uncompressed = 0;
    std::memcpy(&compressed, data.data() + pos, 4);
    std::memcpy(&uncompressed, data.data() + pos + 4, 4);
    if (data.size() - pos - 8 < compressed) throw Error(path + ": truncated compressed data");
    if (uncompressed != n * record) throw Error(path + ": compressed size does not match the header");
    std::string raw;
    try {
      raw = lzf_decompress(data.substr(pos + 8, compressed), uncompressed);
    } catch (const Error& e) {
      throw Error(path + ": " + e.what());
    }
    // Column-major: each field's values for all points are contiguous.
    std::vector<size_t> column(fields.size());
    size_t off = 0;
    for (size_t f = 0; f < fields.size(); ++f) { column[f] = off; off += n * fields[f].size * fields[f].count; }
    return assemble(fields, n, [&](size_t k, int f) {
      return read_scalar(raw.data() + column[f] + k * fields[f].size * fields[f].count, fields[f].type, fields[f].size, false);
    });
  }
  throw Error(path + ": unknown PCD DATA format '" + format + "'");
}

bool ply_type(const std::string& name, char& type, int& size) {
  static const std::pair<const char*, std::pair<char, int>> table[] = {
      {"char", {'I', 1}},   {"int8", {'I', 1}},    {"uchar", {'U', 1}},  {"uint8", {'U', 1}},
      {"short", {'I', 2}},  {"int16", {'I', 2}},   {"ushort", {'U', 2}}, {"uint16", {'U', 2}},
      {"int", {'I', 4}},    {"int32", {'I', 4}},   {"uint", {'U', 4}},   {"uint32", {'U', 4}},
      {"float", {'F', 4}},  {"float32", {'F', 4}}, {"double", {'F', 8}}, {"float64", {'F', 8}}};
  for (const auto& [n, ts] : table) {
    if (name == n) {
      type = ts.first;
      size = ts.second;
      return true;
    }
  }
  return false;
}

PointCloud read_ply(const std::string& path) {
  const std::string data = read_file(path);
  if (data.empty()) throw Error(path + ": empty file");
  size_t pos = 0;
  if (next_line(path, data, pos) != "ply") throw Error(path + ": not a PLY file (missing 'ply' magic)");
  struct Element {
    std::string name;
    size_t count = 0;
    std::vector<Field> props;
    bool has_list = false;
    size_t record = 0;
  };
  std::vector<Element> elements;
  std::string format;
  while (true) {
    const std::string line = next_line(path, data, pos);
    auto tok = split_ws(line);
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") break;
    if (tok[0] == "format" && tok.size() >= 2) {
      format = tok[1];
    } else if (tok[0] == "element" && tok.size() == 3) {
      Element el;
      el.name = tok[1];
      el.count = static_cast<size_t>(parse_long(path, "element count", tok[2]));
      elements.push_back(el);
    } else if (tok[0] == "property" && !elements.empty()) {
      Element& el = elements.back();
      if (tok.size() >= 2 && tok[1] == "list") {
        el.has_list = true;
        continue;
      }
      Field f;
      if (tok.size() != 3 || !ply_type(tok[1], f.type, f.size)) throw Error(path + ": bad PLY property line '" + line + "'");
      f.name = tok[2];
      f.offset = el.record;
      el.record += f.size;
      el.props.push_back(f);
    } else {
      throw Error(path + ": bad PLY header line '" + line.substr(0, 40) + "'");
    }
  }
  const bool ascii = format == "ascii";
  const bool big = format == "binary_big_endian";
  if (!ascii && !big && format != "binary_little_endian") throw Error(path + ": unknown PLY format '" + format + "'");

  for (const Element& el : elements) {
    if (el.name != "vertex") {
      // Elements before the vertices must be skipped; only fixed-size ones can be.
      if (el.has_list) throw Error(path + ": PLY element '" + el.name + "' with a list precedes the vertices (unsupported)");
      if (ascii) {
        for (size_t i = 0; i < el.count; ++i) next_line(path, data, pos);
      } else {
        if (data.size() - pos < el.count * el.record) throw Error(path + ": truncated");
        pos += el.count * el.record;
      }
      continue;
    }
    if (el.has_list) throw Error(path + ": PLY vertex element with a list property (unsupported)");
    require_xyz(path, el.props);
    const size_t n = el.count, cols = el.props.size();
    if (ascii) {
      std::vector<double> values(n * cols);
      for (size_t i = 0; i < n; ++i) {
        if (pos >= data.size()) throw Error(path + ": truncated (" + std::to_string(i) + " of " + std::to_string(n) + " vertices)");
        const auto tok = split_ws(next_line(path, data, pos));
        if (tok.size() < cols) throw Error(path + ": vertex line " + std::to_string(i + 1) + " has too few values");
        for (size_t c = 0; c < cols; ++c)
          if (!parse_double(tok[c].data(), tok[c].data() + tok[c].size(), values[i * cols + c]))
            throw Error(path + ": bad number on vertex line " + std::to_string(i + 1));
      }
      return assemble(el.props, n, [&](size_t k, int f) { return values[k * cols + f]; });
    }
    if (data.size() - pos < n * el.record)
      throw Error(path + ": truncated (" + std::to_string((data.size() - pos) / std::max<size_t>(el.record, 1)) + " of " + std::to_string(n) + " vertices)");
    const char* base = data.data() + pos;
    return assemble(el.props, n, [&](size_t k, int f) {
      return read_scalar(base + k * el.record + el.props[f].offset, el.props[f].type, el.props[f].size, big);
    });
  }
  throw Error(path + ": PLY file has no vertex element");
}

std::string extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext;
}

}  // namespace

BinFields parse_bin_fields(const std::string& name) {
  if (name == "xyzi") return BinFields::xyzi;
  if (name == "xyz") return BinFields::xyz;
  throw Error("--bin-fields: expected xyz or xyzi, got '" + name + "'");
}

std::string lzf_decompress(const std::string& in, size_t expected_size) {
  std::string out(expected_size, '\0');
  const auto* ip = reinterpret_cast<const unsigned char*>(in.data());
  const auto* in_end = ip + in.size();
  size_t op = 0;
  while (ip < in_end) {
    unsigned ctrl = *ip++;
    if (ctrl < 32) {
      const size_t len = ctrl + 1;
      if (static_cast<size_t>(in_end - ip) < len || op + len > expected_size) throw Error("corrupt LZF data (literal run)");
      std::memcpy(&out[op], ip, len);
      ip += len;
      op += len;
    } else {
      size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_end) throw Error("corrupt LZF data");
        len += *ip++;
      }
      if (ip >= in_end) throw Error("corrupt LZF data");
      const size_t back = ((ctrl & 0x1f) << 8) + *ip++ + 1;
      len += 2;
      if (back > op || op + len > expected_size) throw Error("corrupt LZF data (back reference)");
      for (size_t k = 0; k < len; ++k, ++op) out[op] = out[op - back];  // may overlap on purpose
    }
  }
  if (op != expected_size) throw Error("corrupt LZF data (short output)");
  return out;
}

PointCloud read_point_cloud(const std::string& path, BinFields bin_fields) {
  const std::string ext = extension(path);
  PointCloud cloud;
  if (ext == ".bin") cloud = read_bin(path, bin_fields);
  else if (ext == ".pcd") cloud = read_pcd(path);
  else if (ext == ".ply") cloud = read_ply(path);
  else throw Error(path + ": unknown point cloud format '" + ext + "' (expected .bin, .pcd or .ply)");
  const size_t dropped = remove_non_finite(cloud);
  if (dropped) spdlog::warn("{}: dropped {} non-finite points", path, dropped);
  return cloud;
}

namespace {
// float32 x y z records, with intensity when with_i (0 where the cloud has none).
void write_records(std::ostream& out, const PointCloud& cloud, bool with_i) {
  std::vector<float> buf;
  buf.reserve(cloud.size() * 4);
  for (size_t i = 0; i < cloud.size(); ++i) {
    buf.insert(buf.end(), cloud.points[i].data(), cloud.points[i].data() + 3);
    if (with_i) buf.push_back(cloud.has_intensities() ? cloud.intensities[i] : 0.0f);
  }
  out.write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size() * sizeof(float)));
}
}  // namespace

void write_ply(const std::string& path, const PointCloud& cloud) {
  static_assert(std::endian::native == std::endian::little, "writer assumes a little-endian host");
  write_file_atomic(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\ncomment written by gcmap\nelement vertex " << cloud.size()
        << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (cloud.has_intensities()) out << "property float intensity\n";
    out << "end_header\n";
    write_records(out, cloud, cloud.has_intensities());
  });
}

void write_pcd(const std::string& path, const PointCloud& cloud) {
  write_file_atomic(path, [&](std::ostream& out) {
    const bool with_i = cloud.has_intensities();
    out << "# .PCD v0.7 - written by gcmap\nVERSION 0.7\nFIELDS x y z" << (with_i ? " intensity" : "")
        << "\nSIZE 4 4 4" << (with_i ? " 4" : "") << "\nTYPE F F F" << (with_i ? " F" : "") << "\nCOUNT 1 1 1"
        << (with_i ? " 1" : "") << "\nWIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS "
        << cloud.size() << "\nDATA binary\n";
    write_records(out, cloud, cloud.has_intensities());
  });
}

void write_bin(const std::string& path, const PointCloud& cloud, BinFields fields) {
  static_assert(std::endian::native == std::endian::little, "writer assumes a little-endian host");
  write_file_atomic(path, [&](std::ostream& out) { write_records(out, cloud, fields == BinFields::xyzi); });
}

void write_point_cloud(const std::string& path, const PointCloud& cloud, BinFields bin_fields) {
  const std::string ext = extension(path);
  if (ext == ".ply") write_ply(path, cloud);
  else if (ext == ".pcd") write_pcd(path, cloud);
  else if (ext == ".bin") write_bin(path, cloud, bin_fields);
  else throw Error(path + ": cannot write format '" + ext + "' (use .ply, .pcd or .bin)");
}

}  // namespace gcmap
