// Skeleton queries, validation, bone frames and forward kinematics.
#include "myoskin/skeleton.h"

#include <cmath>
#include <unordered_set>

#include "myoskin/errors.h"

namespace myoskin {

int Skeleton::find(const std::string& name) const {
  for (int i = 0; i < numBones(); ++i)
    if (bones[i].name == name) return i;
  return -1;
}

std::vector<int> Skeleton::children(int i) const {
  std::vector<int> out;
  for (int j = 0; j < numBones(); ++j)
    if (bones[j].parent == i) out.push_back(j);
  return out;
}

void validateSkeleton(const Skeleton& skeleton) {
  if (skeleton.bones.empty()) throw InputError("skeleton: has no bones");
  std::unordered_set<std::string> names;
  for (int i = 0; i < skeleton.numBones(); ++i) {
    const Bone& b = skeleton.bones[i];
    const std::string label = "skeleton: bone " + std::to_string(i) + " '" + b.name + "'";
    if (b.name.empty()) throw InputError("skeleton: bone " + std::to_string(i) + " has an empty name");
    if (!names.insert(b.name).second) throw InputError(label + " is a duplicate name");
    if (b.parent < -1 || b.parent >= i)
      throw InputError(label + " has parent index " + std::to_string(b.parent) + " (parents must come first)");
    if (!b.head.allFinite() || !b.tail.allFinite() || !b.rest.allFinite())
      throw InputError(label + " has a NaN or infinite coordinate");
    if (b.length() < 1e-9) throw InputError(label + " has zero length (head equals tail)");
  }
}

Mat4 boneMatrix(const Vec3& head, const Vec3& tail, const Vec3& xHint) {
  const Vec3 y = (tail - head).normalized();
  Vec3 x = xHint - xHint.dot(y) * y;
  if (x.norm() < 1e-9) {
    // Any perpendicular: the world axis least aligned with y.
    Eigen::Index k;
    y.cwiseAbs().minCoeff(&k);
    Vec3 e = Vec3::Zero();
    e[k] = 1.0;
    x = e - e.dot(y) * y;
  }
  x.normalize();
  const Vec3 z = x.cross(y);
  Mat4 m = Mat4::Identity();
  m.block<3, 1>(0, 0) = x;
  m.block<3, 1>(0, 1) = y;
  m.block<3, 1>(0, 2) = z;
  m.block<3, 1>(0, 3) = head;
  return m;
}

Pose restPose(const Skeleton& skeleton) {
  Pose pose;
  pose.matrices.reserve(skeleton.bones.size());
  for (const Bone& b : skeleton.bones) pose.matrices.push_back(b.rest);
  return pose;
}

Pose poseFromLocalRotations(const Skeleton& skeleton, const std::vector<Eigen::Quaterniond>& localRotations) {
  if (static_cast<int>(localRotations.size()) != skeleton.numBones())
    throw InputError("pose: " + std::to_string(localRotations.size()) + " rotations for " +
                     std::to_string(skeleton.numBones()) + " bones");
  Pose pose;
  pose.matrices.resize(skeleton.bones.size());
  for (int i = 0; i < skeleton.numBones(); ++i) {
    const Bone& b = skeleton.bones[i];
    Mat4 local = Mat4::Identity();
    local.block<3, 3>(0, 0) = localRotations[i].normalized().toRotationMatrix();
    // Blender: matrix = parent_matrix * parent_rest^-1 * rest * local_basis.
    const Mat4 parentDelta = b.parent < 0 ? Mat4::Identity()
                                          : Mat4(pose.matrices[b.parent] * skeleton.bones[b.parent].rest.inverse());
    pose.matrices[i] = parentDelta * b.rest * local;
  }
  return pose;
}

Eigen::Matrix3d channelRotation(RotationMode mode, const Eigen::Vector4d& r) {
  switch (mode) {
    case RotationMode::Quaternion: {
      const double n = r.norm();
      const Eigen::Quaterniond q = n > 0 ? Eigen::Quaterniond(r[0] / n, r[1] / n, r[2] / n, r[3] / n)
                                         : Eigen::Quaterniond(0, 1, 0, 0);
      return q.toRotationMatrix();
    }
    case RotationMode::AxisAngle: {
      const Vec3 axis = r.tail<3>();
      if (axis.norm() <= 0) return Eigen::Matrix3d::Identity();
      return Eigen::AngleAxisd(r[0], axis.normalized()).toRotationMatrix();
    }
    default: {
      static const char* orders[] = {"XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"};
      const int code = static_cast<int>(mode);
      if (code < 1 || code > 6) throw InputError("pose: unknown rotation mode " + std::to_string(code));
      Eigen::Matrix3d out = Eigen::Matrix3d::Identity();
      for (const char* a = orders[code - 1]; *a; ++a) {
        const int k = *a - 'X';
        out = Eigen::AngleAxisd(r[k], Vec3::Unit(k)).toRotationMatrix() * out;  // later axes apply after
      }
      return out;
    }
  }
}

BoneChannels channelsFromBasis(const Mat4& basis) {
  BoneChannels c;
  c.location = basis.block<3, 1>(0, 3);
  Mat3 m = basis.block<3, 3>(0, 0);
  c.scale = m.colwise().norm().transpose();
  if (m.determinant() < 0) c.scale = -c.scale;
  for (int k = 0; k < 3; ++k)
    if (c.scale[k] != 0) m.col(k) /= c.scale[k];
  const Eigen::Quaterniond q(m);
  c.rotation = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
  return c;
}

Pose poseFromChannels(const Skeleton& skeleton, const std::vector<BoneChannels>& channels) {
  if (static_cast<int>(channels.size()) != skeleton.numBones())
    throw InputError("pose: " + std::to_string(channels.size()) + " channel sets for " +
                     std::to_string(skeleton.numBones()) + " bones");
  Pose pose;
  pose.matrices.resize(skeleton.bones.size());
  for (int i = 0; i < skeleton.numBones(); ++i) {
    const Bone& b = skeleton.bones[i];
    const BoneChannels& c = channels[i];
    if (!c.location.allFinite() || !c.rotation.allFinite() || !c.scale.allFinite())
      throw InputError("pose: bone '" + b.name + "' has a NaN or infinite channel value");
    Mat4 basis = Mat4::Identity();
    basis.block<3, 3>(0, 0) = channelRotation(c.mode, c.rotation) * c.scale.asDiagonal();
    basis.block<3, 1>(0, 3) = c.location;
    const Mat4 parentDelta = b.parent < 0 ? Mat4::Identity()
                                          : Mat4(pose.matrices[b.parent] * skeleton.bones[b.parent].rest.inverse());
    pose.matrices[i] = parentDelta * b.rest * basis;
  }
  return pose;
}

}  // namespace myoskin
