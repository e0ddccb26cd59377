// Midpoint subdivision of a rigged character: each triangle becomes four, the skin keeps its shape and its
// weights. Used to make large test skins (benchmarks, resolution-independence tests).
#pragma once
#include "myoskin/character.h"

namespace myoskin {

// Splits every triangle into four at its edge midpoints, `levels` times (#F grows by 4^levels). New
// vertices get the mean position of the edge's ends and the mean of their skin weights (the K strongest
// influences kept, renormalised). The skeleton is copied; sourceToWelded becomes the identity.
// Throws InputError for levels < 0 or an invalid character.
Character subdivideMidpoint(const Character& character, int levels = 1);

}  // namespace myoskin
