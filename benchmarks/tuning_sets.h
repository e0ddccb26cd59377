// The extraction tuning sets the benchmarks print over (issue 13): generated bodies of the tune seeds, muscular and
// smooth, and the MakeHuman bodies at plane spacings x 0.9 - 1.1 of the automatic one.
#pragma once
#include <cstdio>
#include <string>

#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"

namespace myoskin::bench {

// fn(label, character, true muscles, options) for each biped and quadruped seed in [first, last], muscular and smooth.
template <class Fn>
void forEachTuningBody(unsigned first, unsigned last, const ExtractionOptions& base, Fn&& fn) {
  for (BodyKind kind : {BodyKind::Biped, BodyKind::Quadruped})
    for (unsigned seed = first; seed <= last; ++seed)
      for (double ms : {1.0, 0.0}) {
        SyntheticBodyOptions so;
        so.seed = seed, so.kind = kind, so.muscleScale = ms;
        const SyntheticCharacter b = makeSyntheticBody(so);
        fn(std::string(ms > 0 ? "" : "smooth_") + bodyKindName(kind) + "_" + std::to_string(seed), b.character,
           b.muscles, base);
      }
}

// fn(label, character, {}, options) for makehuman_muscular_male and makehuman_neutral at 9 plane spacings.
template <class Fn>
void forEachMakeHumanSpacing(const ExtractionOptions& base, Fn&& fn) {
  for (const char* name : {"makehuman_muscular_male", "makehuman_neutral"}) {
    const std::string path = std::string(MYOSKIN_SHARED_DIR "/characters/") + name + "/" + name + ".glb";
    const Character c = loadCharacter(path);
    const Vec3 lo = c.mesh.vertices.colwise().minCoeff().transpose(), hi = c.mesh.vertices.colwise().maxCoeff().transpose();
    for (int step = 0; step <= 8; ++step) {
      ExtractionOptions o = base;
      const double f = 0.9 + 0.025 * step;
      o.planes.spacing = f * (hi - lo).maxCoeff() / 80.0;
      char set[128];
      std::snprintf(set, sizeof set, "%s_x%.3f", name, f);
      fn(std::string(set), c, {}, o);
    }
  }
}

}  // namespace myoskin::bench
