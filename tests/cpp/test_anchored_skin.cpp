// Anchored skin (issue 17): Newton-Raphson closest points, constant-volume ellipsoid muscles, exact rest pose,
// relaxation, bad input; on the synthetic arm and (when ../shared is present) makehuman_muscular_male.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "myoskin/anchored_skin.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "test_support.h"

using namespace myoskin;

namespace {


// ============================================================================
// Brute force: the nearest point of the parametric surface, a dense grid refined by a shrinking pattern search
// ============================================================================

double bruteForceDistance(const Vec3& r, const Vec3& p) {
  auto at = [&](double th, double ph) {
    return Vec3(r[0] * std::sin(th) * std::cos(ph), r[1] * std::sin(th) * std::sin(ph), r[2] * std::cos(th));
  };
  const int nt = 100, np = 200;
  std::vector<std::pair<double, std::pair<double, double>>> seeds;
  for (int i = 0; i <= nt; ++i)
    for (int j = 0; j < np; ++j) {
      const double th = kPi * i / nt, ph = 2 * kPi * j / np;
      seeds.push_back({(at(th, ph) - p).norm(), {th, ph}});
    }
  std::partial_sort(seeds.begin(), seeds.begin() + 6, seeds.end(),
                    [](const auto& a, const auto& b) { return a.first < b.first; });
  double best = seeds[0].first;
  for (int s = 0; s < 6; ++s) {  // several starts: near the medial axis two minima are (almost) equally near
    double th = seeds[s].second.first, ph = seeds[s].second.second, d = seeds[s].first;
    for (double h = kPi / nt; h > 1e-13;) {
      bool moved = false;
      for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b) {
          const double t2 = th + a * h, p2 = ph + b * h;
          const double d2 = (at(t2, p2) - p).norm();
          if (d2 < d) d = d2, th = t2, ph = p2, moved = true;
        }
      if (!moved) h *= 0.5;
    }
    best = std::min(best, d);
  }
  return best;
}

TEST(AnchoredEllipsoid, NewtonMatchesBruteForce) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0), ratio(1.0, 20.0);
  int cases = 0, maxIterations = 0;
  for (int e = 0; e < 9; ++e) {
    // Axis ratios up to 1:20, flat (one short axis) and long (one long axis) ellipsoids among them.
    Vec3 r(1.0, 1.0 / ratio(rng), 1.0 / ratio(rng));
    if (e % 3 == 1) r = Vec3(1.0, 1.0 / 20.0, 1.0 / 20.0);
    if (e % 3 == 2) r = Vec3(1.0 / 20.0, 1.0, 0.7);
    if (e == 0) r = Vec3(0.5, 0.5, 0.5);  // a sphere (three equal axes)
    std::vector<Vec3> points = {Vec3::Zero()};
    for (int a = 0; a < 3; ++a)
      for (double f : {0.0, 0.3, 0.99, 1.5}) {
        Vec3 p = Vec3::Zero();
        p[a] = f * r[a];
        points.push_back(p);
      }
    for (int k = 0; k < 24; ++k) {
      const Vec3 dir(u(rng), u(rng), u(rng));
      const double s = k < 12 ? 0.9 * std::abs(u(rng)) : 1.0 + 2.0 * std::abs(u(rng));  // inside, outside
      points.push_back(s * dir.cwiseProduct(r) / std::max(1e-9, dir.norm()));
    }
    for (const Vec3& p : points) {
      const EllipsoidClosest c = closestPointOnEllipsoid(r, p);
      const double brute = bruteForceDistance(r, p);
      ASSERT_TRUE(c.converged) << "radii " << r.transpose() << " point " << p.transpose();
      EXPECT_LE(c.iterations, 20);
      EXPECT_NEAR(c.distance, brute, 1e-6 * r.maxCoeff()) << "radii " << r.transpose() << " point " << p.transpose();
      EXPECT_NEAR((c.point.array() / r.array()).square().sum(), 1.0, 1e-12);
      maxIterations = std::max(maxIterations, c.iterations);
      ++cases;
    }
  }
  EXPECT_GT(cases, 300);
  std::printf("[ Measured ] %d points, at most %d Newton iterations\n", cases, maxIterations);
}

TEST(AnchoredEllipsoid, BadRadiiAndPoints) {
  EXPECT_NE(test::inputErrorOf([] { closestPointOnEllipsoid(Vec3(1, 0, 1), Vec3(2, 0, 0)); }), "");
  EXPECT_NE(test::inputErrorOf([] { closestPointOnEllipsoid(Vec3(1, NAN, 1), Vec3(2, 0, 0)); }), "");
  EXPECT_NE(test::inputErrorOf([] { closestPointOnEllipsoid(Vec3(1, 1, 1), Vec3(NAN, 0, 0)); }), "");
}

// ============================================================================
// A two-bone chain with one authored ellipsoid muscle
// ============================================================================

Skeleton chain() {
  Skeleton s;
  Bone a;
  a.name = "upper";
  a.head = Vec3(0, 0, 0);
  a.tail = Vec3(1, 0, 0);
  a.rest = boneMatrix(a.head, a.tail, Vec3::UnitZ());
  Bone b;
  b.name = "lower";
  b.parent = 0;
  b.head = Vec3(1, 0, 0);
  b.tail = Vec3(2, 0, 0);
  b.rest = boneMatrix(b.head, b.tail, Vec3::UnitZ());
  s.bones = {a, b};
  return s;
}

TEST(AnchoredComponents, EllipsoidVolumeConstantOverStretch) {
  const Skeleton sk = chain();
  AnchoredComponents comps;
  comps.components.push_back(
      makeEllipsoidMuscle("m", 0, Vec3(0.2, 0.1, 0), 1, Vec3(1.3, 0.1, 0), 0.2, 0.8, 0.1, 0.07, Vec3::UnitZ()));
  // A tiny skin (a triangle round the muscle) so the deformer can be built.
  Mesh skin;
  skin.vertices.resize(3, 3);
  skin.vertices << 0.5, 0.3, 0.0, 0.7, 0.3, 0.1, 0.6, 0.3, -0.1;
  skin.triangles.resize(1, 3);
  skin.triangles << 0, 1, 2;
  SkinWeights w;
  w.joints = IndexMatrix::Zero(3, 1);
  w.weights = WeightMatrix::Ones(3, 1);
  const AnchoredSkin as(skin, w, comps, sk);
  const double v0 = ellipsoidVolume(comps.components[0].radii);
  const double l0 = 1.1;
  int poses = 0;
  for (double stretch = 0.5; stretch <= 2.0 + 1e-9; stretch += 0.125) {
    Pose pose = restPose(sk);
    Mat4 t = Mat4::Identity();
    t(0, 3) = (stretch - 1.0) * l0;  // the insertion's bone slides along the line
    pose.matrices[1] = t * sk.bones[1].rest;
    std::vector<AnchoredComponent> posed;
    as.posedComponents(pose, posed);
    ASSERT_EQ(posed.size(), 1u);
    EXPECT_NEAR(ellipsoidVolume(posed[0].radii) / v0, 1.0, 1e-9) << "stretch " << stretch;
    EXPECT_NEAR(posed[0].radii.y(), stretch * comps.components[0].radii.y(), 1e-12);
    // Placed by the two ratios along the posed line.
    EXPECT_NEAR(posed[0].center.x(), 0.2 + 0.5 * stretch * l0, 1e-12);
    Points out;
    as.evaluate(pose, out);
    EXPECT_TRUE(out.allFinite());
    ++poses;
  }
  EXPECT_EQ(poses, 13);
}

TEST(AnchoredComponents, BadComponents) {
  const Skeleton sk = chain();
  EXPECT_NE(test::inputErrorOf([] {
              makeEllipsoidMuscle("same", 0, Vec3(0.5, 0, 0), 1, Vec3(0.5, 0, 0), 0.2, 0.8, 0.1, 0.1, Vec3::UnitZ());
            }),
            "");
  AnchoredComponents comps;
  comps.components.push_back(
      makeEllipsoidMuscle("m", 0, Vec3(0.2, 0.1, 0), 1, Vec3(1.3, 0.1, 0), 0.2, 0.8, 0.1, 0.07, Vec3::UnitZ()));
  comps.components[0].radii.x() = 0.0;
  const std::string zero = test::inputErrorOf([&] { validateComponents(comps, sk, 2.0); });
  EXPECT_NE(zero.find("radius"), std::string::npos) << zero;
  comps.components[0].radii.x() = 0.1;
  comps.components[0].insertion = comps.components[0].origin;
  EXPECT_NE(test::inputErrorOf([&] { validateComponents(comps, sk, 2.0); }).find("same point"), std::string::npos);
  comps.components[0].insertion = Vec3(1.3, 0.1, 0);
  comps.components[0].bone = 5;
  EXPECT_NE(test::inputErrorOf([&] { validateComponents(comps, sk, 2.0); }), "");
}

// ============================================================================
// The synthetic arm with its extracted muscles
// ============================================================================

struct Arm {
  Character character;
  std::vector<Muscle> muscles;
};

const Arm& arm() {
  static const Arm a = [] {
    Arm r;
    r.character = makeSyntheticArm().character;
    r.muscles = extractMuscles(r.character).muscles;
    return r;
  }();
  return a;
}

Pose elbow(const Skeleton& sk, double degrees) {
  std::vector<Eigen::Quaterniond> q(sk.numBones(), Eigen::Quaterniond::Identity());
  q[sk.find("forearm")] = Eigen::AngleAxisd(degrees * kPi / 180.0, Vec3::UnitX());
  return poseFromLocalRotations(sk, q);
}

TEST(AnchoredSkin, ArmRestExactAndRelaxationMonotone) {
  const Arm& a = arm();
  const Character& c = a.character;
  ASSERT_FALSE(a.muscles.empty());
  const AnchoredComponents comps = deriveComponents(c.skeleton, a.muscles, c.mesh, c.weights);
  int ellipsoids = 0, capsules = 0, spheres = 0;
  for (const auto& k : comps.components) {
    ellipsoids += k.kind == ComponentKind::MuscleEllipsoid;
    capsules += k.kind == ComponentKind::BoneCapsule;
    spheres += k.kind == ComponentKind::JointSphere;
  }
  EXPECT_EQ(ellipsoids, static_cast<int>(a.muscles.size()));
  EXPECT_GE(capsules, 3);
  EXPECT_GE(spheres, 2);
  const AnchoredSkin as(c.mesh, c.weights, comps, c.skeleton);
  const double size = as.report().scale;
  int muscleVertices = 0;
  for (size_t k = 0; k < comps.components.size(); ++k)
    if (comps.components[k].kind == ComponentKind::MuscleEllipsoid) muscleVertices += as.report().verticesPerComponent[k];
  EXPECT_GT(muscleVertices, c.mesh.numVertices() / 20) << "the muscles anchor some of the skin";
  EXPECT_LE(as.report().maxSolverIterations, 20);
  // Rest pose: exact to 1e-6 of the character's size, and the relaxation does nothing there.
  Points out;
  RelaxationTrace trace;
  as.evaluate(restPose(c.skeleton), out, &trace);
  EXPECT_LE((out - c.mesh.vertices).cwiseAbs().maxCoeff(), 1e-6 * size);
  AnchoredSkinOptions noRelax;
  noRelax.relaxIterations = 0;
  const AnchoredSkin plain(c.mesh, c.weights, comps, c.skeleton, noRelax);
  Points unrelaxed;
  plain.evaluate(restPose(c.skeleton), unrelaxed);
  EXPECT_EQ((out - unrelaxed).cwiseAbs().maxCoeff(), 0.0) << "relaxation is a no-op at rest";
  // Bent 90 degrees: finite, and the relaxation's energy never rises (and falls overall).
  as.evaluate(elbow(c.skeleton, 90.0), out, &trace);
  EXPECT_TRUE(out.allFinite());
  ASSERT_GE(trace.energy.size(), 2u);
  for (size_t i = 1; i < trace.energy.size(); ++i) EXPECT_LE(trace.energy[i], trace.energy[i - 1]);
  EXPECT_LT(trace.energy.back(), trace.energy.front());
  // The hand, far from the elbow, moves with the forearm: its skin keeps its distances to the hand bone.
  const Bone& hand = c.skeleton.bones[c.skeleton.find("hand")];
  const Pose bent = elbow(c.skeleton, 90.0);
  const Mat4 t = bent.matrices[c.skeleton.find("hand")] * hand.rest.inverse();
  double worst = 0.0;
  int handVertices = 0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    const Vec3 p = c.mesh.vertices.row(v).transpose();
    if ((p - hand.head).dot((hand.tail - hand.head).normalized()) < 0.3 * hand.length()) continue;
    const Vec3 rigid = t.block<3, 3>(0, 0) * p + t.block<3, 1>(0, 3);
    worst = std::max(worst, (out.row(v).transpose() - rigid).norm());
    ++handVertices;
  }
  ASSERT_GT(handVertices, 100);
  EXPECT_LT(worst, 1e-3 * size);
}

TEST(AnchoredSkin, CylinderMusclesAndThreadsAgree) {
  const Arm& a = arm();
  const Character& c = a.character;
  ComponentOptions co;
  co.muscleCylinders = true;
  const AnchoredComponents comps = deriveComponents(c.skeleton, a.muscles, c.mesh, c.weights, co);
  int cylinders = 0;
  for (const auto& k : comps.components) cylinders += k.kind == ComponentKind::MuscleCylinder;
  EXPECT_EQ(cylinders, static_cast<int>(a.muscles.size()));
  AnchoredSkinOptions one, two;
  one.threads = 1;
  two.threads = 2;
  const AnchoredSkin s1(c.mesh, c.weights, comps, c.skeleton, one), s2(c.mesh, c.weights, comps, c.skeleton, two);
  int onCylinder = 0;
  for (size_t k = 0; k < comps.components.size(); ++k)
    if (comps.components[k].kind == ComponentKind::MuscleCylinder) onCylinder += s1.report().verticesPerComponent[k];
  EXPECT_GT(onCylinder, 0);
  Points rest, p1, p2;
  s1.evaluate(restPose(c.skeleton), rest);
  EXPECT_LE((rest - c.mesh.vertices).cwiseAbs().maxCoeff(), 1e-6 * s1.report().scale);
  s1.evaluate(elbow(c.skeleton, 110.0), p1);
  s2.evaluate(elbow(c.skeleton, 110.0), p2);
  EXPECT_TRUE(p1.allFinite());
  EXPECT_EQ((p1 - p2).cwiseAbs().maxCoeff(), 0.0) << "deterministic whatever the thread count";
  // A cylinder's sections keep the muscle's volume: area scales 1/lambda, lengths lambda.
  std::vector<AnchoredComponent> posed;
  s1.posedComponents(elbow(c.skeleton, 110.0), posed);
  int checked = 0;
  for (size_t k = 0; k < posed.size(); ++k) {
    if (posed[k].kind != ComponentKind::MuscleCylinder || posed[k].sections.size() < 2) continue;
    const auto& r = comps.components[k].sections;
    const auto& q = posed[k].sections;
    const double before = (r.back().z - r.front().z) * r[0].a * r[0].b;
    const double after = (q.back().z - q.front().z) * q[0].a * q[0].b;
    EXPECT_NEAR(after / before, 1.0, 1e-9) << posed[k].name;
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(AnchoredSkin, BadInputGivesErrorsOrDocumentedFallbacks) {
  const Arm& a = arm();
  const Character& c = a.character;
  AnchoredComponents comps = deriveComponents(c.skeleton, a.muscles, c.mesh, c.weights);
  const double size = principalExtent(c.mesh.vertices);
  // A stuffing ellipsoid far outside the skin: nothing anchors to it, nothing breaks.
  AnchoredComponent far;
  far.kind = ComponentKind::Stuffing;
  far.name = "outside";
  far.bone = 0;
  far.center = Vec3(0, 10 * size, 0);
  far.radii = Vec3(0.05, 0.1, 0.05);
  comps.components.push_back(far);
  const AnchoredSkin as(c.mesh, c.weights, comps, c.skeleton);
  EXPECT_EQ(as.report().verticesPerComponent.back(), 0);
  Points out;
  as.evaluate(elbow(c.skeleton, 120.0), out);
  EXPECT_TRUE(out.allFinite());
  // NaN pose, wrong size.
  Pose bad = restPose(c.skeleton);
  bad.matrices[1](0, 3) = NAN;
  EXPECT_NE(test::inputErrorOf([&] { as.evaluate(bad, out); }).find("not finite"), std::string::npos);
  bad.matrices.pop_back();
  EXPECT_NE(test::inputErrorOf([&] { as.evaluate(bad, out); }), "");
  // A muscle whose origin equals its insertion.
  std::vector<Muscle> same = a.muscles;
  same[0].insertion.position = same[0].origin.position;
  EXPECT_NE(test::inputErrorOf([&] { deriveComponents(c.skeleton, same, c.mesh, c.weights); }).find("same point"),
            std::string::npos);
  // No components.
  EXPECT_NE(test::inputErrorOf([&] { AnchoredSkin(c.mesh, c.weights, AnchoredComponents{}, c.skeleton); }), "");
  // A pose that folds a muscle's insertion onto its origin: stretch clamped, output finite.
  Pose fold = restPose(c.skeleton);
  for (int b = 0; b < c.skeleton.numBones(); ++b) fold.matrices[b].block<3, 3>(0, 0).setZero();
  fold = restPose(c.skeleton);
  const int f = c.skeleton.find("forearm");
  Mat4 squash = Mat4::Identity();
  squash.block<3, 1>(0, 3) = c.skeleton.bones[c.skeleton.find("upper_arm")].head - c.skeleton.bones[f].head;
  for (int b = f; b < c.skeleton.numBones(); ++b) fold.matrices[b] = squash * fold.matrices[b];
  as.evaluate(fold, out);
  EXPECT_TRUE(out.allFinite());
}

TEST(AnchoredSkin, EquidistantVertexTakesTheLowerIndex) {
  const Skeleton sk = chain();
  // Two spheres at equal distance from the middle vertex of a strip.
  AnchoredComponents comps;
  for (int i = 0; i < 2; ++i) {
    AnchoredComponent s;
    s.kind = ComponentKind::Stuffing;
    s.name = "s" + std::to_string(i);
    s.bone = i;
    s.center = Vec3(0.5 + i, 0, 0);
    s.radii = Vec3::Constant(0.2);
    comps.components.push_back(s);
  }
  Mesh skin;
  skin.vertices.resize(4, 3);
  skin.vertices << 0.5, 0.5, 0, 1.0, 0.5, 0, 1.5, 0.5, 0, 1.0, 0.5, 0.3;
  skin.triangles.resize(2, 3);
  skin.triangles << 0, 1, 3, 1, 2, 3;
  SkinWeights w;
  w.joints.resize(4, 2);
  w.weights.resize(4, 2);
  w.joints << 0, 1, 0, 1, 0, 1, 0, 1;
  w.weights << 1, 0, 0.5, 0.5, 0, 1, 0.5, 0.5;
  const AnchoredSkin as(skin, w, comps, sk);
  EXPECT_EQ(as.report().vertexComponent[1], 0);
  EXPECT_GE(as.report().ties, 1);
  Points out;
  Pose pose = restPose(sk);
  as.evaluate(pose, out);
  EXPECT_LE((out - skin.vertices).cwiseAbs().maxCoeff(), 1e-12);
}

// ============================================================================
// makehuman_muscular_male
// ============================================================================

TEST(AnchoredSkin, MakeHumanRestExactAndBentFinite) {
  const std::string path = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  MYOSKIN_REQUIRE_SHARED(path);
  LoadOptions lo;
  lo.requireWeights = true;
  const Character c = loadCharacter(path, lo);
  const std::vector<Muscle> muscles = extractMuscles(c).muscles;
  ASSERT_FALSE(muscles.empty());
  const AnchoredComponents comps = deriveComponents(c.skeleton, muscles, c.mesh, c.weights);
  const AnchoredSkin as(c.mesh, c.weights, comps, c.skeleton);
  Points out;
  as.evaluate(restPose(c.skeleton), out);
  const double restError = (out - c.mesh.vertices).cwiseAbs().maxCoeff() / as.report().scale;
  EXPECT_LE(restError, 1e-6);
  std::printf("[ Measured ] makehuman rest pose off by %.2g of the body's size\n", restError);
  std::vector<Eigen::Quaterniond> q(c.skeleton.numBones(), Eigen::Quaterniond::Identity());
  const int fore = c.skeleton.find("lowerarm01.L");
  ASSERT_GE(fore, 0);
  q[fore] = Eigen::AngleAxisd(120.0 * kPi / 180.0, Vec3::UnitX());
  RelaxationTrace trace;
  as.evaluate(poseFromLocalRotations(c.skeleton, q), out, &trace);
  EXPECT_TRUE(out.allFinite());
  ASSERT_GE(trace.energy.size(), 2u);
  for (size_t i = 1; i < trace.energy.size(); ++i) EXPECT_LE(trace.energy[i], trace.energy[i - 1]);
  std::printf("[ Measured ] makehuman: %d components, %d seam vertices, %d fallback, %d ties, %d iterations at most\n",
              as.numComponents(), as.report().seamVertices, as.report().fallbackVertices, as.report().ties,
              as.report().maxSolverIterations);
}

}  // namespace
