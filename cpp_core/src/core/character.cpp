// Whole-character validation.
#include "myoskin/character.h"

#include "myoskin/errors.h"

namespace myoskin {

void validateCharacter(const Character& character) {
  const std::string what = character.name.empty() ? "character" : "character '" + character.name + "'";
  validateMesh(character.mesh, what + " mesh");
  validateSkeleton(character.skeleton);
  if (character.hasWeights())
    validateSkinWeights(character.weights, character.mesh.numVertices(), character.skeleton.numBones());
  for (int w : character.sourceToWelded)
    if (w < 0 || w >= character.mesh.numVertices())
      throw InputError(what + ": vertex map points outside the welded mesh");
}

}  // namespace myoskin
