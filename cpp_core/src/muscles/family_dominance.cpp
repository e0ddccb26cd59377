// Overlapping plane families (DESIGN.md section 4.1): one belly seen by two families (a deltoid cut by the
// shoulder planes and by the upper-arm planes) becomes one muscle, from the dominating family.
#include <algorithm>
#include <vector>

#include "muscles/muscle_util.h"
#include "myoskin/extraction.h"

namespace myoskin {

namespace {

// Share of x's section centres lying within `reach` of y's centre line.
double overlapShare(const Muscle& x, const std::vector<Vec3>& yLine, double reach) {
  if (x.sections.empty()) return 0.0;
  int near = 0;
  for (const MuscleSection& s : x.sections) near += detail::distanceToPolyline(s.center, yLine) <= reach;
  return double(near) / x.sections.size();
}

double meanSemiAxis(const Muscle& m) {
  double s = 0.0;
  for (const MuscleSection& sec : m.sections) s += sec.a;
  return m.sections.empty() ? 0.0 : s / m.sections.size();
}

}  // namespace

std::vector<char> dominantMuscles(const std::vector<Muscle>& muscles, const std::vector<std::string>& families,
                                  double minOverlap) {
  const size_t n = muscles.size();
  std::vector<char> keep(n, 1);
  std::vector<std::vector<Vec3>> lines(n);
  std::vector<double> radius(n);
  for (size_t i = 0; i < n; ++i) {
    for (const MuscleSection& s : muscles[i].sections) lines[i].push_back(s.center);
    radius[i] = meanSemiAxis(muscles[i]);
  }
  // Dominance order: more sections, then higher confidence, then the earlier muscle.
  auto dominates = [&](size_t i, size_t j) {
    if (muscles[i].sections.size() != muscles[j].sections.size()) return muscles[i].sections.size() > muscles[j].sections.size();
    if (muscles[i].confidence != muscles[j].confidence) return muscles[i].confidence > muscles[j].confidence;
    return i < j;
  };
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), dominates);
  for (size_t oi = 0; oi < n; ++oi) {
    const size_t i = order[oi];
    if (!keep[i]) continue;
    for (size_t oj = oi + 1; oj < n; ++oj) {
      const size_t j = order[oj];
      if (!keep[j] || families[i] == families[j]) continue;
      const double reach = std::max(radius[i], radius[j]);
      if (overlapShare(muscles[j], lines[i], reach) >= minOverlap || overlapShare(muscles[i], lines[j], reach) >= minOverlap)
        keep[j] = 0;
    }
  }
  return keep;
}

}  // namespace myoskin
