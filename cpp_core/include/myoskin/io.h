// Loading characters and reading/writing muscles. All loaders throw InputError with a one-line reason.
#pragma once
#include <string>
#include <vector>

#include "myoskin/character.h"
#include "myoskin/muscle.h"

namespace myoskin {

// ============================================================================
// Characters
// ============================================================================

struct LoadOptions {
  double weldTolerance = 1e-6;  // share of the skin's bounding-box diagonal: vertices closer than this are merged
                                // (UV seams, pieces that meet at open boundaries)
  bool requireWeights = false;  // throw when the mesh has no skin weights
  std::string meshName;         // glTF: only the mesh node (or mesh) of this name; empty = the whole character
};

// glTF 2.0 (.glb/.gltf): the character, i.e. every mesh node deformed by the first skin a mesh uses (several
// pieces: body, head, feet...; one Character::pieces entry each), or the mesh named by options.meshName; the
// skin's joints as bones, JOINTS_0/WEIGHTS_0. Positions are placed in the scene by the rest skinning transform
// (node transforms and inverse bind matrices applied), welded by position.
Character loadGltf(const std::string& path, const LoadOptions& options = {});

// Wavefront OBJ (triangles or polygons, fan-triangulated) plus a skeleton JSON:
// {"bones":[{"name","parent"(name or null),"head":[x,y,z],"tail":[x,y,z],"x_axis":[x,y,z]?}],
//  "weights": {"bone": [[vertex, weight], ...]}?}
Character loadObjWithSkeleton(const std::string& objPath, const std::string& skeletonJsonPath,
                              const LoadOptions& options = {});

// Dispatch by extension: .glb/.gltf, or .obj with a sibling <stem>.skeleton.json (or skeletonPath).
Character loadCharacter(const std::string& path, const LoadOptions& options = {},
                        const std::string& skeletonPath = "");

// An OBJ's vertices and triangles as stored (faces fan-triangulated, no welding): e.g. a sculpted frame.
Mesh readObjMesh(const std::string& path);

// Writers used by the generator, tests and the CLI.
void writeObj(const std::string& path, const Points& vertices, const Triangles& triangles);
void writeSkeletonJson(const std::string& path, const Character& character);

// ============================================================================
// Muscles JSON (format "myoskin.muscles", version 1; DESIGN.md section 7)
// ============================================================================

std::string musclesToJson(const std::vector<Muscle>& muscles, int indent = 1);
std::vector<Muscle> musclesFromJson(const std::string& text);  // validates; throws InputError
void writeMusclesJson(const std::string& path, const std::vector<Muscle>& muscles);
std::vector<Muscle> readMusclesJson(const std::string& path);

}  // namespace myoskin
