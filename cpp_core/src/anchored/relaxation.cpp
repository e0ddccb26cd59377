// Relaxation of the anchored skin toward its rest edge lengths near seams (Schneider & Wilhelms 1998, 4.3).
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <algorithm>
#include <cmath>

#include "anchored/anchored_internal.h"

namespace myoskin::anchored {

namespace {
using OMesh = OpenMesh::TriMesh_ArrayKernelT<>;
}

// ============================================================================
// Adjacency
// ============================================================================

std::vector<std::pair<int, int>> Relaxer::meshEdges(const Mesh& mesh) {
  OMesh om;
  std::vector<OMesh::VertexHandle> handles(mesh.numVertices());
  for (int v = 0; v < mesh.numVertices(); ++v) handles[v] = om.add_vertex(OMesh::Point(0, 0, 0));
  std::vector<std::pair<int, int>> edges;
  // OpenMesh refuses faces that would make an edge non-manifold (and says so on stderr): keep it quiet and
  // take those faces' edges directly.
  omerr().disable();
  for (int f = 0; f < mesh.numTriangles(); ++f) {
    const int a = mesh.triangles(f, 0), b = mesh.triangles(f, 1), c = mesh.triangles(f, 2);
    if (a == b || b == c || a == c) continue;
    if (!om.add_face(handles[a], handles[b], handles[c]).is_valid()) {
      edges.emplace_back(std::min(a, b), std::max(a, b));
      edges.emplace_back(std::min(b, c), std::max(b, c));
      edges.emplace_back(std::min(a, c), std::max(a, c));
    }
  }
  omerr().enable();
  for (const auto& e : om.edges()) {
    const int a = e.v0().idx(), b = e.v1().idx();
    edges.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

void Relaxer::build(const Mesh& rest, const std::vector<char>& movable, const std::vector<std::pair<int, int>>& edges) {
  const int nv = rest.numVertices();
  std::vector<int> slot(nv, -1);
  movable_.clear();
  for (int v = 0; v < nv; ++v)
    if (movable[v]) {
      slot[v] = static_cast<int>(movable_.size());
      movable_.push_back(v);
    }
  std::vector<int> count(movable_.size() + 1, 0);
  edgeA_.clear();
  edgeB_.clear();
  edgeRest_.clear();
  for (const auto& [a, b] : edges) {
    if (slot[a] < 0 && slot[b] < 0) continue;
    const double length = (rest.vertices.row(a) - rest.vertices.row(b)).norm();
    edgeA_.push_back(a);
    edgeB_.push_back(b);
    edgeRest_.push_back(length);
    if (slot[a] >= 0) ++count[slot[a] + 1];
    if (slot[b] >= 0) ++count[slot[b] + 1];
  }
  offsets_.assign(count.begin(), count.end());
  for (size_t i = 1; i < offsets_.size(); ++i) offsets_[i] += offsets_[i - 1];
  neighbours_.assign(offsets_.back(), -1);
  restLength_.assign(offsets_.back(), 0.0);
  std::vector<int> fill(offsets_.begin(), offsets_.end() - 1);
  for (size_t e = 0; e < edgeA_.size(); ++e) {
    const int a = edgeA_[e], b = edgeB_[e];
    if (slot[a] >= 0) {
      neighbours_[fill[slot[a]]] = b;
      restLength_[fill[slot[a]]++] = edgeRest_[e];
    }
    if (slot[b] >= 0) {
      neighbours_[fill[slot[b]]] = a;
      restLength_[fill[slot[b]]++] = edgeRest_[e];
    }
  }
  double mean = 0.0;
  for (double l : edgeRest_) mean += l;
  mean = edgeRest_.empty() ? 0.0 : mean / static_cast<double>(edgeRest_.size());
  quiet_ = static_cast<double>(edgeRest_.size()) * (1e-9 * mean) * (1e-9 * mean);
  next_.resize(static_cast<Eigen::Index>(movable_.size()), 3);
  backup_.resize(static_cast<Eigen::Index>(movable_.size()), 3);
}

// ============================================================================
// Iteration
// ============================================================================

double Relaxer::energy(const Eigen::Map<Points>& x) const {
  double e = 0.0;
  for (size_t k = 0; k < edgeA_.size(); ++k) {
    const double d = (x.row(edgeA_[k]) - x.row(edgeB_[k])).norm() - edgeRest_[k];
    e += d * d;
  }
  return e;
}

// Each movable vertex moves `step` of the way to the mean of the points that would give each of its edges its
// rest length (the neighbour plus the rest length along the current edge direction). Jacobi, so the result does
// not depend on the order; an iteration that raises the energy is undone and retried with half the step.
void Relaxer::run(Eigen::Map<Points> x, const AnchoredSkinOptions& options, RelaxationTrace* trace) const {
  if (trace) trace->energy.clear();
  if (movable_.empty() || options.relaxIterations <= 0) return;
  double e = energy(x);
  if (trace) trace->energy.push_back(e);
  if (e <= quiet_) return;  // at rest (rounding only): nothing to relax
  double step = options.relaxStep;
  const int n = static_cast<int>(movable_.size());
  for (int it = 0; it < options.relaxIterations && e > 0.0; ++it) {
    for (int i = 0; i < n; ++i) {
      const int v = movable_[i];
      const Vec3 xv = x.row(v).transpose();
      Vec3 target = Vec3::Zero();
      int used = 0;
      for (int k = offsets_[i]; k < offsets_[i + 1]; ++k) {
        const Vec3 xn = x.row(neighbours_[k]).transpose();
        const Vec3 d = xv - xn;
        const double len = d.norm();
        if (!(len > 0.0)) continue;
        target += xn + d * (restLength_[k] / len);
        ++used;
      }
      backup_.row(i) = xv.transpose();
      const Vec3 moved = used ? Vec3(xv + step * (target / used - xv)) : xv;
      next_.row(i) = moved.transpose();
    }
    for (int i = 0; i < n; ++i) x.row(movable_[i]) = next_.row(i);
    const double after = energy(x);
    if (after > e) {  // undo, halve the step
      for (int i = 0; i < n; ++i) x.row(movable_[i]) = backup_.row(i);
      step *= 0.5;
      if (trace) trace->energy.push_back(e);
      continue;
    }
    const double drop = e - after;
    e = after;
    if (trace) trace->energy.push_back(e);
    if (drop <= options.relaxTolerance * (e + drop)) break;
  }
}

}  // namespace myoskin::anchored
