// Stages 6-7 of the extraction: each kept chain becomes a muscle with its ends; overlapping families and the region
// limit drop some; the rest are named; then their surfaces are lofted.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "muscles/extraction_stages.h"
#include "muscles/muscle_names.h"
#include "muscles/muscle_util.h"
#include "myoskin/muscle_shape.h"

namespace myoskin::stages {

namespace {

// Sector name of a point around a bone, from the bone's rest X and Z axes.
std::string sideName(const Bone& bone, const Vec3& p) {
  const Vec3 c = detail::closestOnSegment(p, bone.head, bone.tail);
  const Vec3 v = p - c;
  const Vec3 x = bone.rest.block<3, 1>(0, 0), z = bone.rest.block<3, 1>(0, 2);
  const double ax = v.dot(x), az = v.dot(z);
  if (std::abs(ax) >= std::abs(az)) return ax >= 0 ? "xpos" : "xneg";
  return az >= 0 ? "zpos" : "zneg";
}

}  // namespace

// ============================================================================
// Ends, regions, names
// ============================================================================

std::vector<Muscle> assembleMuscles(const std::vector<MuscleChain>& kept, const std::vector<SectionBumps>& sections,
                                    const Character& character, const std::vector<BoneRole>& roles,
                                    const EndOptions& ends, int maxPerRegion, ExtractionReport& rep) {
  const Skeleton& sk = character.skeleton;
  std::vector<Muscle> out;
  std::vector<Muscle> muscles(kept.size());
  const std::vector<char> twist = twistSplits(character);
  std::unique_ptr<SkinWinding> skinWinding;  // keeps the ends carried onto the foot inside the skin
  if (ends.spanDistal && std::any_of(kept.begin(), kept.end(), [](const MuscleChain& k) { return k.family == "limb"; }))
    skinWinding = std::make_unique<SkinWinding>(character.mesh.vertices, character.mesh.triangles);
  tbb::parallel_for(size_t(0), kept.size(), [&](size_t i) {
    muscles[i] = buildMuscleEnds(kept[i], sections, sk, ends);
    if (!detail::trunkFamily(kept[i].family)) spanRealJoint(muscles[i], sk, twist, ends);  // act on a real joint
    if (kept[i].family == "limb") spanDistalJoint(muscles[i], sk, twist, roles, kept[i].bone, ends, skinWinding.get());  // onto the foot
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
  if (maxPerRegion > 0) {
    std::map<std::string, std::vector<int>> byRegion;
    for (size_t i = 0; i < kept.size(); ++i)
      if (keep[i]) byRegion[regions[i]].push_back(static_cast<int>(i));
    for (auto& [region, ids] : byRegion) {
      std::stable_sort(ids.begin(), ids.end(), [&](int x, int y) {
        if (kept[x].forced != kept[y].forced) return kept[x].forced;
        return kept[x].confidence > kept[y].confidence;
      });
      for (size_t j = maxPerRegion; j < ids.size(); ++j)
        if (!kept[ids[j]].forced) keep[ids[j]] = 0, ++rep.droppedRegionLimit;
    }
  }
  // Names: anatomical where the muscle's place identifies it ("biceps.L", a second one "biceps_2.L"), else its
  // region and side of the bone ("forearm_front.L"), else (no body frame) the bone and its axis ("forearm_xpos_1").
  // Mirror twins are named as a pair, from their averaged place, with one number: biceps_2.L and biceps_2.R are one
  // muscle on the two sides. A muscle without a twin takes the first number free on its own side.
  const detail::BodyFrame frame = detail::bodyFrame(sk, roles, twist);
  std::vector<int> ids;
  std::vector<const Muscle*> keptMuscles;
  std::vector<std::string> keptFamilies;
  for (size_t i = 0; i < kept.size(); ++i)
    if (keep[i]) ids.push_back(static_cast<int>(i)), keptMuscles.push_back(&muscles[i]), keptFamilies.push_back(kept[i].family);
  const std::vector<int> twin = detail::mirrorTwins(keptMuscles, keptFamilies, frame);
  std::set<std::string> used;
  std::map<std::string, int> nameCount;  // names by bone and axis (no body frame)
  auto numbered = [](const std::string& stem, int k, const std::string& side) {
    return (k == 1 ? stem : stem + "_" + std::to_string(k)) + side;
  };
  auto firstFree = [&](const std::string& stem, const std::vector<std::string>& sides) {
    for (int k = 1;; ++k)
      if (std::none_of(sides.begin(), sides.end(), [&](const std::string& x) { return used.count(numbered(stem, k, x)); }))
        return k;
  };
  auto sideOfCentre = [&](const Muscle& m) {  // a twin's sections are never empty (mirrorTwins)
    Vec3 c = Vec3::Zero();
    for (const MuscleSection& x : m.sections) c += x.center;
    return (c / static_cast<double>(m.sections.size()) - frame.centre).dot(frame.left) > 0 ? ".L" : ".R";
  };
  std::vector<std::string> names(ids.size());
  for (size_t n = 0; n < ids.size(); ++n) {
    if (!names[n].empty()) continue;
    const int i = ids[n], t = twin[n];
    const Muscle& m = muscles[i];
    const Muscle placedFrom = t >= 0 ? detail::symmetrisedForNaming(m, muscles[ids[t]], frame) : Muscle{};
    const Muscle& at = t >= 0 ? placedFrom : m;
    std::string placed = detail::anatomicalName(at, kept[i].bone, kept[i].family, sk, frame);
    if (placed.empty()) placed = detail::regionName(at, kept[i].bone, kept[i].family, sk, frame);
    if (placed.empty()) {  // no body frame: by bone and axis (a twin pair too, each on its own bone)
      for (const int x : {static_cast<int>(n), t}) {
        if (x < 0) continue;
        const Bone& bone = sk.bones[kept[ids[x]].bone];
        const Muscle& mx = muscles[ids[x]];
        const std::string base = bone.name + "_" + sideName(bone, mx.sections[mx.sections.size() / 2].center);
        names[x] = base + "_" + std::to_string(++nameCount[base]);
      }
      continue;
    }
    const size_t dot = placed.find('.');
    const std::string stem = placed.substr(0, dot);
    if (t >= 0) {
      const std::string side = sideOfCentre(m), other = side == std::string(".L") ? ".R" : ".L";
      const int k = firstFree(stem, {side, other});
      names[n] = numbered(stem, k, side), names[t] = numbered(stem, k, other);
      used.insert(names[n]), used.insert(names[t]);
    } else {
      const std::string side = dot == std::string::npos ? "" : placed.substr(dot);
      names[n] = numbered(stem, firstFree(stem, {side}), side);
      used.insert(names[n]);
    }
  }
  for (size_t n = 0; n < ids.size(); ++n) {
    Muscle& m = muscles[ids[n]];
    m.name = names[n];
    if (kept[ids[n]].forced) ++rep.forced;
    out.push_back(std::move(m));
  }
  return out;
}

// ============================================================================
// Surfaces
// ============================================================================

void loftSurfaces(std::vector<Muscle>& muscles, const SurfaceOptions& options) {
  tbb::parallel_for(size_t(0), muscles.size(),
                    [&](size_t i) { muscles[i].surface = loftMuscleSurface(muscles[i], options); });
}

}  // namespace myoskin::stages
