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

}  // namespace myoskin
