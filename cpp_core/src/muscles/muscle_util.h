// Small geometry helpers shared by the muscle stages (internal).
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "myoskin/mesh.h"
#include "myoskin/types.h"

namespace myoskin::detail {

// The trunk's plane families (across the whole body): they get their own height floor and attachments.
inline bool trunkFamily(const std::string& family) { return family == "abdomen" || family == "neck"; }

// Closes a muscle loft: mesh.vertices holds R rings of M vertices (origin ring first) and then the origin and
// insertion poles (rows R * M and R * M + 1); fills mesh.triangles (quads between rings split in two, a fan to
// each pole) and flips them all when the enclosed volume comes out negative, so the surface faces outward.
inline void closeRingTube(Mesh& mesh, int R, int M) {
  const int poleO = R * M, poleI = R * M + 1;
  mesh.triangles.resize(2 * M * (R - 1) + 2 * M, 3);
  int t = 0;
  for (int r = 0; r + 1 < R; ++r)
    for (int k = 0; k < M; ++k) {
      const int a = r * M + k, b = r * M + (k + 1) % M, c = (r + 1) * M + (k + 1) % M, d = (r + 1) * M + k;
      mesh.triangles.row(t++) << a, b, c;
      mesh.triangles.row(t++) << a, c, d;
    }
  for (int k = 0; k < M; ++k) {
    mesh.triangles.row(t++) << poleO, (k + 1) % M, k;
    mesh.triangles.row(t++) << poleI, (R - 1) * M + k, (R - 1) * M + (k + 1) % M;
  }
  if (enclosedVolume(mesh.vertices, mesh.triangles) < 0)
    for (int i = 0; i < mesh.numTriangles(); ++i) std::swap(mesh.triangles(i, 1), mesh.triangles(i, 2));
}

// Closest point to p on segment [a, b]; t receives the segment parameter in [0, 1].
inline Vec3 closestOnSegment(const Vec3& p, const Vec3& a, const Vec3& b, double* t = nullptr) {
  const Vec3 d = b - a;
  const double len2 = d.squaredNorm();
  double s = len2 > 1e-30 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  if (t) *t = s;
  return a + s * d;
}

// Distance from p to a polyline (a single point when it has one vertex; infinity when empty).
inline double distanceToPolyline(const Vec3& p, const std::vector<Vec3>& line) {
  if (line.empty()) return INFINITY;
  if (line.size() == 1) return (p - line[0]).norm();
  double best = INFINITY;
  for (size_t i = 0; i + 1 < line.size(); ++i) best = std::min(best, (p - closestOnSegment(p, line[i], line[i + 1])).norm());
  return best;
}

// Unit vector perpendicular to n closest to v (any perpendicular if v is parallel to n).
inline Vec3 perpendicularTo(const Vec3& v, const Vec3& n) {
  Vec3 r = v - v.dot(n) * n;
  if (r.norm() < 1e-12) {
    r = n.unitOrthogonal();
  }
  return r.normalized();
}

// Polyline length.
inline double polylineLength(const std::vector<Vec3>& line) {
  double s = 0;
  for (size_t i = 0; i + 1 < line.size(); ++i) s += (line[i + 1] - line[i]).norm();
  return s;
}

}  // namespace myoskin::detail
