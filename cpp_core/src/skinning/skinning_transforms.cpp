// Combined skinning transforms: skeleton bones, then muscle joints (joint * bind^-1).
#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

void skinningTransforms(const Skeleton& skeleton, const Pose& pose, const MuscleRig& rig,
                        const MuscleRigState& state, std::vector<Mat4>& transforms) {
  std::vector<Mat4> bones;
  skeletonTransforms(skeleton, pose, bones);
  const int nb = skeleton.numBones(), nj = rig.numJoints();
  if (static_cast<int>(state.jointMatrices.size()) != nj)
    throw InputError("skinning: rig state has " + std::to_string(state.jointMatrices.size()) +
                     " joint matrices for " + std::to_string(nj) + " muscle joints");
  transforms.resize(static_cast<size_t>(nb) + nj);
  for (int b = 0; b < nb; ++b) transforms[b] = bones[b];
  const std::vector<Mat4>& bind = rig.bindMatrices();
  for (int j = 0; j < nj; ++j) {
    if (!state.jointMatrices[j].allFinite())
      throw InputError("skinning: muscle joint " + std::to_string(j) + " '" + rig.jointNames()[j] +
                       "' has a NaN or infinite matrix");
    transforms[nb + j] = state.jointMatrices[j] * bind[j].inverse();
  }
}

std::vector<Mat4> combinedRestMatrices(const Skeleton& skeleton, const MuscleRig& rig) {
  std::vector<Mat4> rest;
  rest.reserve(static_cast<size_t>(skeleton.numBones()) + rig.numJoints());
  for (const auto& bone : skeleton.bones) rest.push_back(bone.rest);
  for (const Mat4& m : rig.bindMatrices()) rest.push_back(m);
  return rest;
}

}  // namespace myoskin
