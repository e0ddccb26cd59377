// Pose-space correctives (issue 16; the sculpt coordinate-space problem of Gray & Hutchinson's procedural
// muscle and skin simulation): a fix sculpted on the posed, skinned mesh is mapped back through the inverse of
// each vertex's blended skinning transform to an offset of the skinner's input (rest space, where Blender's shape
// keys apply, before the Armature modifier), and is driven by the direction of one bone relative to its parent
// with a compactly supported radial basis function, so several sculpted poses of a bone are each reproduced
// exactly, the rest pose stays the rest pose and far from every sculpted pose the corrective does nothing.
//
// The driver is a polynomial of the bone's local rotation quaternion q = (w, x, y, z) (Blender's driver variable
// "Rotation" in Local Space, Quaternion mode): the bone's Y axis is
//   u(q) = (2 (xy - wz), 1 - 2 (xx + zz), 2 (yz + wx)),
// the distance of u to a sample direction a is s = |u - a|^2 / 4 = sin^2(angle / 2), and each sample's kernel is
//   phi = max(1 - s / sin^2(falloff / 2), 0)^3 = max(k0 + k1 (xy - wz) + k2 (xx + zz) + k3 (yz + wx), 0)^3,
// twice continuously differentiable and exactly 0 beyond `falloff`. A corrective's weight is sum_j c_j phi_j over
// its bone's samples (the rest direction first, then each sculpted pose), c solving phi_j(sample i) c = target:
// 1 at its own pose, 0 at the bone's other poses and at rest. Blender plays it with native drivers (a simple
// expression per kernel and one per shape key), no Python needed.
#pragma once
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "myoskin/skeleton.h"
#include "myoskin/skinning.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Rest-space offsets of a sculpt (the coordinate-space problem)
// ============================================================================

// The offsets d (#V by 3) that, added to the skinner's input positions `input` (#V by 3: rest plus whatever is
// already applied before skinning), make the skinner's deform under `transforms` land on `target` (#V by 3):
// d_v = A_v^-1 (target_v - b_v) - input_v with A_v | b_v the vertex's blended transform (Skinner::vertexTransforms;
// linear or Blender's dual quaternions, whichever the skinner does). Throws InputError on mismatched sizes, a
// non-finite target (naming the vertex) or a vertex whose blended transform cannot be inverted.
Points restSpaceOffsets(const Skinner& skinner, const std::vector<Mat4>& transforms, const Points& input,
                        const Points& target);

// ============================================================================
// Driving a corrective by its bone's direction
// ============================================================================

// Bone `bone`'s rotation relative to its parent and its own rest frame under a pose (Blender's PoseBone local
// space, as a driver reads it: the columns of the local matrix normalised, then its quaternion); identity at rest.
Eigen::Quaterniond boneLocalRotation(const Skeleton& skeleton, const Pose& pose, int bone);
// Every bone's (out: numBones, resized once).
void boneLocalRotations(const Skeleton& skeleton, const Pose& pose, std::vector<Eigen::Quaterniond>& out);

// The bone's Y axis u(q) in its rest frame for a local rotation (rest: (0, 1, 0)).
Vec3 boneDirection(const Eigen::Quaterniond& localRotation);

// Coefficients (k0, k1, k2, k3) of the kernel of a sample direction (unit) with an angular falloff in (0, pi].
Eigen::Vector4d correctiveKernel(const Vec3& direction, double falloff);
// The kernel's value max(k0 + k1 (xy - wz) + k2 (xx + zz) + k3 (yz + wx), 0)^3 for a local rotation.
double correctiveKernelValue(const Eigen::Vector4d& kernel, const Eigen::Quaterniond& localRotation);

struct CorrectiveOptions {
  // Angular radius (radians) of each sample's influence: the corrective fades smoothly to exactly 0 where the
  // bone's direction is this far from its sculpted pose (60 degrees; each pose may give its own).
  double falloff = 1.0471975511965976;
  // Two samples of one bone (two poses, or a pose and the rest direction) closer than this angle (radians) are
  // the same driving pose: InputError (0.5 degrees).
  double minSeparation = 0.008726646259971648;
};

// One sculpted pose: the corrective it drives and its bone's direction there.
struct CorrectivePose {
  std::string name;                 // the corrective's name (unique)
  int bone = -1;                    // the driving bone (its index in the caller's skeleton)
  Vec3 direction = Vec3::UnitY();   // the bone's Y axis in its rest frame at the sculpted pose (boneDirection)
  double falloff = 0.0;             // radians; <= 0: CorrectiveOptions::falloff
};

// The radial basis function of one driving bone.
struct BoneCorrectiveRbf {
  int bone = -1;
  std::vector<int> correctives;          // the poses of this bone (indices into the CorrectiveDrivers' poses)
  std::vector<Eigen::Vector4d> kernels;  // 1 + n: the rest direction's kernel, then one per pose
  Eigen::MatrixXd coefficients;          // (1 + n) by n: weight of pose c = sum_j coefficients(j, c) phi_j
};

// Built once from the sculpted poses (any bones); weights() per frame without allocation.
class CorrectiveDrivers {
 public:
  // Throws InputError on an empty or duplicate name, a negative bone, a non-finite or zero direction, a falloff
  // outside (0, pi], two poses of one bone closer than minSeparation (naming both) or a pose at the rest
  // direction, or kernels whose matrix cannot be solved (poses too close for their falloff).
  explicit CorrectiveDrivers(std::vector<CorrectivePose> poses, const CorrectiveOptions& options = {});

  int numCorrectives() const { return static_cast<int>(poses_.size()); }
  const std::vector<CorrectivePose>& poses() const { return poses_; }
  const std::vector<BoneCorrectiveRbf>& bones() const { return bones_; }
  // Index of the corrective called `name`, or -1.
  int find(const std::string& name) const;

  // localRotations: per bone of the skeleton (boneLocalRotations). out: one weight per corrective (resized
  // once). Throws InputError when a driving bone is outside localRotations.
  void weights(const std::vector<Eigen::Quaterniond>& localRotations, Eigen::VectorXd& out) const;

 private:
  std::vector<CorrectivePose> poses_;
  std::vector<BoneCorrectiveRbf> bones_;
};

// out = base + sum_k weights[k] offsets[k] (#V by 3 each; out resized once). Throws InputError on mismatched
// sizes.
void applyCorrectives(const Points& base, const std::vector<Points>& offsets, const Eigen::VectorXd& weights,
                      Points& out);

}  // namespace myoskin
