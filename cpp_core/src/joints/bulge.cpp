// Volume-preserving bulge: slice areas of the rest surface and the closed-form section scales.
#include "joints/bulge.h"

#include <algorithm>
#include <cmath>

namespace myoskin::joints {

double sliceArea(const Mesh& surface, const Vec3& point, const Vec3& normal) {
  // Each crossing triangle gives a segment oriented along normal x (triangle normal): for a closed,
  // outward-oriented mesh the segments run counter-clockwise round the normal, so the shoelace sum over
  // them is the enclosed area.
  double area = 0;
  const auto& V = surface.vertices;
  for (int f = 0; f < surface.numTriangles(); ++f) {
    Vec3 p[3];
    double d[3];
    for (int c = 0; c < 3; ++c) {
      p[c] = V.row(surface.triangles(f, c)).transpose();
      d[c] = (p[c] - point).dot(normal);
    }
    Vec3 hits[2];
    int nh = 0;
    for (int c = 0; c < 3 && nh < 2; ++c) {
      const int e = (c + 1) % 3;
      if ((d[c] < 0) != (d[e] < 0)) hits[nh++] = p[c] + (d[c] / (d[c] - d[e])) * (p[e] - p[c]);
    }
    if (nh < 2) continue;
    const Vec3 triNormal = (p[1] - p[0]).cross(p[2] - p[0]);
    if ((hits[1] - hits[0]).dot(normal.cross(triNormal)) < 0) std::swap(hits[0], hits[1]);
    area += 0.5 * (hits[0] - point).cross(hits[1] - point).dot(normal);
  }
  return std::max(area, 0.0);
}

BulgeProfile makeBulgeProfile(const std::vector<double>& areas, double k) {
  const int n = static_cast<int>(areas.size());
  BulgeProfile profile;
  profile.ratio.assign(n, 1.0);
  const double aMax = n ? *std::max_element(areas.begin(), areas.end()) : 0.0;
  if (n < 2 || !(aMax > 0) || !(k > 0)) return profile;
  std::vector<double> g(n);
  double sumA = 0, sumAg = 0;
  for (int j = 0; j < n; ++j) {
    g[j] = std::pow(std::max(areas[j], 0.0) / aMax, 0.5 * k);
    const double w = (j == 0 || j == n - 1) ? 0.5 : 1.0;
    sumA += w * areas[j];
    sumAg += w * areas[j] * g[j];
  }
  if (!(sumAg > 0)) return profile;
  const double gMean = sumAg / sumA;
  profile.ratioMax = 0;
  for (int j = 0; j < n; ++j) {
    profile.ratio[j] = g[j] / gMean;
    profile.ratioMax = std::max(profile.ratioMax, profile.ratio[j]);
  }
  return profile;
}

double bulgeMu(const BulgeProfile& profile, double lambda) {
  double mu = 1.0 - lambda;
  // Keep 1 + mu (ratio - 1) >= 0.05: for mu > 0 the minimum is at ratio 0, for mu < 0 at ratioMax.
  mu = std::min(mu, 0.95);
  if (profile.ratioMax > 1.0) mu = std::max(mu, -0.95 / (profile.ratioMax - 1.0));
  return mu;
}

}  // namespace myoskin::joints
