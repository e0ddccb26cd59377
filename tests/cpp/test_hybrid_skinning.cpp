// Hybrid skinning with muscles (Equation 3 over skeleton bones + muscle joints) on the generated arm:
// muscle weights, rest pose exactness, elbow bending against plain LBS, bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "test_support.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/sections.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {


// The generated arm with its extracted muscles; the biceps (the anterior upper-arm muscle) gets its
// anatomical attachments as a user would place them: origin near the shoulder, insertion on the forearm
// 4 cm past the elbow, both at the muscle's depth, so it spans the elbow.
struct ArmRig {
  Character character;
  std::vector<Muscle> muscles;
  int biceps = -1;
};

const ArmRig& armRig() {
  static const ArmRig rig = [] {
    ArmRig r;
    r.character = makeSyntheticArm().character;
    r.muscles = extractMuscles(r.character).muscles;
    const Skeleton& sk = r.character.skeleton;
    const Bone& upper = sk.bones[sk.find("upper_arm")];
    const Bone& fore = sk.bones[sk.find("forearm")];
    double best = 0.015;  // the most anterior upper-arm muscle (the generator's biceps lies along +Z)
    std::vector<double> depth(r.muscles.size(), 0.0);
    for (size_t m = 0; m < r.muscles.size(); ++m) {
      for (const MuscleSection& s : r.muscles[m].sections) depth[m] += s.center.z() / r.muscles[m].sections.size();
      if (r.muscles[m].region.rfind("upper_arm", 0) == 0 && depth[m] > best) best = depth[m], r.biceps = static_cast<int>(m);
    }
    if (r.biceps >= 0) {
      Muscle& mu = r.muscles[r.biceps];
      mu.origin = {"upper_arm", upper.head + Vec3(0.03, 0.0, 0.6 * depth[r.biceps])};
      mu.insertion = {"forearm", fore.head + Vec3(0.04, 0.0, 0.5 * depth[r.biceps])};
    }
    return r;
  }();
  return rig;
}

Pose elbowPose(const Skeleton& sk, double degrees) {
  std::vector<Eigen::Quaterniond> q(sk.numBones(), Eigen::Quaterniond::Identity());
  // Flexion: the forearm's tip turns towards +Z (anterior), a rotation about the bone's X axis.
  q[sk.find("forearm")] = Eigen::AngleAxisd(degrees * kPi / 180.0, Vec3::UnitX());
  return poseFromLocalRotations(sk, q);
}

// The elbow region (label 0, others -1): skin the skeleton blends between upper arm and forearm.
IndexVector elbowRegion(const Character& c) {
  IndexVector elbow = IndexVector::Constant(c.mesh.numVertices(), -1);
  const int upperBone = c.skeleton.find("upper_arm"), foreBone = c.skeleton.find("forearm");
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    double wu = 0, wf = 0;
    for (int k = 0; k < c.weights.influences(); ++k) {
      if (c.weights.joints(v, k) == upperBone) wu += c.weights.weights(v, k);
      if (c.weights.joints(v, k) == foreBone) wf += c.weights.weights(v, k);
    }
    if (wu > 0.02 && wf > 0.02) elbow[v] = 0;
  }
  return elbow;
}

double muscleShare(const SkinWeights& w, int v, int numBones, int first = -1, int count = 0) {
  double s = 0;
  for (int k = 0; k < w.influences(); ++k) {
    const int j = w.joints(v, k);
    if (j < numBones) continue;
    if (first < 0 || (j >= numBones + first && j < numBones + first + count)) s += w.weights(v, k);
  }
  return s;
}


}  // namespace

TEST(HybridWeights, RowsSumToOneMusclesDominateAndSmoothSkinHasNone) {
  const ArmRig& a = armRig();
  ASSERT_GE(a.muscles.size(), 3u);
  ASSERT_GE(a.biceps, 0) << "no anterior upper-arm muscle extracted";
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  const int nb = c.skeleton.numBones();
  ASSERT_EQ(w.numVertices(), c.mesh.numVertices());
  EXPECT_EQ(w.influences(), 8);
  validateSkinWeights(w, c.mesh.numVertices(), nb + rig.numJoints());
  int dominated = 0, hand = 0, handWithMuscle = 0;
  const int handBone = c.skeleton.find("hand");
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    EXPECT_NEAR(w.weights.row(v).sum(), 1.0, 1e-12) << "vertex " << v;
    if (muscleShare(w, v, nb) > 0.5) ++dominated;
    Eigen::Index k;
    c.weights.weights.row(v).maxCoeff(&k);
    if (c.weights.joints(v, k) == handBone) {
      ++hand;
      if (muscleShare(w, v, nb) > 0) ++handWithMuscle;
    }
  }
  std::printf("muscle-dominated vertices %d of %d; hand vertices with muscle weight %d of %d\n", dominated,
              c.mesh.numVertices(), handWithMuscle, hand);
  EXPECT_GT(dominated, c.mesh.numVertices() / 10);
  EXPECT_GT(hand, 0);
  EXPECT_EQ(handWithMuscle, 0);  // the hand has no muscles: smooth skin keeps the skeleton weights
  // Smooth over the surface: the muscle share changes little between neighbouring vertices.
  double jump = 0;
  int at = 0;
  for (int f = 0; f < c.mesh.numTriangles(); ++f)
    for (int e = 0; e < 3; ++e) {
      const double d = std::abs(muscleShare(w, c.mesh.triangles(f, e), nb) -
                                muscleShare(w, c.mesh.triangles(f, (e + 1) % 3), nb));
      if (d > jump) jump = d, at = c.mesh.triangles(f, e);
    }
  std::printf("largest muscle-share jump across an edge: %.3f (at vertex %d)\n", jump, at);
  // Measured: 0.147 with the lofts before issue 14 item 4; 0.160 with the muscle surfaces kept inside the skin and
  // smoothed (0.159 from the containment alone, 0.156 from the new loft alone: the same vertex).
  EXPECT_LT(jump, 0.165);
}

TEST(HybridWeights, DominanceGlobalAndPerMuscle) {
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  const int nb = c.skeleton.numBones();
  HybridWeightOptions none;
  none.dominance = 0.0;
  const SkinWeights w0 = computeHybridWeights(c.mesh, c.weights, rig, none);
  for (int v = 0; v < c.mesh.numVertices(); ++v) ASSERT_EQ(muscleShare(w0, v, nb), 0.0);
  HybridWeightOptions half;
  half.dominance = 0.5;
  const SkinWeights wh = computeHybridWeights(c.mesh, c.weights, rig, half);
  const SkinWeights w1 = computeHybridWeights(c.mesh, c.weights, rig);
  double s1 = 0, sh = 0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) s1 += muscleShare(w1, v, nb), sh += muscleShare(wh, v, nb);
  EXPECT_LT(sh, 0.75 * s1);
  EXPECT_GT(sh, 0.25 * s1);
  // Switching the biceps off removes exactly its joints.
  HybridWeightOptions noBiceps;
  noBiceps.muscleDominance[a.muscles[a.biceps].name] = 0.0;
  const SkinWeights wb = computeHybridWeights(c.mesh, c.weights, rig, noBiceps);
  const int first = rig.jointOffset(a.biceps), count = rig.jointCount(a.biceps);
  double before = 0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    ASSERT_EQ(muscleShare(wb, v, nb, first, count), 0.0);
    before += muscleShare(w1, v, nb, first, count);
  }
  EXPECT_GT(before, 100.0);
  HybridWeightOptions four;
  four.maxInfluences = 4;
  const SkinWeights w4 = computeHybridWeights(c.mesh, c.weights, rig, four);
  EXPECT_EQ(w4.influences(), 4);
  for (int v = 0; v < c.mesh.numVertices(); ++v) ASSERT_NEAR(w4.weights.row(v).sum(), 1.0, 1e-12);
}

TEST(HybridWeights, MinWeightDropsTinyMuscleWeights) {
  // Default minWeight 0.01: far fewer muscle-joint weights below 0.01 (those left are ramped ones, the
  // weights stay continuous), fewer influences in all, muscle shares moved by at most 0.01 per muscle,
  // rows still sum to 1.
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  const int nb = c.skeleton.numBones();
  HybridWeightOptions all;
  all.minWeight = 0.0;
  const SkinWeights w0 = computeHybridWeights(c.mesh, c.weights, rig, all);
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  int n0 = 0, n = 0, tiny0 = 0, tiny = 0;
  double largestChange = 0.0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    ASSERT_NEAR(w.weights.row(v).sum(), 1.0, 1e-12) << "vertex " << v;
    for (int k = 0; k < w.influences(); ++k) {
      n0 += w0.joints(v, k) >= 0 && w0.weights(v, k) > 0;
      n += w.joints(v, k) >= 0 && w.weights(v, k) > 0;
      tiny0 += w0.joints(v, k) >= nb && w0.weights(v, k) > 0 && w0.weights(v, k) < 0.01;
      tiny += w.joints(v, k) >= nb && w.weights(v, k) > 0 && w.weights(v, k) < 0.01;
    }
    // Each muscle's share moves by at most minWeight (the ramp's largest step, at 0.01).
    std::vector<int> here;
    for (int k = 0; k < w0.influences(); ++k)
      if (w0.joints(v, k) >= nb && w0.weights(v, k) > 0) here.push_back(rig.jointMuscle()[w0.joints(v, k) - nb]);
    std::sort(here.begin(), here.end());
    const double muscles = static_cast<double>(std::unique(here.begin(), here.end()) - here.begin());
    const double change = std::abs(muscleShare(w, v, nb) - muscleShare(w0, v, nb));
    ASSERT_LE(change, 0.01 * muscles + 1e-12) << "vertex " << v;
    largestChange = std::max(largestChange, change);
  }
  std::printf("influences: %d with every weight (%d muscle weights < 0.01), %d with minWeight 0.01 (%d); largest "
              "muscle share change %.4f\n", n0, tiny0, n, tiny, largestChange);
  EXPECT_GT(tiny0, c.mesh.numVertices() / 20);
  EXPECT_LT(tiny, tiny0 / 4);
  EXPECT_LT(n, n0 - tiny0 / 2);
  HybridWeightOptions bad;
  bad.minWeight = 0.5;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, c.weights, rig, bad); }).find("minWeight"), std::string::npos);
  bad.minWeight = -0.1;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, c.weights, rig, bad); }).find("minWeight"), std::string::npos);
}

TEST(HybridSkinning, RestPoseReproducesTheSkinWithMusclesBound) {
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  MuscleRigState state = rig.makeState();
  const Pose rest = restPose(c.skeleton);
  rig.evaluate(rest, state);
  std::vector<Mat4> t;
  skinningTransforms(c.skeleton, rest, rig, state, t);
  ASSERT_EQ(static_cast<int>(t.size()), c.skeleton.numBones() + rig.numJoints());
  const Skinner skinner(c.mesh.vertices, w, static_cast<int>(t.size()));
  Points out;
  skinner.deform(t, out);
  const double err = (out - c.mesh.vertices).cwiseAbs().maxCoeff();
  std::printf("rest pose with %d muscle joints bound: max error %.2e m\n", rig.numJoints(), err);
  EXPECT_LT(err, 1e-6);
}

TEST(HybridSkinning, ElbowBendKeepsVolumeBetterAndTheBicepsBulges) {
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  const int nb = c.skeleton.numBones();
  const Skinner hybrid(c.mesh.vertices, w, nb + rig.numJoints());
  const Skinner plain(c.mesh.vertices, c.weights, nb);
  const double v0 = enclosedVolume(c.mesh.vertices, c.mesh.triangles);
  // The biceps region: skin at least 30 % weighted to the biceps' joints whose skeleton weight is all on
  // one bone (the belly over the upper arm, where plain LBS moves the skin rigidly).
  std::vector<int> region;
  for (int v = 0; v < c.mesh.numVertices(); ++v)
    if (muscleShare(w, v, nb, rig.jointOffset(a.biceps), rig.jointCount(a.biceps)) > 0.3 &&
        c.weights.weights.row(v).maxCoeff() > 0.999 * c.weights.weights.row(v).sum())
      region.push_back(v);
  ASSERT_GT(region.size(), 200u);
  // The elbow region (per-region volume): skin blended between upper arm and forearm.
  const IndexVector elbow = elbowRegion(c);
  MuscleRigState state = rig.makeState();
  double hybridChange = 0, plainChange = 0, hybridBulge = 0, plainBulge = 0, plainBulgeMax = 0;
  for (double degrees : {35.0, 70.0, 105.0, 140.0}) {
    const Pose pose = elbowPose(c.skeleton, degrees);
    rig.evaluate(pose, state);
    std::vector<Mat4> t, tb;
    skinningTransforms(c.skeleton, pose, rig, state, t);
    skeletonTransforms(c.skeleton, pose, tb);
    Points ph, pp;
    hybrid.deform(t, ph);
    plain.deform(tb, pp);
    hybridChange = (enclosedVolume(ph, c.mesh.triangles) - v0) / v0;
    plainChange = (enclosedVolume(pp, c.mesh.triangles) - v0) / v0;
    const Eigen::VectorXd bh = localBulge(c.mesh.vertices, c.mesh.triangles, ph, c.weights, tb);
    const Eigen::VectorXd bp = localBulge(c.mesh.vertices, c.mesh.triangles, pp, c.weights, tb);
    hybridBulge = plainBulge = plainBulgeMax = 0;
    for (int v : region) {
      hybridBulge += bh[v] / region.size();
      plainBulge += bp[v] / region.size();
      plainBulgeMax = std::max(plainBulgeMax, std::abs(bp[v]));
    }
    const double elbowHybrid = regionVolumeChange(c.mesh.vertices, ph, c.mesh.triangles, elbow, 1)[0];
    const double elbowPlain = regionVolumeChange(c.mesh.vertices, pp, c.mesh.triangles, elbow, 1)[0];
    std::printf("elbow %5.1f deg: skin volume change with muscles %+.3f %%, skeleton only %+.3f %% (elbow region "
                "%+.1f %% vs %+.1f %%) | biceps stretch %.3f, biceps-region bulge with muscles %+.2f mm, plain LBS "
                "%+.4f mm (max |%.4f| mm)\n",
                degrees, 100 * hybridChange, 100 * plainChange, 100 * elbowHybrid, 100 * elbowPlain,
                state.stretch[a.biceps], 1e3 * hybridBulge, 1e3 * plainBulge, 1e3 * plainBulgeMax);
    // The joint region collapses less at every angle.
    EXPECT_LT(std::abs(elbowHybrid), std::abs(elbowPlain)) << degrees << " degrees";
  }
  // At 140 degrees: less volume change than plain LBS, an outward bulge where LBS has none. (At smaller
  // angles the straight biceps path lifts its skin and the volume grows more than LBS loses: printed above.)
  EXPECT_LT(std::abs(hybridChange), std::abs(plainChange));
  EXPECT_GT(hybridBulge, 1e-3);
  EXPECT_LT(plainBulgeMax, 1e-5);
  EXPECT_LT(state.stretch[a.biceps], 0.9);
}

TEST(HybridSkinning, ShoulderSwingAndForearmTwistKeepTheSkinVolume) {
  // Muscles from the clavicle to the upper arm cross the shoulder joint. As straight lines they cut the corner
  // when the arm swings, and the skin bound to them caves in (measured before: -1.5 to -9.8 % skin volume at
  // +60 degrees, +0.6 to +3.9 % at -60, on seeds 0-3). The default joint wrap (EndOptions::jointWrapFraction)
  // bends them round the joint. Measured: -1.1 to -1.8 % at +60, -1.8 to +1.8 % at -60 (plain LBS -0.04 to
  // -0.15 % and -0.84 to -0.98 %).
  for (unsigned seed : {0u, 1u, 2u, 3u}) {
    SyntheticArmOptions so;
    so.seed = seed;
    const Character c = makeSyntheticArm(so).character;
    const std::vector<Muscle> muscles = extractMuscles(c).muscles;
    int wrapped = 0;
    for (const Muscle& m : muscles) {
      if (m.origin.bone == m.insertion.bone) {
        EXPECT_EQ(m.wrap.type, WrapType::None) << m.name;
        continue;
      }
      // A joint wrap on the one joint between the two bones, unless an end lies on the joint itself.
      const Vec3 joint = c.skeleton.bones[c.skeleton.find(m.insertion.bone)].head;
      if (std::min((m.origin.position - joint).norm(), (m.insertion.position - joint).norm()) < 0.00125) continue;
      EXPECT_EQ(m.wrap.type, WrapType::Joint) << m.name;
      EXPECT_EQ(m.wrap.bone, m.insertion.bone) << m.name;
      EXPECT_GE(m.wrap.radius, 0.001) << m.name;
      wrapped += m.origin.bone == "clavicle";
    }
    EXPECT_GE(wrapped, 1) << seed;
    const MuscleRig rig(c.skeleton, muscles);
    const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
    const int nb = c.skeleton.numBones();
    const Skinner hybrid(c.mesh.vertices, w, nb + rig.numJoints());
    const double v0 = enclosedVolume(c.mesh.vertices, c.mesh.triangles);
    MuscleRigState state = rig.makeState();
    for (double degrees : {60.0, -60.0, 90.0}) {
      std::vector<Eigen::Quaterniond> q(nb, Eigen::Quaterniond::Identity());
      const bool twist = degrees == 90.0;  // the forearm's roll about its own axis
      q[c.skeleton.find(twist ? "forearm" : "upper_arm")] =
          Eigen::AngleAxisd(degrees * kPi / 180.0, twist ? Vec3::UnitY() : Vec3::UnitZ());
      const Pose pose = poseFromLocalRotations(c.skeleton, q);
      rig.evaluate(pose, state);
      std::vector<Mat4> t;
      skinningTransforms(c.skeleton, pose, rig, state, t);
      Points ph;
      hybrid.deform(t, ph);
      const double change = (enclosedVolume(ph, c.mesh.triangles) - v0) / v0;
      std::printf("seed %u, %s %+.0f deg: skin volume %+.2f %%\n", seed, twist ? "forearm twist" : "shoulder swing",
                  degrees, 100 * change);
      // Forearm twist: the muscles share the roll as the bones do (MuscleRigOptions::twistFollowsBones), so the
      // skin the forearm moves rigidly is not blended against half-turned muscle joints. Measured -0.98 to
      // -1.50 % (plain LBS -0.90 to -0.96 %; with a share linear in arc length -1.6 to -3.2 %).
      EXPECT_LT(std::abs(change), twist ? 0.02 : 0.03) << seed << " " << degrees;
    }
  }
}

TEST(HybridSkinning, TheElbowCreaseOfAMuscleThatCrossesItFollowsTheSkeleton) {
  // Seed 2's brachialis is followed across the elbow: on flexion it bowstrings, and when it took the crease's
  // skin it lifted it (elbow region +12.2 % at 70 degrees where plain LBS loses 13.9 %). A muscle takes weight
  // only from its belly's segment and none at the plane of a joint it crosses: the crease follows the skeleton.
  SyntheticArmOptions so;
  so.seed = 2;
  const Character c = makeSyntheticArm(so).character;
  const MuscleRig rig(c.skeleton, extractMuscles(c).muscles);
  const int nb = c.skeleton.numBones();
  const IndexVector elbow = elbowRegion(c);
  const Pose pose = elbowPose(c.skeleton, 70.0);
  MuscleRigState state = rig.makeState();
  rig.evaluate(pose, state);
  std::vector<Mat4> t;
  skinningTransforms(c.skeleton, pose, rig, state, t);
  auto region = [&](double relief) {
    HybridWeightOptions o;
    o.creaseRelief = relief;
    const Skinner s(c.mesh.vertices, computeHybridWeights(c.mesh, c.weights, rig, o), nb + rig.numJoints());
    Points p;
    s.deform(t, p);
    return regionVolumeChange(c.mesh.vertices, p, c.mesh.triangles, elbow, 1)[0];
  };
  std::vector<Mat4> skel;
  skeletonTransforms(c.skeleton, pose, skel);
  Points plain;
  Skinner(c.mesh.vertices, c.weights, nb).deform(skel, plain);
  const double lbs = regionVolumeChange(c.mesh.vertices, plain, c.mesh.triangles, elbow, 1)[0];
  const double muscles = region(0.0), relief = region(0.5);
  std::printf("seed 2, elbow 70 deg: elbow region %+.1f %% (plain LBS %+.1f %%), with crease relief 0.5 %+.1f %%\n",
              100 * muscles, 100 * lbs, 100 * relief);
  EXPECT_LT(lbs, -0.05);
  EXPECT_LT(std::abs(muscles), 0.5 * std::abs(lbs));  // neither lifted nor collapsed like LBS
  EXPECT_LT(std::abs(relief), 0.5 * std::abs(lbs));
  HybridWeightOptions bad;
  bad.creaseRelief = 1.5;
  EXPECT_THROW(computeHybridWeights(c.mesh, c.weights, rig, bad), InputError);
}

TEST(HybridWeights, BadInput) {
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  SkinWeights w = c.weights;
  w.weights(5, 0) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, w, rig); }).find("vertex 5"), std::string::npos);
  w = c.weights;
  w.joints(9, 1) = 99;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, w, rig); }).find("vertex 9"), std::string::npos);
  w = c.weights;
  w.weights(11, 0) = -1;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, w, rig); }).find("negative"), std::string::npos);
  SkinWeights shortW;
  shortW.joints = c.weights.joints.topRows(10);
  shortW.weights = c.weights.weights.topRows(10);
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, shortW, rig); }).find("10 rows"), std::string::npos);
  HybridWeightOptions o;
  o.dominance = 1.5;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, c.weights, rig, o); }).find("dominance"), std::string::npos);
  o = {};
  o.muscleDominance["nope"] = 1.0;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, c.weights, rig, o); }).find("'nope'"), std::string::npos);
  o = {};
  o.maxInfluences = 0;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, c.weights, rig, o); }).find("maxInfluences"), std::string::npos);
  o = {};
  o.falloffDistance = 0.1;
  EXPECT_NE(test::inputErrorOf([&] { computeHybridWeights(c.mesh, c.weights, rig, o); }).find("falloffDistance"),
            std::string::npos);
  MuscleRigState state = rig.makeState();
  state.jointMatrices.pop_back();
  std::vector<Mat4> t;
  EXPECT_NE(test::inputErrorOf([&] { skinningTransforms(c.skeleton, restPose(c.skeleton), rig, state, t); }).find("joint matrices"),
            std::string::npos);
}

// The arm's muscles, each attached at both ends to the bone of its region (upper_arm or forearm), but the biceps,
// which keeps its attachments across the elbow.
static std::vector<Muscle> musclesOnTheirRegionBones(const ArmRig& a) {
  const Skeleton& sk = a.character.skeleton;
  std::vector<Muscle> muscles = a.muscles;
  for (size_t m = 0; m < muscles.size(); ++m) {
    if (static_cast<int>(m) == a.biceps) continue;
    const std::string bone = muscles[m].region.substr(0, muscles[m].region.find('.'));
    EXPECT_GE(sk.find(bone), 0) << muscles[m].region;
    muscles[m].origin.bone = muscles[m].insertion.bone = bone;
  }
  return muscles;
}

TEST(HybridWeights, MusclesTakeWeightOnlyFromTheBonesTheySpan) {
  // A muscle between upper_arm attachments leaves the clavicle's and forearm's share of the skin's blend
  // near the shoulder and elbow alone; a muscle across the elbow may take both arm bones' shares.
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const Skeleton& sk = c.skeleton;
  // Every muscle attached at both ends to the bone of its region (upper_arm or forearm), but the biceps,
  // which keeps its attachments across the elbow.
  const std::vector<Muscle> muscles = musclesOnTheirRegionBones(a);
  const MuscleRig rig(sk, muscles);
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  const int nb = sk.numBones();
  auto spans = [&](int m, int bone) {
    const int o = sk.find(muscles[m].origin.bone), i = sk.find(muscles[m].insertion.bone);
    const int lo = std::min(o, i), hi = std::max(o, i);  // the arm is one chain: bones lo..hi
    return bone >= lo && bone <= hi;
  };
  int checked = 0, kept = 0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    std::vector<double> skeleton(nb, 0.0), hybrid(nb, 0.0);
    double sum = 0;
    for (int k = 0; k < c.weights.influences(); ++k)
      if (c.weights.joints(v, k) >= 0) skeleton[c.weights.joints(v, k)] += c.weights.weights(v, k), sum += c.weights.weights(v, k);
    std::vector<int> musclesHere;
    for (int k = 0; k < w.influences(); ++k) {
      const int j = w.joints(v, k);
      if (j < 0) continue;
      if (j < nb) hybrid[j] += w.weights(v, k);
      else musclesHere.push_back(rig.jointMuscle()[j - nb]);
    }
    if (musclesHere.empty()) continue;
    for (int b = 0; b < nb; ++b) {
      bool spanned = false;
      for (int m : musclesHere) spanned = spanned || spans(m, b);
      if (spanned || skeleton[b] <= 0) continue;
      ++checked;
      EXPECT_NEAR(hybrid[b], skeleton[b] / sum, 1e-9) << "vertex " << v << " bone " << sk.bones[b].name;
      kept += std::abs(hybrid[b] - skeleton[b] / sum) < 1e-9;
    }
  }
  std::printf("muscle vertices with weight on a bone no muscle there spans: %d, weight kept exactly: %d\n", checked, kept);
  EXPECT_GT(checked, 100) << "the arm's muscles reach skin the skeleton blends with other bones";
}

TEST(HybridWeights, BorderReliefLeavesSkinSharedWithOtherSegmentsToTheSkeleton) {
  // Every muscle on its region's bone (the biceps across the elbow), unsmoothed: with borderRelief 0.1 no muscle
  // weighs on skin that has 10 % or more of its skeleton weight outside the muscle's bones; skin entirely on
  // the bones of the muscles that weigh on it keeps the weights it has without the relief.
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const Skeleton& sk = c.skeleton;
  ASSERT_GE(a.biceps, 0);
  const std::vector<Muscle> muscles = musclesOnTheirRegionBones(a);
  const MuscleRig rig(sk, muscles);
  const int nb = sk.numBones();
  const std::vector<char> twist = twistSplits(sk, c.weights);
  ASSERT_EQ(std::count(twist.begin(), twist.end(), 1), 0);  // no twist splits: a segment is one bone
  // Share of vertex v's skeleton weight outside muscle m's chain (the arm is one chain: bones lo..hi).
  auto outside = [&](int m, int v) {
    const int o = sk.find(muscles[m].origin.bone), i = sk.find(muscles[m].insertion.bone);
    double sum = 0, out = 0;
    for (int k = 0; k < c.weights.influences(); ++k) {
      const int b = c.weights.joints(v, k);
      if (b < 0) continue;
      sum += c.weights.weights(v, k);
      if (b < std::min(o, i) || b > std::max(o, i)) out += c.weights.weights(v, k);
    }
    return sum > 0 ? out / sum : 0.0;
  };
  HybridWeightOptions o;
  o.smoothingIterations = 0;
  o.minWeight = 0.0;
  o.borderRelief = 0.0;
  const SkinWeights off = computeHybridWeights(c.mesh, c.weights, rig, o);
  o.borderRelief = 0.1;
  const SkinWeights on = computeHybridWeights(c.mesh, c.weights, rig, o);
  int borderOff = 0, borderOn = 0, inside = 0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    bool allInside = true;
    for (int m = 0; m < rig.numMuscles(); ++m) {
      const bool border = outside(m, v) >= 0.1;
      if (muscleShare(off, v, nb, rig.jointOffset(m), rig.jointCount(m)) > 0) allInside = allInside && outside(m, v) == 0.0;
      if (!border) continue;
      borderOff += muscleShare(off, v, nb, rig.jointOffset(m), rig.jointCount(m)) > 0;
      borderOn += muscleShare(on, v, nb, rig.jointOffset(m), rig.jointCount(m)) > 0;
    }
    if (allInside && muscleShare(off, v, nb) > 0) {
      ++inside;
      EXPECT_NEAR(muscleShare(on, v, nb), muscleShare(off, v, nb), 1e-12) << "vertex " << v;
    }
  }
  std::printf("border skin with muscle weight: %d without relief, %d with 0.1; skin on the muscles' bones: %d\n",
              borderOff, borderOn, inside);
  EXPECT_GT(borderOff, 20);
  EXPECT_EQ(borderOn, 0);
  EXPECT_GT(inside, 100);
  HybridWeightOptions bad;
  bad.borderRelief = 1.5;
  EXPECT_THROW(computeHybridWeights(c.mesh, c.weights, rig, bad), InputError);
}

TEST(SlideLimits, AreTheDistanceOverWhichTheMusclesWeightRisesAlongTheBone) {
  // A muscle weight rising linearly by wMax over a length l along joint 0's bone (and flat beyond) lets that joint
  // slide towards the bone's head at most l / wMax before the skin folds (1 + o g = 0, g = wMax / l), and
  // unlimited towards its tail (the weight never falls that way); joints that carry no skin get no limit.
  const ArmRig& a = armRig();
  const Character& c = a.character;
  const MuscleRig rig(c.skeleton, a.muscles);
  const int B = c.skeleton.numBones(), V = c.mesh.numVertices();
  const Vec3 axis = rig.slideAxes()[0];
  ASSERT_NEAR(axis.norm(), 1.0, 1e-12);
  double lo = 1e300, hi = -1e300;
  for (int v = 0; v < V; ++v) {
    const double s = c.mesh.vertices.row(v).dot(axis);
    lo = std::min(lo, s), hi = std::max(hi, s);
  }
  const double l = 0.3 * (hi - lo), s0 = lo + 0.3 * (hi - lo), wMax = 0.6;
  SkinWeights w;
  w.joints.resize(V, 2);
  w.weights.resize(V, 2);
  for (int v = 0; v < V; ++v) {
    const double m = wMax * std::clamp((c.mesh.vertices.row(v).dot(axis) - s0) / l, 0.0, 1.0);
    w.joints(v, 0) = 0, w.weights(v, 0) = 1.0 - m;
    w.joints(v, 1) = B + 0, w.weights(v, 1) = m;
  }
  const std::vector<std::array<double, 2>> limits = computeSlideLimits(c.mesh, w, rig);
  ASSERT_EQ(static_cast<int>(limits.size()), rig.numJoints());
  std::printf("joint 0's slide limit towards the head %.4f m, l / wMax %.4f m\n", limits[0][0], l / wMax);
  // A triangle's gradient along the axis is (wMax / l) |P axis|^2 <= wMax / l (P its plane's projection): equal for a
  // triangle the axis lies in, which the arm's tube has nearly.
  EXPECT_GE(limits[0][0], (1 - 1e-9) * l / wMax);
  EXPECT_LT(limits[0][0], 1.05 * l / wMax);
  EXPECT_EQ(limits[0][1], 0.0);
  for (int j = 1; j < rig.numJoints(); ++j) EXPECT_EQ(limits[j][0] + limits[j][1], 0.0) << "joint " << j;
  const std::vector<std::array<double, 2>> half = computeSlideLimits(c.mesh, w, rig, 0.5);
  EXPECT_NEAR(half[0][0], 0.5 * limits[0][0], 1e-12 * l);
  // Bad input: rows that are not the skin's, a margin that is not positive, a joint past the combined joints.
  SkinWeights fewer = w;
  fewer.joints.conservativeResize(V - 1, 2);
  fewer.weights.conservativeResize(V - 1, 2);
  EXPECT_THROW(computeSlideLimits(c.mesh, fewer, rig), InputError);
  EXPECT_THROW(computeSlideLimits(c.mesh, w, rig, 0.0), InputError);
  EXPECT_THROW(computeSlideLimits(c.mesh, w, rig, std::nan("")), InputError);
  SkinWeights past = w;
  past.joints(3, 1) = B + rig.numJoints();
  EXPECT_THROW(computeSlideLimits(c.mesh, past, rig), InputError);
}
