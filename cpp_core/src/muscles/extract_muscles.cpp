// The extraction pipeline (DESIGN.md section 4), a short orchestrator over the stages of extraction_stages.h:
// body surface + scale context -> bone roles, cutting planes, profiles -> CDT, bumps and ellipses per section
// (parallel, deterministic) -> linking -> chain filters -> ends, regions, names -> surfaces.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "muscles/extraction_stages.h"
#include "myoskin/errors.h"
#include "myoskin/memory_budget.h"
#include "myoskin/extraction.h"
#include "myoskin/muscle_shape.h"

namespace myoskin {

namespace {

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
         std::to_string(rep.droppedFlat) + " too flat, " + std::to_string(rep.droppedContour) + " trunk contour, " + std::to_string(rep.droppedConfidence) +
         " low confidence, " + std::to_string(rep.droppedOverlap) + " overlapped): the relief is too faint or too short";
}

// Throws InputError on options out of range or masks of the wrong size (before any work).
void validateExtraction(const Character& character, const ExtractionOptions& options) {
  validateCharacter(character);
  const int nv = character.mesh.numVertices();
  if (!options.vertexMask.empty() && static_cast<int>(options.vertexMask.size()) != nv)
    throw InputError("extraction vertex mask has " + std::to_string(options.vertexMask.size()) +
                     " entries, the skin has " + std::to_string(nv) + " vertices");
  for (size_t r = 0; r < options.forcedRegions.size(); ++r)
    if (static_cast<int>(options.forcedRegions[r].size()) != nv)
      throw InputError("forced region " + std::to_string(r) + " has " + std::to_string(options.forcedRegions[r].size()) +
                       " entries, the skin has " + std::to_string(nv) + " vertices");
  if (!std::isfinite(options.scale.referenceLimbRadius)) throw InputError("referenceLimbRadius must be finite");
  // The user-facing options (named as the CLI and Python name them too) and the expert floors.
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw InputError(what);
  };
  // A spacing below kMinSpacingRadii (an eighth of the automatic one on a human body) is a value in metres given
  // to an option that takes limb radii: it would cut tens of thousands of planes.
  require(options.scale.spacing == 0 || (options.scale.spacing >= kMinSpacingRadii && std::isfinite(options.scale.spacing)),
          "spacing (scale.spacing) is in limb radii: 0 (automatic) or at least " + std::to_string(kMinSpacingRadii) +
              ", got " + std::to_string(options.scale.spacing) + " (a value in metres?)");
  require(options.planes.spacing >= 0 && std::isfinite(options.planes.spacing),
          "planes.spacing must be >= 0 (0 = automatic)");
  require(options.filters.minConfidence >= 0 && options.filters.minConfidence <= 1,
          "min_confidence (filters.minConfidence) must be in [0, 1]");
  require(options.link.minSections >= 1, "min_sections (link.minSections) must be >= 1");
  require(options.maxPerRegion >= 0, "max_per_region (maxPerRegion) must be >= 0 (0 = all)");
  require(options.ends.jointWrapFraction >= 0 && std::isfinite(options.ends.jointWrapFraction),
          "joint_wrap (ends.jointWrapFraction) must be >= 0 (0 = straight lines)");
  require(options.sectionBumps.weakFraction > 0 && options.sectionBumps.weakFraction <= 1,
          "sectionBumps.weakFraction must be in (0, 1]");
  require(options.sectionBumps.faintRelative >= 0 && options.sectionBumps.faintRelative <= 1,
          "sectionBumps.faintRelative must be in [0, 1]");
  require(options.bumps.minProtrusion >= 0 && std::isfinite(options.bumps.minProtrusion),
          "bumps.minProtrusion must be finite and >= 0 (it also sets the smallest section loop: twice it)");
  require(options.profiles.sampleSpacing > 0 && std::isfinite(options.profiles.sampleSpacing),
          "profiles.sampleSpacing must be finite and > 0");
  require(options.filters.minRelative >= 0, "filters.minRelative must be >= 0");
  require(options.filters.minEvidence >= 0, "filters.minEvidence must be >= 0");
  require(options.filters.continuousEvidence >= 0, "filters.continuousEvidence must be >= 0");
  if (options.sectionBumps.trunkHarmonics < 0 || options.sectionBumps.trunkHarmonics > 16)
    throw InputError("trunkHarmonics must be in [0, 16], got " + std::to_string(options.sectionBumps.trunkHarmonics));
  if (!(options.filters.spindleEnds >= 0.0 && options.filters.spindleEnds <= 1.0) ||
      !(options.filters.spindleLength >= 0.0 && std::isfinite(options.filters.spindleLength)) ||
      !(options.filters.spindleSteepness >= 0.0 && std::isfinite(options.filters.spindleSteepness)))
    throw InputError("spindle options: spindleEnds must be in [0, 1], spindleLength and spindleSteepness finite "
                     "and >= 0");
  if (!(options.filters.twinReach >= 0.0 && std::isfinite(options.filters.twinReach)))
    throw InputError("twinReach must be finite and >= 0");
  if (options.bumps.baseHarmonics < 0 || options.bumps.baseHarmonics > 16)
    throw InputError("bumps.baseHarmonics must be in [0, 16], got " + std::to_string(options.bumps.baseHarmonics));
}

}  // namespace

// ============================================================================
// One-shot pipeline: body surface and scale, then the stages
// ============================================================================

namespace {

// Why the muscles of a body far from the reference size depend on its size (ExtractionReport::scaleNote); empty near
// it, in continuous mode, and when no limb was analysed (the limb radius is then a fallback, and the roles the cause).
std::string scaleNote(const stages::ScaleContext& scale, const BodyScaleOptions& options,
                      const std::vector<BoneRole>& roles, bool analysed) {
  const double reference = scale.reference;
  const bool limbs = std::find(roles.begin(), roles.end(), BoneRole::Limb) != roles.end();
  if (options.continuous || !analysed || !limbs || !(reference > 0) || !(scale.limbRadius > 0)) return "";
  const double ratio = scale.limbRadius * scale.factor / reference;
  if (ratio >= 2.0 / 3.0 && ratio <= 1.5) return "";
  auto number = [](const char* format, double x) {
    char text[32];
    std::snprintf(text, sizeof text, format, x);
    return std::string(text);
  };
  return "limb radius " + number("%.3g", scale.limbRadius * scale.factor) + " m in the units found (" +
         number("%.4g", scale.limbRadius) + " in the character's own) is " + number("%.2f", ratio) + " times the " +
         number("%.3g", reference) + " m the defaults are stated for: the muscles found depend on the body's size (a " +
         "character in feet or inches, or far from life size); the expert option scale.continuous analyses it at the "
         "reference size";
}

}  // namespace

ExtractionResult extractMuscles(const Character& character, const ExtractionOptions& options) {
  using Clock = std::chrono::steady_clock;
  using stages::secondsSince;
  validateExtraction(character, options);
  const int nv = character.mesh.numVertices();
  requireMemory(extractionMemoryEstimate(nv), "muscle extraction on " + std::to_string(nv) + " vertices");

  // Stage 0: the body surface at body scale, and its scale context.
  const stages::BodySurface surface = stages::makeBodySurface(character, options);
  const Character& body = surface.body;
  const stages::ScaleContext& scale = surface.scale;
  ExtractionResult result;
  ExtractionReport& rep = result.report;

  // Stages 1-2: roles, planes, profiles (timings "planes" and "sections").
  const stages::SectionCut cut = stages::cutBodySections(body, scale, surface.roles, options.planes, options.profiles,
                                                         options.bumps.minProtrusion, surface.vertexMask, rep);
  // Stages 3-4: CDT, bumps, ellipses per section.
  auto t0 = Clock::now();
  const stages::SectionBumpsResult found = stages::findSectionBumps(
      body, cut, scale, options.bumps, options.sectionBumps, surface.vertexMask, surface.forcedRegions, rep);
  rep.timings.push_back({"bumps", secondsSince(t0)});
  // Stage 5: linking and the chain filters.
  t0 = Clock::now();
  std::vector<MuscleChain> chains =
      stages::linkSectionChains(found, options.link, options.sectionBumps, surface.forcedRegions.size(), rep);
  const std::vector<MuscleChain> kept = stages::filterChains(std::move(chains), found.sections, cut, body.skeleton, scale,
                                                             options.filters, options.link.minSections,
                                                             options.sectionBumps.weakFraction,
                                                             options.bumps.minRelativeProtrusion, rep);
  rep.timings.push_back({"link", secondsSince(t0)});
  // Stage 6: ends, naming, regions.
  t0 = Clock::now();
  result.muscles = stages::assembleMuscles(kept, found.sections, body, cut.roles, options.ends, options.maxPerRegion, rep);
  rep.timings.push_back({"ends", secondsSince(t0)});
  // Stage 7: surfaces.
  t0 = Clock::now();
  if (options.buildSurfaces) stages::loftSurfaces(result.muscles, options.surface);
  rep.timings.push_back({"surface", secondsSince(t0)});
  rep.muscles = static_cast<int>(result.muscles.size());

  // Back to the character's units.
  const double factor = scale.factor;
  auto fromBody = [&](const Vec3& p) { return Vec3(p / factor); };
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
  for (ChainRecord& r : rep.chainRecords) {
    for (Vec3& p : r.centres) p = fromBody(p);
    for (double& x : r.radius) x /= factor;
  }
  rep.limbRadius = scale.limbRadius;
  rep.scale = factor;
  rep.excluded = surface.excluded;
  rep.analysed = rep.sections > 0;
  rep.scaleNote = scaleNote(scale, options.scale, surface.roles, rep.analysed);
  if (result.muscles.empty()) rep.diagnosis = diagnose(rep);
  return result;
}

}  // namespace myoskin
