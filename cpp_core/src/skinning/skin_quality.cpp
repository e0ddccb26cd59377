// Quality measures of a deformed skin: normals, per-region volume, local bulge.
#include <cmath>

#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace {

void requireTriangles(const Triangles& triangles, Eigen::Index numVertices, const char* what) {
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int c = 0; c < 3; ++c)
      if (triangles(f, c) < 0 || triangles(f, c) >= numVertices)
        throw InputError(std::string(what) + ": triangle " + std::to_string(f) + " uses vertex " +
                         std::to_string(triangles(f, c)) + ", outside 0.." + std::to_string(numVertices - 1));
}

}  // namespace

// ============================================================================
// Normals
// ============================================================================

Points vertexNormals(const Points& vertices, const Triangles& triangles) {
  requireTriangles(triangles, vertices.rows(), "vertex normals");
  Points n = Points::Zero(vertices.rows(), 3);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Vec3 a = vertices.row(triangles(f, 0)), b = vertices.row(triangles(f, 1)), c = vertices.row(triangles(f, 2));
    const Vec3 area2 = (b - a).cross(c - a);  // length = twice the area: area weighting
    for (int k = 0; k < 3; ++k) n.row(triangles(f, k)) += area2.transpose();
  }
  for (Eigen::Index v = 0; v < n.rows(); ++v) {
    const double len = n.row(v).norm();
    if (len > 0) n.row(v) /= len;
  }
  return n;
}

// ============================================================================
// Region volumes
// ============================================================================

std::vector<double> regionVolumes(const Points& vertices, const Triangles& triangles, const IndexVector& labels,
                                  int numRegions) {
  if (labels.rows() != vertices.rows())
    throw InputError("region volumes: " + std::to_string(labels.rows()) + " labels for " +
                     std::to_string(vertices.rows()) + " vertices");
  if (numRegions < 0) throw InputError("region volumes: negative region count");
  requireTriangles(triangles, vertices.rows(), "region volumes");
  for (Eigen::Index v = 0; v < labels.rows(); ++v)
    if (labels[v] < -1 || labels[v] >= numRegions)
      throw InputError("region volumes: vertex " + std::to_string(v) + " has label " + std::to_string(labels[v]) +
                       ", outside -1.." + std::to_string(numRegions - 1));
  std::vector<Vec3> centroid(numRegions, Vec3::Zero());
  std::vector<int> count(numRegions, 0);
  for (Eigen::Index v = 0; v < labels.rows(); ++v)
    if (labels[v] >= 0) {
      centroid[labels[v]] += vertices.row(v).transpose();
      ++count[labels[v]];
    }
  for (int r = 0; r < numRegions; ++r)
    if (count[r] > 0) centroid[r] /= count[r];
  std::vector<double> volume(numRegions, 0.0);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const int r = labels[triangles(f, 0)];
    if (r < 0 || labels[triangles(f, 1)] != r || labels[triangles(f, 2)] != r) continue;
    const Vec3 a = vertices.row(triangles(f, 0)).transpose() - centroid[r];
    const Vec3 b = vertices.row(triangles(f, 1)).transpose() - centroid[r];
    const Vec3 c = vertices.row(triangles(f, 2)).transpose() - centroid[r];
    volume[r] += a.dot(b.cross(c)) / 6.0;
  }
  return volume;
}

std::vector<double> regionVolumeChange(const Points& rest, const Points& deformed, const Triangles& triangles,
                                       const IndexVector& labels, int numRegions) {
  if (rest.rows() != deformed.rows())
    throw InputError("region volume change: rest has " + std::to_string(rest.rows()) + " vertices, deformed " +
                     std::to_string(deformed.rows()));
  const std::vector<double> v0 = regionVolumes(rest, triangles, labels, numRegions);
  const std::vector<double> v1 = regionVolumes(deformed, triangles, labels, numRegions);
  std::vector<double> change(numRegions, 0.0);
  for (int r = 0; r < numRegions; ++r)
    if (std::abs(v0[r]) > 0) change[r] = (v1[r] - v0[r]) / std::abs(v0[r]);
  return change;
}

// ============================================================================
// Local bulge
// ============================================================================

Eigen::VectorXd localBulge(const Points& rest, const Triangles& triangles, const Points& deformed,
                           const SkinWeights& skeletonWeights, const std::vector<Mat4>& skeletonTransforms) {
  if (rest.rows() != deformed.rows())
    throw InputError("local bulge: rest has " + std::to_string(rest.rows()) + " vertices, deformed " +
                     std::to_string(deformed.rows()));
  validateSkinWeights(skeletonWeights, static_cast<int>(rest.rows()), static_cast<int>(skeletonTransforms.size()));
  const Points normals = vertexNormals(rest, triangles);
  std::vector<Mat4> inverse(skeletonTransforms.size());
  for (size_t b = 0; b < inverse.size(); ++b) inverse[b] = skeletonTransforms[b].inverse();
  Eigen::VectorXd bulge = Eigen::VectorXd::Zero(rest.rows());
  for (Eigen::Index v = 0; v < rest.rows(); ++v) {
    int best = -1;
    double bestWeight = 0.0;
    for (int k = 0; k < skeletonWeights.influences(); ++k)
      if (skeletonWeights.joints(v, k) >= 0 && skeletonWeights.weights(v, k) > bestWeight) {
        best = skeletonWeights.joints(v, k);
        bestWeight = skeletonWeights.weights(v, k);
      }
    if (best < 0) continue;
    const Vec3 local = (inverse[best] * deformed.row(v).transpose().homogeneous()).head<3>();
    bulge[v] = (local - rest.row(v).transpose()).dot(normals.row(v).transpose());
  }
  return bulge;
}

}  // namespace myoskin
