// Shared declarations of the _core module's parts (one file per area of the core).
#pragma once
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <mutex>
#include <string>
#include <vector>

#include "myoskin/deformation.h"
#include "myoskin/skeleton.h"
#include "myoskin/skin_weights.h"
#include "myoskin/skinning.h"
#include "myoskin/types.h"

namespace myoskin::python {

namespace py = pybind11;

void bindCharacter(py::module_& m);
void bindMuscles(py::module_& m);
void bindGenerate(py::module_& m);
void bindExtraction(py::module_& m);
void bindDeformation(py::module_& m);
void bindSkinning(py::module_& m);
void bindSkinSolve(py::module_& m);
void bindCorrectives(py::module_& m);
void bindAnchored(py::module_& m);
void bindDynamics(py::module_& m);

// The _core.MuscleRig object (bind_deformation.cpp; also taken by bind_skinning.cpp): the rig plus its
// evaluation state, reused across evaluate() calls (no per-frame allocation in the core); the mutex
// serialises callers, since evaluate runs without the GIL.
struct PyMuscleRig : MuscleRig {
  using MuscleRig::MuscleRig;
  MuscleRigState state = makeState();
  std::mutex mutex;
};

// ============================================================================
// Array conversions shared by the parts (array_convert.cpp)
// ============================================================================

using MatrixStack = py::array_t<double, py::array::c_style | py::array::forcecast>;
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IntArray = py::array_t<int32_t, py::array::c_style | py::array::forcecast>;
// #V by K joint indices and weights (the same shape; 1-D arrays are one influence per vertex) -> SkinWeights
// (bind_skinning.cpp); InputError on other shapes or another row count.
SkinWeights weightsArg(const IntArray& joints, const DoubleArray& weights, Eigen::Index numVertices);
// 'pivot' | 'blended' -> DualQuatScale (bind_skinning.cpp); InputError on another name.
DualQuatScale dualQuatScaleArg(const std::string& name);
// N by 4 by 4 array -> matrices; InputError naming `what` on another shape.
std::vector<Mat4> matricesFromArray(const MatrixStack& a, const char* what);
// matrices -> N by 4 by 4 array (a copy).
py::array_t<double> matricesToArray(const std::vector<Mat4>& m);
// A copy of `values` as a 1-D int32 array. (Debian 12's pybind11 2.10 array_t(count[, ptr]) constructor can give
// the array stride 0, every entry then reading as the first: build 1-D arrays from a ShapeContainer.)
py::array_t<int32_t> indexArray(const std::vector<int>& values);
// #B by 4 by 4 posed bone matrices (Blender's PoseBone.matrix) -> Pose; InputError on another size.
Pose poseFromArray(const MatrixStack& a, int numBones);


}  // namespace myoskin::python
