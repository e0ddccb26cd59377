// Mesh validation, topology statistics, welding, bounds and volume.
#include "myoskin/mesh.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "myoskin/errors.h"

namespace myoskin {

// ============================================================================
// Validation
// ============================================================================

void validateMesh(const Mesh& mesh, const std::string& what) {
  if (mesh.vertices.rows() == 0) throw InputError(what + ": has no vertices");
  if (mesh.triangles.rows() == 0) throw InputError(what + ": has no triangles");
  for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i)
    if (!mesh.vertices.row(i).allFinite())
      throw InputError(what + ": vertex " + std::to_string(i) + " has a NaN or infinite coordinate");
  const int n = mesh.numVertices();
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles(f, k);
      if (v < 0 || v >= n)
        throw InputError(what + ": triangle " + std::to_string(f) + " uses vertex " + std::to_string(v) +
                         ", outside 0.." + std::to_string(n - 1));
    }
}

// ============================================================================
// Topology
// ============================================================================

namespace {

// Union-find over triangle indices.
int findRoot(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

}  // namespace

TopologyReport analyzeTopology(const Mesh& mesh) {
  TopologyReport report;
  struct EdgeUse {
    int count = 0;
    int forward = 0;  // uses as (min -> max)
    int firstTriangle = -1;
  };
  std::unordered_map<uint64_t, EdgeUse> edges;
  edges.reserve(static_cast<size_t>(mesh.numTriangles()) * 2);
  const int nf = mesh.numTriangles();
  std::vector<int> parent(nf);
  std::iota(parent.begin(), parent.end(), 0);
  for (int f = 0; f < nf; ++f) {
    const int t[3] = {mesh.triangles(f, 0), mesh.triangles(f, 1), mesh.triangles(f, 2)};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++report.degenerateTriangles;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      const uint64_t key = (static_cast<uint64_t>(std::min(a, b)) << 32) | static_cast<uint32_t>(std::max(a, b));
      EdgeUse& use = edges[key];
      ++use.count;
      if (a < b) ++use.forward;
      if (use.firstTriangle < 0)
        use.firstTriangle = f;
      else
        parent[findRoot(parent, f)] = findRoot(parent, use.firstTriangle);
    }
  }
  for (const auto& [key, use] : edges) {
    if (use.count == 1) ++report.boundaryEdges;
    if (use.count > 2) ++report.nonManifoldEdges;
    if (use.count == 2 && use.forward != 1) ++report.inconsistentEdges;
  }
  for (int f = 0; f < nf; ++f) {
    const int t0 = mesh.triangles(f, 0), t1 = mesh.triangles(f, 1), t2 = mesh.triangles(f, 2);
    if (t0 != t1 && t1 != t2 && t0 != t2 && findRoot(parent, f) == f) ++report.components;
  }
  return report;
}

// ============================================================================
// Welding
// ============================================================================

Mesh weldByPosition(const Mesh& mesh, double tolerance, std::vector<int>& weldMap) {
  const int n = mesh.numVertices();
  weldMap.assign(n, -1);
  const double cell = std::max(tolerance, 1e-12);
  // Hash grid on cells of size `cell`; candidates are searched in the 27 neighbouring cells.
  // Cell coordinates in 64 bits, clamped (and NaN at 0): p / cell exceeds int's range for a large skin and a
  // small tolerance (5.7e10 at 0.057 m and 1e-12), and casting it to int was undefined (UBSan).
  using Cell = Eigen::Matrix<int64_t, 3, 1>;
  auto cellOf = [&](const Vec3& p) {
    Cell c;
    for (int k = 0; k < 3; ++k) {
      const double q = std::floor(p[k] / cell);
      c[k] = q == q ? static_cast<int64_t>(std::clamp(q, -4e18, 4e18)) : 0;
    }
    return c;
  };
  auto hashOf = [](const Cell& c) {
    return (static_cast<uint64_t>(c.x()) * 73856093ULL) ^ (static_cast<uint64_t>(c.y()) * 19349663ULL) ^
           (static_cast<uint64_t>(c.z()) * 83492791ULL);
  };
  std::unordered_multimap<uint64_t, int> grid;
  grid.reserve(n);
  std::vector<int> representatives;
  representatives.reserve(n);
  for (int i = 0; i < n; ++i) {
    const Vec3 p = mesh.vertices.row(i).transpose();
    const Cell c = cellOf(p);
    int found = -1;
    for (int dx = -1; dx <= 1 && found < 0; ++dx)
      for (int dy = -1; dy <= 1 && found < 0; ++dy)
        for (int dz = -1; dz <= 1 && found < 0; ++dz) {
          auto range = grid.equal_range(hashOf(c + Cell(dx, dy, dz)));
          for (auto it = range.first; it != range.second; ++it) {
            const int r = it->second;
            if ((mesh.vertices.row(representatives[r]).transpose() - p).norm() <= tolerance &&
                (found < 0 || r < found))
              found = r;
          }
        }
    if (found < 0) {
      found = static_cast<int>(representatives.size());
      representatives.push_back(i);
      grid.emplace(hashOf(c), found);
    }
    weldMap[i] = found;
  }
  Mesh out;
  out.vertices.resize(static_cast<Eigen::Index>(representatives.size()), 3);
  for (size_t r = 0; r < representatives.size(); ++r) out.vertices.row(r) = mesh.vertices.row(representatives[r]);
  std::vector<Eigen::Vector3i> kept;
  kept.reserve(mesh.numTriangles());
  for (int f = 0; f < mesh.numTriangles(); ++f) {
    const Eigen::Vector3i t(weldMap[mesh.triangles(f, 0)], weldMap[mesh.triangles(f, 1)], weldMap[mesh.triangles(f, 2)]);
    if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) kept.push_back(t);
  }
  out.triangles.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t f = 0; f < kept.size(); ++f) out.triangles.row(f) = kept[f].transpose();
  return out;
}

// ============================================================================
// Measures
// ============================================================================

double principalExtent(const Points& points) {
  if (points.rows() == 0) throw InputError("principalExtent: no points");
  const Vec3 mean = points.colwise().mean().transpose();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Vec3 d = points.row(i).transpose() - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Points projected = (points.rowwise() - mean.transpose()) * eig.eigenvectors();
  return (projected.colwise().maxCoeff() - projected.colwise().minCoeff()).maxCoeff();
}

void boundingBox(const Points& points, Vec3& min, Vec3& max) {
  min = points.colwise().minCoeff().transpose();
  max = points.colwise().maxCoeff().transpose();
}

double enclosedVolume(const Points& vertices, const Triangles& triangles) {
  double six = 0.0;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Vec3 a = vertices.row(triangles(f, 0)).transpose();
    const Vec3 b = vertices.row(triangles(f, 1)).transpose();
    const Vec3 c = vertices.row(triangles(f, 2)).transpose();
    six += a.dot(b.cross(c));
  }
  return six / 6.0;
}

}  // namespace myoskin
