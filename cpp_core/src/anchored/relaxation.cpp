// Relaxation of the anchored skin toward its rest edge lengths near seams (Schneider & Wilhelms 1998, 4.3).
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <functional>

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
  neighbourSlot_.resize(neighbours_.size());
  for (size_t k = 0; k < neighbours_.size(); ++k) neighbourSlot_[k] = slot[neighbours_[k]];
  strained_.assign(movable_.size(), 0);
  active_.assign(movable_.size(), 0);
  activeList_.assign(movable_.size(), 0);
  next_.resize(static_cast<Eigen::Index>(movable_.size()), 3);
  backup_.resize(static_cast<Eigen::Index>(movable_.size()), 3);
}

// ============================================================================
// Iteration
// ============================================================================

// Energy of the active vertices' edges: sum of (|e| - |e_rest|)^2, an edge between two active vertices counted
// once (half from each end). A deterministic reduction (fixed chunks, fixed order).
double Relaxer::energy(const Eigen::Map<Points>& x, int count) const {
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<int>(0, count, 2048), 0.0,
      [&](const tbb::blocked_range<int>& r, double e) {
        for (int a = r.begin(); a < r.end(); ++a) {
          const int i = activeList_[a];
          const Vec3 xv = x.row(movable_[i]).transpose();
          for (int k = offsets_[i]; k < offsets_[i + 1]; ++k) {
            const double d = (xv - x.row(neighbours_[k]).transpose()).norm() - restLength_[k];
            const int j = neighbourSlot_[k];
            e += (j >= 0 && active_[j] ? 0.5 : 1.0) * d * d;
          }
        }
        return e;
      },
      std::plus<double>());
}

// Only the strained part of the seams works: a movable vertex with an edge off its rest length by more than 1e-6
// of it, and its movable neighbours, are active this frame; the others keep their anchored positions. Each active
// vertex moves `step` of the way to the mean of the points that would give each of its edges its rest length (the
// neighbour plus the rest length along the current edge direction). Jacobi, so the result does not depend on the
// order; with relaxTangential the move keeps off the vertex's normal (the skin slides over its components
// instead of shrinking onto them). An iteration that raises the energy is undone and retried with half the step.
void Relaxer::run(Eigen::Map<Points> x, const Points& normals, const AnchoredSkinOptions& options,
                  RelaxationTrace* trace) const {
  if (trace) trace->energy.clear();
  if (movable_.empty() || options.relaxIterations <= 0) return;
  const int n = static_cast<int>(movable_.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 2048), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i < r.end(); ++i) {
      const Vec3 xv = x.row(movable_[i]).transpose();
      char s = 0;
      for (int k = offsets_[i]; k < offsets_[i + 1] && !s; ++k)
        s = std::abs((xv - x.row(neighbours_[k]).transpose()).norm() - restLength_[k]) > 1e-6 * restLength_[k];
      strained_[i] = s;
    }
  });
  int count = 0;
  for (int i = 0; i < n; ++i) {
    char a = strained_[i];
    for (int k = offsets_[i]; k < offsets_[i + 1] && !a; ++k) a = neighbourSlot_[k] >= 0 && strained_[neighbourSlot_[k]];
    active_[i] = a;
    if (a) activeList_[count++] = i;
  }
  if (count == 0) return;  // at rest, or every seam moving rigidly: nothing to relax
  double e = energy(x, count);
  if (trace) trace->energy.push_back(e);
  double step = options.relaxStep;
  for (int it = 0; it < options.relaxIterations && e > 0.0; ++it) {
    tbb::parallel_for(tbb::blocked_range<int>(0, count, 1024), [&](const tbb::blocked_range<int>& r) {
      for (int a = r.begin(); a < r.end(); ++a) {
        const int i = activeList_[a];
        const Vec3 xv = x.row(movable_[i]).transpose();
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
        backup_.row(a) = xv.transpose();
        Vec3 delta = used ? Vec3(step * (target / used - xv)) : Vec3::Zero();
        if (options.relaxTangential) {
          const Vec3 nrm = normals.row(movable_[i]).transpose();
          delta -= delta.dot(nrm) * nrm;
        }
        const Vec3 moved = xv + delta;
        next_.row(a) = moved.transpose();
      }
    });
    for (int a = 0; a < count; ++a) x.row(movable_[activeList_[a]]) = next_.row(a);
    const double after = energy(x, count);
    if (after > e) {  // undo, halve the step
      for (int a = 0; a < count; ++a) x.row(movable_[activeList_[a]]) = backup_.row(a);
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
