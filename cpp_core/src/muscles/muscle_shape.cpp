// Shape measures of a lofted muscle surface and its containment in the skin (issue 14 item 4).
#include "myoskin/muscle_shape.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "muscles/muscle_util.h"
#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace {

constexpr int kBisections = 26;  // inside/outside bisection steps: 2^-26 of a ring radius, far below float noise

// Number of rings of a surface with loftMuscleSurface's layout (R rings of M, then two poles); throws otherwise.
int ringCount(const Mesh& surface, int M, const char* who) {
  const int nv = surface.numVertices();
  if (M < 3 || nv < M + 2 || (nv - 2) % M != 0)
    throw InputError(std::string(who) + ": the surface (" + std::to_string(nv) + " vertices) is not a loft of rings of " +
                     std::to_string(M) + " vertices and two poles");
  return (nv - 2) / M;
}

Vec3 vertex(const Mesh& m, int v) { return m.vertices.row(v).transpose(); }

// A ring's centre, unit plane normal, unit major axis and aspect (major / minor extent), by principal axes.
struct RingFrame {
  Vec3 center, normal, major;
  double aspect = 1.0;
};
RingFrame ringFrame(const Mesh& m, int r, int M) {
  RingFrame f;
  f.center.setZero();
  for (int k = 0; k < M; ++k) f.center += vertex(m, r * M + k);
  f.center /= M;
  Mat3 cov = Mat3::Zero();
  for (int k = 0; k < M; ++k) {
    const Vec3 d = vertex(m, r * M + k) - f.center;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Mat3> es(cov);  // ascending eigenvalues
  f.normal = es.eigenvectors().col(0);
  f.major = es.eigenvectors().col(2);
  const double l1 = std::max(es.eigenvalues()(1), 0.0), l2 = std::max(es.eigenvalues()(2), 0.0);
  f.aspect = l1 > 0 ? std::sqrt(l2 / l1) : INFINITY;
  return f;
}

}  // namespace

// ============================================================================
// Measures
// ============================================================================

MuscleShape measureMuscleShape(const Mesh& surface, int M, const SkinWinding* skin, double limbRadius) {
  const int R = ringCount(surface, M, "measureMuscleShape");
  MuscleShape s;
  const TopologyReport topo = analyzeTopology(surface);
  s.volume = enclosedVolume(surface.vertices, surface.triangles);
  s.watertight = topo.closed() && topo.manifold() && topo.oriented() && topo.components == 1 && s.volume > 0;
  s.selfIntersections = selfIntersections(surface.vertices, surface.triangles);

  // Twist: neighbouring elongated rings' major axes, projected into the later ring's plane, mod 180 degrees.
  std::vector<RingFrame> frames(R);
  for (int r = 0; r < R; ++r) frames[r] = ringFrame(surface, r, M);
  for (int r = 0; r + 1 < R; ++r) {
    if (frames[r].aspect < 1.25 || frames[r + 1].aspect < 1.25) continue;
    const Vec3 n = frames[r + 1].normal;
    const Vec3 a = frames[r].major - frames[r].major.dot(n) * n, b = frames[r + 1].major;
    if (a.norm() < 1e-9) continue;
    const double c = std::min(1.0, std::abs(a.normalized().dot(b)));
    s.maxTwist = std::max(s.maxTwist, std::acos(c) * 180.0 / kPi);
  }

  // Spikes: each ring vertex's offset from the mean of its neighbours along its normal (the umbrella Laplacian's
  // normal part: uneven ring spacing moves the mean along the surface, a spike off it), in units of its ring's mean
  // radius (at least a quarter of the largest ring's, so the tapered tips' tiny rings do not count as spikes).
  const int nv = surface.numVertices();
  std::vector<double> ringRadius(R, 0.0);
  double largest = 0.0;
  for (int r = 0; r < R; ++r) {
    for (int k = 0; k < M; ++k) ringRadius[r] += (vertex(surface, r * M + k) - frames[r].center).norm() / M;
    largest = std::max(largest, ringRadius[r]);
  }
  std::vector<std::vector<int>> nbrs(nv);
  std::map<std::pair<int, int>, std::vector<int>> edgeFaces;
  for (int f = 0; f < surface.numTriangles(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int a = surface.triangles(f, c), b = surface.triangles(f, (c + 1) % 3);
      nbrs[a].push_back(b), nbrs[b].push_back(a);
      edgeFaces[{std::min(a, b), std::max(a, b)}].push_back(f);
    }
  std::vector<Vec3> vertexNormal(nv, Vec3::Zero());  // area-weighted
  for (int f = 0; f < surface.numTriangles(); ++f) {
    const Vec3 a = vertex(surface, surface.triangles(f, 0)), b = vertex(surface, surface.triangles(f, 1)),
               c = vertex(surface, surface.triangles(f, 2));
    for (int k = 0; k < 3; ++k) vertexNormal[surface.triangles(f, k)] += (b - a).cross(c - a);
  }
  for (int v = 0; v < R * M; ++v) {
    auto& nb = nbrs[v];
    std::sort(nb.begin(), nb.end());
    nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
    if (nb.empty()) continue;
    Vec3 mean = Vec3::Zero();
    for (int u : nb) mean += vertex(surface, u);
    mean /= nb.size();
    const double radius = std::max(ringRadius[v / M], 0.25 * largest);
    if (radius > 0 && vertexNormal[v].norm() > 0)
      s.maxSpike = std::max(s.maxSpike, std::abs((vertex(surface, v) - mean).dot(vertexNormal[v].normalized())) / radius);
  }
  auto normal = [&](int f) {
    const Vec3 a = vertex(surface, surface.triangles(f, 0)), b = vertex(surface, surface.triangles(f, 1)),
               c = vertex(surface, surface.triangles(f, 2));
    return Vec3((b - a).cross(c - a));
  };
  for (const auto& [edge, faces] : edgeFaces) {
    if (faces.size() != 2) continue;
    const Vec3 n0 = normal(faces[0]), n1 = normal(faces[1]);
    if (n0.norm() < 1e-300 || n1.norm() < 1e-300) continue;
    const double c = std::clamp(n0.normalized().dot(n1.normalized()), -1.0, 1.0);
    s.maxDihedral = std::max(s.maxDihedral, std::acos(c) * 180.0 / kPi);
  }

  // Outside the skin.
  if (skin) {
    std::vector<double> out(nv, 0.0);
    tbb::parallel_for(tbb::blocked_range<int>(0, nv, 64), [&](const tbb::blocked_range<int>& range) {
      for (int v = range.begin(); v < range.end(); ++v) {
        const Vec3 p = vertex(surface, v);
        if (!skin->inside(p)) out[v] = std::max(skin->distance(p), 1e-300);
      }
    });
    for (double d : out)
      if (d > 0) ++s.outside, s.maxOutside = std::max(s.maxOutside, d / std::max(limbRadius, 1e-300));
  }
  return s;
}

// ============================================================================
// Containment
// ============================================================================

namespace {


// The surface cut down to rings [first, last] (loftMuscleSurface's layout and triangulation, outward), with the
// given poles.
Mesh keepRings(const Mesh& surface, int M, int first, int last, const Vec3& poleO, const Vec3& poleI) {
  const int R = last - first + 1;
  Mesh mesh;
  mesh.vertices.resize(R * M + 2, 3);
  mesh.vertices.topRows(R * M) = surface.vertices.middleRows(first * M, R * M);
  mesh.vertices.row(R * M) = poleO.transpose();
  mesh.vertices.row(R * M + 1) = poleI.transpose();
  detail::closeRingTube(mesh, R, M);
  return mesh;
}

// The last point inside the skin on the segment from `in` (inside) to `out` (bisection).
Vec3 exitPoint(const SkinWinding& skin, const Vec3& in, const Vec3& out) {
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < kBisections; ++it) {
    const double mid = 0.5 * (lo + hi);
    (skin.inside(in + mid * (out - in)) ? lo : hi) = mid;
  }
  return in + lo * (out - in);
}

}  // namespace

int containMuscleSurface(Mesh& surface, int M, const SkinWinding& skin, double margin) {
  int R = ringCount(surface, M, "containMuscleSurface");
  if (!(margin >= 0) || !std::isfinite(margin)) throw InputError("containMuscleSurface: margin must be >= 0");
  std::vector<Vec3> centers(R, Vec3::Zero());
  std::vector<char> centerInside(R, 0);
  for (int r = 0; r < R; ++r) {
    for (int k = 0; k < M; ++k) centers[r] += vertex(surface, r * M + k);
    centers[r] /= M;
    centerInside[r] = skin.inside(centers[r]);
  }
  // End rings whose centres lie outside the skin (a tendon running past an open limb end) are cut off: the end then
  // closes at the point where the centre line leaves the skin.
  int first = 0, last = R - 1, cut = 0;
  while (first < R && !centerInside[first]) ++first;
  while (last >= 0 && !centerInside[last]) --last;
  if (first > last) return 0;
  if (first > 0 || last < R - 1) {
    const Vec3 poleO = first > 0 ? exitPoint(skin, centers[first], centers[first - 1]) : Vec3(vertex(surface, R * M));
    const Vec3 poleI = last < R - 1 ? exitPoint(skin, centers[last], centers[last + 1]) : Vec3(vertex(surface, R * M + 1));
    cut = (R - 1 - last + first) * M;
    surface = keepRings(surface, M, first, last, poleO, poleI);
    centers = std::vector<Vec3>(centers.begin() + first, centers.begin() + last + 1);
    centerInside = std::vector<char>(centerInside.begin() + first, centerInside.begin() + last + 1);
    R = last - first + 1;
  }
  // Each ring's anchor: its centre, or for a ring whose centre lies outside the skin, the nearest (by ring) centre
  // inside; none when no centre is inside.
  std::vector<int> anchor(R, -1);
  for (int r = 0; r < R; ++r)
    for (int o = 0; o < R && anchor[r] < 0; ++o) {
      if (r - o >= 0 && centerInside[r - o]) anchor[r] = r - o;
      else if (r + o < R && centerInside[r + o]) anchor[r] = r + o;
    }
  // Per vertex the largest share s in [0, 1] with c + (1 + margin) s d inside (bisection from the inside anchor c).
  std::vector<double> share(R * M, 1.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, R * M, 16), [&](const tbb::blocked_range<int>& range) {
    for (int v = range.begin(); v < range.end(); ++v) {
      const int r = v / M;
      if (anchor[r] < 0) continue;
      const Vec3 c = centers[anchor[r]], d = (1.0 + margin) * (vertex(surface, v) - c);
      if (skin.inside(c + d)) continue;
      double lo = 0.0, hi = 1.0;
      for (int it = 0; it < kBisections; ++it) {
        const double mid = 0.5 * (lo + hi);
        (skin.inside(c + mid * d) ? lo : hi) = mid;
      }
      share[v] = lo;
    }
  });
  // Erode then average over the same window (around: +-2 vertices, along: +-1 ring): never above a vertex's share.
  const int wk = 2, wr = 1;
  auto filter = [&](const std::vector<double>& in, bool erode, bool around) {
    std::vector<double> out(in.size());
    for (int r = 0; r < R; ++r)
      for (int k = 0; k < M; ++k) {
        double acc = erode ? INFINITY : 0.0;
        int count = 0;
        const int w = around ? wk : wr;
        for (int o = -w; o <= w; ++o) {
          int rr = r, kk = k;
          if (around) {
            kk = ((k + o) % M + M) % M;
          } else {
            rr = r + o;
            if (rr < 0 || rr >= R) continue;
          }
          const double x = in[rr * M + kk];
          acc = erode ? std::min(acc, x) : acc + x;
          ++count;
        }
        out[r * M + k] = erode ? acc : acc / count;
      }
    return out;
  };
  std::vector<double> s = filter(filter(share, true, true), true, false);
  s = filter(filter(s, false, true), false, false);
  int moved = 0;
  for (int v = 0; v < R * M; ++v) {
    if (s[v] >= 1.0 || anchor[v / M] < 0) continue;
    const Vec3 c = centers[anchor[v / M]];
    surface.vertices.row(v) = (c + s[v] * (vertex(surface, v) - c)).transpose();
    ++moved;
  }
  // A pole outside the skin moves towards its ring's centre the same way.
  for (int pole = 0; pole < 2; ++pole) {
    const int v = R * M + pole, r = anchor[pole == 0 ? 0 : R - 1];
    if (r < 0) continue;
    const Vec3 c = centers[r], d = (1.0 + margin) * (vertex(surface, v) - c);
    if (skin.inside(c + d)) continue;
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < kBisections; ++it) {
      const double mid = 0.5 * (lo + hi);
      (skin.inside(c + mid * d) ? lo : hi) = mid;
    }
    surface.vertices.row(v) = (c + lo * (vertex(surface, v) - c)).transpose();
    ++moved;
  }
  return moved + cut;
}

}  // namespace myoskin
