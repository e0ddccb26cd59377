// Pose-space correctives on the synthetic arm: the per-vertex affine maps equal the skinner, a sculpt mapped back
// to rest space reproduces itself when re-skinned (linear, Preserve Volume with the muscle joints, both of
// Blender's dual-quaternion scale modes), the radial basis functions are exact at their poses, 0 at rest and beyond
// the falloff, smooth in between, and bad input is refused.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "myoskin/correctives.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"
#include "test_support.h"

using namespace myoskin;

namespace {

constexpr double kDeg = M_PI / 180.0;

double maxDiff(const Points& a, const Points& b) { return (a - b).rowwise().norm().maxCoeff(); }

double sizeOf(const Points& v) { return (v.colwise().maxCoeff() - v.colwise().minCoeff()).norm(); }

// The arm, its muscles as joints and combined weights, built once for every test.
struct Arm {
  Character c;
  MuscleRig rig;
  SkinWeights hybrid;
  std::vector<Mat4> rest;
  double size;
  Arm()
      : c(makeSyntheticArm().character),
        rig(c.skeleton, extractMuscles(c).muscles),
        hybrid(computeHybridWeights(c.mesh, c.weights, rig)),
        rest(combinedRestMatrices(c.skeleton, rig)),
        size(sizeOf(c.mesh.vertices)) {}
};

const Arm& arm() {
  static const Arm a;
  return a;
}

// Local rotations: bone name -> angle about an axis (the rest of the skeleton at rest).
Pose posed(const Skeleton& s, std::initializer_list<std::tuple<const char*, double, Vec3>> bones) {
  std::vector<Eigen::Quaterniond> q(s.numBones(), Eigen::Quaterniond::Identity());
  for (const auto& [name, degrees, axis] : bones) q[s.find(name)] = Eigen::AngleAxisd(degrees * kDeg, axis.normalized());
  return poseFromLocalRotations(s, q);
}

std::vector<Mat4> transformsOf(const Arm& a, const Pose& pose) {
  MuscleRigState state = a.rig.makeState();
  a.rig.evaluate(pose, state);
  std::vector<Mat4> t;
  skinningTransforms(a.c.skeleton, pose, a.rig, state, t);
  return t;
}

// The three ways Blender skins a bound mesh: linear, Preserve Volume as 4.x/5.x and as 3.x.
struct Mode {
  const char* name;
  SkinnerOptions options;
};

std::vector<Mode> modes(const Arm& a) {
  SkinnerOptions pivot, blended;
  pivot.preserveVolume = blended.preserveVolume = true;
  pivot.jointRest = blended.jointRest = a.rest;
  blended.dualQuatScale = DualQuatScale::Blended;
  return {{"linear", {}}, {"preserve volume (pivot)", pivot}, {"preserve volume (blended)", blended}};
}

// A sculpted fix on the posed skin: a smooth bulge of `amplitude` (of the size) round the point nearest
// `center`, along the skin's posed position away from the centroid of the region.
Points sculptOn(const Points& posedSkin, const Vec3& center, double radius, double amplitude, double size) {
  Points out = posedSkin;
  for (Eigen::Index v = 0; v < out.rows(); ++v) {
    const Vec3 p = posedSkin.row(v).transpose();
    const double d = (p - center).norm() / radius;
    if (d >= 1.0) continue;
    const double f = std::pow(1.0 - d * d, 3);
    out.row(v) += (amplitude * size * f * Vec3(0.3, 0.2, 1.0).normalized()).transpose();
  }
  return out;
}

// The skin under `transforms` with the offsets applied to the skinner's input.
Points reskin(const Points& input, const SkinWeights& w, const std::vector<Mat4>& t, const SkinnerOptions& o) {
  const Skinner s(input, w, static_cast<int>(t.size()), o);
  Points out;
  s.deform(t, out);
  return out;
}

Vec3 elbowOf(const Arm& a) { return a.c.skeleton.bones[a.c.skeleton.find("forearm")].head; }

}  // namespace

TEST(Correctives, VertexTransformsAreTheSkinnersAffineMapInEveryMode) {
  const Arm& a = arm();
  const Pose pose = posed(a.c.skeleton, {{"upper_arm", 50.0, Vec3(0, 0, 1)}, {"forearm", 120.0, Vec3(1, 0, 0)}});
  const std::vector<Mat4> t = transformsOf(a, pose);
  for (const Mode& m : modes(a)) {
    const Skinner s(a.c.mesh.vertices, a.hybrid, static_cast<int>(t.size()), m.options);
    VertexTransforms affine;
    s.vertexTransforms(t, affine);
    ASSERT_EQ(affine.rows(), a.c.mesh.vertices.rows());
    // the map at the rest positions is the deform, and at shifted positions the deform of the shifted skin
    Points shift = Points::Random(a.c.mesh.vertices.rows(), 3) * (0.02 * a.size);
    const Points moved = a.c.mesh.vertices + shift;
    Points atRest(moved.rows(), 3), atMoved(moved.rows(), 3);
    for (Eigen::Index v = 0; v < moved.rows(); ++v) {
      const Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> m34(affine.row(v).data());
      atRest.row(v) = (m34.leftCols<3>() * a.c.mesh.vertices.row(v).transpose() + m34.col(3)).transpose();
      atMoved.row(v) = (m34.leftCols<3>() * moved.row(v).transpose() + m34.col(3)).transpose();
    }
    Points deformed;
    s.deform(t, deformed);
    const double e0 = maxDiff(atRest, deformed) / a.size;
    const double e1 = maxDiff(atMoved, reskin(moved, a.hybrid, t, m.options)) / a.size;
    std::printf("%s: affine map vs deform %.2e, vs deform of the shifted skin %.2e of the size\n", m.name, e0, e1);
    EXPECT_LT(e0, 1e-6) << m.name;
    EXPECT_LT(e1, 1e-6) << m.name;
  }
}

TEST(Correctives, OneSculptIsReproducedAtItsPoseAndNothingChangesAtRestOrBeyondTheFalloff) {
  const Arm& a = arm();
  const Skeleton& sk = a.c.skeleton;
  const int forearm = sk.find("forearm");
  const Pose pose = posed(sk, {{"forearm", 100.0, Vec3(1, 0, 0)}});
  const std::vector<Mat4> t = transformsOf(a, pose);
  for (const Mode& m : modes(a)) {
    const Skinner s(a.c.mesh.vertices, a.hybrid, static_cast<int>(t.size()), m.options);
    Points posedSkin;
    s.deform(t, posedSkin);
    const Points sculpt = sculptOn(posedSkin, (pose.matrices[forearm] * sk.bones[forearm].rest.inverse() *
                                               elbowOf(a).homogeneous()).head<3>(),
                                   0.15 * a.size, 0.02, a.size);
    ASSERT_GT(maxDiff(sculpt, posedSkin), 0.015 * a.size);
    const Points offsets = restSpaceOffsets(s, t, a.c.mesh.vertices, sculpt);
    const CorrectiveDrivers drivers({{"elbow", forearm, boneDirection(boneLocalRotation(sk, pose, forearm)), 0.0}});
    ASSERT_EQ(drivers.bones().size(), 1u);
    EXPECT_EQ(drivers.bones()[0].kernels.size(), 2u);
    std::vector<Eigen::Quaterniond> q;
    Eigen::VectorXd w;
    Points input;
    // at the sculpted pose: weight 1, the sculpt to 1e-6 of the size
    boneLocalRotations(sk, pose, q);
    drivers.weights(q, w);
    EXPECT_NEAR(w[0], 1.0, 1e-12);
    applyCorrectives(a.c.mesh.vertices, {offsets}, w, input);
    const double err = maxDiff(reskin(input, a.hybrid, t, m.options), sculpt) / a.size;
    std::printf("%s: sculpt reproduced to %.2e of the size (sculpt moves the skin up to %.3f of it)\n", m.name, err,
                maxDiff(sculpt, posedSkin) / a.size);
    EXPECT_LT(err, 1e-6) << m.name;
    // at rest: weight exactly 0, the rest skin exactly
    boneLocalRotations(sk, restPose(sk), q);
    drivers.weights(q, w);
    EXPECT_EQ(w[0], 0.0);
    applyCorrectives(a.c.mesh.vertices, {offsets}, w, input);
    EXPECT_EQ(maxDiff(input, a.c.mesh.vertices), 0.0);
    // beyond the falloff (60 degrees from the pose and from rest): exactly 0
    for (const Pose& far : {posed(sk, {{"forearm", -100.0, Vec3(1, 0, 0)}}), posed(sk, {{"forearm", 90.0, Vec3(0, 0, 1)}})}) {
      boneLocalRotations(sk, far, q);
      drivers.weights(q, w);
      EXPECT_EQ(w[0], 0.0);
    }
    // the parent moved, the bone's own pose the sculpted one: relative to its parent, so still 1
    boneLocalRotations(sk, posed(sk, {{"forearm", 100.0, Vec3(1, 0, 0)}, {"upper_arm", 80.0, Vec3(0, 0, 1)}}), q);
    drivers.weights(q, w);
    EXPECT_NEAR(w[0], 1.0, 1e-12);
  }
}

TEST(Correctives, WeightIsContinuousWithABoundedDerivativeAlongABend) {
  const Arm& a = arm();
  const Skeleton& sk = a.c.skeleton;
  const int forearm = sk.find("forearm");
  const double falloff = 50.0 * kDeg;
  const CorrectiveDrivers drivers(
      {{"elbow", forearm, boneDirection(boneLocalRotation(sk, posed(sk, {{"forearm", 90.0, Vec3(1, 0, 0)}}), forearm)),
        falloff}});
  const BoneCorrectiveRbf& rbf = drivers.bones()[0];
  double coefficientSum = 0.0;
  for (Eigen::Index j = 0; j < rbf.coefficients.rows(); ++j) coefficientSum += std::abs(rbf.coefficients(j, 0));
  // |d phi / d angle| <= 3 / (2 sin^2(falloff / 2)) for each kernel (s = sin^2(angle / 2), |ds/dangle| <= 1/2)
  const double bound = coefficientSum * 1.5 / std::pow(std::sin(0.5 * falloff), 2);
  std::vector<Eigen::Quaterniond> q(sk.numBones(), Eigen::Quaterniond::Identity());
  Eigen::VectorXd w;
  const double step = 0.01 * kDeg;
  double previous = 0.0, steepest = 0.0, largestJump = 0.0;
  int nonZero = 0;
  for (int i = 0; i <= 18000; ++i) {
    q[forearm] = Eigen::AngleAxisd(i * step, Vec3::UnitX());
    drivers.weights(q, w);
    if (i > 0) {
      steepest = std::max(steepest, std::abs(w[0] - previous) / step);
      largestJump = std::max(largestJump, std::abs(w[0] - previous));
    }
    if (w[0] != 0.0) ++nonZero;
    if (i == 9000) EXPECT_NEAR(w[0], 1.0, 1e-12);
    if (i * step < 90.0 * kDeg - falloff - 1e-9 || i * step > 90.0 * kDeg + falloff + 1e-9) EXPECT_EQ(w[0], 0.0) << i;
    previous = w[0];
  }
  std::printf("elbow 0-180 degrees in 0.01-degree steps: largest step %.2e, steepest slope %.3f per radian (bound %.3f)\n",
              largestJump, steepest, bound);
  EXPECT_GT(nonZero, 9000);  // non-zero over the falloff's 100 degrees
  EXPECT_LE(steepest, bound);
  EXPECT_LT(largestJump, bound * step * 1.0001);
}

TEST(Correctives, SeveralPosesPerBoneAreEachReproducedAndRestStaysRest) {
  const Arm& a = arm();
  const Skeleton& sk = a.c.skeleton;
  const int forearm = sk.find("forearm"), upper = sk.find("upper_arm");
  struct Sculpted {
    const char* name;
    int bone;
    Pose pose;
  };
  // two elbow poses whose kernels overlap (60 and 110 degrees, falloff 80), and the shoulder raised with the
  // elbow at its first pose (so the elbow's corrective is on when the shoulder's is sculpted)
  const std::vector<Sculpted> sculpted = {
      {"elbow_60", forearm, posed(sk, {{"forearm", 60.0, Vec3(1, 0, 0)}})},
      {"elbow_110", forearm, posed(sk, {{"forearm", 110.0, Vec3(1, 0, 0)}})},
      {"shoulder_70", upper, posed(sk, {{"upper_arm", 70.0, Vec3(0, 0, 1)}, {"forearm", 60.0, Vec3(1, 0, 0)}})}};
  CorrectiveOptions options;
  options.falloff = 80.0 * kDeg;
  for (const Mode& m : modes(a)) {
    std::vector<CorrectivePose> poses;
    std::vector<Points> offsets, sculpts;
    std::vector<Eigen::Quaterniond> q;
    Eigen::VectorXd w;
    Points input;
    for (const Sculpted& s : sculpted) {
      const std::vector<Mat4> t = transformsOf(a, s.pose);
      const Skinner skinner(a.c.mesh.vertices, a.hybrid, static_cast<int>(t.size()), m.options);
      poses.push_back({s.name, s.bone, boneDirection(boneLocalRotation(sk, s.pose, s.bone)), 0.0});
      offsets.push_back(Points::Zero(a.c.mesh.vertices.rows(), 3));
      const CorrectiveDrivers drivers(poses, options);
      boneLocalRotations(sk, s.pose, q);
      drivers.weights(q, w);
      applyCorrectives(a.c.mesh.vertices, offsets, w, input);  // what the skinner gets before this sculpt
      Points posedSkin;
      skinner.deform(t, posedSkin);
      const Vec3 joint = sk.bones[s.bone].head;
      sculpts.push_back(sculptOn(reskin(input, a.hybrid, t, m.options), (s.pose.matrices[s.bone] *
                                 sk.bones[s.bone].rest.inverse() * joint.homogeneous()).head<3>(),
                                 0.12 * a.size, 0.015, a.size));
      offsets.back() = restSpaceOffsets(skinner, t, input, sculpts.back());
    }
    const CorrectiveDrivers drivers(poses, options);
    ASSERT_EQ(drivers.bones().size(), 2u);
    EXPECT_EQ(drivers.bones()[0].correctives.size(), 2u);
    EXPECT_GT(std::abs(drivers.bones()[0].coefficients(1, 1)), 1e-3);  // the elbow's kernels overlap
    for (size_t k = 0; k < sculpted.size(); ++k) {
      const std::vector<Mat4> t = transformsOf(a, sculpted[k].pose);
      boneLocalRotations(sk, sculpted[k].pose, q);
      drivers.weights(q, w);
      applyCorrectives(a.c.mesh.vertices, offsets, w, input);
      const double err = maxDiff(reskin(input, a.hybrid, t, m.options), sculpts[k]) / a.size;
      std::printf("%s, %s: reproduced to %.2e of the size (weights %.3f %.3f %.3f)\n", m.name, sculpted[k].name, err,
                  w[0], w[1], w[2]);
      EXPECT_LT(err, 1e-6) << m.name << " " << sculpted[k].name;
    }
    boneLocalRotations(sk, restPose(sk), q);
    drivers.weights(q, w);
    EXPECT_EQ(w.cwiseAbs().maxCoeff(), 0.0);
    // between the elbow's two poses both are partly on, and the blend is bounded
    boneLocalRotations(sk, posed(sk, {{"forearm", 85.0, Vec3(1, 0, 0)}}), q);
    drivers.weights(q, w);
    EXPECT_GT(w[0], 0.05);
    EXPECT_GT(w[1], 0.05);
    EXPECT_LT(w.cwiseAbs().maxCoeff(), 1.5);
  }
}

TEST(Correctives, BadInputIsRefusedClearly) {
  const Arm& a = arm();
  const Skeleton& sk = a.c.skeleton;
  const int forearm = sk.find("forearm");
  const Pose pose = posed(sk, {{"forearm", 90.0, Vec3(1, 0, 0)}});
  const std::vector<Mat4> t = transformsOf(a, pose);
  const Skinner s(a.c.mesh.vertices, a.hybrid, static_cast<int>(t.size()));
  Points posedSkin;
  s.deform(t, posedSkin);
  using myoskin::test::inputErrorOf;
  EXPECT_NE(inputErrorOf([&] { restSpaceOffsets(s, t, a.c.mesh.vertices, posedSkin.topRows(10)); }).find("vertices"),
            std::string::npos);
  Points nan = posedSkin;
  nan(7, 1) = std::nan("");
  EXPECT_NE(inputErrorOf([&] { restSpaceOffsets(s, t, a.c.mesh.vertices, nan); }).find("vertex 7"), std::string::npos);
  const Vec3 dir = boneDirection(boneLocalRotation(sk, pose, forearm));
  EXPECT_NE(inputErrorOf([&] { CorrectiveDrivers({{"a", forearm, dir, 0.0}, {"b", forearm, dir, 0.0}}); })
                .find("same pose"),
            std::string::npos);
  EXPECT_NE(inputErrorOf([&] { CorrectiveDrivers({{"a", forearm, Vec3::UnitY(), 0.0}}); }).find("rest direction"),
            std::string::npos);
  EXPECT_NE(inputErrorOf([&] { CorrectiveDrivers({{"a", -1, dir, 0.0}}); }).find("bone"), std::string::npos);
  EXPECT_NE(inputErrorOf([&] { CorrectiveDrivers({{"a", forearm, Vec3(NAN, 0, 0), 0.0}}); }).find("NaN"),
            std::string::npos);
  EXPECT_NE(inputErrorOf([&] { CorrectiveDrivers({{"a", forearm, dir, 4.0}}); }).find("falloff"), std::string::npos);
  EXPECT_NE(inputErrorOf([&] { CorrectiveDrivers({{"a", forearm, dir, 0.0}, {"a", 0, dir, 0.0}}); }).find("two"),
            std::string::npos);
  EXPECT_NE(inputErrorOf([&] { boneLocalRotation(sk, pose, sk.numBones()); }).find("bone index"), std::string::npos);
  // a vertex blended half and half between opposite turns has no inverse; a vertex without weights stays at rest
  Points two(2, 3);
  two << 0.3, 0.1, 0.2, 0.5, 0.5, 0.5;
  SkinWeights half;
  half.joints.resize(2, 2);
  half.weights.resize(2, 2);
  half.joints << 0, 1, 0, -1;
  half.weights << 0.5, 0.5, 0.0, 0.0;
  Mat4 turn = Mat4::Identity();
  turn.block<3, 3>(0, 0) = Eigen::AngleAxisd(M_PI, Vec3::UnitZ()).toRotationMatrix();
  const Skinner halfSkinner(two, half, 2);
  EXPECT_NE(inputErrorOf([&] { restSpaceOffsets(halfSkinner, {Mat4::Identity(), turn}, two, two); })
                .find("vertex 0"),
            std::string::npos);
  half.weights(0, 1) = 0.25;  // no longer collapsed; vertex 1 (no weights) moves exactly as sculpted
  const Skinner uneven(two, half, 2);
  Points target = two;
  target(1, 0) += 0.1;
  const Points d = restSpaceOffsets(uneven, {Mat4::Identity(), turn}, two, target);
  EXPECT_NEAR(d(1, 0), 0.1, 1e-12);
  const CorrectiveDrivers ok({{"a", forearm, dir, 0.0}});
  Eigen::VectorXd w;
  EXPECT_THROW(ok.weights({Eigen::Quaterniond::Identity()}, w), InputError);
}
