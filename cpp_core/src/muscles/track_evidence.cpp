// Track-level evidence for faint bellies: the closed-spindle test on a chain's significance profile.
#include "muscles/track_evidence.h"

#include <algorithm>
#include <cmath>

namespace myoskin::detail {

// ============================================================================
// Closed spindles
// ============================================================================

// The real links' (plane order, significance), sorted by plane order.
std::vector<std::pair<int, double>> trackProfile(const MuscleChain& chain, const std::vector<SectionBumps>& sections) {
  std::vector<std::pair<int, double>> profile;
  for (const ChainLink& l : chain.links)
    if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].significance.size()))
      profile.emplace_back(sections[l.section].plane.order, sections[l.section].significance[l.bump]);
  std::sort(profile.begin(), profile.end());
  return profile;
}

// Mean of relative / width over the chain's real links.
double chainSteepness(const MuscleChain& chain, const std::vector<SectionBumps>& sections) {
  double steep = 0.0;
  int count = 0;
  for (const ChainLink& l : chain.links) {
    if (l.bump < 0) continue;
    const SectionBumps& s = sections[l.section];
    const bool measured = l.bump < static_cast<int>(s.width.size()) && l.bump < static_cast<int>(s.relative.size());
    steep += measured && s.width[l.bump] > 0 ? s.relative[l.bump] / s.width[l.bump] : 0.0;
    ++count;
  }
  return count > 0 ? steep / count : 0.0;
}

// Consecutive planes over minLength radii, one peak (reversals within tolerance), low ends, steep bumps.
bool closedSpindle(const MuscleChain& chain, const std::vector<SectionBumps>& sections, const SpindleOptions& options) {
  const std::vector<std::pair<int, double>> profile = trackProfile(chain, sections);
  const int n = static_cast<int>(profile.size());
  if (n < 3 || chainSteepness(chain, sections) < options.steepness) return false;
  // Its length in its bumps' mean radius: first to last real link's centre, in 3D.
  const ChainLink *first = nullptr, *last = nullptr;
  double radius = 0.0;
  for (const ChainLink& l : chain.links) {
    if (l.bump < 0) continue;
    if (!first || sections[l.section].plane.order < sections[first->section].plane.order) first = &l;
    if (!last || sections[l.section].plane.order > sections[last->section].plane.order) last = &l;
    radius += std::sqrt(l.ellipse.a * l.ellipse.b) / n;
  }
  const double length = (planePoint(sections[last->section].plane, last->ellipse.center) -
                         planePoint(sections[first->section].plane, first->ellipse.center)).norm();
  if (!(length >= options.minLength * radius)) return false;
  for (int k = 1; k < n; ++k)
    if (profile[k].first != profile[k - 1].first + 1) return false;
  int peak = 0;
  for (int k = 1; k < n; ++k)
    if (profile[k].second > profile[peak].second) peak = k;
  const double top = profile[peak].second, slack = options.tolerance * top;
  if (!(top > 0.0) || profile.front().second >= options.ends * top || profile.back().second >= options.ends * top)
    return false;
  for (int k = 1; k <= peak; ++k)
    if (profile[k].second < profile[k - 1].second - slack) return false;
  for (int k = peak + 1; k < n; ++k)
    if (profile[k].second > profile[k - 1].second + slack) return false;
  return true;
}

}  // namespace myoskin::detail
