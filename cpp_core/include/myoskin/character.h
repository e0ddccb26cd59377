// A rigged character: skin mesh, skeleton, skin weights. What the loaders return.
#pragma once
#include <string>
#include <vector>

#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"
#include "myoskin/skin_weights.h"

namespace myoskin {

// One mesh object of a character made of several (body, head, feet...), in source-vertex numbering.
struct MeshPiece {
  std::string name;
  int firstVertex = 0;  // index of its first vertex as stored (sourceToWelded maps it to the welded mesh)
  int vertexCount = 0;
};

struct Character {
  std::string name;
  Mesh mesh;  // welded skin, rest pose, scene space (metres)
  Skeleton skeleton;
  SkinWeights weights;  // per welded vertex; empty (0 rows) when the file has none
  // For each vertex as stored in the file, its index in `mesh` (identity when nothing was welded).
  std::vector<int> sourceToWelded;
  int sourceVertexCount = 0;
  std::vector<MeshPiece> pieces;  // the meshes it was loaded from (empty: one)

  bool hasWeights() const { return weights.numVertices() > 0; }
};

// Checks mesh (finite, in range), skeleton (names, parents, lengths) and weights (shape, range).
void validateCharacter(const Character& character);

}  // namespace myoskin
