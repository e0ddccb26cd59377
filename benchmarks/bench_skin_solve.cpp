// The per-frame skin solve (skin_solve.h) against the Eq. 3 skinner on the same frame: makehuman_muscular_male
// (13k vertices; target under 10 ms) and a generated biped of ~100k vertices (target under 100 ms), 2 threads.
// Prints the median time per frame of the skinner (baseline), the rig's evaluation with surfaces and the solve, and
// the solve's ratio to the skinner and to its target, and the CPU time over all threads (the machine may be shared).
// MYOSKIN_SKIN_SOLVE_ITERATIONS=N overrides the sweep budget (0: refit and the last collision pass alone).
#include <algorithm>
#include <cstdlib>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "myoskin/character.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/skin_solve.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

constexpr int kThreads = 2;

double cpuMs() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * t.tv_sec + 1e-6 * t.tv_nsec;
}

// Median wall time of f in milliseconds over `runs` runs (after one warm-up); cpu receives the mean CPU time of
// the process (all threads) per run, which on a busy machine says more than the wall time.
template <class F>
double medianMs(F&& f, int runs, double* cpu = nullptr) {
  f();
  std::vector<double> t;
  const double c0 = cpuMs();
  for (int i = 0; i < runs; ++i) {
    const auto a = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
  }
  if (cpu) *cpu = (cpuMs() - c0) / runs;
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// Every bone whose name starts with one of `prefixes` (and its subtree) turned `degrees` about the world axis
// perpendicular to its parent bone and +Z (forward flexion; negative: backward), on top of `pose`.
void flex(const Skeleton& sk, Pose& pose, const std::vector<std::string>& prefixes, double degrees) {
  for (int b = 0; b < sk.numBones(); ++b) {
    const std::string& name = sk.bones[b].name;
    bool hit = false;
    for (const std::string& p : prefixes) hit |= name.rfind(p, 0) == 0;
    if (!hit || sk.bones[b].parent < 0) continue;
    const Bone& hinge = sk.bones[sk.bones[b].parent];
    const Vec3 axis = (hinge.tail - hinge.head).normalized().cross(Vec3::UnitZ()).normalized();
    const Vec3 joint = pose.matrices[b].block<3, 1>(0, 3);
    Mat4 m = Mat4::Identity();
    m.block<3, 3>(0, 0) = Eigen::AngleAxisd(degrees * kPi / 180.0, axis).toRotationMatrix();
    m.block<3, 1>(0, 3) = joint - m.block<3, 3>(0, 0) * joint;
    std::vector<char> moved(sk.numBones(), 0);
    for (int i = 0; i < sk.numBones(); ++i) {
      moved[i] = i == b || (sk.bones[i].parent >= 0 && moved[sk.bones[i].parent]);
      if (moved[i]) pose.matrices[i] = m * pose.matrices[i];
    }
  }
}

void run(const std::string& label, const Character& c, const Pose& pose, double targetMs) {
  const ExtractionResult ex = extractMuscles(c);
  if (ex.muscles.empty()) {
    std::printf("%s: no muscles extracted, skipped\n", label.c_str());
    return;
  }
  const MuscleRig rig(c.skeleton, ex.muscles);
  const SkinWeights combined = computeHybridWeights(c.mesh, c.weights, rig);
  const int nb = c.skeleton.numBones();
  SkinnerOptions so;
  so.threads = kThreads;
  const Skinner skinner(c.mesh.vertices, combined, nb + rig.numJoints(), so);
  SkinSolveOptions o;
  o.threads = kThreads;
  if (const char* it = std::getenv("MYOSKIN_SKIN_SOLVE_ITERATIONS")) o.iterations = std::atoi(it);
  const auto b0 = std::chrono::steady_clock::now();
  SkinSolver solver(c.mesh, rig, defaultGoalWeights(combined, nb, o.slide, o.fullShare), o);
  const double buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - b0).count();
  MuscleRigState state = rig.makeState();
  std::vector<Mat4> t;
  rig.evaluate(pose, state, true);
  skinningTransforms(c.skeleton, pose, rig, state, t);
  PointsF goal;
  skinner.deform(t, goal);
  Points out;
  double deformCpu = 0.0, solveCpu = 0.0;
  const double deformMs = medianMs([&] { skinner.deform(t, goal); }, 31, &deformCpu);
  const double evaluateMs = medianMs([&] { rig.evaluate(pose, state, true); }, 31);
  const double solveMs = medianMs([&] { solver.solve(goal, state, out); }, 15, &solveCpu);
  const SkinSolveReport& r = solver.report();
  std::printf("%s: %d skin vertices, %d muscles, %d regions, %d sliding vertices, %d inside at rest; build %.0f ms\n",
              label.c_str(), c.mesh.numVertices(), rig.numMuscles(), r.regions, r.slidingVertices, r.insideAtRest,
              buildMs);
  std::printf("  per frame (%d threads, median wall time): Eq. 3 deform %.3f ms; rig evaluate with surfaces %.3f ms; "
              "skin solve %.3f ms = %.1fx the deform, %.2f of the %.0f ms target\n",
              kThreads, deformMs, evaluateMs, solveMs, solveMs / deformMs, solveMs / targetMs, targetMs);
  std::printf("  CPU time per frame (all threads): deform %.3f ms, skin solve %.3f ms (%.1fx); CPU time / %d = %.2f of "
              "the target\n",
              deformCpu, solveCpu, solveCpu / deformCpu, kThreads, solveCpu / kThreads / targetMs);
}

}  // namespace

int main() {
  const std::string mh = std::string(MYOSKIN_SHARED_DIR) + "/characters/makehuman_muscular_male/makehuman_muscular_male.glb";
  if (std::ifstream(mh).good()) {
    const Character c = loadCharacter(mh);
    Pose pose = restPose(c.skeleton);
    flex(c.skeleton, pose, {"lowerarm01"}, 90.0);
    flex(c.skeleton, pose, {"lowerleg01"}, -90.0);
    run("makehuman_muscular_male (elbows 90, knees 90)", c, pose, 10.0);
  } else {
    std::printf("makehuman_muscular_male: %s missing, skipped\n", mh.c_str());
  }
  SyntheticBodyOptions o;
  o.seed = 1;
  const Character body = makeSyntheticBody(o).character;
  Pose pose = restPose(body.skeleton);
  flex(body.skeleton, pose, {"forearm"}, 90.0);
  flex(body.skeleton, pose, {"shin"}, -90.0);
  run("generated biped (seed 1)", body, pose, 100.0);
  return 0;
}
