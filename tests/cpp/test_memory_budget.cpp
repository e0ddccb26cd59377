// The memory budget: a stage that would not fit stops with a clear InputError (never an out-of-memory kill), and
// the estimates stay above what the stages really take (measured here from the process's peak resident set).
#include <gtest/gtest.h>
#include <cstdlib>
#include <fstream>
#include <string>
#include "myoskin/deformation.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/memory_budget.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

// Sets MYOSKIN_MEMORY_LIMIT for one scope.
struct MemoryLimit {
  explicit MemoryLimit(const char* value) { setenv("MYOSKIN_MEMORY_LIMIT", value, 1); }
  ~MemoryLimit() { unsetenv("MYOSKIN_MEMORY_LIMIT"); }
};

// A /proc/self/status field in bytes.
std::uint64_t statusBytes(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, key.size() + 1, key + ":") == 0) return std::stoull(line.substr(key.size() + 1)) * 1024ull;
  return 0;
}

// Resets the peak resident set (VmHWM) to the current one; false where the kernel does not allow it.
bool resetPeak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.close();
  return static_cast<bool>(out);
}

template <class F>
void expectRefused(F&& stage, const std::string& what) {
  try {
    stage();
    ADD_FAILURE() << what << " ran under a 1 MiB MYOSKIN_MEMORY_LIMIT";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("needs about"), std::string::npos) << message;
    EXPECT_NE(message.find("MYOSKIN_MEMORY_LIMIT"), std::string::npos) << message;
    EXPECT_NE(message.find(what), std::string::npos) << message;
  }
}

const SyntheticCharacter& body() {
  static const SyntheticCharacter b = makeSyntheticBody();
  return b;
}

}  // namespace

TEST(MemoryBudget, AvailableIsBoundedByTheSystemAndTheEnvironment) {
  const std::uint64_t free = availableMemoryBytes();
  EXPECT_GT(free, 0u);
  {
    MemoryLimit limit("1G");
    const std::uint64_t capped = availableMemoryBytes();
    EXPECT_LE(capped, 1ull << 30);
    EXPECT_GE(capped + statusBytes("VmRSS"), std::min<std::uint64_t>(free, 1ull << 30) - (64ull << 20))
        << "the cap is the limit minus the resident set";
  }
  {
    MemoryLimit limit("512MiB");
    EXPECT_LE(availableMemoryBytes(), 512ull << 20);
  }
  for (const char* bad : {"lots", "-4G", "4X", "0", "1e30G"}) {
    MemoryLimit limit(bad);
    EXPECT_THROW(availableMemoryBytes(), InputError) << bad;
  }
}

TEST(MemoryBudget, StagesThatWouldNotFitAreRefusedClearly) {
  const Character& c = body().character;
  const ExtractionResult extracted = extractMuscles(c);
  ASSERT_GT(extracted.muscles.size(), 0u);
  const MuscleRig rig(c.skeleton, extracted.muscles);
  const SkinWeights weights = computeHybridWeights(c.mesh, c.weights, rig);
  MemoryLimit limit("1M");
  expectRefused([&] { extractMuscles(c); }, "muscle extraction on");
  expectRefused([&] { computeHybridWeights(c.mesh, c.weights, rig); }, "binding");
  expectRefused([&] { Skinner(c.mesh.vertices, weights, c.skeleton.numBones() + rig.numJoints()); }, "skinning");
}

TEST(MemoryBudget, EstimatesCoverTheMeasuredPeaks) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's shadow memory and quarantine inflate the peaks";
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
  GTEST_SKIP() << "AddressSanitizer's shadow memory and quarantine inflate the peaks";
#endif
#endif
  const Character& c = body().character;
  const std::int64_t nv = c.mesh.numVertices();
  if (!resetPeak()) GTEST_SKIP() << "/proc/self/clear_refs is not writable here";
  std::uint64_t before = statusBytes("VmRSS");
  const ExtractionResult extracted = extractMuscles(c);
  const std::uint64_t extraction = statusBytes("VmHWM") - before;
  ASSERT_GT(extracted.muscles.size(), 0u);
  const MuscleRig rig(c.skeleton, extracted.muscles);
  ASSERT_TRUE(resetPeak());
  before = statusBytes("VmRSS");
  const SkinWeights weights = computeHybridWeights(c.mesh, c.weights, rig);
  const std::uint64_t binding = statusBytes("VmHWM") - before;
  ASSERT_TRUE(resetPeak());
  before = statusBytes("VmRSS");
  const Skinner skinner(c.mesh.vertices, weights, c.skeleton.numBones() + rig.numJoints());
  const std::uint64_t skinning = statusBytes("VmHWM") - before;
  ASSERT_GT(extraction, 0u);
  // Conservative (the refusal must come before a job that would be killed), but not absurdly so.
  EXPECT_GE(extractionMemoryEstimate(nv), extraction);
  EXPECT_LE(extractionMemoryEstimate(nv), 4 * extraction + (32ull << 20));
  EXPECT_GE(hybridWeightsMemoryEstimate(nv, rig.numMuscles()), binding);
  EXPECT_GE(skinnerMemoryEstimate(nv, weights.influences()), skinning);
}
