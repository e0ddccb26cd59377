// Hybrid skinning (DESIGN.md section 6; Yang & Zhang 2006, Equation 3):
//   V_c = sum_i w_i M_ic M_id^-1 V_d   over skeleton bones and muscle joints.
// Joint index space shared by weights, transforms and the Blender add-on ("combined joints"):
//   [0, #B)        skeleton bones, in Skeleton order;
//   [#B, #B + #J)  muscle joints, in MuscleRig order (deformation.h).
// Weight semantics equal Blender's Armature modifier: weights are normalised at deform time and a vertex
// whose weight sum is <= 1e-4 stays at rest.
#pragma once
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "myoskin/deformation.h"
#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"
#include "myoskin/skin_weights.h"
#include "myoskin/types.h"

namespace myoskin {

using PointsF = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;  // #V by 3 float32
// #V by 12: per vertex the row-major 3 by 4 affine map [A | b] a deform applies to it (Skinner::vertexTransforms).
using VertexTransforms = Eigen::Matrix<double, Eigen::Dynamic, 12, Eigen::RowMajor>;

// Weight sum at or below which a vertex stays at rest (Blender's Armature modifier).
constexpr double kRestWeightThreshold = 1e-4;
// Most smoothing passes HybridWeightOptions::smoothingDistance asks for per muscle (cost grows as 1 / edge^4).
constexpr int kMaxSmoothingPasses = 1000;

// ============================================================================
// Muscle weights
// ============================================================================

struct HybridWeightOptions {
  double dominance = 1.0;                         // global muscle dominance in [0, 1] (0 = skeleton only)
  std::map<std::string, double> muscleDominance;  // per muscle name, multiplies the global one (>= 0)
  // Influences per vertex in the result, bones and muscle joints together (>= 1): the largest are kept and
  // renormalised. 4 is what game engines take (glTF's JOINTS_0); it is not the default because cutting
  // renormalises the bones no muscle spans too and moves muscle shares by up to 0.034 (synthetic arm), for
  // ~0.01 ms per frame in Blender 4.5 (50k vertices, mean 2.5 influences, 7 at most).
  int maxInfluences = 8;
  // Influence of a muscle on a skin vertex from the vertex's distance d to the muscle's surface, in units
  // of the muscle's mean section radius r: full up to fullDistance * r, falling smoothly to 0 at
  // falloffDistance * r (so smooth skin away from every muscle gets none).
  double fullDistance = 0.35;
  double falloffDistance = 1.5;
  int smoothingIterations = 24;  // Laplacian smoothing passes (one edge ring each) of each muscle's weight
  // Body-relative smoothing instead of the pass count (0 = off, the default: smoothingIterations): a diffusion
  // distance L in units of the muscle's mean section radius, so a coarse and a fine mesh of the same body get the
  // same weights. Each pass sets a vertex to 1/2 itself + 1/2 its ring's mean, a lazy random walk whose RMS reach after
  // n passes is sqrt(n <e^2> / 2), so n = 2 L^2 / <e^2> (<e^2> the mean squared edge length around the muscle),
  // rounded, at most kMaxSmoothingPasses. The fixed 24 passes reach 0.4-1.5 radii on the 110k-vertex generated bodies
  // and 0.8-4.2 radii on makehuman_muscular_male's coarse skin. Not the default: measured (README "Plantar flexion"),
  // 0.5 or 0.7 radii help MakeHuman (elbow +Preserve Volume -20.4 -> -13.3 %, calf bulge 0.030 -> 0.047 r) but cost
  // held-out bodies (biped 20's elbow 121 -> 183 crossing pairs, LBS 159; makehuman_neutral's knee -15.0 -> -16.9 %).
  double smoothingDistance = 0.0;
  // Fraction of the straight rest line origin -> insertion, from each end, over which the muscle's weight
  // fades to 0, so the skin over the tendons and attachments follows the bones (0 = no fade).
  double endTaper = 0.5;
  // Further relief in the skeleton's joint creases: each muscle's weight (before smoothing) is multiplied by
  // 1 - creaseRelief * beta, beta = 2 (1 - the vertex's largest bone share) clamped to [0, 1] (0 on skin one
  // bone moves rigidly, 1 at an even two-bone blend; twist splits count too) (0 = off, the default). Without it a muscle already leaves the crease to the skeleton: it takes weight only
  // from its belly's segment, and none at the plane of a real joint it crosses (fading over falloffDistance
  // radii). Measured (synthetic arm seed 2, elbow 70 degrees; plain LBS -13.9 %): elbow region -4.6 % with 0,
  // -5.4 % with 0.5 (before the segment rule and joint fade: +12.2 %, the brachialis lifting the crease).
  double creaseRelief = 0.0;
  // Relief at the border of the muscle's segments: with s the share of a vertex's skeleton weight on the segments
  // a muscle spans (the bones of its origin-to-insertion chain with their twist-split neighbours), the muscle's
  // weight (before smoothing) is multiplied by smoothstep((s - 1) / borderRelief + 1): full where the skin belongs
  // to the muscle's segments alone (s = 1), none where a share of borderRelief or more belongs to other bones. Skin
  // the skeleton blends between the trunk and a limb thus keeps the skeleton's blend under a muscle spanning the
  // limb's root joint (the clavicular pectoral onto the humerus, whose muscle joints barely turn with the arm);
  // skin within a limb (s = 1) is unchanged. 0 = off. Measured (makehuman_muscular_male, 120 degrees shoulder
  // abduction, Preserve Volume): band -27.6 % and 16 crossings with 0, -25.6 % and 3 with 0.1 (LBS -62.7 % / 6,
  // DQS -24.8 % / 0); elbow and knee within 0.1 point.
  double borderRelief = 0.1;
  // Smallest muscle weight kept, in [0, 0.25] (0 = keep every weight): a muscle's share of a vertex below
  // minWeight goes back to the bones it came from, and the smaller part of its split between two joints
  // below minWeight goes to the other joint; shares in [c, 2c) ramp linearly from 0 to 2c, so the weights
  // stay continuous over the skin. Fewer influences per vertex make Blender's Armature modifier cheaper
  // (~5 ns per influence per frame); the bone weights of bones no muscle spans stay exact.
  double minWeight = 0.01;
};

// Combined weights (#V by maxInfluences over combined joints [0, #B + #J)) from the skeleton weights
// (#V by K over the #B bones) and the rig's muscles: each muscle's weight at a vertex comes from the
// vertex's distance to the muscle's rest surface (MuscleRig::restSurface)
// and the muscle's side (the skin normal must face away from the muscle), times the dominance; it is
// smoothed over the skin, faded at the muscle's ends (endTaper) and at the plane of each real joint it crosses,
// taken only from the bones of its belly's segment (a bone with its twist-split neighbours, twistSplits), split
// linearly between the two muscle joints nearest along the muscle, and the skeleton weights (normalised) fill
// the remainder. Every row sums to 1 where the skeleton row was
// non-empty (sum > 1e-4); empty rows stay empty. Throws InputError on mismatched sizes or bad options.
SkinWeights computeHybridWeights(const Mesh& skin, const SkinWeights& skeletonWeights, const MuscleRig& rig,
                                 const HybridWeightOptions& options = {});

// #J by 2 slide limits for the rig's joints on a bound skin (MuscleRigOptions::slideLimits: how far each joint may
// slide along its bone towards the bone's head, towards its tail; 0 = no limit that way). Skin carried by a muscle
// with total weight W (its joints' weights summed, `weights` over combined joints [0, #B + #J)) slides W o when its
// joints slide o along the axis a, so a rest triangle whose gradient of W along a is g folds once 1 + o g < 0: the
// limit towards the tail is 1 / max(-g), towards the head 1 / max(g), over the triangles where the joint has weight,
// times `margin` (> 0); slivers (sin^2 of their angle under 1e-6) are skipped. Throws InputError when the weights'
// rows are not the skin's vertices, a joint index lies past #B + #J, or the margin is not positive.
std::vector<std::array<double, 2>> computeSlideLimits(const Mesh& skin, const SkinWeights& weights,
                                                     const MuscleRig& rig, double margin = 1.0);

// ============================================================================
// Transforms
// ============================================================================

// #B + #J skinning transforms M_c * M_d^-1 (combined joints) for a skeleton pose and an evaluated rig.
void skinningTransforms(const Skeleton& skeleton, const Pose& pose, const MuscleRig& rig,
                        const MuscleRigState& state, std::vector<Mat4>& transforms);

// #B + #J rest matrices of the combined joints: the skeleton's bone rest matrices, then the rig's muscle
// joint bind matrices (SkinnerOptions::jointRest for the preserve-volume mode).
std::vector<Mat4> combinedRestMatrices(const Skeleton& skeleton, const MuscleRig& rig);

// #B skeleton-only skinning transforms pose.matrices[i] * rest_i^-1 (plain LBS). Throws InputError on a
// pose of the wrong size or with non-finite values.
void skeletonTransforms(const Skeleton& skeleton, const Pose& pose, std::vector<Mat4>& transforms);

// ============================================================================
// The skinner: built once from rest vertices + sparse weights, then deform(transforms) per frame
// ============================================================================

// How the preserve-volume mode carries a joint's scale (Blender changed it between versions; measured: 3.4.1
// blends, 4.5 and 5.2 pivot):
//   Pivot   (Blender 4.x, 5.x: add_weighted_dq_dq_pivot) each joint's scale becomes the translation it causes at
//           the vertex, so every joint alone still carries the vertex to its linear position;
//   Blended (Blender 3.x: add_weighted_dq_dq) the joints' scale matrices are blended linearly (joints without
//           scale count as the identity) and applied before the blended rigid motion.
enum class DualQuatScale { Pivot, Blended };

struct SkinnerOptions {
  int grainSize = 2048;  // vertices per parallel task (TBB parallel_for grain)
  int threads = 0;       // worker threads; 0 = all cores
  // 0: any weight sum is accepted and normalised (Blender's semantics). > 0: strict, every row must sum to
  // 1 within this tolerance (InputError naming the vertex and its sum otherwise).
  double sumTolerance = 0.0;
  // Blender's "Preserve Volume" (the Armature modifier's use_deform_preserve_volume): blend each vertex's
  // joint transforms as dual quaternions instead of matrices, the way Blender does (mat4_to_dquat splits each
  // joint's scale from its rotation in the joint's own rest frame, orthogonalising about the bone's Y axis;
  // add_weighted_dq_dq(_pivot) with the scale as dualQuatScale says; normalize_dq, mul_v3m3_dq), in float32.
  // Rest pose exact.
  bool preserveVolume = false;
  DualQuatScale dualQuatScale = DualQuatScale::Pivot;  // preserveVolume only: which Blender's scale handling
  // preserveVolume only: each joint's rest matrix M_d (Blender's Bone.matrix_local; combinedRestMatrices),
  // numJoints of them, or empty = identity. Only joints with scale or shear depend on it (the frame in which
  // scale is split from rotation), so rigid transforms give the same result either way.
  std::vector<Mat4> jointRest;
  // Volume blend (volume_blend.h): #V shares s in [0, 1], empty = off (every vertex linear, or every vertex dual
  // quaternion with preserveVolume, as above). When set, each vertex is (1 - s) * linear + s * dual quaternion
  // (preserveVolume is then ignored; dualQuatScale and jointRest still shape the dual-quaternion part), computed in
  // float32 as Blender's second Armature modifier with Preserve Volume and Multi Modifier mixes its result with the
  // first (linear) one through its vertex group, whose weight g = 1 - s is the LINEAR result's share (measured on
  // Blender 3.4.1; a vertex not in the group takes the dual-quaternion result): s = 0 is the linear result, s = 1 the
  // dual-quaternion one, bit for bit.
  std::vector<double> dqsShare;
};

// Equation 3 (or, with SkinnerOptions::preserveVolume, Blender's dual-quaternion blend) in float32 over a
// structure-of-arrays copy of the rest skin: positions x[], y[], z[] and,
// per vertex, its non-empty influences (joint index, weight normalised once at build time, which is
// Blender's deform-time normalisation since the weights do not change). A vertex whose weight sum is
// <= kRestWeightThreshold keeps its rest position. Empty slots (-1 or weight 0) cost nothing.
class Skinner {
 public:
  // rest: #V by 3; weights: #V by K over [0, numJoints). Throws InputError naming the offending
  // vertex/slot on a size mismatch, NaN/inf or negative weight, or a joint index outside [-1, numJoints),
  // on options.jointRest of the wrong count or with a non-finite or singular matrix, and on options.dqsShare of a
  // length other than #V or with a value outside [0, 1] (NaN included).
  Skinner(const Points& rest, const SkinWeights& weights, int numJoints, const SkinnerOptions& options = {});
  ~Skinner();
  Skinner(Skinner&&) noexcept;
  Skinner& operator=(Skinner&&) noexcept;

  int numVertices() const;
  int numJoints() const;
  int influences() const;            // slots per vertex in the packed layout (max used over vertices)
  int restVertices() const;          // vertices that stay at rest (weight sum <= threshold)
  const SkinnerOptions& options() const;
  void setOptions(const SkinnerOptions& options);  // for later deform calls (validated like the constructor)
  size_t bytesPerFrame() const;      // memory read + written by one deform (for bandwidth bounds)

  // transforms: numJoints() skinning transforms (M_c M_d^-1; the last row is ignored). out: #V by 3.
  // Throws InputError on a wrong count or non-finite transform. Thread-safe (const).
  void deform(const std::vector<Mat4>& transforms, PointsF& out) const;
  void deform(const std::vector<Mat4>& transforms, Points& out) const;
  // Raw output buffer of 3 * numVertices() floats (row-major #V by 3), e.g. a numpy array or a PC2 frame.
  void deform(const std::vector<Mat4>& transforms, float* out) const;

  // Per vertex the affine map x -> A x + b that deform() applies to the vertex's input position x (in float64):
  // for fixed weights both blends are affine in x (linear: A | b = sum w_i T_i; Blender's dual quaternions: the
  // blended rotation and, Pivot, the scale's translation at the pivot x, or, Blended, the blended scale matrix),
  // so a shape offset d moves the skinned vertex by A d, and A^-1 maps a sculpt back to the skinner's input
  // (correctives.h). out: #V by 12 (resized once). Same errors as deform.
  void vertexTransforms(const std::vector<Mat4>& transforms, VertexTransforms& out) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// One-shot Equation 3: #V by 3 deformed positions (float64 result of the float32 skinner).
Points skin(const Points& rest, const SkinWeights& weights, const std::vector<Mat4>& transforms,
            const SkinnerOptions& options = {});

// ============================================================================
// Quality measures (tests, examples)
// ============================================================================

// #V by 3 unit area-weighted vertex normals (zero for isolated vertices).
Points vertexNormals(const Points& vertices, const Triangles& triangles);

// Enclosed volume of each region of a skin: a triangle belongs to region r when all three vertices carry
// label r (labels: #V, values in [0, numRegions), -1 = none); each region's volume is the signed volume of
// the cone from the region's vertex centroid to its triangles, so it moves with the region and the
// regions of a closed skin add up to the skin's enclosed volume. Throws InputError on mismatched sizes.
std::vector<double> regionVolumes(const Points& vertices, const Triangles& triangles, const IndexVector& labels,
                                  int numRegions);

// Per-region relative volume change (deformed - rest) / |rest| (0 for an empty region).
std::vector<double> regionVolumeChange(const Points& rest, const Points& deformed, const Triangles& triangles,
                                       const IndexVector& labels, int numRegions);

// Local bulge: for every vertex, its displacement along its rest normal after undoing the rigid motion
// of its dominant skeleton bone: ((T_b^-1 p_deformed) - p_rest) . n_rest, with b the bone of largest
// skeleton weight and T_b = skeletonTransforms[b]. Plain LBS gives 0 wherever a vertex follows one bone;
// muscles bulging give > 0. rest/deformed: #V by 3; returns #V. Throws InputError on mismatched sizes.
Eigen::VectorXd localBulge(const Points& rest, const Triangles& triangles, const Points& deformed,
                           const SkinWeights& skeletonWeights, const std::vector<Mat4>& skeletonTransforms);

// Number of pairs of triangles that intersect each other (neighbours sharing a vertex or an edge do not count),
// among the triangles with faceMask[f] != 0 (#F; empty = all). Throws InputError on non-finite vertices, bad
// indices or a mask of the wrong size.
int selfIntersections(const Points& vertices, const Triangles& triangles, const std::vector<char>& faceMask = {});

// The intersecting pairs themselves: rows of `triangles`, (smaller, larger), sorted. Throws as selfIntersections.
std::vector<std::pair<int, int>> selfIntersectingPairs(const Points& vertices, const Triangles& triangles,
                                                       const std::vector<char>& faceMask = {});

// The same test of one triangle set at many vertex positions (a fit's trials): the mesh is built once, each call
// only moves its points. pairs() gives selfIntersectingPairs' answer; it throws InputError on non-finite vertices or
// another vertex count than the test was made for, the constructor as selfIntersections on bad indices or mask.
class SelfIntersectionTest {
 public:
  SelfIntersectionTest(const Triangles& triangles, Eigen::Index numVertices, const std::vector<char>& faceMask = {});
  ~SelfIntersectionTest();
  SelfIntersectionTest(const SelfIntersectionTest&) = delete;
  SelfIntersectionTest& operator=(const SelfIntersectionTest&) = delete;
  std::vector<std::pair<int, int>> pairs(const Points& vertices);
  // Only the pairs with at least one triangle in `focus` (#F flags over the constructor's rows; they must be masked
  // in): pairs() restricted to them, without testing the other triangles against each other. Where only the focus
  // triangles move between two calls, the pairs among the others are the same in both, so the counts compare as
  // pairs()'s would. Throws as pairs(), and InputError on a focus of the wrong size.
  std::vector<std::pair<int, int>> pairs(const Points& vertices, const std::vector<char>& focus);

 private:
  void movePoints(const Points& vertices);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// ============================================================================
// Point caches (PC2, Blender's Mesh Cache modifier)
// ============================================================================

// A PC2 file's contents: frames of #V by 3 float32 positions.
struct PointCache {
  int numPoints = 0;
  float startFrame = 0.0f;
  float sampleRate = 1.0f;  // frames between samples
  std::vector<PointsF> frames;
};

// Streams frames to a .pc2 file (header "POINTCACHE2", version 1, little-endian); the sample count in
// the header is patched on close(). Throws InputError when the file cannot be written or a frame has
// the wrong size / non-finite values.
class PC2Writer {
 public:
  PC2Writer(const std::string& path, int numPoints, float startFrame = 0.0f, float sampleRate = 1.0f);
  ~PC2Writer();  // closes (errors are swallowed here; call close() to see them)
  void writeFrame(const PointsF& positions);
  void writeFrame(const Points& positions);
  void writeFrame(const float* positions);  // 3 * numPoints floats
  void close();
  int framesWritten() const { return frames_; }

 private:
  struct File;
  std::unique_ptr<File> file_;
  std::string path_;
  int numPoints_ = 0;
  int frames_ = 0;
};

// One-shot writer and the reader (validates the header and the file size; InputError otherwise).
void writePC2(const std::string& path, const std::vector<PointsF>& frames, float startFrame = 0.0f,
              float sampleRate = 1.0f);
PointCache readPC2(const std::string& path);

}  // namespace myoskin
