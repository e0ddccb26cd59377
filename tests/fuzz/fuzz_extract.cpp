// libFuzzer target: muscle extraction end to end (extractMuscles, surfaces included) on a mutated small synthetic
// arm. The input is a list of 6-byte edits applied to the arm: kind, a 16-bit index, three signed bytes d.
//   0 move a skin vertex by d mm          4 set a vertex coordinate to NaN / +-inf (d[0] % 3)
//   1 move a skin vertex by d cm          5 set a vertex's skin weight slot to d[0] / 64 (negative too)
//   2 move a bone's head by d cm          6 set a triangle corner to a vertex index (out of range too)
//   3 move a bone's tail by d cm          7 weld a vertex onto another (duplicates, degenerate triangles)
// Bone edits rebuild the bone's rest matrix from head, tail and its old X axis (a loader's result). No input:
// the arm as made. Accepted characters must give valid, finite muscles that survive a muscles.json round trip.
#include <limits>

#include "fuzz_support.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Character base = [] {
    SyntheticArmOptions o;
    o.ringsPerMetre = 30;  // ~600 vertices: an extraction takes ~1 s under ASan
    o.segmentsAround = 16;
    return makeSyntheticArm(o).character;
  }();
  Character c = base;
  const int nv = c.mesh.numVertices(), nt = static_cast<int>(c.mesh.triangles.rows()), nb = c.skeleton.numBones();
  fuzz::Reader in(data, size);
  for (int edits = 0; in.remaining() >= 6 && edits < 64; ++edits) {
    const uint8_t kind = in.take<uint8_t>() % 8;
    const int index = in.take<uint16_t>();
    Vec3 d;
    for (int k = 0; k < 3; ++k) d[k] = in.take<int8_t>();
    const int v = index % nv;
    switch (kind) {
      case 0: c.mesh.vertices.row(v) += 0.001 * d.transpose(); break;
      case 1: c.mesh.vertices.row(v) += 0.01 * d.transpose(); break;
      case 2:
      case 3: {
        Bone& b = c.skeleton.bones[index % nb];
        (kind == 2 ? b.head : b.tail) += 0.01 * d;
        const Vec3 x = b.rest.block<3, 1>(0, 0);
        if ((b.tail - b.head).norm() > 0) b.rest = boneMatrix(b.head, b.tail, x);
        break;
      }
      case 4: {
        const int mode = static_cast<int>(d.x() + 128) % 3;
        c.mesh.vertices(v, index % 3) = mode == 0   ? std::numeric_limits<double>::quiet_NaN()
                                        : mode == 1 ? std::numeric_limits<double>::infinity()
                                                    : -std::numeric_limits<double>::infinity();
        break;
      }
      case 5:
        if (c.weights.influences() > 0) c.weights.weights(v, index % c.weights.influences()) = d.x() / 64.0;
        break;
      case 6: c.mesh.triangles(index % nt, static_cast<int>(d.x() + 128) % 3) = static_cast<int>(d.y() * 300 + d.z()); break;
      case 7: c.mesh.vertices.row(v) = c.mesh.vertices.row(static_cast<int>(d.x() + 128 + 256 * (d.y() + 128)) % nv); break;
    }
  }
  ExtractionOptions options;
  options.profiles.samples = 48;  // the fewest the derived count gives (~125 here): the bump stage dominates
  fuzz::expectInputErrorOnly([&] {
    const ExtractionResult r = extractMuscles(c, options);
    if (std::getenv("MYOSKIN_FUZZ_VERBOSE")) {
      std::fprintf(stderr, "%zu muscles, %d planes, %d bumps;", r.muscles.size(), r.report.planes, r.report.bumps);
      for (const StageTiming& t : r.report.timings) std::fprintf(stderr, " %s %.3f s", t.stage.c_str(), t.seconds);
      std::fprintf(stderr, "\n");
    }
    if (r.report.muscles != static_cast<int>(r.muscles.size())) fuzz::fail("report counts other muscles");
    try {
      validateMuscles(r.muscles);
      const std::vector<Muscle> again = musclesFromJson(musclesToJson(r.muscles));
      if (again.size() != r.muscles.size()) fuzz::fail("muscle count changed in a muscles.json round trip");
    } catch (const InputError& e) {
      fuzz::fail(std::string("extraction gave muscles that do not validate: ") + e.what());
    }
  });
  return 0;
}
