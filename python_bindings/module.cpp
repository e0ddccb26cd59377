// The `_core` module: numpy in, numpy out. InputError -> ValueError, other core errors -> RuntimeError.
#include <Python.h>

#include <cstring>

#include "bindings.h"
#include "myoskin/errors.h"
#include "myoskin/memory_budget.h"

namespace py = pybind11;

namespace {
// PyErr_SetString needs UTF-8; a message quoting bytes of a damaged file (tinygltf quotes its JSON) may not
// be, and then Python raised the exception with no message at all. Undecodable bytes become U+FFFD.
void setError(PyObject* type, const char* what) {
  PyObject* message = PyUnicode_DecodeUTF8(what, static_cast<Py_ssize_t>(std::strlen(what)), "replace");
  if (message == nullptr) {
    PyErr_Clear();
    PyErr_SetString(type, "(the error message could not be decoded)");
    return;
  }
  PyErr_SetObject(type, message);
  Py_DECREF(message);
}
}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "Myoskin core: muscle extraction, muscle deformation and hybrid skinning (Yang & Zhang 2006).";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const myoskin::InputError& e) {
      setError(PyExc_ValueError, e.what());
    } catch (const myoskin::MyoskinError& e) {
      setError(PyExc_RuntimeError, e.what());
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
        d["pybind11_version"] = std::to_string(PYBIND11_VERSION_MAJOR) + "." + std::to_string(PYBIND11_VERSION_MINOR);
        return d;
      },
      "What this module was built for: myoskin_version, python_version (major.minor), build_type, compiler, "
      "pybind11_version (major.minor).");
  m.def("available_memory", &myoskin::availableMemoryBytes,
        "Bytes the core's large stages may still allocate before they refuse with ValueError: the least of free "
        "memory, the cgroup's memory.max, ulimit -v and MYOSKIN_MEMORY_LIMIT (e.g. '4G') minus the resident set.");
  m.attr("__version__") = MYOSKIN_VERSION;
  myoskin::python::bindCharacter(m);
  myoskin::python::bindMuscles(m);
  myoskin::python::bindGenerate(m);
  myoskin::python::bindExtraction(m);
  myoskin::python::bindDeformation(m);
  myoskin::python::bindSkinning(m);
  myoskin::python::bindSkinSolve(m);
  myoskin::python::bindCorrectives(m);
  myoskin::python::bindAnchored(m);
  myoskin::python::bindDynamics(m);
}
