#include "gcmap/viz/run_pictures.hpp"

#include <filesystem>

namespace gcmap::viz {

std::vector<WrittenFile> write_run_pictures(const std::string& out_dir, const RunPicturesOptions& o) {
  namespace fs = std::filesystem;
  std::vector<WrittenFile> written;
  if (o.map_png) written.push_back(render_run(out_dir, (fs::path(out_dir) / "map.png").string(), o.render));
  if (o.view_html) written.push_back(view_run(out_dir, (fs::path(out_dir) / "view.html").string(), o.view));
  if (o.plots) {
    for (WrittenFile& f : write_plots(out_dir, (fs::path(out_dir) / "plots").string(), o.plot)) written.push_back(std::move(f));
  }
  return written;
}

}  // namespace gcmap::viz
