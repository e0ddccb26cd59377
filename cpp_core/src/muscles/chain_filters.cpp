// Stage 5b of the extraction: the floors a linked chain must pass (length, evidence, height, confidence), the cues that
// keep a chain below them (a closed spindle; the mirror twin of a kept chain), and the shape that drops one above them
// (the trunk's contour on the shoulder planes).
#include <algorithm>
#include <cmath>

#include "muscles/extraction_stages.h"
#include "muscles/muscle_util.h"
#include "muscles/track_evidence.h"

namespace myoskin::stages {

namespace {

// True when the chain's links of at least `fraction` of the significance threshold lie in consecutive planes of
// its family: the belly stands out in every plane between its ends (fainter tail links aside).
bool continuousChain(const MuscleChain& c, const std::vector<SectionBumps>& sections, double fraction) {
  std::vector<int> orders;
  for (const ChainLink& l : c.links)
    if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].significance.size()) &&
        sections[l.section].significance[l.bump] >= fraction)
      orders.push_back(sections[l.section].plane.order);
  std::sort(orders.begin(), orders.end());
  for (size_t i = 1; i < orders.size(); ++i)
    if (orders[i] != orders[i - 1] + 1) return false;
  return !orders.empty();
}

// True when chain b is chain a's mirror twin: a limb chain of the same family on another limb whose real bumps' centres,
// mirrored through the skeleton's mirror plane (point c, unit normal n), lie within `reach` times the larger of the two
// chains' mean semi-axis a of the other's centres, at least half of them both ways (the same belly on the other side).
bool mirrorTwin(const MuscleChain& a, const MuscleChain& b, const std::vector<SectionBumps>& sections, const Vec3& c,
                const Vec3& n, double reach) {
  if (a.family != b.family || a.familyIndex == b.familyIndex) return false;
  auto centres = [&](const MuscleChain& chain, bool mirrored, double& meanA) {
    std::vector<Vec3> out;
    meanA = 0.0;
    for (const ChainLink& l : chain.links) {
      if (l.bump < 0) continue;
      Vec3 p = planePoint(sections[l.section].plane, l.ellipse.center);
      if (mirrored) p -= 2.0 * (p - c).dot(n) * n;
      out.push_back(p);
      meanA += l.ellipse.a;
    }
    if (!out.empty()) meanA /= out.size();
    return out;
  };
  double aA = 0.0, aB = 0.0;
  const std::vector<Vec3> pa = centres(a, true, aA), pb = centres(b, false, aB);
  if (pa.empty() || pb.empty()) return false;
  const double tol = reach * std::max(aA, aB);
  auto mostlyNear = [&](const std::vector<Vec3>& from, const std::vector<Vec3>& to) {
    int near = 0;
    for (const Vec3& p : from) {
      double best = INFINITY;
      for (const Vec3& q : to) best = std::min(best, (p - q).norm());
      near += best <= tol;
    }
    return 2 * near >= static_cast<int>(from.size());
  };
  return mostlyNear(pa, pb) && mostlyNear(pb, pa);
}

// True when a shoulder chain is the trunk's own contour, not a belly: its track starts at the family's first plane (the
// planes enter the trunk there, shoulderStart along the clavicle) and its significance only falls from there towards the
// joint (each rise at most `tolerance` of the first link's). The rounded corner of a smooth trunk is cut obliquely by
// those planes and fades outwards; a deltoid or pectoral grows towards the joint it caps (MakeHuman muscular: rising to
// the last plane), or rises again after a dip (Godot's, which starts at the third plane).
bool trunkContour(const MuscleChain& c, const std::vector<SectionBumps>& sections, double tolerance) {
  if (c.family != "shoulder") return false;
  const std::vector<std::pair<int, double>> profile = detail::trackProfile(c, sections);
  if (profile.size() < 2 || profile.front().first != 0) return false;
  const double slack = tolerance * profile.front().second;
  for (size_t k = 1; k < profile.size(); ++k)
    if (profile[k].second > profile[k - 1].second + slack) return false;
  return true;
}

}  // namespace

// ============================================================================
// Chain filters
// ============================================================================

std::vector<MuscleChain> filterChains(std::vector<MuscleChain> chains, const std::vector<SectionBumps>& sections,
                                      const SectionCut& cut, const Skeleton& sk, const ScaleContext& scale,
                                      const ChainFilterOptions& options, int minSections, double weakFraction,
                                      double bumpRelative, ExtractionReport& rep) {
  const std::vector<CuttingPlane>& planes = cut.planes;
  const double evidenceScale = scale.evidenceScale();  // evidence in sections of the default spacing
  detail::SpindleOptions spindleOptions;  // the closed-spindle cue (track_evidence.h)
  spindleOptions.ends = options.spindleEnds, spindleOptions.minLength = options.spindleLength;
  spindleOptions.steepness = options.spindleSteepness;
  std::vector<MuscleChain> kept;
  std::vector<std::pair<size_t, int>> dropped;  // limb chains the floors dropped: (chain, record index or -1)
  for (size_t ci = 0; ci < chains.size(); ++ci) {
    MuscleChain& c = chains[ci];
    // The chain's record: its bumps along it, its shape, and (set below) the verdict.
    ChainRecord* record = nullptr;
    if (c.realSections >= 2) {
      ChainRecord r;
      r.family = c.family;
      r.bone = c.bone >= 0 ? sk.bones[c.bone].name : "";
      for (const ChainLink& l : c.links)
        if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].significance.size())) {
          r.centres.push_back(planePoint(sections[l.section].plane, l.ellipse.center));
          r.significance.push_back(sections[l.section].significance[l.bump]);
          const std::vector<double>& rel = sections[l.section].relative;
          r.relative.push_back(l.bump < static_cast<int>(rel.size()) ? rel[l.bump] : 0.0);
          r.planes.push_back(sections[l.section].plane.order);
          r.radius.push_back(std::sqrt(l.ellipse.a * l.ellipse.b));
        }
      r.steepness = detail::chainSteepness(c, sections);
      r.spindle = !detail::trunkFamily(c.family) && detail::closedSpindle(c, sections, spindleOptions);
      r.verdict = "kept";
      rep.chainRecords.push_back(std::move(r));
      record = &rep.chainRecords.back();
    }
    auto drop = [&](int& counter, const char* verdict) {
      ++counter;
      if (record) record->verdict = verdict;
    };
    if (c.forced) {
      if (record) record->verdict = "forced";
      kept.push_back(std::move(c));
      continue;
    }
    // The trunk's rounded shoulder, whatever its height (no floor keeps it, no twin restores it).
    if (trunkContour(c, sections, spindleOptions.tolerance)) {
      drop(rep.droppedContour, "contour");
      continue;
    }
    double evidence = 0.0;
    for (const ChainLink& l : c.links)
      if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].significance.size()))
        evidence += sections[l.section].significance[l.bump];
    // The floors on length and height (a chain that misses one is dropped unless it is a closed spindle).
    const bool trunk = detail::trunkFamily(c.family);
    bool shortChain = c.strongSections < minSections || evidence * evidenceScale < options.minEvidence;
    bool flat = false;
    double floor = trunk ? 0.0 : options.minRelative;  // trunk chains: no height floor (minRelative's note)
    if (!trunk && evidence * evidenceScale >= options.continuousEvidence && continuousChain(c, sections, weakFraction))
      floor = std::min(floor, bumpRelative);  // a continuous chain: the height one bump needs
    if (!shortChain && floor > 0) {  // the bumps' mean height relative to their sections' size (faint tails left out)
      double sum = 0.0;
      int count = 0;
      for (const ChainLink& l : c.links)
        if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].relative.size()) &&
            sections[l.section].significance[l.bump] >= weakFraction)
          sum += sections[l.section].relative[l.bump], ++count;
      flat = count == 0 || sum < floor * count;
    }
    const bool spindle = (shortChain || flat) && record && record->spindle;
    if ((shortChain || flat) && !spindle && !trunk)
      dropped.emplace_back(ci, record ? static_cast<int>(record - rep.chainRecords.data()) : -1);
    if (shortChain && !spindle) {
      drop(rep.droppedShort, "short");
      continue;
    }
    if (flat && !spindle) {
      drop(rep.droppedFlat, "flat");
      continue;
    }
    // The confidence floor scores height and count, which a closed spindle is kept without (its shape is its evidence);
    // a chain dropped by it may still be kept as a mirror twin.
    if (c.confidence < options.minConfidence && !spindle) {
      if (!trunk) dropped.emplace_back(ci, record ? static_cast<int>(record - rep.chainRecords.data()) : -1);
      drop(rep.droppedConfidence, "confidence");
      continue;
    }
    rep.spindles += spindle;
    if (spindle) record->verdict = "spindle";
    kept.push_back(c);
  }
  // Mirror twins (ChainFilterOptions::twinReach): on a mirrored body a limb chain the floors dropped is kept when its
  // twin on the other limb passed them (the same belly seen twice; the floors decided on one side's sampling).
  Vec3 mc, mn;
  if (options.twinReach > 0 && skeletonMirrorPlane(planes, mc, mn)) {
    const size_t passed = kept.size();
    for (const auto& [ci, ri] : dropped) {
      const MuscleChain& c = chains[ci];
      bool twin = false;
      for (size_t k = 0; k < passed && !twin; ++k) {
        if (kept[k].forced || !mirrorTwin(kept[k], c, sections, mc, mn, options.twinReach)) continue;
        // Only a missing pair member: not when a kept chain on this chain's limb is that chain's twin already.
        twin = true;
        for (size_t j = 0; j < passed && twin; ++j)
          twin = !(j != k && kept[j].familyIndex == c.familyIndex &&
                   mirrorTwin(kept[k], kept[j], sections, mc, mn, options.twinReach));
      }
      if (!twin) continue;
      ++rep.twins;
      if (ri >= 0) {
        ChainRecord& r = rep.chainRecords[ri];
        (r.verdict == "short" ? rep.droppedShort : r.verdict == "flat" ? rep.droppedFlat : rep.droppedConfidence) -= 1;
        r.verdict = "twin";
      }
      kept.push_back(c);
    }
  }
  return kept;
}

}  // namespace myoskin::stages
