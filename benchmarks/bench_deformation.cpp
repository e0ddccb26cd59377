// Muscle deformation speed (issue 4): 100 muscles x 8 joints evaluated per pose (target < 0.2 ms), by
// wrap type, with and without posed surfaces. Baseline measured in the same run: the skeleton's own
// forward kinematics for the same poses (poseFromLocalRotations), so the ratio says what the muscles
// add on top of posing the skeleton. Muscles are the synthetic arm's extracted ones, repeated.
#include <chrono>
#include <cmath>
#include <cstdio>

#include "myoskin/deformation.h"
#include "myoskin/extraction.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

// Best-of-5 mean seconds per call of f over `calls` calls.
template <typename F>
double timePerCall(int calls, F&& f) {
  double best = 1e30;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < calls; ++i) f(i);
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / calls);
  }
  return best;
}

}  // namespace

int main() {
  const SyntheticCharacter arm = makeSyntheticArm();
  const Skeleton& sk = arm.character.skeleton;
  const std::vector<Muscle> found = extractMuscles(arm.character).muscles;
  if (found.empty()) {
    std::printf("no muscles extracted from the synthetic arm\n");
    return 1;
  }
  const int fa = sk.find("forearm");
  std::vector<Pose> poses;
  std::vector<std::vector<Eigen::Quaterniond>> rotations;
  for (int i = 0; i < 64; ++i) {
    std::vector<Eigen::Quaterniond> q(sk.numBones(), Eigen::Quaterniond::Identity());
    q[fa] = Eigen::AngleAxisd(2.4 * i / 63, Vec3::UnitX()) * Eigen::AngleAxisd(0.02 * i, Vec3::UnitY());
    rotations.push_back(q);
    poses.push_back(poseFromLocalRotations(sk, q));
  }
  const double fk = timePerCall(20000, [&](int i) { volatile auto p = poseFromLocalRotations(sk, rotations[i % 64]); (void)p; });
  std::printf("baseline: skeleton forward kinematics (%d bones)  %.4f ms per pose\n", sk.numBones(), 1e3 * fk);

  for (const char* kind : {"none", "joint", "bone", "mixed"}) {
    std::vector<Muscle> muscles;
    for (int i = 0, c = 0; i < 100; ++c) {
      Muscle m = found[c % found.size()];
      m.name += "_" + std::to_string(i);
      m.joints = 8;
      const std::string k = kind == std::string("mixed") ? (i % 3 == 0 ? "none" : i % 3 == 1 ? "joint" : "bone") : kind;
      if (k != "none") {
        // Half the attachments' distance to the sphere centre / cylinder axis: valid, and wrapping when bent.
        // Default attachments lie on the bones, i.e. on the cylinder's axis: for bone wraps move them into
        // the muscle (its root curve's end sections); muscles that still cannot wrap are passed over.
        if (k == "bone" && m.rootCurve.size() > 4) {
          m.origin.position = m.rootCurve[m.rootCurve.size() / 4];
          m.insertion.position = m.rootCurve[3 * m.rootCurve.size() / 4];
        }
        const Bone& b = sk.bones[fa];
        const Vec3 ax = (b.tail - b.head).normalized();
        auto dist = [&](const Vec3& p) {
          const Vec3 d = p - b.head;
          return k == "joint" ? d.norm() : (d - d.dot(ax) * ax).norm();
        };
        m.wrap.type = wrapTypeFromName(k);
        m.wrap.bone = "forearm";
        m.wrap.radius = 0.5 * std::min(dist(m.origin.position), dist(m.insertion.position));
        if (m.wrap.radius < 1e-3) {
          if (c > 100 * int(found.size())) return std::printf("no muscle can wrap round the forearm\n"), 1;
          continue;
        }
      }
      muscles.push_back(m);
      ++i;
    }
    MuscleRig rig(sk, muscles);
    MuscleRigState st = rig.makeState();
    const double joints = timePerCall(2000, [&](int i) { rig.evaluate(poses[i % 64], st); });
    const double surfaces = timePerCall(100, [&](int i) { rig.evaluate(poses[i % 64], st, true); });
    int vertices = 0;
    for (int m = 0; m < rig.numMuscles(); ++m) vertices += rig.restSurface(m).numVertices();
    std::printf("wrap %-5s: 100 muscles x 8 joints  %.4f ms per pose (%.2f of the 0.2 ms target, %.1fx FK)"
                "   with surfaces (%d vertices) %.3f ms\n",
                kind, 1e3 * joints, joints / 2e-4, joints / fk, vertices, 1e3 * surfaces);
  }
  return 0;
}
