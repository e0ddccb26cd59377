// Stages 3-4 of the extraction: per section, the constrained triangulation, the bumps (with hysteresis, forced
// regions) and their ellipses; parallel over sections, results by index (deterministic).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "muscles/extraction_stages.h"

namespace myoskin::stages {

namespace {

// Per-section work result.
struct SectionWork {
  bool ok = false;
  std::string reason;
  std::vector<Ellipse2> ellipses;
  std::vector<double> significance;
  std::vector<double> relative;
  std::vector<double> width;
  std::vector<int> forcedRegion;  // per ellipse: forced region index or -1
  bool split = false;             // triangulated as two halves along the mirror axis
};

// Does bump arc [first, last] (counter-clockwise, wrapping) contain polygon index i?
bool arcContains(const Bump& b, int i, int n) {
  const int len = ((b.last - b.first) % n + n) % n;
  const int off = ((i - b.first) % n + n) % n;
  return off <= len;
}

// Length of a bump's skin arc (polygon first -> last, counter-clockwise, wrapping).
double bumpArcLength(const Points2& polygon, const Bump& b) {
  const int n = static_cast<int>(polygon.rows());
  double arc = 0.0;
  for (int k = b.first; k != b.last; k = (k + 1) % n) arc += (polygon.row((k + 1) % n) - polygon.row(k)).norm();
  return arc;
}

bool arcsOverlap(const Bump& x, const Bump& y, int n) {
  return arcContains(x, y.first, n) || arcContains(x, y.last, n) || arcContains(y, x.first, n) ||
         arcContains(y, x.apex, n);
}

// An exactly mirror-symmetric trunk section (x -> -x about its y axis): the bumps of its +x side and their
// mirror images, so both sides get exactly mirrored ellipses (the triangulation of a symmetric polygon breaks
// its Delaunay ties one way, which moved one side's ellipses by up to a millimetre).
void mirrorSectionBumps(SectionWork& w) {
  SectionWork out = w;
  out.ellipses.clear(), out.significance.clear(), out.relative.clear(), out.width.clear(), out.forcedRegion.clear();
  for (int pass = 0; pass < 2; ++pass)
    for (size_t b = 0; b < w.ellipses.size(); ++b) {
      Ellipse2 e = w.ellipses[b];
      if (e.center.x() < 0 || (pass == 1 && e.center.x() == 0)) continue;  // on the axis: once
      if (pass == 1) e.center.x() = -e.center.x(), e.angle = -e.angle;      // (cos, sin) -> (-cos, sin) up to sign
      out.ellipses.push_back(e);
      out.significance.push_back(w.significance[b]);
      out.relative.push_back(w.relative[b]);
      out.width.push_back(w.width[b]);
      out.forcedRegion.push_back(w.forcedRegion[b]);
    }
  w = std::move(out);
}

}  // namespace

// ============================================================================
// Bumps per section
// ============================================================================

ProfileBumps profileBumps(const SectionProfile& prof, const BumpOptions& bumpOptions, const SectionBumpOptions& options) {
  // Torso sections are split along their mirror axis, so a symmetric body's two sides triangulate alike.
  std::vector<std::array<int, 2>> split;
  if (prof.plane.mirrorAxis) {
    const std::array<int, 2> axis = axisDiagonal(prof.polygon);
    if (axis[0] >= 0) split.push_back(axis);
  }
  ProfileBumps out;
  out.triangulation = triangulateSection(prof.polygon, split);
  // Hysteresis: bumps down to weakFraction of the threshold (faintFraction for the conditional faint links),
  // significance still relative to the threshold.
  const double weak =
      std::clamp(std::min(options.weakFraction, options.faintRelative > 0 ? options.faintFraction : 1.0), 1e-3, 1.0);
  BumpOptions low = bumpOptions;
  if (prof.plane.mirrorAxis && options.trunkHarmonics > 0) low.baseHarmonics = options.trunkHarmonics;
  low.minProtrusion *= weak;
  low.minRelativeProtrusion *= weak;
  low.supportTolerance /= weak;  // the same tolerance in metres
  out.bumps = findBumps(prof.polygon, low, &out.triangulation, prof.onSkin.empty() ? nullptr : &prof.onSkin);
  for (Bump& b : out.bumps) b.significance *= weak;
  return out;
}

SectionBumpsResult findSectionBumps(const Character& character, const SectionCut& cut, const ScaleContext& scale,
                                    const BumpOptions& bumpOptions, const SectionBumpOptions& options,
                                    const std::vector<char>& vertexMask,
                                    const std::vector<std::vector<char>>& forcedRegions, ExtractionReport& rep) {
  const int nv = character.mesh.numVertices();
  const std::vector<CuttingPlane>& planes = cut.planes;
  const std::vector<SectionProfile>& profiles = cut.profiles;
  const Skeleton& sk = character.skeleton;
  // Forced regions: their vertices, and the slab half-width around each plane that counts as "on" it.
  double slab = scale.planeSpacing;
  if (!(slab > 0)) {
    std::vector<double> gaps;
    for (size_t i = 1; i < planes.size(); ++i)
      if (planes[i].family == planes[i - 1].family && planes[i].familyIndex == planes[i - 1].familyIndex)
        gaps.push_back((planes[i].origin - planes[i - 1].origin).norm());
    std::sort(gaps.begin(), gaps.end());
    slab = gaps.empty() ? 0.02 : gaps[gaps.size() / 2];
  }
  slab *= 0.5;
  std::vector<std::vector<int>> forcedVerts(forcedRegions.size());
  for (size_t r = 0; r < forcedRegions.size(); ++r)
    for (int v = 0; v < nv; ++v)
      if (forcedRegions[r][v]) forcedVerts[r].push_back(v);

  // CDT, bumps, ellipses per section (parallel over sections, results by index).
  std::vector<SectionWork> work(profiles.size());
  tbb::parallel_for(size_t(0), profiles.size(), [&](size_t i) {
    const SectionProfile& prof = profiles[i];
    SectionWork& w = work[i];
    if (!prof.ok) {
      w.reason = prof.skipReason.empty() ? "no clean loop" : prof.skipReason;
      return;
    }
    try {
      ProfileBumps found = profileBumps(prof, bumpOptions, options);
      const SectionTriangulation& tri = found.triangulation;
      w.split = !tri.diagonals.empty();
      std::vector<Bump> bumps = std::move(found.bumps);
      const std::vector<char>* onSkin = prof.onSkin.empty() ? nullptr : &prof.onSkin;  // a clipped profile's chord
      if (!prof.onSkin.empty())  // a clipped profile: bumps lie on the skin, not on the closing chord
        bumps.erase(std::remove_if(bumps.begin(), bumps.end(),
                                   [&](const Bump& b) {
                                     const int np = static_cast<int>(prof.polygon.rows());
                                     for (int i = b.first;; i = (i + 1) % np) {
                                       if (!prof.onSkin[i]) return true;
                                       if (i == b.last) return false;
                                     }
                                   }),
                    bumps.end());
      if (options.minBumpCrossings > 0 && prof.loopPoints > 0 &&
          static_cast<int>(prof.segment.size()) == prof.polygon.rows())  // resolved by the mesh
        bumps.erase(std::remove_if(bumps.begin(), bumps.end(),
                                   [&](const Bump& b) {
                                     const int crossings =
                                         (prof.segment[b.last] - prof.segment[b.first] + prof.loopPoints) % prof.loopPoints;
                                     return crossings < options.minBumpCrossings;
                                   }),
                    bumps.end());
      if (!vertexMask.empty())  // extract only within the mask: the bump's apex must lie on it
        bumps.erase(std::remove_if(bumps.begin(), bumps.end(), [&](const Bump& b) { return !prof.inMask[b.apex]; }),
                    bumps.end());
      std::vector<int> forced(bumps.size(), -1);
      if (!forcedVerts.empty()) {
        // Weak bumps too, then for each forced region the dominant bump touching the region here.
        BumpOptions weak = bumpOptions;
        if (prof.plane.mirrorAxis && options.trunkHarmonics > 0) weak.baseHarmonics = options.trunkHarmonics;
        weak.minProtrusion = options.forcedMinProtrusion;
        weak.minRelativeProtrusion = 0.0;
        const std::vector<Bump> weakBumps = findBumps(prof.polygon, weak, &tri, onSkin);
        const int np = static_cast<int>(prof.polygon.rows());
        double perim = 0;
        for (int k = 0; k < np; ++k) perim += (prof.polygon.row((k + 1) % np) - prof.polygon.row(k)).norm();
        const double tol = std::max(2.0 * perim / std::max(np, 1), 0.004);
        for (size_t r = 0; r < forcedVerts.size(); ++r) {
          std::vector<char> near(np, 0);
          bool any = false;
          for (int v : forcedVerts[r]) {
            const Vec3 p = character.mesh.vertices.row(v).transpose() - prof.plane.origin;
            if (std::abs(p.dot(prof.plane.normal)) > slab) continue;
            const Vec2 q(p.dot(prof.plane.xAxis), p.dot(prof.plane.yAxis));
            for (int k = 0; k < np; ++k)
              if ((prof.polygon.row(k).transpose() - q).norm() <= tol) near[k] = 1, any = true;
          }
          if (!any) continue;
          int best = -1;
          for (size_t b = 0; b < weakBumps.size(); ++b) {
            bool touches = false;
            for (int k = 0; k < np && !touches; ++k) touches = near[k] && arcContains(weakBumps[b], k, np);
            if (touches && (best < 0 || weakBumps[b].protrusion > weakBumps[best].protrusion)) best = static_cast<int>(b);
          }
          if (best < 0) continue;
          int same = -1;
          for (size_t b = 0; b < bumps.size(); ++b)
            if (arcsOverlap(bumps[b], weakBumps[best], np)) same = static_cast<int>(b);
          if (same >= 0) {
            forced[same] = static_cast<int>(r);
          } else {
            Bump fb = weakBumps[best];
            fb.significance = bumpOptions.minProtrusion > 0 ? fb.protrusion / bumpOptions.minProtrusion : 1.0;
            bumps.push_back(fb);
            forced.push_back(static_cast<int>(r));
          }
        }
      }
      // A muscle lies beside the bone, not around it: an ellipse centred within a quarter of the section's
      // mean radius of the bone describes the whole section, not a belly (on limbs, which the bone centres).
      const double meanRadius = prof.polygon.rowwise().norm().mean();
      for (size_t b = 0; b < bumps.size(); ++b) {
        const Ellipse2 e = fitBumpEllipse(prof.polygon, bumps[b], tri);
        if (!std::isfinite(e.center.x()) || !std::isfinite(e.center.y()) || !(e.a > 0) || !(e.b > 0)) continue;
        if (forced[b] < 0) {
          const bool clipped = !prof.onSkin.empty() && prof.plane.clipRadius > 0;  // a clipped shoulder profile
          if (!clipped && e.center.norm() < 0.25 * meanRadius) continue;
          // A clipped (shoulder) profile is not centred on its bone: there the belly must not enclose the bone.
          const Vec2 local = Eigen::Rotation2Dd(-e.angle) * (-e.center);
          if (clipped && std::pow(local.x() / e.a, 2) + std::pow(local.y() / e.b, 2) <= 1.0) continue;
        }
        w.ellipses.push_back(e);
        w.significance.push_back(bumps[b].significance);
        w.relative.push_back(meanRadius > 0 ? bumps[b].protrusion / meanRadius : 0.0);
        w.width.push_back(meanRadius > 0 ? bumpArcLength(prof.polygon, bumps[b]) / meanRadius : 0.0);
        w.forcedRegion.push_back(forced[b]);
      }
      if (prof.plane.mirrorAxis && prof.symmetric && w.split && vertexMask.empty() && forcedVerts.empty())
        mirrorSectionBumps(w);  // split along the axis: every bump lies on one side of it
      w.ok = true;
    } catch (const std::exception& ex) {
      w.reason = std::string("triangulation/bumps failed: ") + ex.what();
    }
  });
  std::vector<SectionBumps> sections;
  std::vector<std::vector<int>> forcedOf;  // per section, per ellipse
  for (size_t i = 0; i < profiles.size(); ++i) {
    if (!work[i].ok) {
      const CuttingPlane& p = planes[i];
      rep.skipped.push_back({static_cast<int>(i), p.bone >= 0 ? sk.bones[p.bone].name : "", p.family, work[i].reason});
      continue;
    }
    ++rep.sections;
    rep.mirrored += profiles[i].symmetric;
    rep.split += work[i].split;
    SectionBumps s;
    s.plane = profiles[i].plane;
    s.ellipses = work[i].ellipses;
    s.significance = work[i].significance;
    s.relative = work[i].relative;
    s.width = work[i].width;
    for (int f : work[i].forcedRegion) s.forced.push_back(f >= 0);
    for (double sg : s.significance) rep.bumps += sg >= 1.0;
    forcedOf.push_back(work[i].forcedRegion);
    sections.push_back(std::move(s));
  }
  return {std::move(sections), std::move(forcedOf)};
}

}  // namespace myoskin::stages
