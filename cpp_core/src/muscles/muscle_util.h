// Small geometry helpers shared by the muscle stages (internal).
#pragma once
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "myoskin/types.h"

namespace myoskin::detail {

// The trunk's plane families (across the whole body): they get their own height floor and attachments.
inline bool trunkFamily(const std::string& family) { return family == "abdomen" || family == "neck"; }

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
