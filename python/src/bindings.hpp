#pragma once
// One function per part of the library, each adding its classes and functions to the module.
#include <pybind11/pybind11.h>

namespace gcmap::python {

void bind_io(pybind11::module_& m);            // read_points, write_points, trajectories
void bind_registration(pybind11::module_& m);  // register, RegistrationResult
void bind_config(pybind11::module_& m);        // MappingConfig
void bind_pipeline(pybind11::module_& m);      // MappingPipeline
void bind_sim_eval(pybind11::module_& m);      // simulate, kitti, ate, rpe, mme

}  // namespace gcmap::python
