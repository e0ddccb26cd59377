// Sparse skin weights with a fixed number of influence slots per vertex.
#pragma once
#include <vector>

#include "myoskin/types.h"

namespace myoskin {

// joints: #V by K bone indices (-1 = empty slot); weights: #V by K. Semantics match Blender's Armature
// modifier: weights are normalised at deform time and a vertex whose weight sum is <= 1e-4 stays at rest.
struct SkinWeights {
  IndexMatrix joints;
  WeightMatrix weights;

  int numVertices() const { return static_cast<int>(joints.rows()); }
  int influences() const { return static_cast<int>(joints.cols()); }
};

// Throws InputError (naming the vertex) on shape mismatch, NaN or negative weight, or an index outside
// [-1, numBones). numVertices must match the mesh.
void validateSkinWeights(const SkinWeights& weights, int numVertices, int numBones);

// Total weight of each bone over all vertices (size numBones).
std::vector<double> boneWeightTotals(const SkinWeights& weights, int numBones);

}  // namespace myoskin
