// Shared declarations of the _core module's parts (one file per area of the core).
#pragma once
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

namespace myoskin::python {

namespace py = pybind11;

void bindCharacter(py::module_& m);
void bindMuscles(py::module_& m);
void bindGenerate(py::module_& m);
void bindExtraction(py::module_& m);
void bindSkinning(py::module_& m);


}  // namespace myoskin::python
