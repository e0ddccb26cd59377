// How sensitive the muscles found are to each load-bearing extraction floor (issue 13, item 6: floors with margin).
// Each floor is scaled by x 0.9, 0.95, 1.05 and 1.1; per factor: how many characters of the tuning set find other
// muscles (count or names) and of them how many another count (names alone flip where a muscle lies near the boundary
// between two facings, e.g. a forearm's top and outer), the mean recall and precision over the generated muscular
// bodies and arms (true muscles known; a mean over bodies, each arm and body weighing the same; a body where nothing is
// found has precision 1), the muscles found on the smooth bodies (false alarms), and MakeHuman muscular / neutral at
// the sweep's spacing x 1 (1/80 of the bounding box, where the automatic spacing, 1/80 of the principal extent, gives
// 20 / 6). A floor that changes many characters at 5 % sits on decisions a character nobody tuned on may fall either
// side of; one that changes recall or precision little is safe to move. Last, the profiles' resolution
// (ProfileOptions::sampleSpacing), scaled alike.
//   bench_floor_margins [--full] [--row KEY]   (default: tune seeds 1-4, muscular and smooth, MakeHuman muscular and
//   neutral at spacings x 0.95, 1 and 1.05, the low-poly male, the horse and the soldier, the synthetic arms 0-11 at
//   muscle scales 1 and 0.2; --full: tune seeds 1-11 and the nine spacings of bench_floor_ablation; --row: one row).
//   Printed, never asserted.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "tuning_sets.h"

using namespace myoskin;

namespace {

struct Body {
  std::string label;
  Character character;
  std::vector<TrueMuscle> truth;  // empty: unknown (or a smooth body when `smooth`)
  ExtractionOptions options;      // the set's own (a plane spacing for the MakeHuman sweep)
  bool smooth = false;
};

struct Outcome {
  std::vector<std::string> signature;  // per body: muscle count and sorted names
  std::vector<int> counts;             // per body: muscle count
  double recall = 0, precision = 0;    // means over the bodies with true muscles
  int falseAlarms = 0;                 // muscles on the smooth bodies
  int muscular = -1, neutral = -1;     // MakeHuman at the sweep's spacing x 1
};

Outcome evaluate(const std::vector<Body>& bodies, const ExtractionOptions& floors) {
  Outcome out;
  int known = 0;
  for (const Body& b : bodies) {
    ExtractionOptions o = floors;
    o.planes.spacing = b.options.planes.spacing;
    const ExtractionResult r = extractMuscles(b.character, o);
    std::vector<std::string> names;
    for (const Muscle& m : r.muscles) names.push_back(m.name);
    std::sort(names.begin(), names.end());
    std::string s = std::to_string(names.size());
    for (const std::string& n : names) s += " " + n;
    out.signature.push_back(s);
    out.counts.push_back(static_cast<int>(names.size()));
    if (b.smooth) out.falseAlarms += static_cast<int>(r.muscles.size());
    if (!b.truth.empty()) {
      const ExtractionAccuracy acc = measureExtraction(r.muscles, b.truth);
      out.recall += acc.recall, out.precision += acc.precision, ++known;
    }
    if (b.label == "makehuman_muscular_male_x1.000") out.muscular = static_cast<int>(r.muscles.size());
    if (b.label == "makehuman_neutral_x1.000") out.neutral = static_cast<int>(r.muscles.size());
  }
  if (known > 0) out.recall /= known, out.precision /= known;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const char* floors[] = {"bumps.minProtrusion",       "bumps.minRelativeProtrusion", "bumps.maxWidthFraction",
                          "sectionBumps.weakFraction", "sectionBumps.faintFraction",  "sectionBumps.faintRelative",
                          "filters.minEvidence",       "filters.minRelative",         "filters.continuousEvidence",
                          "filters.spindleEnds",       "filters.spindleLength",       "filters.spindleSteepness",
                          "filters.twinReach",         "link.maxLateralFactor",       "link.maxAngle",
                          "link.mergeFactor"};
  const char* resolution = "profiles.sampleSpacing";  // the last row, not an expert key
  bool full = false;
  std::string only;  // --row KEY: that row alone
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--full") == 0) {
      full = true;
    } else if (std::strcmp(argv[i], "--row") == 0 && i + 1 < argc) {
      only = argv[++i];
      bool known = only == resolution;
      for (const char* key : floors) known |= only == key;
      if (!known) {
        std::fprintf(stderr, "bench_floor_margins: no row %s (the floors' expert keys or %s)\n", only.c_str(),
                     resolution);
        return 2;
      }
    } else {
      std::fprintf(stderr, "usage: bench_floor_margins [--full] [--row KEY]\n");
      return 2;
    }
  }
  ExtractionOptions base;
  base.buildSurfaces = false;
  std::vector<Body> bodies;
  auto add = [&](const std::string& label, const Character& c, const std::vector<TrueMuscle>& truth,
                 const ExtractionOptions& o) {
    const bool smooth = label.rfind("smooth_", 0) == 0;
    if (!full && label.rfind("makehuman", 0) == 0 && label.find("x0.950") == std::string::npos &&
        label.find("x1.000") == std::string::npos && label.find("x1.050") == std::string::npos)
      return;
    bodies.push_back({label, c, smooth ? std::vector<TrueMuscle>{} : truth, o, smooth});
  };
  bench::forEachTuningBody(1, full ? 11 : 4, base, add);
  bench::forEachMakeHumanSpacing(base, add);
  for (const char* file : {"godot_male_base_mesh_lowpoly/male_base_mesh.glb", "quaternius_horse/horse.glb",
                           "quaternius_woman_soldier/woman_soldier.glb"})
    bodies.push_back({file, loadCharacter(std::string(MYOSKIN_SHARED_DIR "/characters/") + file), {}, base, false});
  for (double scale : {1.0, 0.2})
    for (unsigned seed = 0; seed <= 11; ++seed) {
      SyntheticArmOptions ao;
      ao.seed = seed, ao.muscleScale = scale;
      const SyntheticCharacter arm = makeSyntheticArm(ao);
      bodies.push_back({"arm_" + std::to_string(seed) + (scale < 1 ? "_faint" : ""), arm.character,
                        scale < 1 ? std::vector<TrueMuscle>{} : arm.muscles, base, false});
    }
  const Outcome reference = evaluate(bodies, base);
  std::printf("%zu characters. Defaults: recall %.3f precision %.3f, %d muscles on smooth bodies, MakeHuman %d / %d\n",
              bodies.size(), reference.recall, reference.precision, reference.falseAlarms, reference.muscular,
              reference.neutral);
  std::printf("per factor: characters changed (muscles or names) / of them in count, recall, precision, smooth-body "
              "muscles, MakeHuman muscular/neutral\n");
  // One row: the value scaled by each factor through `set` (which may throw InputError for a value out of range).
  auto row = [&](const char* label, double value, auto set) {
    if (!only.empty() && only != label) return;
    std::printf("%-28s %7.4g", label, value);
    for (double f : {0.9, 0.95, 1.05, 1.1}) {
      ExtractionOptions o = base;
      Outcome r;
      try {  // a value out of the option's range: refused by setExpertOption or by extractMuscles' checks
        set(o, value * f);
        r = evaluate(bodies, o);
      } catch (const InputError&) {
        std::printf(" | x%.2f out of range", f);
        continue;
      }
      int changed = 0, recounted = 0;
      for (size_t i = 0; i < bodies.size(); ++i) {
        changed += r.signature[i] != reference.signature[i];
        recounted += r.counts[i] != reference.counts[i];
      }
      std::printf(" | x%.2f %2d/%2d %.3f %.3f %d %d/%d", f, changed, recounted, r.recall, r.precision, r.falseAlarms,
                  r.muscular, r.neutral);
    }
    std::printf("\n");
    std::fflush(stdout);
  };
  for (const char* key : floors)
    row(key, expertOption(base, key), [&](ExtractionOptions& o, double v) { setExpertOption(o, key, v); });
  // Not a floor but the profiles' resolution (no expert key: the sample count, profiles.samples, is the knob).
  row(resolution, base.profiles.sampleSpacing,
      [](ExtractionOptions& o, double v) { o.profiles.sampleSpacing = v; });
  return 0;
}
