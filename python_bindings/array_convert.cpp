// numpy <-> core conversions shared by the module's parts (stacks of 4x4 matrices, poses).
#include <algorithm>

#include "bindings.h"
#include "myoskin/errors.h"

namespace myoskin::python {

std::vector<Mat4> matricesFromArray(const py::array_t<double, py::array::c_style | py::array::forcecast>& a,
                                    const char* what) {
  if (a.ndim() != 3 || a.shape(1) != 4 || a.shape(2) != 4)
    throw InputError(std::string(what) + " must be an N by 4 by 4 array");
  auto v = a.unchecked<3>();
  std::vector<Mat4> out(a.shape(0));
  for (py::ssize_t i = 0; i < a.shape(0); ++i)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) out[i](r, c) = v(i, r, c);
  return out;
}

py::array_t<double> matricesToArray(const std::vector<Mat4>& m) {
  py::array_t<double> out({static_cast<py::ssize_t>(m.size()), py::ssize_t(4), py::ssize_t(4)});
  auto a = out.mutable_unchecked<3>();
  for (size_t i = 0; i < m.size(); ++i)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) a(i, r, c) = m[i](r, c);
  return out;
}

Pose poseFromArray(const py::array_t<double, py::array::c_style | py::array::forcecast>& a, int numBones) {
  Pose p;
  p.matrices = matricesFromArray(a, "pose");
  if (static_cast<int>(p.matrices.size()) != numBones)
    throw InputError("pose has " + std::to_string(p.matrices.size()) + " matrices, the skeleton has " +
                     std::to_string(numBones) + " bones");
  return p;
}

py::array_t<int32_t> indexArray(const std::vector<int>& values) {
  py::array_t<int32_t> out(py::array::ShapeContainer{static_cast<py::ssize_t>(values.size())});
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

}  // namespace myoskin::python
