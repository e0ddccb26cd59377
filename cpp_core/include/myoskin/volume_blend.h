// Volume blend (issue 14 item 3, "joints keep their volume"): a per-vertex share s in [0, 1] between the linear
// (Equation 3) skin and the dual-quaternion one (Blender's Preserve Volume), SkinnerOptions::dqsShare:
//   p = (1 - s) * linear + s * dual quaternion.
// Linear blending loses volume at a bent joint (the crease collapses), dual quaternions keep it or, at joints whose
// skin the skeleton blends over a wide band (hips, some knees), over-inflate it. The share of each real joint is the
// one that keeps its band's volume at a reference bend; a vertex takes the shares of the joints its skeleton weights
// blend across. Blender evaluates the same result with two Armature modifiers (the second with Preserve Volume and
// Multi Modifier, 1 - the share as its vertex group), so Blender = core stays exact.
#pragma once
#include <vector>

#include <Eigen/Geometry>

#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"
#include "myoskin/skin_weights.h"
#include "myoskin/skinning.h"
#include "myoskin/types.h"

namespace myoskin {

class MuscleRig;  // deformation.h

// ============================================================================
// Options and per-joint report
// ============================================================================

struct VolumeBlendOptions {
  // Reference flexion of each joint, in degrees: the joint's child subtree turns about the joint by this angle
  // (forward, about d x facing, d the child bone's direction; down a leg, a limb whose skin reaches the lowest fifth
  // of the body's height, the joints alternate from its root: hip forward, knee backward, a horse's hock forward; an
  // arm's joints bend forward however far it hangs; a child along the facing, a foot, turns its tail down).
  double bendDegrees = 90.0;
  // The joint's share is the largest whose |band change| at the reference flexion is at most the smallest any share
  // gives or keepTolerance x |linear's change|: dual quaternions are kept where they already keep the volume that
  // well (measured: generated bipeds' elbows +0.8..+1.3 % against linear's -16..-22 % at 90 degrees, which a share
  // of 0.93-0.98 would zero but then lose 1-2 points more at 120 degrees).
  double keepTolerance = 0.1;
  // Band = the skin within bandRadius limb radii of the joint (bodyLimbRadius: the median distance of the limbs' skin
  // from their bones, so the band scales with the body; benchmarks/skin_quality.py measures the same band).
  double bandRadius = 1.5;
  // A vertex belongs to a joint's blend when b = 2 min(share inside the child's subtree, share outside) >= minBlend
  // (b = 1 at an even blend across the joint, 0 on skin one side moves alone).
  double minBlend = 0.05;
  // Share of a vertex outside every real joint's band that no joint and no twist split blends across (b < minBlend):
  // one bone moves it, so the two blends differ there only by the muscle joints' rotation and scale (measured on
  // MakeHuman, generated bodies, the soldier and the horse: band changes and bulges unchanged). 0 = linear, which
  // Blender 4.x/5.x evaluate with one Armature modifier instead of two (the volume blend's playback cost). Inside a
  // band, across a twist split (dual quaternions keep a twisting forearm from collapsing) and across a joint whose
  // band could not be measured the share stays 1.
  double unblendedShare = 0.0;
  // The body's up axis; zero = automatic: against the sum of the limb bones (legs point down; arms sideways or down),
  // across the left-right axis; without limbs +Y when the skin is taller along Y than along Z (glTF), else +Z
  // (Blender). The left-right axis is the normal of the skeleton's mirror plane (skeletonMirrorPlane; X without one),
  // facing = left x up, turned where the feet (bones hanging from a downward limb bone and lying along the ground)
  // point, without feet where the neck leans (a horse's), else with +X the left. So the shares follow the body, not its
  // coordinates: turned in space or imported Y-up or Z-up, a character gets the same shares (to 1e-9 for quarter
  // turns; band changes are measured in float64).
  Vec3 up = Vec3::Zero();
};

// What computeDqsShare found at one joint (the head of `bone`, whose subtree turns).
struct JointVolumeBlend {
  int bone = -1;
  double radius = 0.0;        // the body's limb radius the band is measured in (character units)
  int blendedVertices = 0;    // vertices with b >= minBlend
  int bandTriangles = 0;      // triangles whose three vertices lie in the band
  double share = 1.0;         // the joint's dual-quaternion share
  double linearChange = 0.0;    // band volume change at the reference flexion, linear (relative to rest)
  double dualQuatChange = 0.0;  // the same, dual quaternions
  double blendChange = 0.0;     // the same, with the chosen share
  Vec3 axis = Vec3::Zero();     // the reference flexion's rotation axis (unit)
};

// ============================================================================
// Shares
// ============================================================================

// #V dual-quaternion shares in [0, 1] for a skin (#V vertices, its triangles) bound to a skeleton by its skeleton
// weights (#V by K over the bones): for each real joint (a bone with a parent, not a twist split: twistSplits) whose
// skin the skeleton blends across it, the share s_j in [0, 1] minimising |band volume change| of the blend at the
// reference flexion (within keepTolerance; s_j = 1 where dual quaternions lose volume there too: elbows, shoulders);
// each vertex takes sum_j b_j s_j / sum_j b_j over the joints it blends across (b_j >= minBlend), 1 where it blends
// across twist splits or unmeasured joints only or inside a joint's band, and unblendedShare (0) elsewhere.
// Deterministic (no threads).
// `joints` (optional) receives one entry per joint measured. Throws InputError on mismatched sizes, bad weights or
// indices, non-finite vertices or options out of range (bendDegrees in (0, 180], bandRadius > 0, keepTolerance in
// [0, 1], minBlend in (0, 1], unblendedShare in [0, 1]).
Eigen::VectorXd computeDqsShare(const Skeleton& skeleton, const SkinWeights& skeletonWeights, const Mesh& skin,
                                const VolumeBlendOptions& options = {}, std::vector<JointVolumeBlend>* joints = nullptr);

// ============================================================================
// Volume keys
// ============================================================================

// A joint's volume key (a shape key in Blender): rest-space offsets of the skin around a real joint (along the rest
// normals or away from the joint's head) that keep the band's volume as it bends: outward where the blend still
// loses volume there, inward where it gains (the muscles over a knee thickening more than the joint collapses); a
// negative weight moves the skin the other way (a band that gains volume at small bends and loses it at deep ones).
// Its weight follows the swing of the joint's child bone, s = x^2 + z^2 = sin^2(swing / 2) of the bone's local rotation
// quaternion (w, x, y, z) (twist about the bone moves nothing; Blender reads it with a driver on the bone's Local
// Space quaternion):  weight = clamp(s (k1 + k2 s) g, -1, 1), s (k1 + k2 s) in [-1, 1] for every swing by construction;
// g = 1, or for a directional key (a limb's root: one per quarter of swing directions) g = max(swing . lean, 0)^2 /
// max(|lean|^2, 1e-12), lean = (xy - wz, yz + wx) the way the bone's Y axis leans in its rest frame's x and z (the
// four quarters' g sum to 1).
struct VolumeKey {
  int bone = -1;               // the joint's child bone (its local rotation drives the key)
  std::vector<int> vertices;   // the skin vertices it moves, ascending
  Points offsets;              // #vertices by 3, rest-space offsets at weight 1
  double k1 = 0.0, k2 = 0.0;   // weight = s (k1 + k2 s)
  Eigen::Vector2d swing = Eigen::Vector2d::Zero();  // unit (x, z) in the bone's rest frame; zero: any swing
  // The fit: the swing axis the samples turn about (the reference flexion's, made perpendicular to the bone's rest Y;
  // a limb root's quarters turn it about that Y by 90, 180, 270 degrees) and per sample flexion the band's volume
  // change (relative to rest) without and with the key.
  Vec3 axis = Vec3::Zero();
  std::vector<double> sampleDegrees, changeWithout, changeWith;
};

struct VolumeKeyOptions {
  // Flexions (degrees about each joint's reference flexion axis, VolumeBlendOptions) at which the key would keep
  // the band's volume; the weight's two coefficients fit the amplitudes found there (least squares in s).
  std::vector<double> sampleDegrees = {45.0, 90.0, 135.0};
  // The largest offset, in body limb radii (the profile is the joint's blend b, 1 where the skin blends evenly across
  // it, tapering to 0 at the band's edge, on the outer side, all round or on the crease's side).
  double maxOffset = 1.0;
  // With a muscle rig (Bind's skin): how the dual-quaternion part carries the muscle joints' scale, as Bind's
  // Blender does (SkinnerOptions::dualQuatScale: Pivot on 4.x/5.x, Blended on 3.x).
  DualQuatScale dualQuatScale = DualQuatScale::Pivot;
};

// One volume key per limb joint (a real joint, as computeDqsShare's, whose bone or the real joint above it has the Limb
// role: shoulders, elbows, wrists, hips, knees, ankles, a horse's knees and hocks; a trunk or a digit bends over many
// bones, each joint a little) whose band still changes volume under the volume blend
// `share` (#V, computeDqsShare's) when the joint bends about its reference flexion axis. The key pushes out when the
// sample with the largest change loses volume, in when it gains. At each sample flexion the
// amplitude is the one that keeps the band's cone volume (at most maxOffset limb radii), lowered until the band has
// no more self-intersecting triangle pairs than without the key; the weight's fit is checked the same way every 30
// degrees. Skin that touches other skin under the push (the back of the knee, under the armpit) stays still, the
// profile faded back over half a limb radius: every contact held, or only those the push makes. The profile swells
// the outer side, the skin all round or the crease's side, or swells the outer side while it draws the crease's side
// in, each along the rest normals or away from the joint's head (at a crease closing against the trunk, a raised arm's
// shoulder, both facing sides then move out together); of the sixteen fits (directions times sides times contact
// modes) that lower the band's largest |change| over the samples, the key is the one with the least sum of |change|
// there, then the fewest self-intersecting pairs (swing axes fitted in parallel on TBB's threads; the choice does not
// depend on them). With `rig` (built on `skeleton`) and its `hybridWeights` (computeHybridWeights: #V rows over the
// bones, then the rig's joints) the bends are Bind's skin, the muscle joints included (combinedRestMatrices, the share,
// keyOptions.dualQuatScale): the keys give back only the volume the muscles leave lost, or take back what they add.
// Deterministic. Throws
// InputError on what computeDqsShare refuses, a share of the wrong size or outside [0, 1], no samples or a sample
// outside (0, 180], maxOffset <= 0, a rig without its weights (or weights without a rig), a rig over another number of
// bones, or hybrid weights of the wrong size or out of range.
std::vector<VolumeKey> computeVolumeKeys(const Skeleton& skeleton, const SkinWeights& skeletonWeights,
                                         const Mesh& skin, const Eigen::VectorXd& share,
                                         const VolumeBlendOptions& options = {},
                                         const VolumeKeyOptions& keyOptions = {}, const MuscleRig* rig = nullptr,
                                         const SkinWeights* hybridWeights = nullptr);

// The key's weight for its bone's local rotation (boneLocalRotation in correctives.h; any norm).
double volumeKeyWeight(const VolumeKey& key, const Eigen::Quaterniond& localRotation);

// out = base + sum_k volumeKeyWeight(key k, localRotations[key k's bone]) offsets_k (base: #V by 3; out resized
// once). Throws InputError when a key's vertex or bone is out of range.
void applyVolumeKeys(const std::vector<VolumeKey>& keys, const std::vector<Eigen::Quaterniond>& localRotations,
                     const Points& base, Points& out);

}  // namespace myoskin
