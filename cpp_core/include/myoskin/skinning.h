// Hybrid skinning (DESIGN.md section 6; Yang & Zhang 2006, Equation 3):
//   V_c = sum_i w_i M_ic M_id^-1 V_d   over skeleton bones and muscle joints.
// Joint index space shared by weights, transforms and the Blender add-on ("combined joints"):
//   [0, #B)        skeleton bones, in Skeleton order;
//   [#B, #B + #J)  muscle joints, in MuscleRig order (deformation.h).
// Weight semantics equal Blender's Armature modifier: weights are normalised at deform time and a vertex
// whose weight sum is <= 1e-4 stays at rest.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "myoskin/deformation.h"
#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"
#include "myoskin/skin_weights.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Muscle weights
// ============================================================================

struct HybridWeightOptions {
  double dominance = 1.0;                         // global muscle dominance in [0, 1] (0 = skeleton only)
  std::map<std::string, double> muscleDominance;  // per muscle name, multiplies the global one
  int maxInfluences = 8;                          // slots per vertex in the result
};

// Skeleton weights (#V by K over bones) blended with muscle-joint weights into combined joints; every
// row sums to 1 where the skeleton row did. Throws InputError on mismatched sizes.
SkinWeights computeHybridWeights(const Mesh& skin, const SkinWeights& skeletonWeights, const MuscleRig& rig,
                                 const HybridWeightOptions& options = {});

// ============================================================================
// Transforms
// ============================================================================

// #B + #J skinning transforms M_c * M_d^-1 (combined joints) for a skeleton pose and an evaluated rig.
void skinningTransforms(const Skeleton& skeleton, const Pose& pose, const MuscleRig& rig,
                        const MuscleRigState& state, std::vector<Mat4>& transforms);

}  // namespace myoskin
