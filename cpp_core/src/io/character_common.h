// Internal helpers shared by the character loaders (glTF, OBJ + skeleton JSON). Not part of the public API.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "myoskin/character.h"
#include "myoskin/io.h"

namespace myoskin::io_detail {

// One vertex's influences as (bone index, weight) pairs, in any order, duplicates allowed.
using Influences = std::vector<std::pair<int, double>>;

// Throws InputError "<path>: file not found" unless `path` is an existing regular file.
void requireFile(const std::string& path);

// File name without directory and extension ("a/b/c.glb" -> "c").
std::string fileStem(const std::string& path);

// Parent-before-child order of items whose parents are given (-1 = root), stable otherwise.
// order[k] = old index of the k-th item. Throws InputError naming `path` on a cycle.
std::vector<int> parentFirstOrder(const std::vector<int>& parents, const std::string& path);

// Packs per-vertex influences into K = max(minSlots, most influences) slots: duplicates merged, zero weights
// dropped, sorted by weight (descending) then bone, sums > 1e-4 normalised to 1, empty slots -1 / 0.
// Throws InputError naming `path` and the vertex on a NaN, infinite or negative weight.
SkinWeights packInfluences(const std::vector<Influences>& perVertex, int minSlots, const std::string& path);

// Welds `source` by options.weldTolerance, keeps each welded vertex's weights from the first source vertex of
// its group, fills the vertex maps, applies options.requireWeights and validates; every InputError names `path`.
Character finishCharacter(const std::string& path, const Mesh& source, Skeleton skeleton,
                          const SkinWeights& sourceWeights, const LoadOptions& options);

}  // namespace myoskin::io_detail
