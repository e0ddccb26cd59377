// The Equation 3 skinner (against a float64 reference, Blender's weight semantics, threads), skeleton
// transforms, quality measures and PC2 point caches.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "test_support.h"
#include "myoskin/errors.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

// Random skin: #V points in a 1 m box, K slots over J joints (some empty), positive weights.
struct RandomSkin {
  Points rest;
  SkinWeights weights;
  std::vector<Mat4> transforms;
};

RandomSkin randomSkin(int nv, int k, int nj, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RandomSkin s;
  s.rest.resize(nv, 3);
  s.weights.joints.resize(nv, k);
  s.weights.weights.resize(nv, k);
  for (int v = 0; v < nv; ++v) {
    s.rest.row(v) << 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng);
    for (int i = 0; i < k; ++i) {
      const bool empty = u(rng) < -0.6;
      s.weights.joints(v, i) = empty ? -1 : static_cast<int>((u(rng) + 1.0) * 0.5 * (nj - 1) + 0.5);
      s.weights.weights(v, i) = empty ? 0.0 : 0.1 + (u(rng) + 1.0);  // not normalised on purpose
    }
    if (s.weights.joints(v, 0) < 0) s.weights.joints(v, 0) = v % nj;
    s.weights.weights(v, 0) = std::max(s.weights.weights(v, 0), 0.2);
  }
  for (int j = 0; j < nj; ++j) {
    // Rotation, translation and non-uniform scale (muscle joints carry diag(s, lambda, s)).
    const Eigen::Quaterniond q = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    Mat4 m = Mat4::Identity();
    m.block<3, 3>(0, 0) = q.toRotationMatrix() * Eigen::Vector3d(1.0 + 0.3 * u(rng), 1.0 + 0.3 * u(rng), 0.9).asDiagonal();
    m.block<3, 1>(0, 3) << 0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng);
    s.transforms.push_back(m);
  }
  return s;
}

// Float64 Equation 3 with Blender's semantics (normalise; sum <= 1e-4 stays at rest).
Points reference(const Points& rest, const SkinWeights& w, const std::vector<Mat4>& transforms) {
  Points out = rest;
  for (Eigen::Index v = 0; v < rest.rows(); ++v) {
    Vec3 p = Vec3::Zero();
    double total = 0;
    for (int k = 0; k < w.influences(); ++k) {
      const int j = w.joints(v, k);
      if (j < 0) continue;
      p += w.weights(v, k) * (transforms[j] * rest.row(v).transpose().homogeneous()).head<3>();
      total += w.weights(v, k);
    }
    if (total > 1e-4) out.row(v) = p.transpose() / total;
  }
  return out;
}


}  // namespace

// ============================================================================
// Skinner
// ============================================================================

TEST(Skinner, MatchesFloat64ReferenceWithNonUniformScaleUpTo8Influences) {
  for (int k : {1, 4, 8, 11}) {
    const RandomSkin s = randomSkin(5000, k, 37, 7 + k);
    const Skinner skinner(s.rest, s.weights, 37);
    Points out;
    skinner.deform(s.transforms, out);
    const double err = (out - reference(s.rest, s.weights, s.transforms)).cwiseAbs().maxCoeff();
    EXPECT_LT(err, 2e-6) << "K = " << k;  // float32 arithmetic on a 1 m skin
    EXPECT_LE(skinner.influences(), k);
  }
}

TEST(Skinner, OneAndTwoThreadsAndAnyGrainGiveIdenticalResults) {
  const RandomSkin s = randomSkin(20000, 4, 60, 3);
  Skinner skinner(s.rest, s.weights, 60, {256, 1});
  PointsF one, two, coarse;
  skinner.deform(s.transforms, one);
  skinner.setOptions({256, 2});
  skinner.deform(s.transforms, two);
  skinner.setOptions({100000, 0});
  skinner.deform(s.transforms, coarse);
  EXPECT_EQ((one - two).cwiseAbs().maxCoeff(), 0.0f);
  EXPECT_EQ((one - coarse).cwiseAbs().maxCoeff(), 0.0f);
}

TEST(Skinner, NormalisesAtDeformTimeAndKeepsTinyWeightSumsAtRest) {
  RandomSkin s = randomSkin(100, 3, 5, 11);
  SkinWeights scaled = s.weights;
  scaled.weights *= 3.7;
  // Vertex 0: weight sum exactly at the threshold -> rest; vertex 1: just above -> fully deformed.
  scaled.weights.row(0).setZero();
  scaled.weights(0, 0) = 1e-4;
  scaled.joints(0, 0) = 2;
  scaled.weights.row(1).setZero();
  scaled.weights(1, 0) = 2e-4;
  scaled.joints(1, 0) = 2;
  // Vertex 2: no influence at all.
  scaled.joints.row(2).setConstant(-1);
  scaled.weights.row(2).setZero();
  const Skinner skinner(s.rest, scaled, 5);
  EXPECT_EQ(skinner.restVertices(), 2);
  Points out;
  skinner.deform(s.transforms, out);
  EXPECT_LT((out - reference(s.rest, scaled, s.transforms)).cwiseAbs().maxCoeff(), 2e-6);
  EXPECT_LT((out.row(0) - s.rest.row(0)).norm(), 1e-7);
  EXPECT_LT((out.row(2) - s.rest.row(2)).norm(), 1e-7);
  const Vec3 moved = (s.transforms[2] * s.rest.row(1).transpose().homogeneous()).head<3>();
  EXPECT_LT((out.row(1).transpose() - moved).norm(), 1e-6);
  // The normalised input gives the same result.
  Points unscaled;
  Skinner(s.rest, s.weights, 5).deform(s.transforms, unscaled);
  for (int v = 3; v < 100; ++v) EXPECT_LT((unscaled.row(v) - out.row(v)).norm(), 1e-6);
}

TEST(Skinner, RestPoseOfTheSyntheticArmReproducesTheSkin) {
  const SyntheticCharacter arm = makeSyntheticArm();
  const Character& c = arm.character;
  std::vector<Mat4> transforms;
  skeletonTransforms(c.skeleton, restPose(c.skeleton), transforms);
  const Skinner skinner(c.mesh.vertices, c.weights, c.skeleton.numBones());
  Points out;
  skinner.deform(transforms, out);
  EXPECT_LT((out - c.mesh.vertices).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(Skinner, BadInputNamesTheVertexAndSlot) {
  const RandomSkin s = randomSkin(50, 4, 6, 5);
  SkinWeights w = s.weights;
  w.weights(17, 2) = -0.5;
  w.joints(17, 2) = 1;
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, w, 6); }).find("vertex 17 slot 2 has a negative weight"), std::string::npos);
  w = s.weights;
  w.weights(23, 1) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, w, 6); }).find("vertex 23 slot 1 has a NaN"), std::string::npos);
  w = s.weights;
  w.joints(31, 3) = 6;
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, w, 6); }).find("vertex 31 slot 3 uses joint 6, outside 0..5"),
            std::string::npos);
  w = s.weights;
  w.joints(31, 3) = -2;
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, w, 6); }).find("uses joint -2"), std::string::npos);
  w = s.weights;
  w.weights.conservativeResize(49, 4);
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, w, 6); }).find("weights are 49 by 4"), std::string::npos);
  w = s.weights;
  w.joints.conservativeResize(49, 4);
  w.weights.conservativeResize(49, 4);
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, w, 6); }).find("49 weight rows for 50 vertices"), std::string::npos);
  Points nanRest = s.rest;
  nanRest(4, 1) = INFINITY;
  EXPECT_NE(test::inputErrorOf([&] { Skinner(nanRest, s.weights, 6); }).find("vertex 4"), std::string::npos);
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, s.weights, 0); }).find("at least one joint"), std::string::npos);
  // Strict mode: rows must sum to 1.
  SkinWeights unit = s.weights;
  for (int v = 0; v < 50; ++v) unit.weights.row(v) /= unit.weights.row(v).sum();
  SkinnerOptions strict;
  strict.sumTolerance = 1e-6;
  EXPECT_EQ(test::inputErrorOf([&] { Skinner(s.rest, unit, 6, strict); }), "");
  unit.weights(12, 0) += 0.25;
  EXPECT_NE(test::inputErrorOf([&] { Skinner(s.rest, unit, 6, strict); }).find("vertex 12 weights sum to 1.25"),
            std::string::npos);
  EXPECT_EQ(test::inputErrorOf([&] { Skinner(s.rest, unit, 6); }), "");  // Blender semantics: normalised
  const Skinner skinner(s.rest, s.weights, 6);
  Points out;
  std::vector<Mat4> few(s.transforms.begin(), s.transforms.begin() + 5);
  EXPECT_NE(test::inputErrorOf([&] { skinner.deform(few, out); }).find("5 transforms for 6 joints"), std::string::npos);
  std::vector<Mat4> bad = s.transforms;
  bad[3](1, 2) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { skinner.deform(bad, out); }).find("transform 3"), std::string::npos);
}

TEST(SkeletonTransforms, PoseTimesInverseRestAndBadPoses) {
  const SyntheticCharacter arm = makeSyntheticArm();
  const Skeleton& sk = arm.character.skeleton;
  std::vector<Eigen::Quaterniond> rot(sk.numBones(), Eigen::Quaterniond::Identity());
  rot[2] = Eigen::AngleAxisd(1.0, Vec3::UnitX());
  const Pose pose = poseFromLocalRotations(sk, rot);
  std::vector<Mat4> t;
  skeletonTransforms(sk, pose, t);
  ASSERT_EQ(static_cast<int>(t.size()), sk.numBones());
  for (int b = 0; b < sk.numBones(); ++b) EXPECT_LT((t[b] * sk.bones[b].rest - pose.matrices[b]).norm(), 1e-12);
  Pose shortPose = pose;
  shortPose.matrices.pop_back();
  EXPECT_NE(test::inputErrorOf([&] { skeletonTransforms(sk, shortPose, t); }).find("matrices for"), std::string::npos);
  Pose nanPose = pose;
  nanPose.matrices[1](0, 0) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { skeletonTransforms(sk, nanPose, t); }).find("bone 1"), std::string::npos);
}

// ============================================================================
// Quality measures
// ============================================================================

TEST(SkinQuality, RegionVolumesAddUpAndFollowRigidMotion) {
  const SyntheticCharacter arm = makeSyntheticArm();
  const Character& c = arm.character;
  // Label each vertex with its strongest bone.
  IndexVector labels(c.mesh.numVertices());
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    Eigen::Index k;
    c.weights.weights.row(v).maxCoeff(&k);
    labels[v] = c.weights.joints(v, k);
  }
  const int nb = c.skeleton.numBones();
  IndexVector all = IndexVector::Zero(c.mesh.numVertices());
  const double whole = enclosedVolume(c.mesh.vertices, c.mesh.triangles);
  EXPECT_NEAR(regionVolumes(c.mesh.vertices, c.mesh.triangles, all, 1)[0], whole, 1e-12);
  // A rigid motion of the whole skin changes no region's volume and gives no bulge.
  Mat4 rigid = Mat4::Identity();
  rigid.block<3, 3>(0, 0) = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  rigid.block<3, 1>(0, 3) = Vec3(0.3, -0.2, 1.0);
  Points moved(c.mesh.numVertices(), 3);
  for (int v = 0; v < c.mesh.numVertices(); ++v)
    moved.row(v) = (rigid * c.mesh.vertices.row(v).transpose().homogeneous()).head<3>().transpose();
  ASSERT_EQ(regionVolumeChange(c.mesh.vertices, moved, c.mesh.triangles, labels, nb).size(), static_cast<size_t>(nb));
  for (double change : regionVolumeChange(c.mesh.vertices, moved, c.mesh.triangles, labels, nb))
    EXPECT_NEAR(change, 0.0, 1e-9);
  const Eigen::VectorXd bulge =
      localBulge(c.mesh.vertices, c.mesh.triangles, moved, c.weights, std::vector<Mat4>(nb, rigid));
  EXPECT_LT(bulge.cwiseAbs().maxCoeff(), 1e-12);
  // Pushing every vertex 1 mm along its normal: bulge 1 mm, volume grows.
  const Points n = vertexNormals(c.mesh.vertices, c.mesh.triangles);
  const Points pushed = c.mesh.vertices + 1e-3 * n;
  const Eigen::VectorXd b2 =
      localBulge(c.mesh.vertices, c.mesh.triangles, pushed, c.weights, std::vector<Mat4>(nb, Mat4::Identity()));
  EXPECT_NEAR(b2.minCoeff(), 1e-3, 1e-12);
  EXPECT_NEAR(b2.maxCoeff(), 1e-3, 1e-12);
  for (double change : regionVolumeChange(c.mesh.vertices, pushed, c.mesh.triangles, labels, nb))
    EXPECT_GT(change, 0.0);
  EXPECT_NE(test::inputErrorOf([&] { regionVolumes(c.mesh.vertices, c.mesh.triangles, IndexVector::Zero(3), 1); }).find("3 labels"),
            std::string::npos);
  IndexVector badLabel = all;
  badLabel[9] = 4;
  EXPECT_NE(test::inputErrorOf([&] { regionVolumes(c.mesh.vertices, c.mesh.triangles, badLabel, 2); }).find("vertex 9"),
            std::string::npos);
}

TEST(SkinQuality, SelfIntersectionsCountCrossingPairsNotNeighbours) {
  // The synthetic arm's closed skin: no pair crosses; neighbours share vertices and edges without counting.
  const Character c = makeSyntheticArm().character;
  EXPECT_EQ(selfIntersections(c.mesh.vertices, c.mesh.triangles), 0);
  // Independent answer: a square of two triangles, and a third triangle that pierces one of them (1 pair), then
  // both (2 pairs); a fourth far away adds none.
  Points v(10, 3);
  v << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,   // square in z = 0, triangles (0 1 2) and (0 2 3)
      0.6, 0.2, -1, 0.6, 0.2, 1, 0.9, 0.1, 0,  // vertical triangle through (0 1 2) only
      5, 5, 5, 6, 5, 5, 5, 6, 5;
  Triangles t(4, 3);
  t << 0, 1, 2, 0, 2, 3, 4, 5, 6, 7, 8, 9;
  EXPECT_EQ(selfIntersections(v, t), 1);
  v.row(6) << 0.2, 0.8, 0;  // now it also reaches across the diagonal into (0 2 3)
  EXPECT_EQ(selfIntersections(v, t), 2);
  // The pairs themselves, as rows of t (smaller first, sorted): the piercing triangle 2 with each half of the square.
  const std::vector<std::pair<int, int>> pairs = selfIntersectingPairs(v, t);
  EXPECT_EQ(pairs, (std::vector<std::pair<int, int>>{{0, 2}, {1, 2}}));
  EXPECT_EQ(selfIntersectingPairs(v, t, {0, 1, 1, 1}), (std::vector<std::pair<int, int>>{{1, 2}}));  // rows kept
  // One test made once, the points moved between calls (a fit's trials): the same answers as the one-shot calls.
  SelfIntersectionTest test(t, v.rows());
  EXPECT_EQ(test.pairs(v), pairs);
  Points back = v;
  back.row(6) << 0.9, 0.1, 0;  // through (0 1 2) only again
  EXPECT_EQ(test.pairs(back), selfIntersectingPairs(back, t));
  EXPECT_EQ(test.pairs(back).size(), 1u);
  EXPECT_EQ(test.pairs(v), pairs);
  EXPECT_NE(test::inputErrorOf([&] { test.pairs(v.topRows(9)); }).find("9 vertices"), std::string::npos);
  EXPECT_EQ(selfIntersections(v, t, {1, 1, 0, 1}), 0);  // masked out: tested only among the masked
  // A fold: the arm's skin with one end pushed through the rest counts crossings.
  Points folded = c.mesh.vertices;
  for (int i = 0; i < folded.rows(); ++i)
    if (folded(i, 0) > 0.5) folded(i, 0) = 1.0 - folded(i, 0);  // mirror the far part back over x = 0.5
  EXPECT_GT(selfIntersections(folded, c.mesh.triangles), 0);
  EXPECT_NE(test::inputErrorOf([&] { selfIntersections(v, t, {1, 0}); }).find("2 entries"), std::string::npos);
  EXPECT_NE(test::inputErrorOf([&] { test.pairs(v, {1, 0}); }).find("2 entries"), std::string::npos);
  Points bad = v;
  bad(3, 1) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { selfIntersections(bad, t); }).find("finite"), std::string::npos);
}

TEST(SkinQuality, SelfIntersectionsWithAFocusAreThePairsThatHaveAFocusTriangle) {
  // Independent answer: the whole test's pairs, kept where one triangle is in the focus. On the synthetic arm folded
  // back over itself (thousands of crossings), with foci of several sizes: a slab across the fold, every third
  // triangle, one triangle, none; a stretched sliver spanning the arm and a collinear triangle are in the focus too.
  const Character c = makeSyntheticArm().character;
  Points folded = c.mesh.vertices;
  for (int i = 0; i < folded.rows(); ++i)
    if (folded(i, 0) > 0.5) folded(i, 0) = 1.0 - folded(i, 0);
  const Triangles& t = c.mesh.triangles;
  const Eigen::Index nf = t.rows();
  Points stretched = folded;
  stretched.row(t(7, 0)) = folded.row(t(nf / 2, 0));  // triangle 7 now reaches across the arm's length
  const Eigen::Index flat = nf / 3;  // a triangle with two corners at one point: a pair with itself
  stretched.row(t(flat, 2)) = stretched.row(t(flat, 0));
  SelfIntersectionTest test(t, folded.rows());
  size_t checkedPairs = 0;
  for (const Points* p : {&folded, &stretched}) {
    const std::vector<std::pair<int, int>> all = test.pairs(*p);
    ASSERT_GT(all.size(), 100u);
    if (p == &stretched) {  // the sliver crosses the skin and the collinear triangle is a pair with itself
      EXPECT_GT(std::count_if(all.begin(), all.end(), [](const auto& pr) { return pr.first == 7 || pr.second == 7; }), 2);
      EXPECT_TRUE(std::binary_search(all.begin(), all.end(), std::make_pair(int(flat), int(flat))));
    }
    std::vector<std::vector<char>> foci(4, std::vector<char>(static_cast<size_t>(nf), 0));
    for (Eigen::Index f = 0; f < nf; ++f) {
      const double x = (*p)(t(f, 0), 0);
      foci[0][static_cast<size_t>(f)] = x > 0.35 && x < 0.45;
      foci[1][static_cast<size_t>(f)] = f % 3 == 0;
    }
    foci[2][7] = 1;
    foci[0][7] = foci[0][static_cast<size_t>(flat)] = 1;
    for (const std::vector<char>& focus : foci) {
      std::vector<std::pair<int, int>> expected;
      for (const auto& pr : all)
        if (focus[static_cast<size_t>(pr.first)] || focus[static_cast<size_t>(pr.second)]) expected.push_back(pr);
      EXPECT_EQ(test.pairs(*p, focus), expected);
      checkedPairs += expected.size();
    }
  }
  EXPECT_GT(checkedPairs, 1000u);
  // Coordinates whose span passes the double range (no grid fits them): the same answer, from the whole test.
  Points v(9, 3);
  v << 0, 0, 0, 1, 0, 0, 1, 1, 0,  // a triangle in z = 0
      0.6, 0.2, -1, 0.6, 0.2, 1, 0.9, 0.1, 0,  // one through it
      -1e308, 0.5, 0.5, 1e308, 0.5, 0.5, 0.0, 0.5, -0.5;  // one across everything, through both
  Triangles t3(3, 3);
  t3 << 0, 1, 2, 3, 4, 5, 6, 7, 8;
  SelfIntersectionTest small(t3, v.rows());
  const std::vector<std::pair<int, int>> whole = small.pairs(v);
  EXPECT_EQ(whole, (std::vector<std::pair<int, int>>{{0, 1}, {0, 2}}));
  EXPECT_EQ(small.pairs(v, {0, 0, 1}), (std::vector<std::pair<int, int>>{{0, 2}}));  // past the grid
  EXPECT_EQ(small.pairs(v, {1, 0, 0}), whole);  // the grid, the wide triangle against every box
}

// ============================================================================
// PC2
// ============================================================================

TEST(PointCache, WriteReadRoundTripAndBadFiles) {
  const auto dir = std::filesystem::temp_directory_path() / "myoskin_test_pc2";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "cache.pc2").string();
  std::vector<PointsF> frames;
  for (int f = 0; f < 3; ++f) {
    PointsF p(7, 3);
    for (int i = 0; i < 7; ++i) p.row(i) << f + 0.5f * i, -1.0f * i, 0.25f * f;
    frames.push_back(p);
  }
  writePC2(path, frames, 10.0f, 1.0f);
  EXPECT_EQ(std::filesystem::file_size(path), 32u + 3u * 7u * 12u);
  const PointCache c = readPC2(path);
  EXPECT_EQ(c.numPoints, 7);
  EXPECT_EQ(c.startFrame, 10.0f);
  EXPECT_EQ(c.sampleRate, 1.0f);
  ASSERT_EQ(c.frames.size(), 3u);
  for (int f = 0; f < 3; ++f) EXPECT_EQ((c.frames[f] - frames[f]).cwiseAbs().maxCoeff(), 0.0f);
  // Truncated file, wrong signature, wrong frame size, NaN frame, missing file.
  std::filesystem::resize_file(path, 32 + 7 * 12 + 5);
  EXPECT_NE(test::inputErrorOf([&] { readPC2(path); }).find("header promises"), std::string::npos);
  { std::ofstream(path, std::ios::binary) << "NOTACACHE000000000000000000000000000"; }
  EXPECT_NE(test::inputErrorOf([&] { readPC2(path); }).find("not a PC2 file"), std::string::npos);
  EXPECT_NE(test::inputErrorOf([&] { readPC2((dir / "missing.pc2").string()); }).find("cannot open"), std::string::npos);
  PC2Writer w(path, 7);
  EXPECT_NE(test::inputErrorOf([&] { w.writeFrame(PointsF(PointsF::Zero(6, 3))); }).find("has 6 points"), std::string::npos);
  PointsF nan = frames[0];
  nan(2, 1) = std::nanf("");
  EXPECT_NE(test::inputErrorOf([&] { w.writeFrame(nan); }).find("point 2"), std::string::npos);
  w.writeFrame(frames[1]);
  w.close();
  EXPECT_EQ(readPC2(path).frames.size(), 1u);
  std::filesystem::remove_all(dir);
}

TEST(Skinner, PortableKernelGivesTheSameResultAsTheVectorKernel) {
  const RandomSkin s = randomSkin(3000, 8, 20, 21);
  const Skinner skinner(s.rest, s.weights, 20);
  PointsF fast, portable;
  skinner.deform(s.transforms, fast);
  setenv("MYOSKIN_SCALAR_SKINNING", "1", 1);
  skinner.deform(s.transforms, portable);
  unsetenv("MYOSKIN_SCALAR_SKINNING");
  EXPECT_LT((fast - portable).cwiseAbs().maxCoeff(), 1e-6f);
  Points ref = reference(s.rest, s.weights, s.transforms);
  EXPECT_LT((portable.cast<double>() - ref).cwiseAbs().maxCoeff(), 2e-6);
}
