// Extraction accuracy on varied generated characters (issue 13, "Any character", item 7): recall and precision
// against the generator's ground truth (each true muscle's visible length, measureExtraction) per kind and seed,
// muscular and smooth. Seeds 1-3 are the ones to look at ("tune"); 20-27 are held out (tests/cpp/test_varied_characters.cpp asserts on them). Printed, never asserted.
//   bench_varied_characters [first_seed last_seed]   (default: 1-3 and 20-27)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "myoskin/extraction.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<unsigned> seeds = {1, 2, 3, 20, 21, 22, 23, 24, 25, 26, 27};
  if (argc == 3) {
    seeds.clear();
    for (unsigned s = static_cast<unsigned>(std::atoi(argv[1])); s <= static_cast<unsigned>(std::atoi(argv[2])); ++s)
      seeds.push_back(s);
  }
  std::printf("%-10s %-5s %-8s %-6s %7s %5s %5s %5s %7s %9s %6s %7s %7s\n", "kind", "seed", "set", "split", "verts",
              "true", "found", "match", "recall", "precision", "smooth", "gen s", "extr s");
  for (BodyKind kind : {BodyKind::Biped, BodyKind::Quadruped}) {
    for (bool split : {false, true}) {
      double recall = 0.0, precision = 0.0;
      int heldOut = 0, smoothWorst = 0;
      for (unsigned seed : seeds) {
        SyntheticBodyOptions o;
        o.seed = seed;
        o.kind = kind;
        o.split = split;
        auto t0 = std::chrono::steady_clock::now();
        const SyntheticCharacter body = makeSyntheticBody(o);
        const double gen = seconds(t0);
        t0 = std::chrono::steady_clock::now();
        const ExtractionResult r = extractMuscles(body.character);
        const double ext = seconds(t0);
        const ExtractionAccuracy acc = measureExtraction(r.muscles, body.muscles);
        o.muscleScale = 0.0;
        const size_t smooth = extractMuscles(makeSyntheticBody(o).character).muscles.size();
        const bool held = seed >= 20;
        std::printf("%-10s %-5u %-8s %-6s %7d %5d %5d %5d %7.3f %9.3f %6zu %7.2f %7.2f\n", bodyKindName(kind), seed,
                    held ? "held-out" : "tune", split ? "yes" : "no", body.character.mesh.numVertices(), acc.trueMuscles,
                    acc.foundMuscles, acc.matched, acc.recall, acc.precision, smooth, gen, ext);
        if (held) recall += acc.recall, precision += acc.precision, ++heldOut;
        smoothWorst = std::max(smoothWorst, static_cast<int>(smooth));
      }
      if (heldOut > 0)
        std::printf("%-10s held-out mean (%s): recall %.3f, precision %.3f; smooth bodies: at most %d muscles\n",
                    bodyKindName(kind), split ? "split" : "one mesh", recall / heldOut, precision / heldOut, smoothWorst);
    }
  }
  return 0;
}
