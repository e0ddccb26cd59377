// Core data model: mesh checks, welding, volume, skeleton frames, forward kinematics, muscles JSON.
#include <gtest/gtest.h>

#include <cmath>

#include "myoskin/errors.h"
#include "myoskin/io.h"
#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"

using namespace myoskin;

namespace {

// A unit cube as 12 triangles, outward oriented; `split` duplicates every vertex per face (UV-seam style).
Mesh cube(bool split) {
  const double c[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const int q[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
  Mesh m;
  m.vertices.resize(split ? 24 : 8, 3);
  m.triangles.resize(12, 3);
  if (!split)
    for (int i = 0; i < 8; ++i) m.vertices.row(i) << c[i][0], c[i][1], c[i][2];
  for (int f = 0; f < 6; ++f) {
    int idx[4];
    for (int k = 0; k < 4; ++k) {
      idx[k] = split ? f * 4 + k : q[f][k];
      if (split) m.vertices.row(f * 4 + k) << c[q[f][k]][0], c[q[f][k]][1], c[q[f][k]][2];
    }
    m.triangles.row(2 * f) << idx[0], idx[1], idx[2];
    m.triangles.row(2 * f + 1) << idx[0], idx[2], idx[3];
  }
  return m;
}

}  // namespace

TEST(Mesh, CubeIsClosedManifoldOrientedWithUnitVolume) {
  const Mesh m = cube(false);
  const TopologyReport t = analyzeTopology(m);
  EXPECT_TRUE(t.closed());
  EXPECT_TRUE(t.manifold());
  EXPECT_TRUE(t.oriented());
  EXPECT_EQ(t.components, 1);
  EXPECT_NEAR(enclosedVolume(m.vertices, m.triangles), 1.0, 1e-12);
}

TEST(Mesh, SplitCubeHasBoundariesUntilWelded) {
  const Mesh split = cube(true);
  const TopologyReport before = analyzeTopology(split);
  EXPECT_EQ(before.boundaryEdges, 24);
  EXPECT_EQ(before.components, 6);
  std::vector<int> map;
  const Mesh welded = weldByPosition(split, 1e-9, map);
  EXPECT_EQ(welded.numVertices(), 8);
  ASSERT_EQ(map.size(), 24u);
  for (int i = 0; i < 24; ++i) EXPECT_EQ(welded.vertices.row(map[i]), split.vertices.row(i));
  const TopologyReport after = analyzeTopology(welded);
  EXPECT_TRUE(after.closed() && after.manifold() && after.oriented());
  EXPECT_EQ(after.components, 1);
}

TEST(Mesh, FlippedTriangleAndExtraFaceAreReported) {
  Mesh m = cube(false);
  std::swap(m.triangles(0, 1), m.triangles(0, 2));
  EXPECT_GT(analyzeTopology(m).inconsistentEdges, 0);
  Mesh fin = cube(false);
  fin.triangles.conservativeResize(13, 3);
  fin.triangles.row(12) << 0, 2, 6;  // an internal fin: edge 0-2 now has three triangles
  EXPECT_GT(analyzeTopology(fin).nonManifoldEdges, 0);
}

TEST(Mesh, ValidateRejectsNaNAndBadIndices) {
  Mesh m = cube(false);
  m.vertices(3, 1) = std::nan("");
  EXPECT_THROW(validateMesh(m), InputError);
  Mesh k = cube(false);
  k.triangles(5, 2) = 8;
  try {
    validateMesh(k);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 5"), std::string::npos) << e.what();
  }
  EXPECT_THROW(validateMesh(Mesh{}), InputError);
}

TEST(Skeleton, BoneMatrixIsOrthonormalWithYAlongTheBone) {
  const Vec3 head(0.1, 0.2, 0.3), tail(0.4, -0.1, 0.5);
  const Mat4 m = boneMatrix(head, tail, Vec3(0, 0, 1));
  const Mat3 r = m.block<3, 3>(0, 0);
  EXPECT_LT((r.transpose() * r - Mat3::Identity()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  EXPECT_LT((r.col(1) - (tail - head).normalized()).norm(), 1e-12);
  EXPECT_LT((m.block<3, 1>(0, 3) - head).norm(), 1e-15);
  // A hint parallel to the bone still gives a valid frame.
  const Mat4 p = boneMatrix(Vec3::Zero(), Vec3(0, 0, 2), Vec3(0, 0, 1));
  const Mat3 pr = p.block<3, 3>(0, 0);
  EXPECT_NEAR(pr.determinant(), 1.0, 1e-12);
}

TEST(Skeleton, ForwardKinematicsRotatesChildrenAboutTheParentHead) {
  Skeleton s;
  s.bones.push_back(Bone{"upper", -1, Vec3(0, 0, 0), Vec3(1, 0, 0), boneMatrix(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3::UnitZ())});
  s.bones.push_back(Bone{"lower", 0, Vec3(1, 0, 0), Vec3(2, 0, 0), boneMatrix(Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3::UnitZ())});
  validateSkeleton(s);
  std::vector<Eigen::Quaterniond> rot(2, Eigen::Quaterniond::Identity());
  const Pose rest = poseFromLocalRotations(s, rot);
  for (int i = 0; i < 2; ++i) EXPECT_LT((rest.matrices[i] - s.bones[i].rest).norm(), 1e-12);
  // 90 degrees about the upper bone's local X (= world Z by the hint): the lower bone's head goes to (0,1,0).
  rot[0] = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX()));
  const Pose bent = poseFromLocalRotations(s, rot);
  const Vec3 lowerHead = bent.matrices[1].block<3, 1>(0, 3);
  EXPECT_LT((lowerHead - Vec3(0, 1, 0)).norm(), 1e-12) << lowerHead.transpose();
}

TEST(Skeleton, ForwardKinematicsFromChannelsFollowsBlenderConventions) {
  using RM = RotationMode;
  const Vec3 e(0.3, -0.7, 1.1);
  auto R = [](int axis, double a) { return Eigen::AngleAxisd(a, Vec3::Unit(axis)).toRotationMatrix(); };
  const Eigen::Vector4d euler(e.x(), e.y(), e.z(), 0.0);
  // Euler 'XYZ' applies X first: R = Rz Ry Rx; 'ZXY': R = Ry Rx Rz.
  EXPECT_LT((channelRotation(RM::XYZ, euler) - R(2, e.z()) * R(1, e.y()) * R(0, e.x())).norm(), 1e-12);
  EXPECT_LT((channelRotation(RM::ZXY, euler) - R(1, e.y()) * R(0, e.x()) * R(2, e.z())).norm(), 1e-12);
  EXPECT_LT((channelRotation(RM::YZX, euler) - R(0, e.x()) * R(2, e.z()) * R(1, e.y())).norm(), 1e-12);
  // A quaternion is normalised; a zero one is (0, 1, 0, 0) (180 degrees about X), as in Blender.
  EXPECT_LT((channelRotation(RM::Quaternion, Eigen::Vector4d(2, 0, 0, 0)) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((channelRotation(RM::Quaternion, Eigen::Vector4d::Zero()) - R(0, M_PI)).norm(), 1e-12);
  // Axis-angle: (angle, axis), the axis normalised; a zero axis gives no rotation.
  EXPECT_LT((channelRotation(RM::AxisAngle, Eigen::Vector4d(0.5, 0, 0, 3)) - R(2, 0.5)).norm(), 1e-12);
  EXPECT_LT((channelRotation(RM::AxisAngle, Eigen::Vector4d(0.5, 0, 0, 0)) - Eigen::Matrix3d::Identity()).norm(), 1e-12);

  Skeleton s;
  s.bones.push_back(Bone{"upper", -1, Vec3(0, 0, 0), Vec3(1, 0, 0), boneMatrix(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3::UnitZ())});
  s.bones.push_back(Bone{"lower", 0, Vec3(1, 0, 0), Vec3(2, 0, 0), boneMatrix(Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3::UnitZ())});
  std::vector<BoneChannels> c(2);
  const Pose rest = poseFromChannels(s, c);
  for (int i = 0; i < 2; ++i) EXPECT_LT((rest.matrices[i] - s.bones[i].rest).norm(), 1e-12);
  // Quaternion channels alone equal poseFromLocalRotations; location and scale give T R S in the bone frame.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.8, Vec3(1, 2, 3).normalized()));
  c[0].rotation = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
  const Pose a = poseFromChannels(s, c);
  const Pose b = poseFromLocalRotations(s, {q, Eigen::Quaterniond::Identity()});
  for (int i = 0; i < 2; ++i) EXPECT_LT((a.matrices[i] - b.matrices[i]).norm(), 1e-12);
  c[1].location = Vec3(0.1, 0.2, 0.3);
  c[1].scale = Vec3(2, 2, 2);
  c[1].mode = RM::XYZ;
  c[1].rotation = euler;
  const Pose d = poseFromChannels(s, c);
  Mat4 basis = Mat4::Identity();
  basis.block<3, 3>(0, 0) = channelRotation(RM::XYZ, euler) * 2.0;
  basis.block<3, 1>(0, 3) = c[1].location;
  const Mat4 expected = a.matrices[0] * s.bones[0].rest.inverse() * s.bones[1].rest * basis;
  EXPECT_LT((d.matrices[1] - expected).norm(), 1e-12);
  // channelsFromBasis inverts the basis T R S (quaternion channels), also for a scale along the bone's
  // own axes (a muscle joint's diag(s, lambda, s)) and a mirroring (negative) scale.
  for (const Vec3& size : {Vec3(0.9, 1.3, 0.9), Vec3(-1.0, -1.0, -1.0)}) {
    Mat4 m = Mat4::Identity();
    m.block<3, 3>(0, 0) = channelRotation(RM::ZXY, euler) * size.asDiagonal();
    m.block<3, 1>(0, 3) = Vec3(0.3, -0.2, 0.1);
    const BoneChannels back = channelsFromBasis(m);
    EXPECT_EQ(back.mode, RM::Quaternion);
    Mat4 again = Mat4::Identity();
    again.block<3, 3>(0, 0) = channelRotation(RM::Quaternion, back.rotation) * back.scale.asDiagonal();
    again.block<3, 1>(0, 3) = back.location;
    EXPECT_LT((again - m).norm(), 1e-12) << size.transpose();
  }
  c[1].scale.x() = std::nan("");
  EXPECT_THROW(poseFromChannels(s, c), InputError);
  EXPECT_THROW(poseFromChannels(s, std::vector<BoneChannels>(1)), InputError);
}

TEST(Skeleton, ValidationNamesTheBadBone) {
  Skeleton s;
  s.bones.push_back(Bone{"root", -1, Vec3(0, 0, 0), Vec3(0, 1, 0)});
  s.bones.push_back(Bone{"flat", 0, Vec3(0, 1, 0), Vec3(0, 1, 0)});
  try {
    validateSkeleton(s);
    FAIL() << "zero-length bone accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'flat' has zero length"), std::string::npos) << e.what();
  }
  s.bones[1] = Bone{"root", 0, Vec3(0, 1, 0), Vec3(0, 2, 0)};
  EXPECT_THROW(validateSkeleton(s), InputError);  // duplicate name
  s.bones[1] = Bone{"child", 1, Vec3(0, 1, 0), Vec3(0, 2, 0)};
  EXPECT_THROW(validateSkeleton(s), InputError);  // parent after child
}

TEST(MusclesJson, RoundTripIsExactAndValidates) {
  Muscle m;
  m.name = "biceps";
  m.region = "upper_arm";
  m.origin = {"upper_arm", Vec3(0.1, 0.2, 0.3)};
  m.insertion = {"forearm", Vec3(0.4, 0.2, 0.3)};
  m.rootCurve = {Vec3(0.1, 0.2, 0.3), Vec3(0.25, 0.21, 0.31), Vec3(0.4, 0.2, 0.3)};
  m.sections = {{-0.3, Vec3(0.2, 0.2, 0.3), Vec3(0, 1, 0), 0.02, 0.015, Vec3(1, 0, 0)},
                {0.4, Vec3(0.3, 0.2, 0.3), Vec3(0, 1, 0), 0.025, 0.018, Vec3(1, 0, 0)}};
  m.wrap = {WrapType::Joint, "forearm", 0.03, -1};
  m.bulge = 2.0;
  m.joints = 5;
  const std::vector<Muscle> back = musclesFromJson(musclesToJson({m}));
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].name, "biceps");
  EXPECT_EQ(back[0].rootCurve[1], m.rootCurve[1]);
  EXPECT_EQ(back[0].sections[1].a, 0.025);
  EXPECT_EQ(back[0].wrap.type, WrapType::Joint);
  EXPECT_EQ(back[0].wrap.side, -1);
  EXPECT_EQ(back[0].joints, 5);
  m.sections[1].u = -0.5;  // not increasing
  EXPECT_THROW(musclesFromJson(musclesToJson({m})), InputError);
}
