// The extraction pipeline (DESIGN.md section 4): bone roles -> cutting planes -> profile sections ->
// CDT, bumps and ellipses per section (parallel, deterministic) -> linking -> ends -> surfaces -> names.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>

#include "muscles/muscle_names.h"
#include "muscles/muscle_util.h"
#include "muscles/track_evidence.h"
#include "myoskin/errors.h"
#include "myoskin/memory_budget.h"
#include "myoskin/extraction.h"
#include "myoskin/muscle_shape.h"

namespace myoskin {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

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

// Sector name of a point around a bone, from the bone's rest X and Z axes.
std::string sideName(const Bone& bone, const Vec3& p) {
  const Vec3 c = detail::closestOnSegment(p, bone.head, bone.tail);
  const Vec3 v = p - c;
  const Vec3 x = bone.rest.block<3, 1>(0, 0), z = bone.rest.block<3, 1>(0, 2);
  const double ax = v.dot(x), az = v.dot(z);
  if (std::abs(ax) >= std::abs(az)) return ax >= 0 ? "xpos" : "xneg";
  return az >= 0 ? "zpos" : "zneg";
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

// Why nothing was found, from the report of a run that returned no muscle.
std::string diagnose(const ExtractionReport& rep) {
  if (rep.activeBones == 0 || rep.planes == 0)
    return "no limb chain recognised: none of the " + std::to_string(rep.bones) +
           " bones has a limb, spine or neck role, by name or by the shape of the bone tree (name them with a role "
           "map: myoskin roles / extract --roles, Python bone_roles)";
  if (rep.sections == 0) {
    std::map<std::string, int> reasons;
    for (const SkippedSection& s : rep.skipped) ++reasons[s.reason];
    std::vector<std::pair<int, std::string>> byCount;
    for (const auto& [reason, count] : reasons) byCount.emplace_back(-count, reason);
    std::sort(byCount.begin(), byCount.end());
    std::string text = "every one of the " + std::to_string(rep.planes) + " sections was skipped (";
    for (size_t i = 0; i < byCount.size() && i < 3; ++i)
      text += (i ? "; " : "") + std::to_string(-byCount[i].first) + "x " + byCount[i].second;
    return text + "): the skin around the bones gives no closed loop (open or non-manifold skin?)";
  }
  if (rep.bumps == 0)
    return "no significant relief: " + std::to_string(rep.sections) +
           " sections analysed and none stands out of its smooth base by the threshold (smooth skin?)";
  return std::to_string(rep.chains) + " chains of bumps in " + std::to_string(rep.sections) +
         " sections, none kept as a muscle (" + std::to_string(rep.droppedShort) + " too short, " +
         std::to_string(rep.droppedFlat) + " too flat, " + std::to_string(rep.droppedConfidence) +
         " low confidence, " + std::to_string(rep.droppedOverlap) + " overlapped): the relief is too faint or too short";
}

ExtractionResult extractAtBodyScale(const Character& character, const ExtractionOptions& options);

}  // namespace

// ============================================================================
// One-shot pipeline: body surface and scale, then the stages
// ============================================================================

ExtractionResult extractMuscles(const Character& character, const ExtractionOptions& options) {
  validateCharacter(character);
  const int nv = character.mesh.numVertices();
  if (!options.vertexMask.empty() && static_cast<int>(options.vertexMask.size()) != nv)
    throw InputError("extraction vertex mask has " + std::to_string(options.vertexMask.size()) +
                     " entries, the skin has " + std::to_string(nv) + " vertices");
  for (size_t r = 0; r < options.forcedRegions.size(); ++r)
    if (static_cast<int>(options.forcedRegions[r].size()) != nv)
      throw InputError("forced region " + std::to_string(r) + " has " + std::to_string(options.forcedRegions[r].size()) +
                       " entries, the skin has " + std::to_string(nv) + " vertices");
  if (!std::isfinite(options.referenceLimbRadius)) throw InputError("referenceLimbRadius must be finite");
  requireMemory(extractionMemoryEstimate(nv), "muscle extraction on " + std::to_string(nv) + " vertices");

  // The body surface: small and rigidly bound components left out, vertices renumbered.
  std::vector<ExcludedComponent> excluded;
  const std::vector<char> keep = bodySurfaceMask(character, excluded);
  std::vector<int> newIndex(nv, -1);
  Character body;
  body.name = character.name;
  body.skeleton = weightedSkeleton(character);
  std::vector<char> used(nv, 0);
  for (int f = 0; f < character.mesh.numTriangles(); ++f)
    for (int c = 0; c < 3; ++c) used[character.mesh.triangles(f, c)] = 1;
  int count = 0;
  for (int v = 0; v < nv; ++v)
    if (used[v] && keep[v]) newIndex[v] = count++;
  body.mesh.vertices.resize(count, 3);
  if (character.hasWeights()) {
    body.weights.joints.resize(count, character.weights.influences());
    body.weights.weights.resize(count, character.weights.influences());
  }
  for (int v = 0; v < nv; ++v) {
    if (newIndex[v] < 0) continue;
    body.mesh.vertices.row(newIndex[v]) = character.mesh.vertices.row(v);
    if (character.hasWeights()) {
      body.weights.joints.row(newIndex[v]) = character.weights.joints.row(v);
      body.weights.weights.row(newIndex[v]) = character.weights.weights.row(v);
    }
  }
  std::vector<Eigen::Vector3i> tris;
  for (int f = 0; f < character.mesh.numTriangles(); ++f) {
    const Eigen::Vector3i t = character.mesh.triangles.row(f).transpose();
    if (newIndex[t[0]] >= 0 && newIndex[t[1]] >= 0 && newIndex[t[2]] >= 0)
      tris.emplace_back(newIndex[t[0]], newIndex[t[1]], newIndex[t[2]]);
  }
  body.mesh.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) body.mesh.triangles.row(static_cast<Eigen::Index>(f)) = tris[f].transpose();
  ExtractionOptions o = options;
  auto remap = [&](const std::vector<char>& mask) {
    std::vector<char> out(count, 0);
    for (int v = 0; v < nv; ++v)
      if (newIndex[v] >= 0) out[newIndex[v]] = mask[v];
    return out;
  };
  if (!o.vertexMask.empty()) o.vertexMask = remap(options.vertexMask);
  for (auto& region : o.forcedRegions) region = remap(region);

  // The body scale: the character's units are found from its limb radius (the power of ten that brings it nearest
  // the reference) and it is scaled about the origin into them, so mm, cm, m and x100 exports give the same muscles.
  const std::vector<BoneRole> roles = characterBoneRoles(body, options.roleOverrides);
  const double limbRadius = bodyLimbRadius(body, roles);
  const double reference = options.referenceLimbRadius == 0 ? kReferenceLimbRadius : options.referenceLimbRadius;
  const double factor = reference > 0 && limbRadius > 0 ? std::pow(10.0, std::round(std::log10(reference / limbRadius))) : 1.0;
  auto toBody = [&](const Vec3& p) { return Vec3(p * factor); };
  auto fromBody = [&](const Vec3& p) { return Vec3(p / factor); };
  for (int v = 0; v < count; ++v) body.mesh.vertices.row(v) = toBody(body.mesh.vertices.row(v).transpose()).transpose();
  for (Bone& b : body.skeleton.bones) {
    b.head = toBody(b.head), b.tail = toBody(b.tail);
    b.rest.block<3, 1>(0, 3) = toBody(b.rest.block<3, 1>(0, 3));
  }
  o.planes.spacing *= factor;

  ExtractionResult result = extractAtBodyScale(body, o);
  for (Muscle& m : result.muscles) {
    m.origin.position = fromBody(m.origin.position);
    m.insertion.position = fromBody(m.insertion.position);
    for (Vec3& p : m.rootCurve) p = fromBody(p);
    for (MuscleSection& s : m.sections) s.center = fromBody(s.center), s.a /= factor, s.b /= factor;
    m.wrap.radius /= factor;
    for (Eigen::Index v = 0; v < m.surface.vertices.rows(); ++v)
      m.surface.vertices.row(v) = fromBody(m.surface.vertices.row(v).transpose()).transpose();
  }
  // At rest every muscle lies inside the skin: the whole skin as given (eyes, hooves and props included: what is seen).
  if (options.buildSurfaces && options.surface.containInSkin && !result.muscles.empty()) {
    const SkinWinding skin(character.mesh.vertices, character.mesh.triangles);
    for (Muscle& m : result.muscles)
      containMuscleSurface(m.surface, std::max(3, options.surface.ringVertices), skin, options.surface.skinMargin);
  }
  ExtractionReport& rep = result.report;
  for (ChainRecord& r : rep.chainRecords) {
    for (Vec3& p : r.centres) p = fromBody(p);
    for (double& x : r.radius) x /= factor;
  }
  rep.limbRadius = limbRadius;
  rep.scale = factor;
  rep.excluded = std::move(excluded);
  rep.analysed = rep.sections > 0;
  if (result.muscles.empty()) rep.diagnosis = diagnose(rep);
  return result;
}

namespace {

ExtractionResult extractAtBodyScale(const Character& character, const ExtractionOptions& options) {
  const int nv = character.mesh.numVertices();
  if (options.trunkHarmonics < 0 || options.trunkHarmonics > 16)
    throw InputError("trunkHarmonics must be in [0, 16], got " + std::to_string(options.trunkHarmonics));
  if (!(options.spindleEnds >= 0.0 && options.spindleEnds <= 1.0) || !(options.spindleLength >= 0.0 && std::isfinite(options.spindleLength)) ||
      !(options.spindleSteepness >= 0.0 && std::isfinite(options.spindleSteepness)))
    throw InputError("spindle options: spindleEnds must be in [0, 1], spindleLength and spindleSteepness finite "
                     "and >= 0");
  if (!(options.twinReach >= 0.0 && std::isfinite(options.twinReach)))
    throw InputError("twinReach must be finite and >= 0");
  if (options.bumps.baseHarmonics < 0 || options.bumps.baseHarmonics > 16)
    throw InputError("bumps.baseHarmonics must be in [0, 16], got " + std::to_string(options.bumps.baseHarmonics));
  ExtractionResult result;
  ExtractionReport& rep = result.report;
  const Skeleton& sk = character.skeleton;

  // Stage 1: roles and planes.
  auto t0 = Clock::now();
  const std::vector<BoneRole> roles = characterBoneRoles(character, options.roleOverrides);
  rep.bones = sk.numBones();
  for (BoneRole r : roles) rep.activeBones += r != BoneRole::Ignore;
  const std::vector<CuttingPlane> planes = makeCuttingPlanes(character, roles, options.planes);
  rep.planes = static_cast<int>(planes.size());
  rep.timings.push_back({"planes", secondsSince(t0)});

  // Stage 2: profiles.
  t0 = Clock::now();
  const std::vector<SectionProfile> profiles =
      cutSections(character, planes, options.profiles, options.vertexMask.empty() ? nullptr : &options.vertexMask);
  rep.timings.push_back({"sections", secondsSince(t0)});

  // Forced regions: their vertices, and the slab half-width around each plane that counts as "on" it.
  double slab = options.planes.spacing;
  if (!(slab > 0)) {
    std::vector<double> gaps;
    for (size_t i = 1; i < planes.size(); ++i)
      if (planes[i].family == planes[i - 1].family && planes[i].familyIndex == planes[i - 1].familyIndex)
        gaps.push_back((planes[i].origin - planes[i - 1].origin).norm());
    std::sort(gaps.begin(), gaps.end());
    slab = gaps.empty() ? 0.02 : gaps[gaps.size() / 2];
  }
  slab *= 0.5;
  std::vector<std::vector<int>> forcedVerts(options.forcedRegions.size());
  for (size_t r = 0; r < options.forcedRegions.size(); ++r)
    for (int v = 0; v < nv; ++v)
      if (options.forcedRegions[r][v]) forcedVerts[r].push_back(v);

  // Stages 3-4: CDT, bumps, ellipses per section (parallel over sections, results by index).
  t0 = Clock::now();
  std::vector<SectionWork> work(profiles.size());
  tbb::parallel_for(size_t(0), profiles.size(), [&](size_t i) {
    const SectionProfile& prof = profiles[i];
    SectionWork& w = work[i];
    if (!prof.ok) {
      w.reason = prof.skipReason.empty() ? "no clean loop" : prof.skipReason;
      return;
    }
    try {
      // Torso sections are split along their mirror axis, so a symmetric body's two sides triangulate alike.
      std::vector<std::array<int, 2>> split;
      if (prof.plane.mirrorAxis) {
        const std::array<int, 2> axis = axisDiagonal(prof.polygon);
        if (axis[0] >= 0) split.push_back(axis);
      }
      const SectionTriangulation tri = triangulateSection(prof.polygon, split);
      w.split = !tri.diagonals.empty();
      // Hysteresis: bumps down to weakFraction of the threshold (faintFraction for the conditional faint links),
      // significance still relative to the threshold.
      const double weak =
          std::clamp(std::min(options.weakFraction, options.faintRelative > 0 ? options.faintFraction : 1.0), 1e-3, 1.0);
      BumpOptions low = options.bumps;
      if (prof.plane.mirrorAxis && options.trunkHarmonics > 0) low.baseHarmonics = options.trunkHarmonics;
      low.minProtrusion *= weak;
      low.minRelativeProtrusion *= weak;
      low.supportTolerance /= weak;  // the same tolerance in metres
      std::vector<Bump> bumps = findBumps(prof.polygon, low, &tri);
      for (Bump& b : bumps) b.significance *= weak;
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
      if (!options.vertexMask.empty())  // extract only within the mask: the bump's apex must lie on it
        bumps.erase(std::remove_if(bumps.begin(), bumps.end(), [&](const Bump& b) { return !prof.inMask[b.apex]; }),
                    bumps.end());
      std::vector<int> forced(bumps.size(), -1);
      if (!forcedVerts.empty()) {
        // Weak bumps too, then for each forced region the dominant bump touching the region here.
        BumpOptions weak = options.bumps;
        if (prof.plane.mirrorAxis && options.trunkHarmonics > 0) weak.baseHarmonics = options.trunkHarmonics;
        weak.minProtrusion = options.forcedMinProtrusion;
        weak.minRelativeProtrusion = 0.0;
        const std::vector<Bump> weakBumps = findBumps(prof.polygon, weak, &tri);
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
            fb.significance = options.bumps.minProtrusion > 0 ? fb.protrusion / options.bumps.minProtrusion : 1.0;
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
      if (prof.plane.mirrorAxis && prof.symmetric && w.split && options.vertexMask.empty() && forcedVerts.empty())
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
  rep.timings.push_back({"bumps", secondsSince(t0)});

  // Stage 5: linking.
  t0 = Clock::now();
  LinkOptions linkOptions = options.link;  // faint links (below weakFraction) kept only near their chain's peak
  if (options.faintRelative > 0 && options.faintFraction < options.weakFraction) {
    linkOptions.faintBelow = std::clamp(options.weakFraction, 1e-3, 1.0);
    linkOptions.faintRelative = options.faintRelative;
  }
  std::vector<MuscleChain> chains = linkBumps(sections, linkOptions, &rep.branches);
  rep.chains = static_cast<int>(chains.size());
  // Each forced region keeps one chain: the one with the most links from that region.
  for (MuscleChain& c : chains) c.forced = false;
  for (size_t r = 0; r < options.forcedRegions.size(); ++r) {
    int best = -1, bestCount = 0;
    for (size_t c = 0; c < chains.size(); ++c) {
      int count = 0;
      for (const ChainLink& l : chains[c].links)
        if (l.bump >= 0 && forcedOf[l.section][l.bump] == static_cast<int>(r)) ++count;
      if (count > bestCount) best = static_cast<int>(c), bestCount = count;
    }
    if (best >= 0) chains[best].forced = true;
  }
  // Evidence is counted in sections of the default spacing (ExtractionOptions::minEvidence).
  double evidenceScale = 1.0;
  if (options.planes.spacing > 0) {
    evidenceScale = options.planes.spacing / (principalExtent(character.mesh.vertices) / 80.0);
  }
  detail::SpindleOptions spindle;  // the closed-spindle cue (track_evidence.h)
  spindle.ends = options.spindleEnds, spindle.minLength = options.spindleLength;
  spindle.steepness = options.spindleSteepness;
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
      r.spindle = !detail::trunkFamily(c.family) && detail::closedSpindle(c, sections, spindle);
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
    double evidence = 0.0;
    for (const ChainLink& l : c.links)
      if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].significance.size()))
        evidence += sections[l.section].significance[l.bump];
    // The floors on length and height (a chain that misses one is dropped unless it is a closed spindle).
    const bool trunk = detail::trunkFamily(c.family);
    bool shortChain = c.strongSections < options.link.minSections || evidence * evidenceScale < options.minEvidence;
    bool flat = false;
    double floor = trunk ? options.minRelativeTrunk : options.minRelative;
    if (!trunk && options.continuousFraction > 0 && evidence * evidenceScale >= options.continuousEvidence &&
        continuousChain(c, sections, options.magnitudeFraction))
      floor *= std::min(options.continuousFraction, 1.0);
    if (!shortChain && floor > 0) {  // the bumps' mean height relative to their sections' size (faint tails left out)
      double sum = 0.0;
      int count = 0;
      for (const ChainLink& l : c.links)
        if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].relative.size()) &&
            sections[l.section].significance[l.bump] >= options.magnitudeFraction)
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
  // Mirror twins (ExtractionOptions::twinReach): on a mirrored body a limb chain the floors dropped is kept when its
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
  rep.timings.push_back({"link", secondsSince(t0)});

  // Stage 6: ends, naming, regions.
  t0 = Clock::now();
  std::vector<Muscle> muscles(kept.size());
  const std::vector<char> twist = twistSplits(character);
  std::unique_ptr<SkinWinding> skinWinding;  // keeps the ends carried onto the foot inside the skin
  if (options.ends.spanDistal && std::any_of(kept.begin(), kept.end(), [](const MuscleChain& k) { return k.family == "limb"; }))
    skinWinding = std::make_unique<SkinWinding>(character.mesh.vertices, character.mesh.triangles);
  tbb::parallel_for(size_t(0), kept.size(), [&](size_t i) {
    muscles[i] = buildMuscleEnds(kept[i], sections, sk, options.ends);
    if (!detail::trunkFamily(kept[i].family)) spanRealJoint(muscles[i], sk, twist, options.ends);  // act on a real joint
    if (kept[i].family == "limb") spanDistalJoint(muscles[i], sk, twist, roles, kept[i].bone, options.ends, skinWinding.get());  // onto the foot
    muscles[i].confidence = kept[i].confidence;
  });
  std::vector<std::string> regions(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    const std::string& bone = sk.bones[kept[i].bone].name;
    regions[i] = kept[i].family == "limb" ? bone : "torso." + kept[i].family + "." + bone;
    muscles[i].region = regions[i];
  }
  // Overlapping families: keep the dominating family's muscle (forced muscles always stay).
  std::vector<std::string> families(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) families[i] = kept[i].family;
  std::vector<char> keep = dominantMuscles(muscles, families);
  for (size_t i = 0; i < kept.size(); ++i) {
    if (kept[i].forced) keep[i] = 1;
    rep.droppedOverlap += !keep[i];
  }
  // Region limit: the most confident (forced first) per region.
  if (options.maxPerRegion > 0) {
    std::map<std::string, std::vector<int>> byRegion;
    for (size_t i = 0; i < kept.size(); ++i)
      if (keep[i]) byRegion[regions[i]].push_back(static_cast<int>(i));
    for (auto& [region, ids] : byRegion) {
      std::stable_sort(ids.begin(), ids.end(), [&](int x, int y) {
        if (kept[x].forced != kept[y].forced) return kept[x].forced;
        return kept[x].confidence > kept[y].confidence;
      });
      for (size_t j = options.maxPerRegion; j < ids.size(); ++j)
        if (!kept[ids[j]].forced) keep[ids[j]] = 0, ++rep.droppedRegionLimit;
    }
  }
  // Names: anatomical where the muscle's place identifies it ("biceps.L", a second one "biceps_2.L"), else its
  // region and side of the bone ("forearm_front.L"), else (no body frame) the bone and its axis ("forearm_xpos_1").
  std::map<std::string, int> nameCount;
  const detail::BodyFrame frame = detail::bodyFrame(sk, roles, twist);
  for (size_t i = 0; i < kept.size(); ++i) {
    if (!keep[i]) continue;
    Muscle& m = muscles[i];
    const Bone& bone = sk.bones[kept[i].bone];
    const Vec3 mid = m.sections[m.sections.size() / 2].center;
    // Anatomical where the place identifies it, else by region ("forearm_front.L"); a second one "biceps_2.L".
    std::string placed = detail::anatomicalName(m, kept[i].bone, kept[i].family, sk, frame);
    if (placed.empty()) placed = detail::regionName(m, kept[i].bone, kept[i].family, sk, frame);
    if (!placed.empty()) {
      const size_t dot = placed.find('.');
      const std::string stem = placed.substr(0, dot), side = dot == std::string::npos ? "" : placed.substr(dot);
      const int k = ++nameCount[placed];
      m.name = k == 1 ? placed : stem + "_" + std::to_string(k) + side;
      if (kept[i].forced) ++rep.forced;
      result.muscles.push_back(std::move(m));
      continue;
    }
    const std::string base = bone.name + "_" + sideName(bone, mid);
    m.name = base + "_" + std::to_string(++nameCount[base]);
    if (kept[i].forced) ++rep.forced;
    result.muscles.push_back(std::move(m));
  }
  rep.timings.push_back({"ends", secondsSince(t0)});

  // Stage 7: surfaces.
  t0 = Clock::now();
  if (options.buildSurfaces) {
    tbb::parallel_for(size_t(0), result.muscles.size(), [&](size_t i) {
      result.muscles[i].surface = loftMuscleSurface(result.muscles[i], options.surface);
    });
  }
  rep.timings.push_back({"surface", secondsSince(t0)});
  rep.muscles = static_cast<int>(result.muscles.size());
  return result;
}

}  // namespace

}  // namespace myoskin
