// The _gcmap extension: NumPy in and out, the GIL released while C++ works, gcmap::Error turned
// into ValueError (FileNotFoundError for a missing file, RuntimeError for a misused object).
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "arrays.hpp"
#include "bindings.hpp"

PYBIND11_MODULE(_gcmap, m) {
  namespace py = pybind11;
  using namespace gcmap::python;
  m.doc() = "gcmap: globally consistent 3D LiDAR mapping (C++ core). Import the `gcmap` package, not this module.";
  // One plain line per message on stderr, as the CLI prints them.
  auto logger = spdlog::get("gcmap_python");
  if (!logger) logger = spdlog::stderr_logger_mt("gcmap_python");
  logger->set_pattern("[gcmap %l] %v");
  spdlog::set_default_logger(logger);

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const FileMissing& e) { PyErr_SetString(PyExc_FileNotFoundError, e.what()); } catch (const StateError& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    } catch (const gcmap::Error& e) { PyErr_SetString(PyExc_ValueError, e.what()); }
  });

  bind_io(m);
  bind_registration(m);
  bind_config(m);
  bind_pipeline(m);
  bind_sim_eval(m);
}
