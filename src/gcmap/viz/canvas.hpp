#pragma once
// A thin layer over cairo shared by the map picture and the charts.
#include <cairo.h>

#include <Eigen/Core>
#include <string>

#include "gcmap/viz/image.hpp"

namespace gcmap::viz {

enum class FigureFormat { png, svg };
FigureFormat parse_figure_format(const std::string& name);  // throws Error naming the value
const char* figure_extension(FigureFormat f);               // ".png" / ".svg"

enum class Align { left, center, right };

class Canvas {
 public:
  explicit Canvas(Image& image);                       // draws onto the image's pixels
  Canvas(int width, int height, FigureFormat format);  // a figure on a white page
  ~Canvas();
  Canvas(const Canvas&) = delete;
  Canvas& operator=(const Canvas&) = delete;

  cairo_t* cr() { return cr_; }
  void colour(Rgb c, double alpha = 1.0);
  void line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double width);
  void dot(const Eigen::Vector2d& centre, double radius);  // filled
  void rect(double x, double y, double w, double h);       // filled
  // Text with its baseline at y; `size` in pixels; rotated 90 deg counter-clockwise when vertical.
  void text(double x, double y, const std::string& s, double size, Align align = Align::left, bool vertical = false);
  double text_width(const std::string& s, double size);

  // The figure's bytes (PNG or SVG); only for the figure constructor.
  std::string finish();

 private:
  cairo_surface_t* surface_ = nullptr;
  cairo_t* cr_ = nullptr;
  FigureFormat format_ = FigureFormat::png;
  std::string svg_;
};

// Writes the canvas's figure to `path` atomically.
void write_figure(const std::string& path, Canvas& canvas);

}  // namespace gcmap::viz
