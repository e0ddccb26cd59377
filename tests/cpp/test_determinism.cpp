// Determinism: the same input gives bit-identical muscles.json, hybrid weights and PC2 output across runs and
// across thread counts (TBB limited to 1 and to 2 threads; the skinner's own thread option likewise). The
// extraction's sections, the hybrid weights' muscle distances and the skinner run in parallel (tbb::parallel_for);
// each writes its own slots, so the results must not depend on the schedule.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <cstring>
#include <unistd.h>

#include "myoskin/deformation.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

struct RunOutput {
  std::string musclesJson;
  SkinWeights weights;
  std::string pc2;  // the file's bytes
  int muscles = 0;
};

std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Extraction -> muscles.json, hybrid weights, and a 4-frame elbow/shoulder animation through the skinner to a PC2.
RunOutput run(const Character& c, int threads, const std::string& tag) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  RunOutput out;
  const ExtractionResult r = extractMuscles(c);
  out.muscles = static_cast<int>(r.muscles.size());
  out.musclesJson = musclesToJson(r.muscles);
  // The rig reads the muscles back from the JSON, as `myoskin deform --muscles` does.
  const MuscleRig rig(c.skeleton, musclesFromJson(out.musclesJson));
  out.weights = computeHybridWeights(c.mesh, c.weights, rig, {});
  SkinnerOptions so;
  so.threads = threads;
  so.grainSize = 256;  // many tasks, so two threads really share the skin
  const Skinner skinner(c.mesh.vertices, out.weights, c.skeleton.numBones() + rig.numJoints(), so);
  const int forearm = c.skeleton.find("forearm"), upper = c.skeleton.find("upper_arm");
  const std::string path =
      (std::filesystem::temp_directory_path() / ("myoskin_determinism_" + tag + "_" + std::to_string(::getpid()) + ".pc2")).string();
  {
    PC2Writer writer(path, c.mesh.numVertices(), 1.0f, 1.0f);
    MuscleRigState state = rig.makeState();
    std::vector<Mat4> transforms;
    PointsF frame;
    for (int f = 0; f < 4; ++f) {
      std::vector<Eigen::Quaterniond> rotations(c.skeleton.bones.size(), Eigen::Quaterniond::Identity());
      rotations[forearm] = Eigen::AngleAxisd(0.6 * f, Vec3::UnitZ());
      rotations[upper] = Eigen::AngleAxisd(0.2 * f, Vec3::UnitX());
      const Pose pose = poseFromLocalRotations(c.skeleton, rotations);
      rig.evaluate(pose, state);
      skinningTransforms(c.skeleton, pose, rig, state, transforms);
      skinner.deform(transforms, frame);
      writer.writeFrame(frame);
    }
    writer.close();
  }
  out.pc2 = readBytes(path);
  std::filesystem::remove(path);
  return out;
}

bool sameWeights(const SkinWeights& a, const SkinWeights& b) {
  if (a.joints.rows() != b.joints.rows() || a.joints.cols() != b.joints.cols()) return false;
  if (a.joints != b.joints) return false;
  // Bit for bit (== would call -0.0 and 0.0 equal).
  return std::memcmp(a.weights.data(), b.weights.data(), sizeof(double) * a.weights.size()) == 0;
}

}  // namespace

TEST(Determinism, SameOutputAcrossRunsAndThreadCounts) {
  const Character c = makeSyntheticArm().character;
  ASSERT_GE(c.skeleton.find("forearm"), 0);
  ASSERT_GE(c.skeleton.find("upper_arm"), 0);
  const RunOutput one = run(c, 1, "t1");
  const RunOutput twoA = run(c, 2, "t2a");
  const RunOutput twoB = run(c, 2, "t2b");
  // Not vacuous: the canonical arm has its muscles, they carry weight, and the animation moves the skin.
  ASSERT_GE(one.muscles, 4);
  ASSERT_GT(one.weights.influences(), 0);
  ASSERT_GT(one.weights.joints.maxCoeff(), c.skeleton.numBones() - 1) << "no vertex has a muscle joint";
  ASSERT_EQ(one.pc2.size(), 32u + 4u * 3u * 4u * static_cast<size_t>(c.mesh.numVertices()));
  const size_t frameBytes = 12u * static_cast<size_t>(c.mesh.numVertices());
  ASSERT_NE(one.pc2.substr(32, frameBytes), one.pc2.substr(32 + 3 * frameBytes, frameBytes)) << "the pose moved nothing";

  EXPECT_EQ(twoA.musclesJson, twoB.musclesJson) << "two runs with 2 threads differ in muscles.json";
  EXPECT_EQ(one.musclesJson, twoA.musclesJson) << "muscles.json differs between 1 and 2 threads";
  EXPECT_TRUE(sameWeights(twoA.weights, twoB.weights)) << "two runs with 2 threads differ in hybrid weights";
  EXPECT_TRUE(sameWeights(one.weights, twoA.weights)) << "hybrid weights differ between 1 and 2 threads";
  EXPECT_TRUE(twoA.pc2 == twoB.pc2) << "two runs with 2 threads differ in the PC2 cache";
  EXPECT_TRUE(one.pc2 == twoA.pc2) << "the PC2 cache differs between 1 and 2 threads";
}
