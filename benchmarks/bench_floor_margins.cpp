// How far each load-bearing extraction floor sits from the nearest change (issue 13, item 6: floors with margin).
// For each floor, the value is scaled by factors stepping away from 1 (x 1.025, 1.05, 1.1, 1.2, 1.4 and their
// inverses) until the muscles found (count and names per character) first differ from the defaults' over the tuning
// set; the window between those steps is printed, with the character that changed first on each side. A floor whose
// window is +-2.5 % sits on a decision: a character nobody tuned on may fall either side of it.
//   bench_floor_margins [--full]   (default: tune seeds 1-4, MakeHuman muscular and neutral at spacings x 0.95, 1 and
//   1.05, the shared characters, the synthetic arms 0-11 at muscle scales 1 and 0.2; --full: tune seeds 1-11 and the
//   nine MakeHuman spacings of bench_floor_ablation). Printed, never asserted; tune seeds only.
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
  ExtractionOptions options;  // the set's own (a plane spacing for the MakeHuman sweep)
};

// Muscle count and sorted names: what a floor decides (positions are the end and surface stages' business).
std::string signature(const Body& b, const ExtractionOptions& floors) {
  ExtractionOptions o = floors;
  o.planes.spacing = b.options.planes.spacing;
  const ExtractionResult r = extractMuscles(b.character, o);
  std::vector<std::string> names;
  for (const Muscle& m : r.muscles) names.push_back(m.name);
  std::sort(names.begin(), names.end());
  std::string s = std::to_string(names.size());
  for (const std::string& n : names) s += " " + n;
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  const bool full = argc > 1 && std::strcmp(argv[1], "--full") == 0;
  ExtractionOptions base;
  base.buildSurfaces = false;
  std::vector<Body> bodies;
  auto add = [&](const std::string& label, const Character& c, const std::vector<TrueMuscle>&, const ExtractionOptions& o) {
    bodies.push_back({label, c, o});
  };
  bench::forEachTuningBody(1, full ? 11 : 4, base, add);
  if (full) {
    bench::forEachMakeHumanSpacing(base, add);
  } else {
    bench::forEachMakeHumanSpacing(base, [&](const std::string& label, const Character& c,
                                             const std::vector<TrueMuscle>& t, const ExtractionOptions& o) {
      if (label.find("x0.950") != std::string::npos || label.find("x1.000") != std::string::npos ||
          label.find("x1.050") != std::string::npos)
        add(label, c, t, o);
    });
  }
  for (const char* file : {"godot_male_base_mesh_lowpoly/male_base_mesh.glb", "quaternius_horse/horse.glb",
                           "quaternius_woman_soldier/woman_soldier.glb"})
    bodies.push_back({file, loadCharacter(std::string(MYOSKIN_SHARED_DIR "/characters/") + file), base});
  for (double scale : {1.0, 0.2})
    for (unsigned seed = 0; seed <= 11; ++seed) {
      SyntheticArmOptions ao;
      ao.seed = seed, ao.muscleScale = scale;
      bodies.push_back({"arm_" + std::to_string(seed) + (scale < 1 ? "_faint" : ""), makeSyntheticArm(ao).character, base});
    }
  std::vector<std::string> reference;
  for (const Body& b : bodies) reference.push_back(signature(b, base));
  std::printf("%zu characters; window = the factors on the floor with the same muscles everywhere\n", bodies.size());
  std::printf("%-34s %9s  %-26s %-26s\n", "floor", "default", "down to (first change)", "up to (first change)");

  const char* floors[] = {"bumps.minProtrusion",       "bumps.minRelativeProtrusion", "bumps.maxWidthFraction",
                          "sectionBumps.weakFraction", "sectionBumps.faintFraction",  "sectionBumps.faintRelative",
                          "filters.minEvidence",       "filters.minRelative",         "filters.continuousEvidence",
                          "filters.spindleEnds",       "filters.spindleLength",       "filters.spindleSteepness",
                          "filters.twinReach",         "link.maxLateralFactor",       "link.maxAngle",
                          "link.mergeFactor"};
  const double steps[] = {1.025, 1.05, 1.1, 1.2, 1.4};
  for (const char* key : floors) {
    const double value = expertOption(base, key);
    std::string edge[2];
    double reach[2] = {0, 0};
    for (int side = 0; side < 2; ++side) {
      for (double step : steps) {
        const double f = side == 0 ? 1.0 / step : step;
        ExtractionOptions o = base;
        try {
          setExpertOption(o, key, value * f);
        } catch (const InputError&) {
          edge[side] = "(out of range)";
          break;
        }
        std::string changed;
        for (size_t i = 0; i < bodies.size() && changed.empty(); ++i)
          if (signature(bodies[i], o) != reference[i]) changed = bodies[i].label;
        if (!changed.empty()) {
          edge[side] = "x" + std::to_string(f).substr(0, 5) + " " + changed;
          break;
        }
        reach[side] = f;
      }
      if (edge[side].empty()) edge[side] = "(none within x1.4)";
    }
    char lo[64], hi[64];
    std::snprintf(lo, sizeof lo, "%s", reach[0] > 0 ? ("x" + std::to_string(reach[0]).substr(0, 5)).c_str() : "x1");
    std::snprintf(hi, sizeof hi, "%s", reach[1] > 0 ? ("x" + std::to_string(reach[1]).substr(0, 5)).c_str() : "x1");
    std::printf("%-34s %9.4g  %-6s %-19.19s %-6s %-19.19s\n", key, value, lo, edge[0].c_str(), hi, edge[1].c_str());
    std::fflush(stdout);
  }
  return 0;
}
