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

// Roles from chain topology plus name heuristics (Rigify, MakeHuman, Mixamo); `overrides` (bone name ->
// role) wins. Returns one role per bone.
std::vector<BoneRole> classifyBones(const Skeleton& skeleton, const std::map<std::string, BoneRole>& overrides = {});

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
};

struct PlaneOptions {
  double spacing = 0.0;  // metres between planes; 0 = derived from the mesh size (~1/70 of the height)
  double endMargin = 0.12;  // fraction of a bone's length left out at each end (joints give no clean loops)
};

std::vector<CuttingPlane> makeCuttingPlanes(const Character& character, const std::vector<BoneRole>& roles,
                                            const PlaneOptions& options = {});

// The skin's profile on one plane: a closed, simple, counter-clockwise polygon (2D plane coordinates,
// metres, about evenly spaced), the loop that encloses the bone.
struct SectionProfile {
  CuttingPlane plane;
  Points2 polygon;          // #P by 2, counter-clockwise; empty when skipped
  bool ok = false;
  std::string skipReason;   // why the section was skipped (no loop around the bone, open loop, ...)
};

struct ProfileOptions {
  int samples = 0;  // points per profile after even resampling; 0 = derived from the spacing (~2 mm apart, 48..400)
};

// Cut every plane through the skin. `vertexMask` (#V, optional): only triangles with a masked vertex count.
std::vector<SectionProfile> cutSections(const Character& character, const std::vector<CuttingPlane>& planes,
                                        const ProfileOptions& options = {},
                                        const std::vector<char>* vertexMask = nullptr);

}  // namespace myoskin
