// Skeleton-only skinning transforms (plain linear blend skinning).
#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

void skeletonTransforms(const Skeleton& skeleton, const Pose& pose, std::vector<Mat4>& transforms) {
  if (static_cast<int>(pose.matrices.size()) != skeleton.numBones())
    throw InputError("skinning: pose has " + std::to_string(pose.matrices.size()) + " matrices for " +
                     std::to_string(skeleton.numBones()) + " bones");
  transforms.resize(skeleton.bones.size());
  for (int b = 0; b < skeleton.numBones(); ++b) {
    if (!pose.matrices[b].allFinite())
      throw InputError("skinning: pose matrix of bone " + std::to_string(b) + " '" + skeleton.bones[b].name +
                       "' has a NaN or infinite value");
    transforms[b] = pose.matrices[b] * skeleton.bones[b].rest.inverse();
  }
}

}  // namespace myoskin
