#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace gcmap::viz {

struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
  std::string hex() const;  // "#rrggbb", for HTML
};

// Opaque raster in cairo's ARGB32 layout (one uint32 per pixel, 0xffRRGGBB, row-major).
struct Image {
  int width = 0, height = 0;
  std::vector<uint32_t> pixels;

  Image() = default;
  Image(int w, int h, Rgb fill);
  Rgb at(int x, int y) const;
  void set(int x, int y, Rgb c) { pixels[static_cast<size_t>(y) * width + x] = 0xff000000u | (c.r << 16) | (c.g << 8) | c.b; }
};

// PNG bytes of the image (the same bytes for the same pixels).
std::string encode_png(const Image& image);
void write_png(const std::string& path, const Image& image);  // atomically

// Ordered colour scale for t in [0, 1] (dark blue, cyan, green, yellow, red); t is clamped.
Rgb colormap(double t);
// Distinct colours for categories (submaps): a golden-angle walk around the hue circle.
Rgb category_colour(int i);
// Brightness scaling of a colour, f in [0, 1].
Rgb scaled(Rgb c, double f);

}  // namespace gcmap::viz
