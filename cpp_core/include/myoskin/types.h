// Array types shared by the whole core. Row-major so numpy arrays map onto them without copies.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace myoskin {

// Pi, the one definition for the whole core (file-local copies collide in a unity build).
constexpr double kPi = 3.14159265358979323846;

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Points2 = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;  // #P by 2
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;   // #V by 3
using Triangles = Eigen::Matrix<int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;  // #F by 3
using IndexMatrix = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using WeightMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using IndexVector = Eigen::Matrix<int32_t, Eigen::Dynamic, 1>;

}  // namespace myoskin
