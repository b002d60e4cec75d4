#include "gcmap/viz/canvas.hpp"

#include <cairo-svg.h>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap::viz {

namespace {
cairo_status_t append(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}
}  // namespace

FigureFormat parse_figure_format(const std::string& name) {
  if (name == "png") return FigureFormat::png;
  if (name == "svg") return FigureFormat::svg;
  throw Error("figure format \"" + name + "\": expected png or svg");
}

const char* figure_extension(FigureFormat f) { return f == FigureFormat::png ? ".png" : ".svg"; }

Canvas::Canvas(Image& image) {
  surface_ = cairo_image_surface_create_for_data(reinterpret_cast<unsigned char*>(image.pixels.data()), CAIRO_FORMAT_ARGB32,
                                                 image.width, image.height, image.width * 4);
  cr_ = cairo_create(surface_);
}

Canvas::Canvas(int width, int height, FigureFormat format) : format_(format) {
  if (format == FigureFormat::svg) {
    surface_ = cairo_svg_surface_create_for_stream(append, &svg_, width, height);
  } else {
    surface_ = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height);
  }
  cr_ = cairo_create(surface_);
  if (cairo_status(cr_) != CAIRO_STATUS_SUCCESS) throw Error(std::string("cairo: ") + cairo_status_to_string(cairo_status(cr_)));
  colour({255, 255, 255});
  cairo_paint(cr_);
}

Canvas::~Canvas() {
  cairo_destroy(cr_);
  cairo_surface_destroy(surface_);
}

void Canvas::colour(Rgb c, double alpha) { cairo_set_source_rgba(cr_, c.r / 255.0, c.g / 255.0, c.b / 255.0, alpha); }

void Canvas::line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double width) {
  cairo_set_line_width(cr_, width);
  cairo_set_line_cap(cr_, CAIRO_LINE_CAP_ROUND);
  cairo_move_to(cr_, a.x(), a.y());
  cairo_line_to(cr_, b.x(), b.y());
  cairo_stroke(cr_);
}

void Canvas::dot(const Eigen::Vector2d& centre, double radius) {
  cairo_new_sub_path(cr_);
  cairo_arc(cr_, centre.x(), centre.y(), radius, 0.0, 2.0 * M_PI);
  cairo_fill(cr_);
}

void Canvas::rect(double x, double y, double w, double h) {
  cairo_rectangle(cr_, x, y, w, h);
  cairo_fill(cr_);
}

void Canvas::text(double x, double y, const std::string& s, double size, Align align, bool vertical) {
  const double w = text_width(s, size);
  const double shift = align == Align::left ? 0.0 : align == Align::center ? -0.5 * w : -w;
  cairo_save(cr_);
  cairo_translate(cr_, x, y);
  if (vertical) cairo_rotate(cr_, -M_PI / 2);
  cairo_move_to(cr_, shift, 0.0);
  cairo_show_text(cr_, s.c_str());
  cairo_restore(cr_);
}

double Canvas::text_width(const std::string& s, double size) {
  cairo_select_font_face(cr_, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr_, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr_, s.c_str(), &e);
  return e.x_advance;
}

std::string Canvas::finish() {
  cairo_surface_flush(surface_);
  if (format_ == FigureFormat::svg) {
    cairo_surface_finish(surface_);
    return svg_;
  }
  std::string png;
  const cairo_status_t st = cairo_surface_write_to_png_stream(surface_, append, &png);
  if (st != CAIRO_STATUS_SUCCESS) throw Error(std::string("PNG encoding failed: ") + cairo_status_to_string(st));
  return png;
}

void write_figure(const std::string& path, Canvas& canvas) {
  const std::string bytes = canvas.finish();
  write_file_atomic(path, [&](std::ostream& out) { out.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
}

}  // namespace gcmap::viz
