// Which chain-filter floors still decide anything (issue 13, item 6: few knobs): extraction with expert options
// overridden from the command line, over the tune characters (generated seeds, muscular and smooth, biped and
// quadruped), MakeHuman muscular and neutral at plane spacings x 0.9-1.1 and the shared characters at their defaults.
// One line per character: its muscle count, matched and true muscles (generated characters), names, and a checksum of
// the root curves, so two runs are compared with diff. Printed, never asserted; tune seeds only unless --heldout.
//   bench_floor_ablation [--seeds FIRST LAST] [--heldout] [--generated] [--arms] [--records] [key=value ...]   (default
//   seeds 1-11; keys: expertOptions(), filters.minConfidence and profiles.sampleSpacing). --arms: the synthetic arms
//   instead (seeds 0-11 at muscle scales 1, 0.2, 0.1 and 0: the arm tests' tuned and held-out seeds, faint and smooth
//   arms; --seeds and --heldout do not apply).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "tuning_sets.h"

using namespace myoskin;

namespace {

bool records = false;  // --records: every chain record (family, verdict, bone, significance, height, planes)

// One character's line: count, matched, true, sorted names, root-curve checksum (in limb radii, so scale-free).
void report(const std::string& set, const Character& c, const std::vector<TrueMuscle>& truth, const ExtractionOptions& o) {
  const ExtractionResult r = extractMuscles(c, o);
  std::vector<std::string> names;
  double sum = 0.0;
  for (const Muscle& m : r.muscles) {
    names.push_back(m.name);
    for (const Vec3& p : m.rootCurve) sum += (p.x() + 2.0 * p.y() + 3.0 * p.z()) / r.report.limbRadius;
  }
  std::sort(names.begin(), names.end());
  const int matched = truth.empty() ? 0 : measureExtraction(r.muscles, truth).matched;
  std::printf("%-34s found %2zu matched %2d true %2zu sum %.4f :", set.c_str(), r.muscles.size(), matched, truth.size(),
              sum);
  for (const std::string& n : names) std::printf(" %s", n.c_str());
  std::printf("\n");
  if (records)
    for (const ChainRecord& ch : r.report.chainRecords) {
      std::printf("    %-8s %-10s %-16s spindle %d steep %.4f sig", ch.family.c_str(), ch.verdict.c_str(), ch.bone.c_str(),
                  ch.spindle ? 1 : 0, ch.steepness);
      for (double v : ch.significance) std::printf(" %.2f", v);
      std::printf(" rel");
      for (double v : ch.relative) std::printf(" %.3f", v);
      std::printf(" planes");
      for (int v : ch.planes) std::printf(" %d", v);
      std::printf("\n");
    }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  unsigned first = 1, last = 11;
  ExtractionOptions base;
  base.buildSurfaces = false;
  bool shared = true, arms = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seeds" && i + 2 < argc) {
      first = std::atoi(argv[i + 1]), last = std::atoi(argv[i + 2]);
      i += 2;
    } else if (a == "--heldout") {
      first = 20, last = 27, shared = false;
    } else if (a == "--records") {
      records = true;
    } else if (a == "--arms") {
      arms = true;
    } else if (a == "--generated") {
      shared = false;
    } else {
      const size_t eq = a.find('=');
      if (eq == std::string::npos) {
        std::fprintf(stderr, "expected key=value, got %s\n", a.c_str());
        return 2;
      }
      if (a.substr(0, eq) == "filters.minConfidence")  // user-facing, not an expert key
        base.filters.minConfidence = std::atof(a.c_str() + eq + 1);
      else if (a.substr(0, eq) == "profiles.sampleSpacing") {  // the profiles' resolution, no expert key either
        base.profiles.sampleSpacing = std::atof(a.c_str() + eq + 1);
        if (!(base.profiles.sampleSpacing > 0)) {
          std::fprintf(stderr, "profiles.sampleSpacing must be > 0, got %s\n", a.c_str() + eq + 1);
          return 2;
        }
      }
      else
        setExpertOption(base, a.substr(0, eq), std::atof(a.c_str() + eq + 1));
    }
  }
  if (arms) {
    for (double scale : {1.0, 0.2, 0.1, 0.0})
      for (unsigned seed = 0; seed <= 11; ++seed) {
        SyntheticArmOptions ao;
        ao.seed = seed, ao.muscleScale = scale;
        const SyntheticCharacter a = makeSyntheticArm(ao);
        char set[64];
        std::snprintf(set, sizeof set, "arm_%u_scale%.1f", seed, scale);
        report(set, a.character, a.muscles, base);
      }
    return 0;
  }
  bench::forEachTuningBody(first, last, base, report);
  if (!shared) return 0;
  bench::forEachMakeHumanSpacing(base, report);
  for (const char* file : {"makehuman_muscular_male/makehuman_muscular_male.glb", "makehuman_neutral/makehuman_neutral.glb",
                           "godot_male_base_mesh_lowpoly/male_base_mesh.glb", "quaternius_horse/horse.glb",
                           "quaternius_woman_soldier/woman_soldier.glb"})
    report(file, loadCharacter(std::string(MYOSKIN_SHARED_DIR "/characters/") + file), {}, base);
  return 0;
}
