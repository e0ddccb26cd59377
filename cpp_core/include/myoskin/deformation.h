// Muscle deformation (DESIGN.md section 5; Yang & Zhang 2006, "Muscle Deformation", "Muscle Movement"):
// action paths (straight, wrapping round a joint sphere, wrapping round a bone cylinder), the frame
// carried along them, volume-preserving bulge, and the muscle joints whose matrices Equation 3 uses.
//
// Conventions (shared with skinning.h and the Blender add-on):
// - every matrix is in mesh space (metres), like Blender's Bone.matrix_local / PoseBone.matrix;
// - a muscle joint's frame follows Blender's bone convention: its Y axis is the path tangent
//   (origin -> insertion), X and Z span the section plane. A joint matrix is
//   T(path point) * R(carried frame) * diag(s, lambda, s): scale s across the muscle, the path's stretch
//   lambda = L / L0 along it. So a muscle joint can be written 1:1 to a Blender deform bone whose
//   matrix_local is the joint's bind matrix (head = bind translation, tail along bind Y).
// - the skinning transform of joint j is jointMatrices[j] * bindMatrices[j]^-1; at rest it is identity.
#pragma once
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "myoskin/mesh.h"
#include "myoskin/muscle.h"
#include "myoskin/skeleton.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Options
// ============================================================================

struct MuscleRigOptions {
  int jointsOverride = 0;        // > 0: use this many joints per muscle instead of Muscle::joints
  // Turn the carried frames about the path by a share of the twist between the frame carried to the
  // insertion and the frame the insertion bone carries there (like twist bones), so that a forearm's roll
  // reaches the skin on the muscle; false: frames anchored to the origin bone only.
  // The twist is taken in (-180, 180] degrees: a roll of the insertion past 180 degrees wraps round.
  bool distributeTwist = true;
  // How the twist is shared along the path: true (default) = as the skeleton shares it, by where each station
  // lies at rest (share d_o^2 / (d_o^2 + d_i^2) of its distances to the origin and insertion bones: none along
  // the origin bone, all along the insertion bone, a ramp across the joint; the end stations exactly 0 and 1),
  // so skin the skeleton moves rigidly with the insertion bone is not blended against a half-twisted muscle
  // joint; false = linear in arc length. Bones between the two ends are not looked at: along a middle bone of
  // a two-joint muscle the share is about a half.
  bool twistFollowsBones = true;
  // Whether a muscle joint's position along the bone it lies on follows the muscle (true, the default: the joint
  // rides its station of the posed path, so a shortening muscle carries the skin over its belly along the limb
  // towards its origin) or the bone (false: the component of the joint's motion along its bone's axis is that bone's;
  // the path still sets its offset across the bone, its frame and its scale; the surface's stations move the same
  // way). The bone is the one of the origin-to-insertion chain nearest to the joint at rest. Measured (README "Joints
  // that do not slide"): false nearly halves the tune bipeds' crumples over the bend sweep under the volume blend and
  // raises the biceps' bulge, but the sliding skin is what keeps the elbow's crease in linear and Preserve Volume
  // skinning (makehuman_muscular_male's elbow at 120 degrees with Preserve Volume: -20.3 % with true, -34.0 % with
  // false, LBS -45.5 %). The add-on's Joints Slide setting and the CLI's --joints-slide choose it.
  bool jointsSlide = true;
  // With jointsSlide: how far each muscle joint may slide along its bone (#J by 2, the rig's joint order: towards
  // the bone's head, towards its tail; mesh units; empty = no limit, an entry <= 0 or not finite = none that way).
  // A joint's offset o along its bone from where the bone carries its rest point becomes rho tanh(o / rho), rho the
  // limit on o's side: the same for small slides, never past rho. Skin a muscle carries with weight W slides W o
  // along the limb, so where W falls by dW over ds in the direction of the slide the skin folds once o dW / ds
  // reaches 1; computeSlideLimits (skinning.h) gives each joint the rho that keeps it below that on a bound skin.
  // The surface's stations between two joints' stations take 1 / rho interpolated between theirs.
  std::vector<std::array<double, 2>> slideLimits;
};

// ============================================================================
// Evaluated state (preallocated by MuscleRig::makeState, refilled by evaluate without allocating)
// ============================================================================

struct MuscleRigState {
  std::vector<Mat4> jointMatrices;   // #J posed joint matrices (mesh space)
  std::vector<double> length;        // #M action-path length (a joint wrap's two ways: their weighted mean)
  std::vector<double> stretch;       // #M lambda = length / rest length
  std::vector<char> wrapped;         // #M 1 when the path (of a joint wrap, the way that weighs more) wraps
  std::vector<Points> surfaces;      // #M posed surfaces (#V_m by 3), filled when requested
};

// ============================================================================
// The stateful evaluator: built once from skeleton + muscles, then evaluate(pose) per frame
// ============================================================================

class MuscleRig {
 public:
  // Validates (InputError naming the muscle/bone): attachment bones exist, origin != insertion, wrap bone
  // exists and radius > 0 when wrapping, sections usable. Muscles are copied.
  MuscleRig(const Skeleton& skeleton, const std::vector<Muscle>& muscles, const MuscleRigOptions& options = {});

  int numMuscles() const;
  int numJoints() const;                        // total muscle joints #J over all muscles
  int jointOffset(int muscle) const;            // first joint index of a muscle
  int jointCount(int muscle) const;             // joints of a muscle
  const std::vector<std::string>& jointNames() const;   // #J, "<muscle name>.j<k>" (k from 0, origin side)
  const std::vector<int>& jointMuscle() const;          // #J muscle index of each joint
  const std::vector<int>& jointParentBone() const;      // #J skeleton bone (the muscle's origin bone)
  const std::vector<Mat4>& bindMatrices() const;        // #J rest joint matrices (rigid: scale 1)
  const std::vector<double>& restLengths() const;       // #M rest action-path length (as MuscleRigState::length)
  const std::vector<Muscle>& muscles() const;
  const Skeleton& skeleton() const;
  const Mesh& restSurface(int muscle) const;            // the surface evaluate() deforms (lofted if absent)
  bool jointsSlide() const;                             // MuscleRigOptions::jointsSlide it was built with
  const std::vector<std::array<double, 2>>& slideLimits() const;  // #J by 2 MuscleRigOptions::slideLimits (0 = none)
  const std::vector<Vec3>& slideAxes() const;           // #J rest unit axis (head -> tail) of the bone each joint
                                                        // slides along (its origin-to-insertion chain's nearest)

  // A state sized for this rig (allocates once).
  MuscleRigState makeState() const;
  // Fill state.jointMatrices/length/stretch/wrapped from a pose (#B posed bone matrices); with
  // withSurfaces also state.surfaces. No allocation once state came from makeState. Throws InputError
  // on a pose of the wrong size or with non-finite values.
  void evaluate(const Pose& pose, MuscleRigState& state, bool withSurfaces = false) const;

  struct Impl;

 private:
  std::shared_ptr<const Impl> impl_;
};

}  // namespace myoskin
