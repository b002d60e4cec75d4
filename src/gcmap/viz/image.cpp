#include "gcmap/viz/image.hpp"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap::viz {

std::string Rgb::hex() const {
  char buf[8];
  std::snprintf(buf, sizeof(buf), "#%02x%02x%02x", r, g, b);
  return buf;
}

namespace {
size_t checked_pixels(int w, int h) {
  if (w <= 0 || h <= 0) throw Error("image size " + std::to_string(w) + "x" + std::to_string(h) + ": must be positive");
  return static_cast<size_t>(w) * h;
}
}  // namespace

Image::Image(int w, int h, Rgb fill) : width(w), height(h), pixels(checked_pixels(w, h)) {
  set(0, 0, fill);
  std::fill(pixels.begin(), pixels.end(), pixels[0]);
}

Rgb Image::at(int x, int y) const {
  const uint32_t p = pixels[static_cast<size_t>(y) * width + x];
  return {static_cast<uint8_t>(p >> 16), static_cast<uint8_t>(p >> 8), static_cast<uint8_t>(p)};
}

namespace {
// libpng reports errors by longjmp: nothing with a destructor may live in the frames it skips.
void append_png(png_structp png, png_bytep data, png_size_t length) {
  bool failed = false;
  try {
    static_cast<std::string*>(png_get_io_ptr(png))->append(reinterpret_cast<const char*>(data), length);
  } catch (...) { failed = true; }
  if (failed) png_error(png, "out of memory");
}
}  // namespace

// libpng directly rather than cairo's writer: zlib level 1 encodes a map picture several times
// faster for a slightly larger file, and RGB needs no alpha channel.
std::string encode_png(const Image& image) {
  std::string out;
  std::vector<png_byte> row(3 * static_cast<size_t>(image.width));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw Error("PNG encoding: out of memory");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw Error("PNG encoding failed (out of memory?)");
  }
  png_set_write_fn(png, &out, append_png, nullptr);
  png_set_IHDR(png, info, image.width, image.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 1);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);  // one filter: trying all five per row costs more than it saves
  png_write_info(png, info);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const Rgb c = image.at(x, y);
      row[3 * x] = c.r, row[3 * x + 1] = c.g, row[3 * x + 2] = c.b;
    }
    png_write_row(png, row.data());
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

void write_png(const std::string& path, const Image& image) {
  const std::string bytes = encode_png(image);
  write_file_atomic(path, [&](std::ostream& out) { out.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
}

Rgb colormap(double t) {
  static const double stops[][3] = {{0.18, 0.20, 0.60}, {0.10, 0.55, 0.85}, {0.15, 0.80, 0.55},
                                    {0.75, 0.88, 0.20}, {0.98, 0.72, 0.15}, {0.90, 0.25, 0.15}};
  constexpr int n = 6;
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * (n - 1);
  const int i = std::min(static_cast<int>(t), n - 2);
  const double f = t - i;
  auto channel = [&](int c) { return static_cast<uint8_t>(std::lround(255.0 * (stops[i][c] * (1 - f) + stops[i + 1][c] * f))); };
  return {channel(0), channel(1), channel(2)};
}

Rgb category_colour(int i) {
  const double h = std::fmod(i * 137.508, 360.0) / 60.0, s = 0.65, v = 0.95;
  const double c = v * s, x = c * (1 - std::abs(std::fmod(h, 2.0) - 1)), m = v - c;
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h)) {
    case 0: r = c, g = x; break;
    case 1: r = x, g = c; break;
    case 2: g = c, b = x; break;
    case 3: g = x, b = c; break;
    case 4: r = x, b = c; break;
    default: r = c, b = x; break;
  }
  auto q = [&](double u) { return static_cast<uint8_t>(std::lround(255.0 * (u + m))); };
  return {q(r), q(g), q(b)};
}

Rgb scaled(Rgb c, double f) {
  f = std::clamp(f, 0.0, 1.0);
  return {static_cast<uint8_t>(std::lround(c.r * f)), static_cast<uint8_t>(std::lround(c.g * f)),
          static_cast<uint8_t>(std::lround(c.b * f))};
}

}  // namespace gcmap::viz
