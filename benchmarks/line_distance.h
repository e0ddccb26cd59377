// Distance of a point from a polyline, for the benchmarks that match found sections to true centre lines.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

#include "myoskin/types.h"

namespace myoskin::bench {

// Distance of p from the polyline `line` (INFINITY for fewer than two points).
inline double lineDistance(const Vec3& p, const std::vector<Vec3>& line) {
  double best = INFINITY;
  for (size_t k = 1; k < line.size(); ++k) {
    const Vec3 d = line[k] - line[k - 1];
    const double t = d.squaredNorm() > 0 ? std::clamp((p - line[k - 1]).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
    best = std::min(best, (p - (line[k - 1] + t * d)).norm());
  }
  return best;
}

}  // namespace myoskin::bench
