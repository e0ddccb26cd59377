// Stage 1-2 of extraction (DESIGN.md section 4): cutting planes from the skeleton and the skin's
// profile curve on each plane, as a 2D polygon in the plane's own frame.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "myoskin/character.h"
#include "myoskin/types.h"

namespace myoskin {

// What a bone is for extraction. Limb bones get perpendicular planes; the torso gets the paper's groups.
enum class BoneRole {
  Ignore,    // fingers, toes, face, helpers: no planes
  Limb,      // upper arm, forearm, thigh, shin: planes perpendicular to the bone
  Shoulder,  // clavicle/shoulder: planes around the shoulder joint
  Neck,      // planes perpendicular to the neck
  Spine,     // parallel horizontal planes over the abdomen and chest
  Pelvis,    // hips/pelvis: parallel planes, like the spine
};
const char* boneRoleName(BoneRole role);
BoneRole boneRoleFromName(const std::string& name);  // throws InputError on an unknown name

// Roles from the shape of the bone tree (mirrored limb pairs, each limb's girdle, long segments and extremity, the
// trunk between the limbs' attachments, the neck above), with names as hints where they say something (Rigify,
// MakeHuman, Mixamo words); `overrides` (bone name -> role) win; non-deform bones are ignored. One role per bone.
// `twist` (optional, #B, twistSplits) joins a limb's bones into segments only across twist splits; without it
// nearly collinear bones join.
std::vector<BoneRole> classifyBones(const Skeleton& skeleton, const std::map<std::string, BoneRole>& overrides = {},
                                    const std::vector<char>* twist = nullptr);

// Per bone: 1 when its joint with its parent is a twist split, not a real joint: the bone continues its parent
// (head at the parent's tail, within 30 degrees) and the skin the two share is blended over much of it (at least
// 45 % of the vertices weighted mostly to the pair have both shares between 0.1 and 0.9; a real joint blends in a
// narrow band: measured on MakeHuman 0.27-0.29 at elbow and knee, 0.53-0.68 at its twist splits). #B.
std::vector<char> twistSplits(const Character& character);
std::vector<char> twistSplits(const Skeleton& skeleton, const SkinWeights& weights);


// The skeleton as extraction sees it: bone tails from the joints (each bone ends at its continuing child's head;
// importers guess tails differently) and every bone that carries no skin weight marked non-deform (IK targets,
// poles, helpers).
Skeleton weightedSkeleton(const Character& character);

// classifyBones on weightedSkeleton(character) with its twistSplits: the roles extraction uses.
std::vector<BoneRole> characterBoneRoles(const Character& character,
                                         const std::map<std::string, BoneRole>& overrides = {});

// One cutting plane. The plane's frame: origin on the bone, normal n, in-plane axes xAxis, yAxis
// (right-handed: xAxis x yAxis = normal). 2D coordinates of a point p are ((p-origin).xAxis, (p-origin).yAxis).
struct CuttingPlane {
  int bone = -1;            // bone the plane belongs to
  std::string family;       // "limb", "shoulder", "neck", "abdomen", ...; planes of one family are ordered
  int familyIndex = 0;      // index of the family instance (e.g. one per limb bone chain / per shoulder)
  int order = 0;            // position within its family, increasing along the bone
  double t = 0.0;           // parameter along the bone (0 head, 1 tail) or along the family's axis
  Vec3 origin = Vec3::Zero();
  Vec3 normal = Vec3::UnitY();
  Vec3 xAxis = Vec3::UnitX();
  Vec3 yAxis = Vec3::UnitZ();
  double clipRadius = 0.0;  // > 0: the profile keeps only the skin within this distance of the origin (planes
                            // on shoulder bones, which cut the whole side of the torso), closed by a chord
  bool mirrorAxis = false;  // the plane's y axis lies in the skeleton's mirror (sagittal) plane: torso planes
                            // normal to the spine or neck, their X axis turned sideways where the spine's rest
                            // frame has another axis sideways (skeletonMirrorPlane). Such sections get an even
                            // sample count (mirrored samples on a symmetric body) and are triangulated as two
                            // halves split along the y axis
  std::vector<int> region;  // bones whose skin the profile must stay on (by each vertex's dominant bone);
                            // empty = anywhere. Limbs: the chain, its subtree and its parent; torso
                            // families: every bone outside the limbs (the shoulder also the arm's first bone)
};

struct PlaneOptions {
  double spacing = 0.0;  // metres between planes; 0 = derived from the mesh size (1/80 of its largest extent along its principal axes, principalExtent)
  double endMargin = 0.12;  // fraction of a bone's length left out at each end (joints give no clean loops)
  double bendAngle = 0.26;  // radians: a joint bending more than this inside a chain gets the end margins
  double shoulderStart = 0.35;  // shoulder planes start this fraction along the clavicle chain
  double shoulderSpacing = 0.5;  // the shoulder family's planes are this times `spacing` apart (the shoulder
                                 // chain is short: a muscle needs link.minSections sections)
  double shoulderClip = 1.5;    // planes on shoulder bones clip their profiles to this many times the shoulder
                                // chain's length around the bone (deltoid, pectoral and trapezius reach that far);
                                // 0 = no clipping (such profiles then usually leave the region and are skipped)
};

// Families (planes of one family instance are ordered by CuttingPlane::order):
//   "limb"     one instance per chain of limb bones (upper arm + forearm, thigh + shin, twist splits
//              included; an arm's chain starts at its shoulder bones, from shoulderStart of their length, so
//              the deltoid is followed across the shoulder): planes perpendicular to the bone, `spacing` apart
//              along the chain, end margins at the chain's ends and at joints bending more than bendAngle;
//              the in-plane X axis is transported along the chain from the first bone's rest X axis, so
//              consecutive 2D frames never flip.
//   "shoulder" one instance per shoulder chain (clavicle, shoulder): perpendicular planes from
//              shoulderStart of the chain to the shoulder joint (the trapezius/deltoid cap).
//   "neck"     one instance per neck chain: perpendicular planes whose region is the neck's bones and everything
//              below them (the head), so where a plane cuts into the trunk its trunk runs become chords.
//   "abdomen"  one instance: parallel planes normal to the spine's overall direction, from above the hip
//              joints to the top of the spine, each centred on the spine where it crosses the plane.
// Overlaps (shoulder vs upper arm, abdomen vs shoulder) are resolved later per muscle by dominance
// (extraction.h, dominantMuscles). Deterministic: bones are visited in index order.
std::vector<CuttingPlane> makeCuttingPlanes(const Character& character, const std::vector<BoneRole>& roles,
                                            const PlaneOptions& options = {});

// The automatic plane spacing (PlaneOptions::spacing = 0): 1/80 of the skin's largest principal extent (#V by 3).
double automaticPlaneSpacing(const Points& vertices);

// The skeleton's mirror plane (point c, unit normal n): through the first torso plane on it (CuttingPlane::mirrorAxis),
// normal to that plane's x or y axis, whichever maps the limb planes' origins closer onto another limb's (rest frames
// differ in which in-plane axis of the spine points sideways; makeCuttingPlanes turns the torso frames so it is x).
// False without a mirror-axis plane or without two limb planes.
bool skeletonMirrorPlane(const std::vector<CuttingPlane>& planes, Vec3& c, Vec3& n);

// The skin's profile on one plane: a closed, simple, counter-clockwise polygon (2D plane coordinates,
// metres, about evenly spaced), the loop that encloses the bone.
struct SectionProfile {
  CuttingPlane plane;
  Points2 polygon;          // #P by 2, counter-clockwise; empty when skipped
  std::vector<char> inMask;  // #P: the point lies on masked skin (all 1 without a mask)
  std::vector<char> onSkin;  // #P: 1 on the skin, 0 on the chord that closes a clipped profile (empty = all 1)
  std::vector<int> segment;  // #P: the segment of the cut loop each sample lies on; the loop's points are where the
                             // plane crosses mesh edges, so they tell how finely the mesh resolves an arc
  int loopPoints = 0;        // points of the cut loop (segment indices run over [0, loopPoints))
  double perimeter = 0.0;   // metres
  bool symmetric = false;   // made exactly mirror-symmetric (its mirrored samples within one sample spacing): about
                            // the plane's y axis (trunk), or with its mirrored twin on the other side (limbs)
  bool ok = false;
  std::string skipReason;   // why the section was skipped (no loop around the bone, open loop, ...)
};

struct ProfileOptions {
  int samples = 0;  // points per profile after even resampling; 0 = derived: one every sampleSpacing, 48..400
  double sampleSpacing = 0.002;  // metres: the derived resampling's spacing, and that of the points on a trunk
                                 // section's chords. A resolution, yet as decisive as the bump floor: the muscles
                                 // found do not converge as it shrinks (README "Extraction options")
  double minRegionShare = 0.9;  // share of the loop's length that must lie on the plane's region
  double minPerimeter = 0.007;  // metres: smaller loops are skipped (extractMuscles derives it: twice the bump
                                // floor BumpOptions::minProtrusion, the default here)
  double trunkClipShare = 0.4;  // a trunk (mirror-axis) plane whose loop runs into the arms or legs (less than
                                // minRegionShare on its region, at least this much): the runs off the region
                                // become straight chords (onSkin 0), so the chest between the shoulders is
                                // sectioned too; 0 = such planes are skipped
  bool mirrorLimbs = false;  // also average a left and a right plane's profiles that mirror each other about the
                             // trunk's mirror plane within one sample spacing (limbs, shoulders), so mirrored limbs give
                             // exactly mirrored bumps. Off by default: measured on MakeHuman, limbs are mirrored
                             // within 1 cm without it at the default hysteresis, and with it the neutral body keeps
                             // 8 muscles instead of 6; it is needed for fainter hysteresis (weakFraction 0.5)
};

// Cut every plane through the skin: the closed loop enclosing the plane origin (the smallest one), kept when
// at least minRegionShare of it lies on the plane's region (else skipped: armpit, groin, a neighbouring limb).
// A plane with clipRadius > 0 keeps instead the longest run of the loop that lies on its region and within
// clipRadius of the origin (at least clipRadius long), closed by a straight chord (onSkin 0 there);
// made counter-clockwise and resampled evenly starting on the +Y axis. `vertexMask` (#V, optional) marks the
// profile points on masked skin (inMask); a section with no masked point is skipped. Parallel over planes,
// deterministic. Throws InputError for a mask of the wrong size or a sampleSpacing that is not finite and > 0.
std::vector<SectionProfile> cutSections(const Character& character, const std::vector<CuttingPlane>& planes,
                                        const ProfileOptions& options = {},
                                        const std::vector<char>* vertexMask = nullptr);

}  // namespace myoskin
