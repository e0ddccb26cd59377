// Muscles found on each shared character scaled by factors that are not powers of ten (a character modelled in feet
// or inches, or 1.5 or 2 units tall), with the default units detection (the power of ten nearest the reference limb
// radius) and with scale.continuous (the exact factor), and with the reference limb radius moved by +-5 %: how far the
// detection depends on the body's size rather than its shape. Prints counts; the baseline is each character at x1.
#include <cstdio>
#include <exception>
#include <string>

#include "myoskin/extraction.h"
#include "myoskin/io.h"

using namespace myoskin;

namespace {

Character scaled(const Character& c, double s) {
  Character out = c;
  out.mesh.vertices *= s;
  for (Bone& b : out.skeleton.bones) b.head *= s, b.tail *= s, b.rest.block<3, 1>(0, 3) = b.head;
  return out;
}

size_t count(const Character& c, bool continuous, double reference = 0.0) {
  ExtractionOptions o;
  o.buildSurfaces = false;
  o.scale.continuous = continuous;
  o.scale.referenceLimbRadius = reference;
  return extractMuscles(c, o).muscles.size();
}

}  // namespace

int main() {
  const std::string shared = MYOSKIN_SHARED_DIR;
  const char* files[] = {"makehuman_muscular_male/makehuman_muscular_male.glb",
                         "makehuman_neutral/makehuman_neutral.glb",
                         "quaternius_woman_soldier/woman_soldier.glb", "quaternius_horse/horse.glb",
                         "godot_male_base_mesh_lowpoly/male_base_mesh.glb"};
  const double scales[] = {0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 2.54, 3.2808, 5.0};
  std::printf("muscles per scale (x1 is the baseline); units = default power-of-ten detection, continuous = "
              "scale.continuous\n");
  for (const char* file : files) {
    Character c;
    try {
      c = loadCharacter(shared + "/characters/" + file);
    } catch (const std::exception& e) {
      std::printf("%s: skipped (%s)\n", file, e.what());
      continue;
    }
    for (bool continuous : {false, true}) {
      std::printf("%-52s %-10s", file, continuous ? "continuous" : "units");
      for (double s : scales) std::printf(" x%g:%zu", s, count(scaled(c, s), continuous));
      std::printf("\n");
    }
    std::printf("%-52s %-10s", file, "reference");
    for (double r : {0.95, 0.975, 1.0, 1.025, 1.05})
      std::printf(" x%.3f:%zu", r, count(c, true, r * kReferenceLimbRadius));
    std::printf("  (continuous, reference limb radius x)\n");
  }
}
