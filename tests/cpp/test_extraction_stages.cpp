// The extraction's stage functions (muscles/extraction_stages.h) run one by one give the one-shot result; the scale
// context; spacing in limb radii; expert options by name.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "muscles/extraction_stages.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

SyntheticCharacter body(unsigned seed, BodyKind kind, double scale = 1.0) {
  SyntheticBodyOptions o;
  o.seed = seed;
  o.kind = kind;
  o.scale = scale;
  return makeSyntheticBody(o);
}

}  // namespace

// ============================================================================
// Stages alone = one shot
// ============================================================================

TEST(Stages, EachStageAloneGivesTheOneShotResult) {
  for (const BodyKind kind : {BodyKind::Biped, BodyKind::Quadruped}) {
    const SyntheticCharacter c = body(21, kind);
    ExtractionOptions o;
    o.buildSurfaces = false;  // the one shot then keeps the muscles as assembled (no containment in the skin)
    const ExtractionResult shot = extractMuscles(c.character, o);
    ASSERT_GT(shot.muscles.size(), 4u) << bodyKindName(kind);

    ExtractionReport rep;
    const stages::BodySurface surface = stages::makeBodySurface(c.character, o);
    const stages::ScaleContext& scale = surface.scale;
    EXPECT_EQ(scale.limbRadius, shot.report.limbRadius);
    EXPECT_EQ(scale.factor, shot.report.scale);
    EXPECT_GT(scale.defaultSpacing, 0.0);
    EXPECT_GT(scale.meanEdgeLength, 0.0);
    EXPECT_LT(scale.meanEdgeLength, scale.limbRadius * scale.factor);  // the limb is resolved by its mesh
    EXPECT_EQ(scale.evidenceScale(), 1.0);                              // automatic spacing
    const stages::SectionCut cut = stages::cutBodySections(surface.body, scale, surface.roles, o.planes, o.profiles,
                                                           o.bumps.minProtrusion, surface.vertexMask, rep);
    EXPECT_EQ(rep.planes, shot.report.planes);
    EXPECT_EQ(cut.profiles.size(), cut.planes.size());
    const stages::SectionBumpsResult found = stages::findSectionBumps(
        surface.body, cut, scale, o.bumps, o.sectionBumps, surface.vertexMask, surface.forcedRegions, rep);
    EXPECT_EQ(rep.sections, shot.report.sections);
    EXPECT_EQ(rep.bumps, shot.report.bumps);
    EXPECT_EQ(found.sections.size(), found.forcedOf.size());
    std::vector<MuscleChain> chains = stages::linkSectionChains(found, o.link, o.sectionBumps, 0, rep);
    EXPECT_EQ(rep.chains, shot.report.chains);
    const std::vector<MuscleChain> kept = stages::filterChains(std::move(chains), found.sections, cut,
                                                               surface.body.skeleton, scale, o.filters,
                                                               o.link.minSections, o.sectionBumps.weakFraction,
                                                               o.bumps.minRelativeProtrusion, rep);
    EXPECT_EQ(rep.droppedShort, shot.report.droppedShort);
    EXPECT_EQ(rep.droppedFlat, shot.report.droppedFlat);
    EXPECT_EQ(rep.droppedConfidence, shot.report.droppedConfidence);
    EXPECT_EQ(rep.droppedContour, shot.report.droppedContour);
    EXPECT_EQ(rep.spindles, shot.report.spindles);
    EXPECT_EQ(rep.twins, shot.report.twins);
    ASSERT_EQ(rep.chainRecords.size(), shot.report.chainRecords.size());
    ASSERT_FALSE(rep.chainRecords.empty());
    for (size_t i = 0; i < rep.chainRecords.size(); ++i)  // every chain's verdict (kept, spindle, twin, dropped why)
      EXPECT_EQ(rep.chainRecords[i].verdict, shot.report.chainRecords[i].verdict) << i;
    const std::vector<Muscle> muscles =
        stages::assembleMuscles(kept, found.sections, surface.body, cut.roles, o.ends, o.maxPerRegion, rep);
    EXPECT_EQ(rep.droppedOverlap, shot.report.droppedOverlap);
    EXPECT_EQ(rep.droppedRegionLimit, shot.report.droppedRegionLimit);
    ASSERT_EQ(muscles.size(), shot.muscles.size()) << bodyKindName(kind);
    for (size_t i = 0; i < muscles.size(); ++i) {  // the same muscles, back in the character's units bit for bit
      EXPECT_EQ(muscles[i].name, shot.muscles[i].name);
      ASSERT_EQ(muscles[i].rootCurve.size(), shot.muscles[i].rootCurve.size());
      for (size_t k = 0; k < muscles[i].rootCurve.size(); ++k)
        EXPECT_EQ(Vec3(muscles[i].rootCurve[k] / scale.factor), shot.muscles[i].rootCurve[k]) << muscles[i].name;
    }
  }
}

// ============================================================================
// Spacing in limb radii
// ============================================================================

TEST(Stages, SpacingInLimbRadiiIsTheBodysOwn) {
  const SyntheticCharacter c = body(24, BodyKind::Biped);
  ExtractionOptions radii;
  radii.buildSurfaces = false;
  radii.scale.spacing = 1.0;
  const ExtractionResult r = extractMuscles(c.character, radii);
  ExtractionOptions metres;  // the same spacing given in the character's units
  metres.buildSurfaces = false;
  metres.planes.spacing = r.report.limbRadius;
  const ExtractionResult m = extractMuscles(c.character, metres);
  EXPECT_EQ(r.report.planes, m.report.planes);
  EXPECT_EQ(r.muscles.size(), m.muscles.size());
  // Coarser than automatic (1/80 of the extent: about 0.4 limb radii here): fewer planes; and the same at another
  // size of the character.
  const ExtractionResult automatic = extractMuscles(c.character, metres = ExtractionOptions{});
  EXPECT_LT(r.report.planes, automatic.report.planes);
  EXPECT_GT(2 * r.report.planes, automatic.report.planes / 2.5);
  const SyntheticCharacter small = body(24, BodyKind::Biped, 0.01);
  const ExtractionResult s = extractMuscles(small.character, radii);
  EXPECT_NEAR(s.report.planes, r.report.planes, 1);
  // Spacing in limb radii out of range.
  radii.scale.spacing = -1.0;
  EXPECT_THROW(extractMuscles(c.character, radii), InputError);
}

// ============================================================================
// Expert options by name
// ============================================================================

TEST(Stages, ExpertOptionsByName) {
  const std::vector<ExpertOption> all = expertOptions();
  ASSERT_GT(all.size(), 40u);
  std::set<std::string> keys;
  for (const ExpertOption& e : all) {
    EXPECT_TRUE(keys.insert(e.key).second) << e.key;
    EXPECT_TRUE(e.type == "double" || e.type == "int" || e.type == "bool") << e.key;
  }
  for (const char* userFacing : {"scale.spacing", "filters.minConfidence", "link.minSections", "maxPerRegion",
                                 "ends.jointWrapFraction", "planes.spacing"})
    EXPECT_EQ(keys.count(userFacing), 0u) << userFacing;
  ExtractionOptions o;
  EXPECT_EQ(expertOption(o, "filters.minEvidence"), o.filters.minEvidence);
  setExpertOption(o, "filters.minEvidence", 7.5);
  setExpertOption(o, "link.maxGap", 5);
  setExpertOption(o, "ends.spanDistal", 0);
  EXPECT_EQ(o.filters.minEvidence, 7.5);
  EXPECT_EQ(o.link.maxGap, 5);
  EXPECT_FALSE(o.ends.spanDistal);
  EXPECT_THROW(setExpertOption(o, "filters.nothing", 1), InputError);
  EXPECT_THROW(setExpertOption(o, "link.maxGap", 2.5), InputError);
  EXPECT_THROW(setExpertOption(o, "ends.spanDistal", 2), InputError);
  EXPECT_THROW(setExpertOption(o, "filters.minEvidence", std::nan("")), InputError);
  // Derived, no longer knobs: the smallest loop (twice the bump floor) and the height floor's share (the hysteresis's
  // weakFraction).
  EXPECT_THROW(setExpertOption(o, "profiles.minPerimeter", 0.01), InputError);
  EXPECT_THROW(setExpertOption(o, "filters.magnitudeFraction", 0.8), InputError);
  EXPECT_THROW(setExpertOption(o, "filters.continuousFraction", 0.6), InputError);
}

// The smallest section loop follows the bump floor: a loop shorter than twice it cannot hold a bump that stands out by
// it. On the synthetic arm (upper arm about 0.28 m round, forearm less) no loop is that small at the default floor;
// with a 0.12 m floor the loops under 0.24 m are skipped as too small, and every one skipped is under it.
TEST(Stages, SmallestLoopFollowsTheBumpFloor) {
  const SyntheticCharacter arm = makeSyntheticArm();
  ExtractionOptions o;
  o.buildSurfaces = false;
  auto tooSmall = [](const ExtractionReport& r) {
    int n = 0;
    for (const SkippedSection& s : r.skipped) n += s.reason.find("too small") != std::string::npos;
    return n;
  };
  EXPECT_EQ(tooSmall(extractMuscles(arm.character, o).report), 0);
  setExpertOption(o, "bumps.minProtrusion", 0.12);
  const ExtractionResult big = extractMuscles(arm.character, o);
  const int skipped = tooSmall(big.report);
  EXPECT_GT(skipped, 0);
  EXPECT_LT(skipped, big.report.planes);  // the upper arm's loops are longer than 0.24 m
  int measured = 0;
  for (const SkippedSection& s : big.report.skipped)
    if (s.reason.find("too small") != std::string::npos) {
      const size_t open = s.reason.find('(');
      ASSERT_NE(open, std::string::npos) << s.reason;
      const double perimeter = std::stod(s.reason.substr(open + 1));
      EXPECT_LT(perimeter, 0.24) << s.reason;
      EXPECT_GT(perimeter, 0.05) << s.reason;  // a limb's loop, not a degenerate one
      ++measured;
    }
  EXPECT_EQ(measured, skipped);
}
