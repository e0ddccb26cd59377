// libFuzzer target: pose JSON (posesFromJson) against the synthetic arm's skeleton. Accepted poses must be
// rigid: finite bone matrices whose rotation part is orthonormal with determinant 1.
#include "fuzz_support.h"
#include "myoskin/pose_io.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Skeleton skeleton = [] {
    SyntheticArmOptions o;
    o.ringsPerMetre = 20;
    o.segmentsAround = 8;
    return makeSyntheticArm(o).character.skeleton;
  }();
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzz::expectInputErrorOnly([&] {
    const PoseSequence seq = posesFromJson(text, skeleton);
    if (seq.frames.empty()) fuzz::fail("accepted a pose file with no frames");
    if (!std::isfinite(seq.startFrame)) fuzz::fail("start frame not finite");
    for (const Pose& pose : seq.frames) {
      if (pose.matrices.size() != skeleton.bones.size()) fuzz::fail("pose has the wrong number of bones");
      for (const Mat4& m : pose.matrices) {
        fuzz::requireFinite(m, "posed bone matrix");
        const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
        if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
            std::abs(r.determinant() - 1.0) > 1e-6)
          fuzz::fail("posed bone matrix is not a rotation");
      }
    }
  });
  return 0;
}
