// The cue of shape behind the spindle rule (ExtractionOptions::spindleEnds; issue 13): every limb chain of 4 or more
// bumps with a significant peak, on the generated tune seeds 1-3 (muscular and smooth, biped and quadruped) and the
// MakeHuman bodies in ../shared, labelled true (it lies on a true muscle: half its centres within 0.75 of the
// muscle's peak radius of the true centre line) or false, with its profile along the bone (higher end / peak, one
// peak or several), its steepness and what the floors made of it (ExtractionReport::chainRecords). Printed, never
// asserted; the summary counts closed spindles per class among the chains the length/height floors drop.
//   bench_spindle_cue [first_seed last_seed [spacing_factor]]   (default: 1 3; the MakeHuman bodies' plane spacing
//   this times the default, 1/80 of the largest extent)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "line_distance.h"
#include "tuning_sets.h"

using namespace myoskin;
using myoskin::bench::lineDistance;

namespace {

// The true muscle a chain lies on, or "" (half its centres within 0.75 of that muscle's peak radius).
std::string trueMuscleOf(const ChainRecord& r, const std::vector<TrueMuscle>& truth) {
  for (const TrueMuscle& m : truth) {
    int near = 0;
    for (const Vec3& p : r.centres) near += lineDistance(p, m.centerLine) < 0.75 * m.peakRadius;
    if (2 * near >= static_cast<int>(r.centres.size())) return m.name;
  }
  return "";
}

struct Tally {
  int chains = 0, spindles = 0;
};

std::map<std::string, Tally> tally;  // class -> dropped-by-the-floors chains and the spindles among them

// One character's rows.
void printChains(const std::string& set, const ExtractionResult& r, const std::vector<TrueMuscle>* truth) {
  for (const ChainRecord& c : r.report.chainRecords) {
    const int n = static_cast<int>(c.significance.size());
    if (c.family == "abdomen" || c.family == "neck" || n < 4) continue;
    const int peak = static_cast<int>(std::max_element(c.significance.begin(), c.significance.end()) - c.significance.begin());
    const double top = c.significance[peak];
    if (top < 1.0) continue;
    bool onePeak = true;
    for (int k = 1; k < n; ++k) onePeak &= k <= peak ? c.significance[k] >= c.significance[k - 1] : c.significance[k] <= c.significance[k - 1];
    const std::string muscle = truth ? trueMuscleOf(c, *truth) : "";
    const std::string cls = truth ? (muscle.empty() ? "false" : "true") : set.substr(0, set.find(' '));
    if (c.verdict == "short" || c.verdict == "flat" || c.verdict == "spindle") {  // below the floors
      Tally& t = tally[cls];
      ++t.chains, t.spindles += c.spindle;
    }
    std::printf("%-22s %-5s %-24s %-16s %-10s n %2d peak %.2f end/peak %.2f %-8s steep %.3f %s\n", set.c_str(), cls.c_str(),
                muscle.c_str(), c.bone.c_str(), c.verdict.c_str(), n, top,
                std::max(c.significance.front(), c.significance.back()) / top, onePeak ? "one-peak" : "several",
                c.steepness, c.spindle ? "SPINDLE" : "");
  }
}

}  // namespace

int main(int argc, char** argv) {
  unsigned first = 1, last = 3;
  if (argc >= 3) first = static_cast<unsigned>(std::atoi(argv[1])), last = static_cast<unsigned>(std::atoi(argv[2]));
  const double spacingFactor = argc >= 4 ? std::atof(argv[3]) : 1.0;
  ExtractionOptions dropped;  // the defaults (no surfaces): the records say what the floors and the rule made of each
  dropped.buildSurfaces = false;
  bench::forEachTuningBody(first, last, dropped,
                           [](const std::string& set, const Character& c, const std::vector<TrueMuscle>& truth,
                              const ExtractionOptions& o) { printChains(set, extractMuscles(c, o), &truth); });
  const std::string dir = MYOSKIN_SHARED_DIR "/characters/";
  for (const char* name : {"makehuman_muscular_male", "makehuman_neutral"}) {
    const std::string path = dir + name + "/" + name + ".glb";
    if (!std::ifstream(path)) {
      std::printf("%s: not found (../shared absent), skipped\n", name);
      continue;
    }
    const Character c = loadCharacter(path);
    ExtractionOptions spaced = dropped;
    spaced.planes.spacing = spacingFactor * principalExtent(c.mesh.vertices) / 80.0;
    printChains(name, extractMuscles(c, spaced), nullptr);
  }
  std::printf("\nchains below the length/height floors (4+ bumps, a significant peak) and the closed spindles among them:\n");
  for (const auto& [cls, t] : tally) std::printf("  %-24s %3d chains, %3d spindles\n", cls.c_str(), t.chains, t.spindles);
  return 0;
}
