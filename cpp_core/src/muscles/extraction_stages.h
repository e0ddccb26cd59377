// The stages of the one-shot extraction (extractMuscles, extract_muscles.cpp), each a function with its own options:
//   body surface + scale context -> roles, planes, profiles -> bumps per section -> linking -> chain filters
//   -> ends, regions, names -> surfaces.
// Every stage works on the body at body scale (the character scaled by ScaleContext::factor); extractMuscles
// scales the muscles back. Exposed to the tests (tests/cpp include cpp_core/src), not to the library's users.
#pragma once
#include <chrono>
#include <vector>

#include "myoskin/bumps.h"
#include "myoskin/extraction.h"

namespace myoskin::stages {

// ============================================================================
// Stage 0: body surface and scale context
// ============================================================================

// The body scale, computed once from the body surface and passed to every stage. Lengths "body" are in the
// analysis units (the character times `factor`); limbRadius is in the character's own units (the report's).
struct ScaleContext {
  double limbRadius = 0.0;      // the body's limb radius in the character's units (bodyLimbRadius)
  double reference = 0.0;       // the limb radius (m) the defaults are stated for (BodyScaleOptions::
                                // referenceLimbRadius, 0 there = kReferenceLimbRadius); < 0 = the file's own units
  double factor = 1.0;          // character units -> analysis units (a power of ten, or any with scale.continuous;
                                // 1 when the reference is < 0)
  double planeSpacing = 0.0;    // requested plane spacing in analysis units (0 = automatic)
  double defaultSpacing = 0.0;  // the automatic spacing's basis: 1/80 of the body's largest extent (analysis units)
  double meanEdgeLength = 0.0;  // the body's mean triangle edge length (analysis units)
  // Evidence is counted in sections of the default spacing (ChainFilterOptions::minEvidence).
  double evidenceScale() const { return planeSpacing > 0 ? planeSpacing / defaultSpacing : 1.0; }
};

// The body surface (stage 0): the character's skin without small and rigidly bound components (bodySurfaceMask),
// vertices renumbered; the masks remapped to it; then scaled into analysis units by the scale context.
struct BodySurface {
  Character body;                               // the analysed skin (#B vertices), in analysis units
  std::vector<char> vertexMask;                 // #B, empty = whole skin
  std::vector<std::vector<char>> forcedRegions; // one #B mask per forced region
  std::vector<ExcludedComponent> excluded;      // components left out
  std::vector<BoneRole> roles;                  // #bones: characterBoneRoles with the options' overrides, found once
  ScaleContext scale;
};

// The body surface, its bone roles and its scale context. The options are extractMuscles' after its checks
// (validateExtraction: mask sizes, a finite referenceLimbRadius, ranges).
BodySurface makeBodySurface(const Character& character, const ExtractionOptions& options);

// The scale context of a body in the character's units (before scaling): its limb radius (over the limbs of `roles`),
// the units factor, and the plane spacing from options.spacing (limb radii) or, when that is 0, from `spacing`
// (PlaneOptions::spacing, the character's units; 0 = automatic). defaultSpacing and meanEdgeLength are filled by
// makeBodySurface.
ScaleContext makeScaleContext(const Character& body, const std::vector<BoneRole>& roles,
                              const BodyScaleOptions& options, double spacing);

// ============================================================================
// Stages 1-2: roles, cutting planes, profiles
// ============================================================================

struct SectionCut {
  std::vector<BoneRole> roles;         // #bones
  std::vector<CuttingPlane> planes;
  std::vector<SectionProfile> profiles;  // one per plane
};

// The cutting planes over the bones of `roles` (BodySurface::roles; spacing from the scale context) and a profile per
// plane. Loops shorter than twice `bumpFloor` (BumpOptions::minProtrusion) are skipped: none of their points lies more
// than half their length from another, so no bump on them stands out by the floor (profiles.minPerimeter is set from
// it). Fills rep.bones, activeBones, planes and the timings "planes" and "sections".
SectionCut cutBodySections(const Character& body, const ScaleContext& scale, const std::vector<BoneRole>& roles,
                           const PlaneOptions& planes, const ProfileOptions& profileOptions, double bumpFloor,
                           const std::vector<char>& vertexMask, ExtractionReport& rep);

// ============================================================================
// Stages 3-4: triangulation, bumps and ellipses per section
// ============================================================================

struct SectionBumpsResult {
  std::vector<SectionBumps> sections;        // the sections that gave a clean loop, in plane order
  std::vector<std::vector<int>> forcedOf;    // per section, per ellipse: forced region index or -1
};

// One profile's triangulation (split along a torso section's mirror axis, CuttingPlane::mirrorAxis) and its bumps down to
// the hysteresis's share of the threshold (SectionBumpOptions weakFraction, or faintFraction with faint links; trunk
// sections with trunkHarmonics), significance relative to the full threshold: the bumps findSectionBumps starts from.
struct ProfileBumps {
  SectionTriangulation triangulation;
  std::vector<Bump> bumps;
};
ProfileBumps profileBumps(const SectionProfile& profile, const BumpOptions& bumps, const SectionBumpOptions& options);

// Bumps of every profile (parallel over sections, deterministic), with the hysteresis and forced regions of
// SectionBumpOptions. Fills rep.skipped, sections, mirrored, split, bumps.
SectionBumpsResult findSectionBumps(const Character& body, const SectionCut& cut, const ScaleContext& scale,
                                    const BumpOptions& bumps, const SectionBumpOptions& options,
                                    const std::vector<char>& vertexMask,
                                    const std::vector<std::vector<char>>& forcedRegions, ExtractionReport& rep);

// ============================================================================
// Stage 5: linking and chain filters
// ============================================================================

// Links the sections' bumps into chains (faint links per SectionBumpOptions) and marks, per forced region, the
// chain with the most links from it. Fills rep.chains, branches.
std::vector<MuscleChain> linkSectionChains(const SectionBumpsResult& found, const LinkOptions& link,
                                           const SectionBumpOptions& options, size_t forcedRegions,
                                           ExtractionReport& rep);

// The floors (length, evidence, height, confidence) and the cues that keep a chain below them (closed spindle,
// mirror twin). Returns the kept chains; fills rep.chainRecords and the dropped counts. `minSections`:
// LinkOptions::minSections; `weakFraction`: SectionBumpOptions::weakFraction (links below it are faint tails, left out
// of the height floor); `bumpRelative`: BumpOptions::minRelativeProtrusion (a continuous chain's height floor).
std::vector<MuscleChain> filterChains(std::vector<MuscleChain> chains, const std::vector<SectionBumps>& sections,
                                      const SectionCut& cut, const Skeleton& skeleton, const ScaleContext& scale,
                                      const ChainFilterOptions& options, int minSections, double weakFraction,
                                      double bumpRelative, ExtractionReport& rep);

// ============================================================================
// Stage 6: ends, regions, names
// ============================================================================

// Each kept chain becomes a muscle with ends (EndOptions); overlapping families and the region limit
// (maxPerRegion, 0 = all) drop some; the rest are named. Fills rep.droppedOverlap, droppedRegionLimit, forced.
std::vector<Muscle> assembleMuscles(const std::vector<MuscleChain>& kept, const std::vector<SectionBumps>& sections,
                                    const Character& body, const std::vector<BoneRole>& roles,
                                    const EndOptions& ends, int maxPerRegion, ExtractionReport& rep);

// ============================================================================
// Stage 7: surfaces
// ============================================================================

// A lofted surface per muscle (parallel).
void loftSurfaces(std::vector<Muscle>& muscles, const SurfaceOptions& options);

// Seconds since t0 (the stages' timings).
inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace myoskin::stages
