// The skinner's preserve-volume mode (Blender's dual quaternion skinning) against an independent float64
// reference, on closed-form cases, the synthetic arm's rest pose and bad input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "test_support.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

SkinnerOptions preserveVolume(std::vector<Mat4> jointRest = {}, DualQuatScale scale = DualQuatScale::Pivot) {
  SkinnerOptions o;
  o.preserveVolume = true;
  o.jointRest = std::move(jointRest);
  o.dualQuatScale = scale;
  return o;
}

// The rotation Blender blends for a joint: the posed bone frame P = T * B made orthonormal about its Y axis
// (Gram-Schmidt: Y, then X without its Y part, Z = X x Y), taken back to the rest frame: R = P_o * B_rot^-1.
Eigen::Quaterniond jointRotation(const Mat4& transform, const Mat4& rest) {
  const Eigen::Matrix3d P = (transform * rest).block<3, 3>(0, 0);
  const Eigen::Vector3d y = P.col(1).normalized();
  const Eigen::Vector3d x = (P.col(0) - P.col(0).dot(y) * y).normalized();
  Eigen::Matrix3d o;
  o << x, y, x.cross(y);
  Eigen::Matrix3d b = rest.block<3, 3>(0, 0);
  for (int c = 0; c < 3; ++c) b.col(c).normalize();
  return Eigen::Quaterniond(o * b.transpose());
}

// Float64 dual quaternion skinning written from the definition. Pivot: each joint moves the vertex rigidly
// by its rotation q_j and the translation that carries the vertex to its linear position T_j v. Blended:
// each joint is split T_j = R_j S_j (R_j rigid, rotation q_j, carrying the joint's rest head to its posed
// head); the S_j are averaged linearly and applied first, then the blend of the rigid R_j. The unit dual
// quaternions (q_j, 1/2 t_j q_j) are blended with signs aligned to the running sum, normalised, and applied.
// Weight sum <= 1e-4 stays at rest.
Points reference(const Points& rest, const SkinWeights& w, const std::vector<Mat4>& transforms,
                 const std::vector<Mat4>& jointRest, bool blended = false) {
  Points out = rest;
  for (Eigen::Index v = 0; v < rest.rows(); ++v) {
    Vec3 co = rest.row(v).transpose();
    Eigen::Vector4d sq = Eigen::Vector4d::Zero(), sd = Eigen::Vector4d::Zero();  // (w, x, y, z)
    Mat4 scale = Mat4::Zero();
    double total = 0.0;
    for (int k = 0; k < w.influences(); ++k) {
      const int j = w.joints(v, k);
      double wt = w.weights(v, k);
      if (j < 0 || wt <= 0.0) continue;
      total += wt;
      const Mat4 B = jointRest.empty() ? Mat4::Identity() : jointRest[j];
      const Eigen::Quaterniond q = jointRotation(transforms[j], B);
      Vec3 t;
      if (blended) {
        Mat4 R = Mat4::Identity();
        R.block<3, 3>(0, 0) = q.toRotationMatrix();
        R.block<3, 1>(0, 3) = (transforms[j] * B).block<3, 1>(0, 3) - q * B.block<3, 1>(0, 3);
        scale += wt * R.inverse() * transforms[j];
        t = R.block<3, 1>(0, 3);
      } else {
        t = (transforms[j] * co.homogeneous()).head<3>() - q * co;
      }
      const Eigen::Quaterniond d = Eigen::Quaterniond(0.0, t.x(), t.y(), t.z()) * q;  // 2x the dual part
      const Eigen::Vector4d qv(q.w(), q.x(), q.y(), q.z()), dv(0.5 * d.w(), 0.5 * d.x(), 0.5 * d.y(), 0.5 * d.z());
      if (qv.dot(sq) < 0.0) wt = -wt;
      sq += wt * qv;
      sd += wt * dv;
    }
    if (total <= kRestWeightThreshold) continue;
    if (blended) co = (scale / total * co.homogeneous()).head<3>();
    const double n = sq.norm();
    const Eigen::Quaterniond q(sq[0] / n, sq[1] / n, sq[2] / n, sq[3] / n);
    const Eigen::Quaterniond d(sd[0] / n, sd[1] / n, sd[2] / n, sd[3] / n);
    const Eigen::Quaterniond t = d * q.conjugate();  // translation = 2 vec(d q*)
    out.row(v) = (q * co + 2.0 * t.vec()).transpose();
  }
  return out;
}

// Random skin in a 1 m box: K slots over J joints, rotations within 120 degrees of each other's, translation,
// non-uniform scale and shear-free rest frames anywhere.
struct RandomSkin {
  Points rest;
  SkinWeights weights;
  std::vector<Mat4> transforms, jointRest;
};

RandomSkin randomSkin(int nv, int k, int nj, unsigned seed, bool scaled) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RandomSkin s;
  s.rest.resize(nv, 3);
  s.weights.joints.resize(nv, k);
  s.weights.weights.resize(nv, k);
  for (int v = 0; v < nv; ++v) {
    s.rest.row(v) << 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng);
    for (int i = 0; i < k; ++i) {
      const bool empty = i > 0 && u(rng) < -0.6;
      s.weights.joints(v, i) = empty ? -1 : static_cast<int>((u(rng) + 1.0) * 0.5 * (nj - 1) + 0.5);
      s.weights.weights(v, i) = empty ? 0.0 : 0.1 + (u(rng) + 1.0);  // not normalised on purpose
    }
  }
  auto randomRotation = [&](double maxAngle) {
    return Eigen::AngleAxisd(maxAngle * 0.5 * (u(rng) + 1.0), Vec3(u(rng), u(rng), u(rng)).normalized())
        .toRotationMatrix();
  };
  for (int j = 0; j < nj; ++j) {
    Mat4 B = Mat4::Identity();
    B.block<3, 3>(0, 0) = randomRotation(M_PI);
    B.block<3, 1>(0, 3) << 0.4 * u(rng), 0.4 * u(rng), 0.4 * u(rng);
    // Pose in the joint's own frame: rotation, translation, and (muscle joints) diag(s, lambda, s).
    Mat4 local = Mat4::Identity();
    const Vec3 scale = scaled ? Vec3(1.0 + 0.3 * u(rng), 1.0 + 0.3 * u(rng), 1.0 + 0.3 * u(rng)) : Vec3::Ones();
    local.block<3, 3>(0, 0) = randomRotation(2.0 * M_PI / 3.0) * scale.asDiagonal();
    local.block<3, 1>(0, 3) << 0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng);
    s.jointRest.push_back(B);
    s.transforms.push_back(B * local * B.inverse());
  }
  return s;
}

double maxDiff(const Points& a, const Points& b) { return (a - b).cwiseAbs().maxCoeff(); }

}  // namespace

TEST(PreserveVolume, TwoRigidBonesBlendOnTheCircleWhereLinearBlendingCutsTheChord) {
  // Bone 1 turns 90 degrees about z at the origin; a vertex at (1, 0, 0) shared half and half lands at
  // 45 degrees on the unit circle, where linear blending gives the chord's midpoint (radius 0.707).
  Points rest(2, 3);
  rest << 1.0, 0.0, 0.0, 0.0, 2.0, 0.0;
  SkinWeights w;
  w.joints.resize(2, 2);
  w.weights.resize(2, 2);
  w.joints << 0, 1, 0, 1;
  w.weights << 0.5, 0.5, 0.0, 3.0;
  Mat4 turn = Mat4::Identity();
  turn.block<3, 3>(0, 0) = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()).toRotationMatrix();
  const std::vector<Mat4> transforms = {Mat4::Identity(), turn};
  const Points dqs = skin(rest, w, transforms, preserveVolume());
  const Points lbs = skin(rest, w, transforms);
  EXPECT_NEAR(dqs(0, 0), std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(dqs(0, 1), std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(dqs(0, 2), 0.0, 1e-7);
  EXPECT_NEAR(lbs.row(0).norm(), std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(dqs(1, 0), -2.0, 1e-6);  // one joint only: its own rigid motion
  EXPECT_NEAR(dqs(1, 1), 0.0, 1e-6);
}

TEST(PreserveVolume, MatchesFloat64ReferenceWithRigidAndScaledJointsUpTo8Influences) {
  for (bool scaled : {false, true}) {
    for (int k : {1, 2, 4, 8}) {
      const RandomSkin s = randomSkin(3000, k, 12, 17 + k + (scaled ? 100 : 0), scaled);
      const Points ref = reference(s.rest, s.weights, s.transforms, s.jointRest);
      const Points got = skin(s.rest, s.weights, s.transforms, preserveVolume(s.jointRest));
      EXPECT_LT(maxDiff(got, ref), 2e-6) << "scaled " << scaled << " K " << k;
      if (!scaled) {  // rigid joints: the rest frames do not matter
        const Points noRest = skin(s.rest, s.weights, s.transforms, preserveVolume());
        EXPECT_LT(maxDiff(noRest, ref), 2e-6) << "K " << k;
      }
    }
  }
}

TEST(PreserveVolume, BlendedScaleLikeBlender3MatchesItsFloat64Reference) {
  for (int k : {1, 2, 4, 8}) {
    const RandomSkin s = randomSkin(3000, k, 12, 51 + k, true);
    const Points ref = reference(s.rest, s.weights, s.transforms, s.jointRest, true);
    const Points got = skin(s.rest, s.weights, s.transforms, preserveVolume(s.jointRest, DualQuatScale::Blended));
    EXPECT_LT(maxDiff(got, ref), 2e-6) << "K " << k;
    if (k > 1) {  // rotated and scaled joints blend differently in the two Blenders
      const Points pivot = skin(s.rest, s.weights, s.transforms, preserveVolume(s.jointRest));
      EXPECT_GT(maxDiff(got, pivot), 1e-3) << "K " << k;
    }
  }
}

TEST(PreserveVolume, OneInfluenceIsTheJointsOwnLinearMotionEvenWhenScaled) {
  const RandomSkin s = randomSkin(2000, 1, 6, 3, true);
  const Points lbs = skin(s.rest, s.weights, s.transforms);
  for (DualQuatScale mode : {DualQuatScale::Pivot, DualQuatScale::Blended})
    EXPECT_LT(maxDiff(skin(s.rest, s.weights, s.transforms, preserveVolume(s.jointRest, mode)), lbs), 2e-6);
}

TEST(PreserveVolume, BlendsDifferFromLinearAndThreadsDoNotChangeTheResult) {
  const RandomSkin s = randomSkin(20000, 4, 10, 9, true);
  Skinner skinner(s.rest, s.weights, 10, preserveVolume(s.jointRest));
  PointsF one, two;
  SkinnerOptions o = skinner.options();
  o.threads = 1;
  skinner.setOptions(o);
  skinner.deform(s.transforms, one);
  o.threads = 2;
  o.grainSize = 333;
  skinner.setOptions(o);
  skinner.deform(s.transforms, two);
  EXPECT_EQ((one - two).cwiseAbs().maxCoeff(), 0.0f);
  const Points lbs = skin(s.rest, s.weights, s.transforms);
  EXPECT_GT(maxDiff(one.cast<double>(), lbs), 1e-3);  // the modes really differ on blended vertices
  o.preserveVolume = false;  // switching the mode off gives the linear skin back
  skinner.setOptions(o);
  skinner.deform(s.transforms, two);
  EXPECT_LT(maxDiff(two.cast<double>(), lbs), 1e-6);
}

TEST(PreserveVolume, RestPoseOfTheSyntheticArmIsExactAndTinyWeightSumsStayAtRest) {
  const SyntheticCharacter arm = makeSyntheticArm();
  const Character& c = arm.character;
  std::vector<Mat4> transforms, rest;
  skeletonTransforms(c.skeleton, restPose(c.skeleton), transforms);
  for (const auto& b : c.skeleton.bones) rest.push_back(b.rest);
  Points out;
  Skinner(c.mesh.vertices, c.weights, c.skeleton.numBones(), preserveVolume(rest)).deform(transforms, out);
  const double size = (c.mesh.vertices.colwise().maxCoeff() - c.mesh.vertices.colwise().minCoeff()).norm();
  EXPECT_LT(maxDiff(out, c.mesh.vertices), 1e-6 * size);

  Points p(1, 3);
  p << 0.3, -0.2, 0.1;
  SkinWeights w;
  w.joints.resize(1, 1);
  w.weights.resize(1, 1);
  w.joints << 0;
  w.weights << 5e-5;
  Mat4 moved = Mat4::Identity();
  moved(0, 3) = 1.0;
  PointsF out1;
  Skinner(p, w, 1, preserveVolume()).deform({moved}, out1);
  const PointsF restF = p.cast<float>();  // the skinner's float32 rest position, unchanged
  EXPECT_EQ(out1(0, 0), restF(0, 0));
  EXPECT_EQ(out1(0, 1), restF(0, 1));
  EXPECT_EQ(out1(0, 2), restF(0, 2));
}

TEST(PreserveVolume, HybridRigOfTheArmIsExactAtRestAndMatchesTheReferenceWithBulgingJoints) {
  const Character c = makeSyntheticArm().character;
  const MuscleRig rig(c.skeleton, extractMuscles(c).muscles);
  ASSERT_GT(rig.numJoints(), 0);
  const std::vector<Mat4> rest = combinedRestMatrices(c.skeleton, rig);
  ASSERT_EQ(static_cast<int>(rest.size()), c.skeleton.numBones() + rig.numJoints());
  EXPECT_EQ(rest[1], c.skeleton.bones[1].rest);
  EXPECT_EQ(rest.back(), rig.bindMatrices().back());
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  const Skinner skinner(c.mesh.vertices, w, static_cast<int>(rest.size()), preserveVolume(rest));
  const double size = (c.mesh.vertices.colwise().maxCoeff() - c.mesh.vertices.colwise().minCoeff()).norm();
  MuscleRigState state = rig.makeState();
  std::vector<Mat4> t;
  Points out;
  for (double degrees : {0.0, 70.0, 120.0}) {
    std::vector<Eigen::Quaterniond> q(c.skeleton.numBones(), Eigen::Quaterniond::Identity());
    q[c.skeleton.find("forearm")] = Eigen::AngleAxisd(degrees * M_PI / 180.0, Vec3::UnitX());
    const Pose pose = poseFromLocalRotations(c.skeleton, q);
    rig.evaluate(pose, state);
    skinningTransforms(c.skeleton, pose, rig, state, t);
    skinner.deform(t, out);
    const double err = maxDiff(out, reference(c.mesh.vertices, w, t, rest)) / size;
    std::printf("arm hybrid rig, elbow %.0f degrees: preserve volume vs float64 reference %.2e of the size\n",
                degrees, err);
    EXPECT_LT(err, 1e-6) << degrees;
    if (degrees == 0.0) EXPECT_LT(maxDiff(out, c.mesh.vertices), 1e-6 * size);
  }
}

TEST(PreserveVolume, BadJointRestMatricesAreRejected) {
  const RandomSkin s = randomSkin(10, 2, 3, 1, false);
  EXPECT_THROW(Skinner(s.rest, s.weights, 3, preserveVolume({Mat4::Identity()})), InputError);
  std::vector<Mat4> singular(3, Mat4::Identity());
  singular[2](1, 1) = 0.0;
  EXPECT_THROW(Skinner(s.rest, s.weights, 3, preserveVolume(singular)), InputError);
  std::vector<Mat4> nan(3, Mat4::Identity());
  nan[0](0, 3) = std::nan("");
  EXPECT_THROW(Skinner(s.rest, s.weights, 3, preserveVolume(nan)), InputError);
  Skinner skinner(s.rest, s.weights, 3, preserveVolume());
  EXPECT_THROW(skinner.setOptions(preserveVolume(singular)), InputError);
  std::vector<Mat4> bad = s.transforms;
  bad[1](0, 0) = std::numeric_limits<double>::infinity();
  Points out;
  EXPECT_THROW(skinner.deform(bad, out), InputError);
  EXPECT_THROW(skinner.deform({Mat4::Identity()}, out), InputError);
}
