// A muscle as extraction produces it and deformation consumes it (DESIGN.md sections 5 and 7).
#pragma once
#include <string>
#include <vector>

#include "myoskin/mesh.h"
#include "myoskin/types.h"

namespace myoskin {

// An attachment point: a position in mesh space (metres) attached to a bone.
struct MuscleAttachment {
  std::string bone;
  Vec3 position = Vec3::Zero();
};

// One elliptical cross-section. u in [-1, 1] along the root curve (origin -1, insertion +1);
// axisA is the unit direction of the semi-axis a, normal the unit normal of the section plane.
struct MuscleSection {
  double u = 0.0;
  Vec3 center = Vec3::Zero();
  Vec3 axisA = Vec3::UnitX();
  double a = 0.0;
  double b = 0.0;
  Vec3 normal = Vec3::UnitZ();
};

enum class WrapType { None, Joint, Bone };

// How the action path wraps: around a sphere at a joint (the head of `bone`) or a cylinder around `bone`.
struct MuscleWrap {
  WrapType type = WrapType::None;
  std::string bone;     // joint: the bone whose head is the sphere centre; bone: the cylinder's bone
  double radius = 0.0;  // metres
  int side = 1;         // +1 or -1: which way round the cylinder
};

struct Muscle {
  std::string name;
  std::string region;  // e.g. "upper_arm.L", "torso.abdomen"
  MuscleAttachment origin;
  MuscleAttachment insertion;
  std::vector<Vec3> rootCurve;  // centre line, origin to insertion
  std::vector<MuscleSection> sections;
  MuscleWrap wrap;
  double bulge = 1.0;  // bulge factor k (0 = uniform thickening)
  int joints = 4;      // muscle joints along the path
  double confidence = 1.0;
  Mesh surface;  // closed, outward-oriented; may be empty when not lofted yet
};

const char* wrapTypeName(WrapType type);
WrapType wrapTypeFromName(const std::string& name);  // throws InputError on an unknown name

// Throws InputError (naming the muscle) when a muscle has NaNs, an empty root curve, u outside
// [-1, 1] or not increasing, non-positive axes, or joints < 1.
void validateMuscles(const std::vector<Muscle>& muscles);

}  // namespace myoskin
