// Per-frame time of the anchored-skin deformer (issue 17) against the Equation 3 skinner on the same character, in
// the same run: makehuman_muscular_male (13k vertices, its extracted muscles; target under 5 ms) and a generated
// biped (makeSyntheticBody, ~100k vertices; target under 40 ms), 1 and 2 threads, an elbow swinging 0-120 degrees.
// Prints times and ratios; never asserts.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "myoskin/anchored_skin.h"
#include "myoskin/deformation.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

// Poses: the bone `name` turning 0..120 degrees about its X axis over `frames` frames; with an empty name every
// bone turning 0..20 degrees (every seam strained: the relaxation's worst case).
std::vector<Pose> swing(const Skeleton& sk, const std::string& name, int frames) {
  std::vector<Pose> poses;
  const int b = sk.find(name);
  for (int f = 0; f < frames; ++f) {
    std::vector<Eigen::Quaterniond> q(sk.numBones(), Eigen::Quaterniond::Identity());
    const double t = static_cast<double>(f) / std::max(1, frames - 1);
    if (b >= 0) q[b] = Eigen::AngleAxisd(2.0944 * t, Vec3::UnitX());
    if (name.empty())
      for (auto& r : q) r = Eigen::AngleAxisd(0.349 * t, Vec3::UnitX());
    poses.push_back(poseFromLocalRotations(sk, q));
  }
  return poses;
}

void run(const std::string& label, const Character& c, const std::string& bone, double targetMs) {
  const double t0 = now();
  const std::vector<Muscle> muscles = extractMuscles(c).muscles;
  const double t1 = now();
  const AnchoredComponents comps = deriveComponents(c.skeleton, muscles, c.mesh, c.weights);
  for (const std::string& moving : {bone, std::string()}) {
  const std::vector<Pose> poses = swing(c.skeleton, moving, 24);
  const MuscleRig rig(c.skeleton, muscles);
  const SkinWeights hybrid = computeHybridWeights(c.mesh, c.weights, rig);
  for (int threads : {1, 2}) {
    AnchoredSkinOptions ao;
    ao.threads = threads;
    const double b0 = now();
    const AnchoredSkin skin(c.mesh, c.weights, comps, c.skeleton, ao);
    const double b1 = now();
    SkinnerOptions so;
    so.threads = threads;
    const Skinner skinner(c.mesh.vertices, hybrid, c.skeleton.numBones() + rig.numJoints(), so);
    MuscleRigState state = rig.makeState();
    std::vector<Mat4> transforms;
    Points out(c.mesh.numVertices(), 3);
    PointsF outF(c.mesh.numVertices(), 3);
    double anchored = 1e30, eq3 = 1e30;
    for (int pass = 0; pass < 5; ++pass) {  // interleaved passes, best per-frame mean
      double s = now();
      for (const Pose& p : poses) skin.evaluate(p, out);
      anchored = std::min(anchored, (now() - s) / poses.size());
      s = now();
      for (const Pose& p : poses) {
        rig.evaluate(p, state);
        skinningTransforms(c.skeleton, p, rig, state, transforms);
        skinner.deform(transforms, outF);
      }
      eq3 = std::min(eq3, (now() - s) / poses.size());
    }
    std::printf("%-28s %-16s %7d vertices %3d components %2d thread(s): anchored %6.2f ms/frame (target %4.0f ms: %.2fx of it), "
                "Eq. 3 (rig + skinner) %6.2f ms, ratio %.2f; build %.2f s, extraction %.2f s, %d seam vertices\n",
                label.c_str(), moving.empty() ? "every bone 0-20" : (moving + " 0-120").c_str(), c.mesh.numVertices(), skin.numComponents(), threads, 1e3 * anchored, targetMs,
                1e3 * anchored / targetMs, 1e3 * eq3, anchored / eq3, b1 - b0, t1 - t0, skin.report().seamVertices);
  }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string shared = argc > 1 ? argv[1] : MYOSKIN_SHARED_DIR;
  const std::string mh = shared + "/characters/makehuman_muscular_male/makehuman_muscular_male.glb";
  try {
    LoadOptions lo;
    lo.requireWeights = true;
    run("makehuman_muscular_male", loadCharacter(mh, lo), "lowerarm01.L", 5.0);
  } catch (const std::exception& e) {
    std::printf("makehuman_muscular_male: skipped (%s)\n", e.what());
  }
  SyntheticBodyOptions bo;
  bo.seed = 21;
  bo.cellSize = 0.008;
  run("generated biped, seed 21", makeSyntheticBody(bo).character, "forearm.L", 40.0);
  return 0;
}
