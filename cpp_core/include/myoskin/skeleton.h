// Skeleton (rest pose) and pose. Conventions follow Blender's bones so the add-on converts 1:1.
#pragma once
#include <string>
#include <vector>

#include "myoskin/types.h"

namespace myoskin {

// One bone at rest. rest maps bone space to mesh space (Blender's Bone.matrix_local): its Y axis runs
// head -> tail, its origin is the head, no scale.
struct Bone {
  std::string name;
  int parent = -1;  // index into Skeleton::bones, -1 for a root; parents come before children
  Vec3 head = Vec3::Zero();
  Vec3 tail = Vec3::UnitY();
  Mat4 rest = Mat4::Identity();
  bool deform = true;  // false for helper bones that carry no weights

  double length() const { return (tail - head).norm(); }
};

// Bones in parent-before-child order.
struct Skeleton {
  std::vector<Bone> bones;

  int numBones() const { return static_cast<int>(bones.size()); }
  // Index of the bone called `name`, or -1.
  int find(const std::string& name) const;
  // Indices of the children of bone i.
  std::vector<int> children(int i) const;
};

// Throws InputError for an empty skeleton, duplicate or empty names, a bad parent index or order,
// non-finite values, or a zero-length bone (length < 1e-9 m; the message names the bone).
void validateSkeleton(const Skeleton& skeleton);

// Rest matrix for a bone from head, tail and roll reference: Y = tail - head, X = the component of
// xHint perpendicular to Y (any perpendicular axis if xHint is parallel to Y).
Mat4 boneMatrix(const Vec3& head, const Vec3& tail, const Vec3& xHint);

// A pose: for each bone its posed matrix in mesh space (Blender's PoseBone.matrix). The skinning
// transform of bone i is matrices[i] * rest_i^-1.
struct Pose {
  std::vector<Mat4> matrices;
};

// The rest pose of a skeleton (every posed matrix equals the rest matrix).
Pose restPose(const Skeleton& skeleton);

// Forward kinematics: localRotations[i] rotates bone i about its head in its own rest frame
// (Blender's PoseBone.rotation_quaternion with no location/scale). Size must equal numBones().
Pose poseFromLocalRotations(const Skeleton& skeleton, const std::vector<Eigen::Quaterniond>& localRotations);

// How a bone's rotation channel is read, as Blender's PoseBone.rotation_mode (same integer codes):
// quaternion (w, x, y, z), axis-angle (angle in radians, axis x, y, z), or Euler angles (x, y, z) applied
// in the named order ('XYZ': X first, R = Rz Ry Rx).
enum class RotationMode : int { AxisAngle = -1, Quaternion = 0, XYZ = 1, XZY = 2, YXZ = 3, YZX = 4, ZXY = 5, ZYX = 6 };

// One bone's local channels (Blender's PoseBone location, rotation, scale): basis = T(location) R S(scale).
struct BoneChannels {
  Vec3 location = Vec3::Zero();
  RotationMode mode = RotationMode::Quaternion;
  Eigen::Vector4d rotation = Eigen::Vector4d(1, 0, 0, 0);  // by mode; an Euler mode uses the first three
  Vec3 scale = Vec3::Ones();
};

// Forward kinematics from local channels with full inheritance (Blender's default bone settings):
// matrix_i = matrix_parent * rest_parent^-1 * rest_i * basis_i. A quaternion is normalised (a zero one
// gives (0, 1, 0, 0), as in Blender), a zero axis gives no rotation. Throws InputError on a size mismatch
// or a non-finite value (naming the bone).
Pose poseFromChannels(const Skeleton& skeleton, const std::vector<BoneChannels>& channels);

// The rotation matrix of one channel (the R of poseFromChannels).
Eigen::Matrix3d channelRotation(RotationMode mode, const Eigen::Vector4d& rotation);

// Quaternion-mode channels of a basis matrix T R S (S a scale along the bone's own axes), decomposed as
// Blender's PoseBone.matrix_basis setter does: scale = column lengths (negated when the determinant is
// negative), rotation = the quaternion of the normalised columns. Inverse of poseFromChannels' basis.
BoneChannels channelsFromBasis(const Mat4& basis);

}  // namespace myoskin
