// Extraction accuracy against known muscles (DESIGN.md section 8): recall, precision and centre error.
#include <algorithm>
#include <cmath>
#include <tuple>
#include <utility>

#include "muscles/muscle_util.h"
#include "myoskin/extraction.h"

namespace myoskin {

ExtractionAccuracy measureExtraction(const std::vector<Muscle>& found, const std::vector<TrueMuscle>& truth,
                                     double minCoverage, double visibleReliefShare) {
  ExtractionAccuracy acc;
  acc.trueMuscles = static_cast<int>(truth.size());
  acc.foundMuscles = static_cast<int>(found.size());
  acc.matchOfTrue.assign(truth.size(), -1);
  acc.coverageOfTrue.assign(truth.size(), 0.0);

  // Coverage of each true muscle by each found muscle: the fraction of the true visible length whose samples lie
  // within half the true peak radius of the found root curve.
  std::vector<std::tuple<double, int, int>> candidates;  // (-coverage, true, found)
  for (int t = 0; t < acc.trueMuscles; ++t) {
    const TrueMuscle& tm = truth[t];
    if (tm.centerLine.size() < 2) continue;
    double peak = tm.peakRadius;
    for (double r : tm.radius) peak = std::max(peak, r);
    const double tol = 0.5 * peak;
    const bool hasRelief = tm.relief.size() == tm.centerLine.size();
    const double reliefFloor =
        hasRelief ? visibleReliefShare * *std::max_element(tm.relief.begin(), tm.relief.end()) : 0.0;
    // Dense samples of the true line: (position, length it stands for), the visible ones only.
    std::vector<std::pair<Vec3, double>> samples;
    double length = 0.0;
    for (size_t i = 0; i + 1 < tm.centerLine.size(); ++i) {
      const Vec3 &p = tm.centerLine[i], &q = tm.centerLine[i + 1];
      const double seg = (q - p).norm();
      const int sub = std::max(1, static_cast<int>(std::ceil(seg / (0.25 * tol + 1e-12))));
      for (int j = 0; j < sub; ++j) {
        const double u = (j + 0.5) / sub;
        if (hasRelief && (1 - u) * tm.relief[i] + u * tm.relief[i + 1] < reliefFloor) continue;
        samples.emplace_back(p + (q - p) * u, seg / sub);
        length += seg / sub;
      }
    }
    if (!(length > 0)) continue;
    for (int f = 0; f < acc.foundMuscles; ++f) {
      double covered = 0;
      for (const auto& [x, w] : samples)
        if (detail::distanceToPolyline(x, found[f].rootCurve) <= tol) covered += w;
      const double coverage = covered / length;
      acc.coverageOfTrue[t] = std::max(acc.coverageOfTrue[t], coverage);
      if (coverage >= minCoverage) candidates.emplace_back(-coverage, t, f);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<char> foundUsed(found.size(), 0);
  double errorSum = 0;
  for (const auto& [negCov, t, f] : candidates) {
    if (acc.matchOfTrue[t] >= 0 || foundUsed[f]) continue;
    acc.matchOfTrue[t] = f;
    foundUsed[f] = 1;
    ++acc.matched;
    double peak = truth[t].peakRadius;
    for (double r : truth[t].radius) peak = std::max(peak, r);
    double e = 0;
    for (const MuscleSection& s : found[f].sections) e += detail::distanceToPolyline(s.center, truth[t].centerLine);
    if (!found[f].sections.empty() && peak > 0) errorSum += e / found[f].sections.size() / peak;
  }
  acc.recall = acc.trueMuscles ? double(acc.matched) / acc.trueMuscles : 1.0;
  acc.precision = acc.foundMuscles ? double(acc.matched) / acc.foundMuscles : 1.0;
  acc.meanCenterError = acc.matched ? errorSum / acc.matched : 0.0;
  return acc;
}

}  // namespace myoskin
