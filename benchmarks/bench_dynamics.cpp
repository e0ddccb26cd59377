// Secondary motion speed on makehuman_muscular_male: the per-frame cost of the jiggle over a 120-frame arm swing, against the plain per-frame skinning (rig evaluation + Equation 3) measured
// in the same run.
#include <chrono>
#include <cstdio>
#include <string>

#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/secondary_motion.h"
#include "myoskin/skinning.h"

using namespace myoskin;

namespace {

// Best of 3 runs of f, seconds.
template <typename F>
double best(F&& f) {
  double b = 1e30;
  for (int rep = 0; rep < 3; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    b = std::min(b, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return b;
}

}  // namespace

int main() {
  const std::string path =
      std::string(MYOSKIN_SHARED_DIR) + "/characters/makehuman_muscular_male/makehuman_muscular_male.glb";
  Character c;
  try {
    LoadOptions lo;
    lo.requireWeights = true;
    c = loadCharacter(path, lo);
  } catch (const std::exception& e) {
    std::printf("skipped: needs %s (%s)\n", path.c_str(), e.what());
    return 0;
  }
  const std::vector<Muscle> muscles = extractMuscles(c).muscles;
  const MuscleRig rig(c.skeleton, muscles);
  const SkinWeights w = computeHybridWeights(c.mesh, c.weights, rig);
  auto skinner = std::make_shared<Skinner>(c.mesh.vertices, w, c.skeleton.numBones() + rig.numJoints());
  // Both arms swing at the shoulder and elbow for 120 frames at 24 fps.
  PoseSequence seq;
  for (int f = 0; f < 120; ++f) {
    std::vector<Eigen::Quaterniond> q(c.skeleton.numBones(), Eigen::Quaterniond::Identity());
    for (int b = 0; b < c.skeleton.numBones(); ++b) {
      const std::string& n = c.skeleton.bones[b].name;
      const double s = std::sin(2 * 3.14159265 * f / 30.0);
      if (n.rfind("upperarm01", 0) == 0) q[b] = Eigen::AngleAxisd(0.6 * s, Vec3::UnitX());
      if (n.rfind("lowerarm01", 0) == 0) q[b] = Eigen::AngleAxisd(0.8 + 0.6 * s, Vec3::UnitX());
    }
    seq.frames.push_back(poseFromLocalRotations(c.skeleton, q));
  }
  std::printf("makehuman_muscular_male: %d vertices, %d bones, %d muscles (%d joints), %zu frames\n",
              c.mesh.numVertices(), c.skeleton.numBones(), rig.numMuscles(), rig.numJoints(), seq.frames.size());
  auto bakeWith = [&](bool jiggle, bool filter) {
    SimulationOptions o;
    o.jiggle = jiggle;
    o.filter = filter;
    Simulation sim(c.mesh, c.skeleton, &rig, skinner, seq, o);
    size_t sum = 0;
    sim.bake(sim.firstFrame(), sim.lastFrame(), [&](int, const PointsF& p) { sum += p.rows(); });
    return sum;
  };
  // The add-on's PC2 inputs: a painted jiggle map (a second skinning per frame) and a shape key mix on every frame.
  std::vector<double> map(c.mesh.numVertices());
  for (int v = 0; v < c.mesh.numVertices(); ++v) map[v] = (v % 2) ? 1.0 : 0.25;
  std::vector<PointsF> offsets(seq.frames.size());
  for (PointsF& o : offsets) o = (0.002 * (c.mesh.vertices.array() * 40.0).sin()).cast<float>().matrix();
  auto bakeExtra = [&](bool withMap, bool withKeys) {
    SimulationOptions o;
    o.jiggle = true;
    if (withMap) o.jiggleVertexInfluence = map;
    Simulation sim(c.mesh, c.skeleton, &rig, skinner, seq, o);
    if (withKeys) sim.setShapeOffsets(offsets);
    size_t sum = 0;
    sim.bake(sim.firstFrame(), sim.lastFrame(), [&](int, const PointsF& p) { sum += p.rows(); });
    return sum;
  };
  const double n = static_cast<double>(seq.frames.size());
  const double plain = best([&] { bakeWith(false, false); }) / n;
  const double jiggle = best([&] { bakeWith(true, false); }) / n;
  const double mapped = best([&] { bakeExtra(true, false); }) / n;
  const double keyed = best([&] { bakeExtra(false, true); }) / n;
  // The jiggle alone: a fresh track (goals evaluated from the poses) per run, offsets and joint update per frame.
  MuscleRigState state = rig.makeState();
  const double track = best([&] {
    JiggleTrack t(rig, seq, 24.0);
    for (int f = 1; f <= 120; ++f) t.apply(f, state);
  }) / n;
  std::printf("baseline: skinning per frame (rig + Equation 3)   %.3f ms\n", 1e3 * plain);
  std::printf("with jiggle                                         %.3f ms  (x%.3f)\n", 1e3 * jiggle, jiggle / plain);
  std::printf("with jiggle and a painted jiggle map (per vertex)   %.3f ms  (x%.3f)\n", 1e3 * mapped, mapped / plain);
  std::printf("with jiggle and a shape key mix on every frame      %.3f ms  (x%.3f)\n", 1e3 * keyed, keyed / plain);
  // How far the jiggle moves the skin (largest vertex displacement over the swing, against plain skinning).
  std::vector<PointsF> plainFrames, jiggleFrames;
  for (bool j : {false, true}) {
    SimulationOptions o;
    o.jiggle = j;
    Simulation sim(c.mesh, c.skeleton, &rig, skinner, seq, o);
    sim.bake(sim.firstFrame(), sim.lastFrame(), [&](int, const PointsF& p) { (j ? jiggleFrames : plainFrames).push_back(p); });
  }
  double moved = 0;
  for (size_t f = 0; f < plainFrames.size(); ++f)
    moved = std::max(moved, double((jiggleFrames[f] - plainFrames[f]).rowwise().norm().maxCoeff()));
  std::printf("largest skin displacement by the jiggle over the swing: %.2f mm\n", 1e3 * moved);
  std::printf("the jiggle track alone (goals, 10 substeps, joints) %.4f ms  (%.1f %% of the baseline)\n", 1e3 * track,
              100 * track / plain);
  return 0;
}
