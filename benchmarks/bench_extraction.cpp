// Whole-body muscle extraction speed (issue 3): makehuman_muscular_male (13k vertices, target < 1 s) and
// the same skin midpoint-subdivided twice (~214k vertices, target < 10 s). Prints seconds per stage,
// the ratio to each target, and how time scales with the vertex count (baseline: the 13k run).
// Usage: bench_extraction [CHARACTER.glb]   (default: the shared MakeHuman character)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/subdivide.h"

using namespace myoskin;

namespace {

struct Run {
  double seconds = 1e30;
  ExtractionResult result;
};

// Best of `repeats` whole extractions (surfaces included).
Run timeExtraction(const Character& c, int repeats) {
  Run best;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    ExtractionResult r = extractMuscles(c);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s < best.seconds) best.seconds = s, best.result = std::move(r);
  }
  return best;
}

void print(const char* label, const Character& c, const Run& run, double target) {
  std::printf("%-22s %8d vertices  %3d muscles  %7.3f s  (%.2f of the %.0f s target)\n", label,
              c.mesh.numVertices(), run.result.report.muscles, run.seconds, run.seconds / target, target);
  std::printf("%-22s", "  stages:");
  for (const StageTiming& t : run.result.report.timings) std::printf(" %s %.3f", t.stage.c_str(), t.seconds);
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1]
                                    : std::string(MYOSKIN_SHARED_DIR) +
                                          "/characters/makehuman_muscular_male/makehuman_muscular_male.glb";
  if (!std::filesystem::exists(path)) {
    std::fprintf(stderr, "bench_extraction: %s not found (pass a character or put ../shared beside the repo)\n",
                 path.c_str());
    return 1;
  }
  try {
    LoadOptions load;
    load.requireWeights = true;
    const Character body = loadCharacter(path, load);
    const Run base = timeExtraction(body, 5);
    print("whole body", body, base, 1.0);
    const Character fine = subdivideMidpoint(body, 2);
    const Run big = timeExtraction(fine, 2);
    print("subdivided x2 (4^2)", fine, big, 10.0);
    std::printf("scaling: %.1fx the vertices took %.1fx the time (%.2f of linear)\n",
                double(fine.mesh.numVertices()) / body.mesh.numVertices(), big.seconds / base.seconds,
                (big.seconds / base.seconds) / (double(fine.mesh.numVertices()) / body.mesh.numVertices()));
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_extraction: error: %s\n", e.what());
    return 1;
  }
}
