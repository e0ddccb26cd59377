// Normal-space sculpt deltas (Gray & Hutchinson, "Applying modeling changes"): the sculpted detail of one frame
// is stored per vertex in the surface's local frame there (area-weighted normal, tangent toward a fixed
// neighbour along an edge, binormal) and added back in each frame's own local frame.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <string>

#include "myoskin/errors.h"
#include "myoskin/secondary_motion.h"

namespace myoskin {

namespace {

constexpr int kGrain = 4096;

}  // namespace

struct SculptDeltas::Impl {
  Triangles triangles;
  std::vector<int> firstFace, faces;   // CSR: the triangles of each vertex
  std::vector<int> neighbour;          // #V: the vertex its tangent points to (-1: no frame)
  Points deltas;                       // #V by 3: (t, b, n) components, or world for frameless vertices
  std::vector<char> framed;            // #V
  Points work;                         // per-frame offsets
  Points single;                       // float positions in double

  int numVertices() const { return static_cast<int>(neighbour.size()); }

  // Local frame (columns t, b, n) of vertex v in positions p; false when degenerate.
  bool frameOf(const Points& p, int v, Mat3& frame) const {
    Vec3 n = Vec3::Zero();
    for (int k = firstFace[v]; k < firstFace[v + 1]; ++k) {
      const int f = faces[k];
      const Vec3 a = p.row(triangles(f, 0)), b = p.row(triangles(f, 1)), c = p.row(triangles(f, 2));
      n += (b - a).cross(c - a);  // area-weighted
    }
    const double nn = n.norm();
    if (!(nn > 0.0) || neighbour[v] < 0) return false;
    n /= nn;
    Vec3 t = p.row(neighbour[v]).transpose() - p.row(v).transpose();
    t -= n * n.dot(t);
    const double tn = t.norm();
    if (!(tn > 1e-12 * (p.row(neighbour[v]) - p.row(v)).norm()) || !(tn > 0.0)) return false;
    t /= tn;
    frame.col(0) = t;
    frame.col(1) = n.cross(t);
    frame.col(2) = n;
    return true;
  }

  // positions (double) -> out with the deltas added; positions may alias out.
  void applyTo(const Points& p, Points& out) {
    const int V = numVertices();
    if (p.rows() != V) throw InputError("sculpt deltas: " + std::to_string(p.rows()) + " positions for " +
                                        std::to_string(V) + " vertices");
    if (!p.allFinite()) throw InputError("sculpt deltas: the positions have a non-finite value");
    Points& added = work;  // the offsets first (frames read the unmodified positions)
    added.resize(V, 3);
    tbb::parallel_for(tbb::blocked_range<int>(0, V, kGrain), [&](const tbb::blocked_range<int>& range) {
      for (int v = range.begin(); v < range.end(); ++v) {
        Mat3 frame;
        if (framed[v] && frameOf(p, v, frame))
          added.row(v) = (frame * deltas.row(v).transpose()).transpose();
        else if (framed[v])
          added.row(v).setZero();  // the frame collapsed on this frame: no direction to add the detail in
        else
          added.row(v) = deltas.row(v);
      }
    });
    out.resize(V, 3);
    out = p + added;
  }
};

namespace {

// The triangles of each vertex (CSR) and each vertex's tangent neighbour; InputError on a bad index.
void buildAdjacency(SculptDeltas::Impl& d, Eigen::Index V, const Triangles& triangles) {
  d.triangles = triangles;
  d.neighbour.assign(V, -1);
  std::vector<int> count(V + 1, 0);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = triangles(f, k);
      if (i < 0 || i >= V)
        throw InputError("sculpt deltas: triangle " + std::to_string(f) + " uses vertex " + std::to_string(i) +
                         ", outside 0.." + std::to_string(V - 1));
      ++count[i + 1];
      // The tangent's edge: the next corner of the vertex's first triangle that is not itself.
      const int j = triangles(f, (k + 1) % 3);
      if (d.neighbour[i] < 0 && j != i) d.neighbour[i] = j;
    }
  d.firstFace.assign(V + 1, 0);
  for (Eigen::Index v = 0; v < V; ++v) d.firstFace[v + 1] = d.firstFace[v] + count[v + 1];
  d.faces.resize(d.firstFace[V]);
  std::vector<int> fill(d.firstFace.begin(), d.firstFace.end() - 1);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) d.faces[fill[triangles(f, k)]++] = static_cast<int>(f);
}

}  // namespace

SculptDeltas::SculptDeltas(const Points& reference, const Triangles& triangles, const Points& sculpted)
    : impl_(std::make_unique<Impl>()) {
  const Eigen::Index V = reference.rows();
  if (sculpted.rows() != V)
    throw InputError("sculpt deltas: the sculpt has " + std::to_string(sculpted.rows()) + " vertices, the surface " +
                     std::to_string(V));
  if (V == 0) throw InputError("sculpt deltas: the surface has no vertices");
  if (!reference.allFinite() || !sculpted.allFinite())
    throw InputError("sculpt deltas: the surface or the sculpt has a non-finite vertex");
  Impl& d = *impl_;
  buildAdjacency(d, V, triangles);
  d.deltas.resize(V, 3);
  d.framed.assign(V, 0);
  for (Eigen::Index v = 0; v < V; ++v) {
    const Vec3 delta = (sculpted.row(v) - reference.row(v)).transpose();
    Mat3 frame;
    if (d.frameOf(reference, static_cast<int>(v), frame)) {
      d.framed[v] = 1;
      d.deltas.row(v) = (frame.transpose() * delta).transpose();
    } else {
      d.deltas.row(v) = delta.transpose();
    }
  }
}

SculptDeltas::SculptDeltas(const Triangles& triangles, const Points& localDeltas, const std::vector<char>& framed)
    : impl_(std::make_unique<Impl>()) {
  const Eigen::Index V = localDeltas.rows();
  if (V == 0) throw InputError("sculpt deltas: no vertices");
  if (static_cast<Eigen::Index>(framed.size()) != V)
    throw InputError("sculpt deltas: " + std::to_string(framed.size()) + " frame flags for " + std::to_string(V) +
                     " deltas");
  if (!localDeltas.allFinite()) throw InputError("sculpt deltas: a delta is not finite");
  Impl& d = *impl_;
  buildAdjacency(d, V, triangles);
  d.deltas = localDeltas;
  d.framed.assign(V, 0);
  for (Eigen::Index v = 0; v < V; ++v) d.framed[v] = framed[v] ? 1 : 0;
}

SculptDeltas::~SculptDeltas() = default;
SculptDeltas::SculptDeltas(SculptDeltas&&) noexcept = default;
SculptDeltas& SculptDeltas::operator=(SculptDeltas&&) noexcept = default;

int SculptDeltas::numVertices() const { return impl_->numVertices(); }
const Points& SculptDeltas::localDeltas() const { return impl_->deltas; }
const std::vector<char>& SculptDeltas::framed() const { return impl_->framed; }

void SculptDeltas::apply(const Points& positions, Points& out) { impl_->applyTo(positions, out); }

void SculptDeltas::apply(const PointsF& positions, PointsF& out) {
  Impl& d = *impl_;
  d.single = positions.cast<double>();
  d.applyTo(d.single, d.single);
  out = d.single.cast<float>();
}

}  // namespace myoskin
