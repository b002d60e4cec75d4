#include "gcmap/viz/image.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "gcmap/core/error.hpp"

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
