// Floating-point exceptions on the NaN-producing paths (as libigl tests them): with FE_INVALID trapped
// (feenableexcept; an invalid operation such as 0/0, inf - inf, sqrt(-1) or a NaN cast to int raises SIGFPE at
// the instruction), the synthetic arm goes through extraction, the muscle rig, the hybrid weights and the skinner
// at rest and at extreme poses, and no invalid operation may happen. TBB is limited to the calling thread (the
// trap mask and the flags are per thread), and the flags are checked afterwards too.
#include <fenv.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <csignal>
#include <cstdio>
#include <unistd.h>

#include "myoskin/bumps.h"
#include "myoskin/deformation.h"
#include "myoskin/extraction.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

const char* gStage = "";

extern "C" void onSigfpe(int) {
  char msg[256];
  const int n = std::snprintf(msg, sizeof msg, "\nSIGFPE: an invalid floating-point operation (NaN produced) in: %s\n", gStage);
  if (n > 0) (void)!::write(2, msg, static_cast<size_t>(n));
  ::_exit(3);
}

// Traps FE_INVALID in this thread for its lifetime; the stage name says where a trap came from.
class InvalidTrap {
 public:
  InvalidTrap() {
    feclearexcept(FE_ALL_EXCEPT);
    std::signal(SIGFPE, onSigfpe);
    feenableexcept(FE_INVALID);
  }
  ~InvalidTrap() {
    fedisableexcept(FE_ALL_EXCEPT);
    std::signal(SIGFPE, SIG_DFL);
  }
  InvalidTrap(const InvalidTrap&) = delete;
  InvalidTrap& operator=(const InvalidTrap&) = delete;
};

}  // namespace

TEST(FloatingPoint, TrapIsArmed) {
  // The test below means something only if the trap fires: 0/0 under it must end the process.
  EXPECT_EXIT(
      {
        InvalidTrap trap;
        gStage = "the deliberate 0/0";
        volatile double zero = 0.0;
        volatile double nan = zero / zero;
        (void)nan;
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(3), "invalid floating-point operation");
}

TEST(FloatingPoint, NoInvalidOperationInExtractionRigWeightsAndSkinning) {
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  SyntheticArmOptions ao;
  ao.seed = 2;  // the arm with the faint brachialis that crosses the elbow (a joint wrap)
  InvalidTrap trap;
  gStage = "makeSyntheticArm";
  const Character c = makeSyntheticArm(ao).character;
  gStage = "extractMuscles";
  const ExtractionResult r = extractMuscles(c);
  ASSERT_GE(r.muscles.size(), 4u);
  gStage = "MuscleRig";
  const MuscleRig rig(c.skeleton, r.muscles);
  gStage = "computeHybridWeights";
  const SkinWeights weights = computeHybridWeights(c.mesh, c.weights, rig, {});
  SkinnerOptions so;
  so.threads = 1;
  gStage = "Skinner";
  const Skinner skinner(c.mesh.vertices, weights, c.skeleton.numBones() + rig.numJoints(), so);
  MuscleRigState state = rig.makeState();
  std::vector<Mat4> transforms;
  PointsF out;
  const int forearm = c.skeleton.find("forearm"), upper = c.skeleton.find("upper_arm"), hand = c.skeleton.find("hand");
  ASSERT_TRUE(forearm >= 0 && upper >= 0 && hand >= 0);
  // Rest, a right angle, the elbow folded flat (175 degrees: muscle joints nearly coincide), a full turn of the
  // shoulder and a twisted wrist.
  for (const double elbow : {0.0, 1.57, 3.05}) {
    for (const double shoulder : {0.0, 3.14159265358979}) {
      std::vector<Eigen::Quaterniond> rotations(c.skeleton.bones.size(), Eigen::Quaterniond::Identity());
      rotations[forearm] = Eigen::AngleAxisd(elbow, Vec3::UnitZ());
      rotations[upper] = Eigen::AngleAxisd(shoulder, Vec3::UnitX());
      rotations[hand] = Eigen::AngleAxisd(elbow, Vec3::UnitY());
      gStage = "poseFromLocalRotations / MuscleRig::evaluate";
      const Pose pose = poseFromLocalRotations(c.skeleton, rotations);
      rig.evaluate(pose, state, true);
      gStage = "skinningTransforms / Skinner::deform";
      skinningTransforms(c.skeleton, pose, rig, state, transforms);
      skinner.deform(transforms, out);
      ASSERT_TRUE(out.allFinite());
    }
  }
  gStage = "";
  EXPECT_EQ(fetestexcept(FE_INVALID), 0) << "FE_INVALID raised without a trap";
}

TEST(FloatingPoint, NoInvalidOperationInTheBumpStage) {
  // A muscular section and a degenerate-ish one (a near-collinear run and a duplicate-free sliver).
  InvalidTrap trap;
  gStage = "bump stage";
  int bumps = 0;
  for (const int lobes : {2, 3, 5}) {
    const int n = 120;
    Points2 p(n, 2);
    for (int i = 0; i < n; ++i) {
      const double t = 2 * 3.14159265358979 * i / n;
      const double r = 0.04 + 0.006 * std::pow(std::max(0.0, std::cos(lobes * t)), 3);
      p.row(i) << r * std::cos(t), r * std::sin(t);
    }
    const SectionTriangulation tri = triangulateSection(p, {axisDiagonal(p)});
    for (const Bump& b : findBumps(p, {}, &tri)) {
      const Ellipse2 e = fitBumpEllipse(p, b, tri);
      ASSERT_TRUE(e.center.allFinite() && std::isfinite(e.a) && std::isfinite(e.b));
      ++bumps;
    }
  }
  EXPECT_GE(bumps, 5);
}
