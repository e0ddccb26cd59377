// Stages 1-2 of the extraction: cutting planes over the bone roles of stage 0 (spacing from the scale context),
// a profile per plane.
#include "muscles/extraction_stages.h"

namespace myoskin::stages {

// ============================================================================
// Planes, profiles
// ============================================================================

SectionCut cutBodySections(const Character& character, const ScaleContext& scale, const std::vector<BoneRole>& roles,
                           const PlaneOptions& planeOptions, const ProfileOptions& profileOptions, double bumpFloor,
                           const std::vector<char>& vertexMask, ExtractionReport& rep) {
  auto t0 = std::chrono::steady_clock::now();
  SectionCut cut;
  cut.roles = roles;
  rep.bones = character.skeleton.numBones();
  for (BoneRole r : cut.roles) rep.activeBones += r != BoneRole::Ignore;
  PlaneOptions planes = planeOptions;
  planes.spacing = scale.planeSpacing;  // analysis units
  cut.planes = makeCuttingPlanes(character, cut.roles, planes);
  rep.planes = static_cast<int>(cut.planes.size());
  rep.timings.push_back({"planes", secondsSince(t0)});
  t0 = std::chrono::steady_clock::now();
  ProfileOptions profiles = profileOptions;
  profiles.minPerimeter = 2.0 * bumpFloor;
  cut.profiles = cutSections(character, cut.planes, profiles, vertexMask.empty() ? nullptr : &vertexMask);
  rep.timings.push_back({"sections", secondsSince(t0)});
  return cut;
}

}  // namespace myoskin::stages
