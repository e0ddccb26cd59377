// Skin weight validation and statistics.
#include "myoskin/skin_weights.h"

#include <cmath>

#include "myoskin/errors.h"

namespace myoskin {

void validateSkinWeights(const SkinWeights& weights, int numVertices, int numBones) {
  if (weights.joints.rows() != weights.weights.rows() || weights.joints.cols() != weights.weights.cols())
    throw InputError("skin weights: joints are " + std::to_string(weights.joints.rows()) + " by " +
                     std::to_string(weights.joints.cols()) + " but weights are " +
                     std::to_string(weights.weights.rows()) + " by " + std::to_string(weights.weights.cols()));
  if (weights.numVertices() != numVertices)
    throw InputError("skin weights: " + std::to_string(weights.numVertices()) + " rows for " +
                     std::to_string(numVertices) + " vertices");
  for (int v = 0; v < weights.numVertices(); ++v)
    for (int k = 0; k < weights.influences(); ++k) {
      const int j = weights.joints(v, k);
      const double w = weights.weights(v, k);
      if (j < -1 || j >= numBones)
        throw InputError("skin weights: vertex " + std::to_string(v) + " uses bone index " + std::to_string(j) +
                         ", outside 0.." + std::to_string(numBones - 1));
      if (!std::isfinite(w)) throw InputError("skin weights: vertex " + std::to_string(v) + " has a NaN weight");
      if (w < 0.0) throw InputError("skin weights: vertex " + std::to_string(v) + " has a negative weight");
    }
}

std::vector<double> boneWeightTotals(const SkinWeights& weights, int numBones) {
  std::vector<double> totals(numBones, 0.0);
  for (int v = 0; v < weights.numVertices(); ++v)
    for (int k = 0; k < weights.influences(); ++k)
      if (weights.joints(v, k) >= 0 && weights.joints(v, k) < numBones) totals[weights.joints(v, k)] += weights.weights(v, k);
  return totals;
}

}  // namespace myoskin
