// Anchored skin: a second deformer beside Equation 3 (Schneider & Wilhelms 1998, "Hybrid anatomically based
// modeling of animals"; Arabaci 2001, "Realistic rendering of human models", section 3.3-3.4).
//
// The skin is anchored once, at rest, to the nearest point of the nearest underlying component: ellipsoid
// muscles between an origin and an insertion (volume-preserving, Arabaci Eqs. 3.8-3.10), deformable-cylinder
// muscles (the extracted muscle's sections along its straight line), stuffing ellipsoids carried by a bone,
// capsules round the character's bones and spheres at its joints. Per pose, each component is posed as an
// affine frame (centre, rotation, scale along its own axes); the anchor moves and scales with the component
// (the attachment vector scales), the offset from the anchor to the skin vertex keeps its length in the
// component's rotated frame (the surface vector does not scale). The rest pose reproduces the skin exactly.
// Where neighbouring vertices anchor to different components the skin kinks; an iterative relaxation toward
// the rest edge lengths near those seams smooths it (a no-op at rest).
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "myoskin/mesh.h"
#include "myoskin/muscle.h"
#include "myoskin/skeleton.h"
#include "myoskin/skin_weights.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Closest point on an ellipsoid (Newton-Raphson, Arabaci Eqs. 3.11-3.17)
// ============================================================================

struct EllipsoidSolverOptions {
  double tolerance = 1e-12;  // stop when the Lagrange parameter's step is below tolerance * (largest radius)^2
  int maxIterations = 20;    // Newton steps (a step leaving the bracket becomes a bisection step)
};

struct EllipsoidClosest {
  Vec3 point = Vec3::Zero();  // on the surface, in the ellipsoid's own frame
  double distance = 0.0;      // |p - point|
  int iterations = 0;         // Newton/bisection steps taken (0 for the closed-form cases)
  bool converged = true;
};

// Nearest point on the axis-aligned ellipsoid (x/r0)^2 + (y/r1)^2 + (z/r2)^2 = 1 to p (its own frame), inside
// or outside: x_i = r_i^2 p_i / (r_i^2 + t) with t the largest root of sum (r_i p_i / (r_i^2 + t))^2 = 1,
// found by Newton-Raphson on 1/sqrt(g(t)) - 1 (nearly linear in t, so a start near the pole costs no extra
// steps) safeguarded by a bracket. Robust at the centre, on the axes (the evolute case: t at the pole, the
// nearest point off the axis) and for flat ellipsoids. Throws InputError on a non-positive or non-finite
// radius or a non-finite point.
EllipsoidClosest closestPointOnEllipsoid(const Vec3& radii, const Vec3& p, const EllipsoidSolverOptions& options = {});

// (4/3) pi r0 r1 r2.
double ellipsoidVolume(const Vec3& radii);

// ============================================================================
// Components
// ============================================================================

enum class ComponentKind { MuscleEllipsoid, MuscleCylinder, Stuffing, BoneCapsule, JointSphere };
const char* componentKindName(ComponentKind kind);

// One cross-section of a deformable-cylinder muscle in the muscle's rest frame (Y along origin -> insertion,
// z = distance along Y from the origin attachment; (x, y) offset of its centre; semi-axes a along X', b).
struct CylinderSection {
  double z = 0.0;
  Vec2 offset = Vec2::Zero();  // centre offset in the frame's (X, Z) plane
  double angle = 0.0;          // direction of semi-axis a in the (X, Z) plane (radians from X)
  double a = 0.0, b = 0.0;
};

// An underlying component. Every kind has a rest frame (`center`, orthonormal `axes` columns X, Y, Z; Y is the
// long axis) and radii along those axes; what carries it differs:
// - MuscleEllipsoid: between the origin attachment (on bone `bone`) and the insertion attachment (on
//   `insertionBone`), spanning the ratios [startRatio, endRatio] of the origin -> insertion line; posed, its Y
//   axis runs origin -> insertion as posed by their bones, stretch lambda = L / L0, effective stretch
//   lambda^bulge, long radius times that and the cross radii times its -1/2 power (volume constant);
// - MuscleCylinder: the same line and stretch; the surface is the `sections` (a deformable cylinder);
// - Stuffing: an ellipsoid carried rigidly by `bone`;
// - BoneCapsule: radius radii.x() round the segment center +- axes.col(1) * halfLength, carried by `bone`;
// - JointSphere: radius radii.x() at a joint (the head of `insertionBone`, child of `bone`), turning half way
//   between the two bones (the rotation slerped at 0.5), placed where the child's head goes.
struct AnchoredComponent {
  ComponentKind kind = ComponentKind::Stuffing;
  std::string name;
  int bone = -1;           // carrying / origin / parent bone (skeleton index)
  int insertionBone = -1;  // muscles: the insertion's bone; joint spheres: the child bone
  Vec3 center = Vec3::Zero();
  Mat3 axes = Mat3::Identity();  // columns X, Y (long axis), Z; orthonormal, right-handed
  Vec3 radii = Vec3::Ones();     // along X, Y, Z (capsule and sphere: radii.x() is the radius)
  double halfLength = 0.0;       // capsule: half the segment
  // Muscles: attachment points at rest (mesh space), placement ratios along them and the bulge ratio.
  Vec3 origin = Vec3::Zero(), insertion = Vec3::Zero();
  double startRatio = 0.0, endRatio = 1.0;
  double bulge = 1.0;  // in [0, 1]: 1 = the whole length change goes into the radii (Arabaci), 0 = rigid
  std::vector<CylinderSection> sections;  // MuscleCylinder only, z increasing
};

struct AnchoredComponents {
  std::vector<AnchoredComponent> components;
};

struct ComponentOptions {
  bool muscleEllipsoids = true;   // one ellipsoid per muscle fitted to its sections
  bool muscleCylinders = false;   // instead: one deformable cylinder per muscle (its sections)
  bool boneCapsules = true;       // one capsule per deform bone that is some vertex's dominant bone
  bool jointSpheres = true;       // one sphere per joint between two bones that both have capsules
  // Capsule radius: this fraction of the median distance from the bone's segment of the skin it dominates.
  double capsuleRadius = 0.6;
  // Joint sphere radius: this times the larger of the two capsules' radii (above 1: the skin round the joint
  // anchors to the sphere rather than to either capsule, so it turns half way with the joint). Measured on
  // MakeHuman's 120-degree elbow: 1.15 -> -21.8 % band volume, 1.4 -> -19.5 % (with the muscles aimed).
  double jointSphereRadius = 1.4;
  double muscleBulge = 1.0;       // the bulge ratio given to every derived muscle
  std::vector<AnchoredComponent> stuffing;  // authored components appended as given (any kind)
};

// An ellipsoid muscle placed as Arabaci places it: between the points at startRatio and endRatio of the line
// origin -> insertion (the two distance ratios), cross radii radiusX and radiusZ, X axis the component of xHint
// across the line; bulge ratio in [0, 1]. Throws InputError when origin equals insertion or the ratios or radii
// are unusable.
AnchoredComponent makeEllipsoidMuscle(const std::string& name, int originBone, const Vec3& origin, int insertionBone,
                                      const Vec3& insertion, double startRatio, double endRatio, double radiusX,
                                      double radiusZ, const Vec3& xHint, double bulge = 1.0);

// Components from the skeleton, the extracted (or authored) muscles and the skin: one ellipsoid (or cylinder)
// per muscle fitted to its sections (long axis origin -> insertion, cross radii the belly's, long radius by
// least squares from how the sections narrow, placement ratios from where it lies), one capsule per deform bone
// with a radius from the skin round it, one sphere per joint, then options.stuffing. skinWeights: #V by K over
// the skeleton's bones. Throws InputError on a muscle whose bone is missing, whose origin equals its insertion,
// or whose sections have no positive radius, and on mismatched sizes.
AnchoredComponents deriveComponents(const Skeleton& skeleton, const std::vector<Muscle>& muscles, const Mesh& skin,
                                    const SkinWeights& skinWeights, const ComponentOptions& options = {});

// Throws InputError (naming the component) on a bad bone index, a non-positive or non-finite radius, axes that
// are not a rotation, a muscle whose origin equals its insertion (within 1e-9 of `scale`) or ratios outside
// [0, 1] / not increasing, a bulge outside [0, 1], or cylinder sections not increasing in z.
void validateComponents(const AnchoredComponents& components, const Skeleton& skeleton, double scale);

// ============================================================================
// The deformer: built once from the rest skin and components, evaluate(pose) per frame
// ============================================================================

struct AnchoredSkinOptions {
  EllipsoidSolverOptions solver;
  // Candidates of a vertex: only components carried by a bone holding at least this share of the vertex's
  // largest skin weight (0 = every component). A vertex with no candidate anchors to the nearest of all.
  double weightShare = 0.2;
  // An ellipsoid muscle competes for a vertex only alongside its belly: the vertex's coordinate along the
  // muscle's long axis within this fraction of the long radius (tips and tendons are left to the bones).
  double bellyReach = 0.9;
  // A muscle competes only for skin one bone moves nearly rigidly: the vertex's largest skin weight at least this
  // share of its weight sum (skin the skeleton blends across a joint anchors to the joint's sphere or the bones'
  // capsules, so a muscle spanning the joint does not drag it along its chord). 0 = no limit.
  double muscleRigidShare = 0.75;
  // How far a muscle's posed long axis turns from where its origin bone carries it toward the posed origin ->
  // insertion line, in [0, 1] (slerp of that turn): 1 = the axis runs origin -> insertion (Schneider & Wilhelms'
  // muscles), 0 = carried by the origin bone only, stretching along it (Arabaci, Fig. 3.10). 0 by default: an aimed
  // muscle turns the skin anchored to it off its own bone (the horse's front knee at 90 degrees: band -127 % with
  // 1, -59 % with 0; MakeHuman's elbow -19.5 % with 1, -13.6 % with 0).
  double muscleAim = 0.0;
  // Relaxation (Schneider & Wilhelms section 4.3): vertices within relaxRings edge rings of a seam (an edge
  // whose vertices anchor to different components) move toward the rest edge lengths, the rest pinned.
  int relaxRings = 2;
  int relaxIterations = 10;       // iteration cap (0 = no relaxation)
  double relaxTolerance = 1e-4;   // stop when an iteration lowers the edge energy by less than this fraction
  double relaxStep = 0.5;         // Jacobi step toward the averaged edge-length targets, in (0, 1]
  // Move only across the vertex's normal (its anchor's posed surface vector): the skin slides over the components
  // instead of shrinking onto them (moving in 3D, MakeHuman's 120-degree elbow band: -36.6 % instead of -13.6 %).
  bool relaxTangential = true;
  std::vector<int> pinned;        // vertices the relaxation never moves (besides those away from seams)
  int grainSize = 4096;           // vertices per parallel task
  int threads = 0;                // worker threads for evaluate; 0 = all cores
};

// What anchoring found (for reports and tests).
struct AnchoringReport {
  std::vector<int> vertexComponent;  // #V the component each vertex anchors to
  std::vector<int> verticesPerComponent;  // #C
  int seamVertices = 0;      // vertices the relaxation may move
  int fallbackVertices = 0;  // vertices with no candidate by weight (anchored to the nearest of all)
  int ties = 0;              // vertices equidistant (1e-9 of the scale) from two candidates: the lower index won
  int maxSolverIterations = 0;
  double scale = 0.0;        // the skin's principal extent
};

// Per-frame statistics of the last evaluate (relaxation energy per iteration).
struct RelaxationTrace {
  // Sum over the edges of this frame's active vertices (strained seam vertices and their neighbours) of
  // (|e| - |e_rest|)^2, before the first iteration and after each; empty when nothing is strained (at rest).
  std::vector<double> energy;
};

class AnchoredSkin {
 public:
  // restSkin: the skin at rest (closed or not; triangles for the relaxation's adjacency); skinWeights: #V by
  // K over the skeleton's bones (which components a vertex may anchor to). Throws InputError on mismatched
  // sizes, NaN vertices, bad components (validateComponents) or an empty component list.
  AnchoredSkin(const Mesh& restSkin, const SkinWeights& skinWeights, const AnchoredComponents& components,
               const Skeleton& skeleton, const AnchoredSkinOptions& options = {});
  ~AnchoredSkin();
  AnchoredSkin(AnchoredSkin&&) noexcept;
  AnchoredSkin& operator=(AnchoredSkin&&) noexcept;

  int numVertices() const;
  int numComponents() const;
  const AnchoredComponents& components() const;
  const AnchoringReport& report() const;
  const AnchoredSkinOptions& options() const;

  // out: #V by 3 posed skin for a pose (#B posed bone matrices). No allocation once out has the right size
  // (scratch buffers are the object's own: one evaluate at a time per object). Throws InputError on a pose of
  // the wrong size or with non-finite values. trace (optional) receives the relaxation's energies.
  void evaluate(const Pose& pose, Points& out, RelaxationTrace* trace = nullptr) const;
  // The same into a raw buffer of 3 * numVertices() doubles (row-major #V by 3, e.g. a numpy array).
  void evaluate(const Pose& pose, double* out, RelaxationTrace* trace = nullptr) const;
  // Posed components (centre, axes, radii) for a pose: what evaluate anchors to (drawing, tests).
  void posedComponents(const Pose& pose, std::vector<AnchoredComponent>& out) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Writes the anchored skin of each pose to a PC2 (Blender's Mesh Cache modifier), frames from startFrame.
void writeAnchoredPC2(const std::string& path, const AnchoredSkin& skin, const std::vector<Pose>& poses,
                      float startFrame = 1.0f);

}  // namespace myoskin
