// The `_core` module: numpy in, numpy out. InputError -> ValueError, other core errors -> RuntimeError.
#include <Python.h>

#include "bindings.h"
#include "myoskin/errors.h"

namespace py = pybind11;

PYBIND11_MODULE(_core, m) {
  m.doc() = "Myoskin core: muscle extraction, muscle deformation and hybrid skinning (Yang & Zhang 2006).";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const myoskin::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const myoskin::MyoskinError& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
  m.def(
      "build_info",
      []() {
        py::dict d;
        d["myoskin_version"] = MYOSKIN_VERSION;
        d["python_version"] = MYOSKIN_PYTHON_VERSION;
        d["build_type"] = MYOSKIN_BUILD_TYPE;
        d["compiler"] = std::string("g++ ") + __VERSION__;
        return d;
      },
      "What this module was built for: myoskin_version, python_version (major.minor), build_type, compiler.");
  m.attr("__version__") = MYOSKIN_VERSION;
  myoskin::python::bindCharacter(m);
  myoskin::python::bindMuscles(m);
  myoskin::python::bindGenerate(m);
  myoskin::python::bindExtraction(m);
  myoskin::python::bindDeformation(m);
  myoskin::python::bindSkinning(m);
}
