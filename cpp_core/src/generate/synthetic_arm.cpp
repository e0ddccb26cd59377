// The procedural muscular right arm: the project's default test character with known muscles.
// The skin is a star-shaped generalized cylinder around the X axis: a smooth muscle-free limb (bone,
// tissue and fat) merged by a smooth maximum with the elliptical muscle bellies (plus a skin layer), so
// each belly shows as a bump with valleys between bumps. Both ends are closed with rounded caps.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"
#include "myoskin/synthetic_character.h"
#include "generate/limb_model.h"

namespace myoskin {

namespace {

using namespace limb;

// ============================================================================
// Arm layout: joints and the muscle-free limb
// ============================================================================

// Canonical joint positions along X: clavicle root, shoulder, elbow, wrist, hand tip.
constexpr std::array<double, 5> kCanonicalJoints = {0.0, 0.18, 0.48, 0.74, 0.83};

struct ArmLayout {
  std::array<double, 5> joints{};  // actual joint x positions (seeded bone lengths)
  double tubeStart = 0.0, tubeEnd = 0.0;  // x range of the cylinder part
  double startCap = 0.0, endCap = 0.0;    // lengths of the rounded end caps
  MonotoneCurve halfWidth, halfHeight;    // muscle-free skin: semi-axes along Y and Z

  // Canonical x (arm of the default proportions) -> actual x, piecewise linear over the bones.
  double mapX(double canonical) const {
    int i = 0;
    while (i < 3 && canonical > kCanonicalJoints[i + 1]) ++i;
    const double t = (canonical - kCanonicalJoints[i]) / (kCanonicalJoints[i + 1] - kCanonicalJoints[i]);
    return joints[i] + t * (joints[i + 1] - joints[i]);
  }

  // Radius of the muscle-free skin (elliptical cross-section) at x in direction theta.
  double baseRadius(double x, double theta) const {
    const double w = halfWidth(x), h = halfHeight(x);
    const double c = std::cos(theta) / w, s = std::sin(theta) / h;
    return 1.0 / std::sqrt(c * c + s * s);
  }
};

// Bone lengths (seeded, +-6 %) and the limb's cross-section stations (core radius + fat).
ArmLayout makeLayout(Jitter& jitter) {
  ArmLayout layout;
  const double lengths[4] = {0.18 * jitter.factor(0.06), 0.30 * jitter.factor(0.06), 0.26 * jitter.factor(0.06),
                             0.09 * jitter.factor(0.06)};
  layout.joints[0] = 0.0;
  for (int i = 0; i < 4; ++i) layout.joints[i + 1] = layout.joints[i] + lengths[i];
  const double thickness = jitter.factor(0.06);
  // Canonical x, core half-width (Y), core half-height (Z): shoulder, upper arm, elbow, forearm, flat hand.
  const double stations[][3] = {{0.00, 0.056, 0.054}, {0.10, 0.055, 0.054}, {0.18, 0.052, 0.053},
                                {0.26, 0.046, 0.046}, {0.33, 0.043, 0.043}, {0.42, 0.041, 0.040},
                                {0.48, 0.038, 0.036}, {0.54, 0.040, 0.038}, {0.64, 0.035, 0.031},
                                {0.74, 0.029, 0.020}, {0.78, 0.038, 0.016}, {0.83, 0.040, 0.014}};
  std::vector<double> xs, ws, hs;
  for (const auto& s : stations) {
    xs.push_back(layout.mapX(s[0]));
    ws.push_back(s[1] * thickness + kFat);
    hs.push_back(s[2] * thickness + kFat);
  }
  layout.halfWidth = MonotoneCurve(xs, ws);
  layout.halfHeight = MonotoneCurve(std::move(xs), hs);
  layout.tubeStart = layout.mapX(0.02);
  layout.tubeEnd = layout.joints[4];
  layout.startCap = 0.04;
  layout.endCap = 0.025;
  return layout;
}

// ============================================================================
// Muscles
// ============================================================================

// Canonical muscles (angles in degrees, canonical x) with seeded perturbation of sizes, angles, extents.
std::vector<MuscleModel> makeMuscles(const ArmLayout& layout, double scale, Jitter& jitter) {
  static const std::vector<MuscleSpec> specs = {
      {"deltoid", "upper_arm", 0.08, 0.36, 90, 160, 0.040, 0.024, 0.0110, 0.40},
      {"biceps", "upper_arm", 0.25, 0.47, 90, 90, 0.030, 0.020, 0.0110, 0.55},
      {"triceps", "upper_arm", 0.21, 0.46, 270, 270, 0.034, 0.017, 0.0090, 0.42},
      {"brachialis", "upper_arm", 0.34, 0.50, 148, 148, 0.018, 0.013, 0.0070, 0.60},
      {"forearm_flexors", "forearm", 0.49, 0.66, 25, 25, 0.025, 0.015, 0.0080, 0.35},
      {"forearm_extensors", "forearm", 0.49, 0.67, 205, 205, 0.023, 0.014, 0.0075, 0.35},
  };
  return limb::makeMuscles(layout, scale, jitter, specs);
}

// ============================================================================
// Skin mesh, skeleton, weights
// ============================================================================

// Rings (tube and caps) around the X axis, closed by a pole at each end; outward-oriented triangles.
Mesh buildSkin(const ArmLayout& layout, const std::vector<MuscleModel>& muscles, int ringsPerMetre, int around) {
  struct Ring {
    double x, scale, evalX;  // position, radius factor (caps), where the cross-section is evaluated
  };
  std::vector<Ring> rings;
  for (int k = kCapRings - 1; k >= 1; --k) {
    const double phi = 0.5 * kPi * k / kCapRings;
    rings.push_back({layout.tubeStart - layout.startCap * std::sin(phi), std::cos(phi), layout.tubeStart});
  }
  const double length = layout.tubeEnd - layout.tubeStart;
  const int tubeRings = std::max(2, static_cast<int>(std::lround(length * ringsPerMetre)) + 1);
  for (int i = 0; i < tubeRings; ++i) {
    const double x = layout.tubeStart + length * i / (tubeRings - 1);
    rings.push_back({x, 1.0, x});
  }
  for (int k = 1; k < kCapRings; ++k) {
    const double phi = 0.5 * kPi * k / kCapRings;
    rings.push_back({layout.tubeEnd + layout.endCap * std::sin(phi), std::cos(phi), layout.tubeEnd});
  }
  const int nr = static_cast<int>(rings.size());
  Mesh mesh;
  mesh.vertices.resize(nr * around + 2, 3);
  mesh.vertices.row(0) << layout.tubeStart - layout.startCap, 0.0, 0.0;
  for (int i = 0; i < nr; ++i)
    for (int j = 0; j < around; ++j) {
      const double theta = 2.0 * kPi * j / around;
      const double r = rings[i].scale * skinRadius(layout, muscles, rings[i].evalX, theta);
      mesh.vertices.row(1 + i * around + j) << rings[i].x, r * std::cos(theta), r * std::sin(theta);
    }
  const int endPole = nr * around + 1;
  mesh.vertices.row(endPole) << layout.tubeEnd + layout.endCap, 0.0, 0.0;

  mesh.triangles.resize(2 * around * nr, 3);
  auto v = [&](int i, int j) { return 1 + i * around + (j % around); };
  int f = 0;
  for (int j = 0; j < around; ++j) mesh.triangles.row(f++) << 0, v(0, j + 1), v(0, j);
  for (int i = 0; i + 1 < nr; ++i)
    for (int j = 0; j < around; ++j) {
      mesh.triangles.row(f++) << v(i, j), v(i, j + 1), v(i + 1, j + 1);
      mesh.triangles.row(f++) << v(i, j), v(i + 1, j + 1), v(i + 1, j);
    }
  for (int j = 0; j < around; ++j) mesh.triangles.row(f++) << v(nr - 1, j), v(nr - 1, j + 1), endPole;
  return mesh;
}

// clavicle -> upper_arm -> forearm -> hand along +X; rest frames with bone X = -Y, bone Z = +Z.
Skeleton buildSkeleton(const ArmLayout& layout) {
  const char* names[4] = {"clavicle", "upper_arm", "forearm", "hand"};
  Skeleton skeleton;
  for (int i = 0; i < 4; ++i) {
    Bone bone;
    bone.name = names[i];
    bone.parent = i - 1;
    bone.head = Vec3(layout.joints[i], 0.0, 0.0);
    bone.tail = Vec3(layout.joints[i + 1], 0.0, 0.0);
    bone.rest = boneMatrix(bone.head, bone.tail, -Vec3::UnitY());
    skeleton.bones.push_back(bone);
  }
  return skeleton;
}

// Four slots; smoothstep blends over kBlendWidth centred on the shoulder, elbow and wrist (sum 1).
SkinWeights buildWeights(const Points& vertices, const ArmLayout& layout) {
  const int n = static_cast<int>(vertices.rows());
  SkinWeights w;
  w.joints = IndexMatrix::Constant(n, 4, -1);
  w.weights = WeightMatrix::Zero(n, 4);
  for (int i = 0; i < n; ++i) {
    const double x = vertices(i, 0);
    double u[3];
    for (int k = 0; k < 3; ++k) u[k] = smoothStep((x - layout.joints[k + 1] + 0.5 * kBlendWidth) / kBlendWidth);
    const double bone[4] = {1.0 - u[0], u[0] - u[1], u[1] - u[2], u[2]};
    int slot = 0;
    for (int b = 0; b < 4; ++b)
      if (bone[b] > 0.0) {
        w.joints(i, slot) = b;
        w.weights(i, slot++) = bone[b];
      }
    // Heaviest influence first.
    if (slot == 2 && w.weights(i, 1) > w.weights(i, 0)) {
      std::swap(w.joints(i, 0), w.joints(i, 1));
      std::swap(w.weights(i, 0), w.weights(i, 1));
    }
  }
  return w;
}

}  // namespace

// ============================================================================
// Public entry
// ============================================================================

// Builds the arm, its skeleton and weights, and the ground-truth muscles; validates the character.
SyntheticCharacter makeSyntheticArm(const SyntheticArmOptions& options) {
  if (options.ringsPerMetre < 20)
    throw InputError("synthetic arm: ringsPerMetre must be at least 20, got " + std::to_string(options.ringsPerMetre));
  if (options.segmentsAround < 8)
    throw InputError("synthetic arm: segmentsAround must be at least 8, got " +
                     std::to_string(options.segmentsAround));
  if (!std::isfinite(options.muscleScale) || options.muscleScale < 0.0)
    throw InputError("synthetic arm: muscleScale must be finite and >= 0");

  Jitter jitter(options.seed);
  const ArmLayout layout = makeLayout(jitter);
  const std::vector<MuscleModel> muscles = makeMuscles(layout, options.muscleScale, jitter);

  SyntheticCharacter out;
  Character& c = out.character;
  c.name = "synthetic_arm";
  c.mesh = buildSkin(layout, muscles, options.ringsPerMetre, options.segmentsAround);
  c.skeleton = buildSkeleton(layout);
  c.weights = buildWeights(c.mesh.vertices, layout);
  c.sourceVertexCount = c.mesh.numVertices();
  c.sourceToWelded.resize(c.sourceVertexCount);
  for (int i = 0; i < c.sourceVertexCount; ++i) c.sourceToWelded[i] = i;
  for (size_t i = 0; i < muscles.size(); ++i) {
    TrueMuscle t = trueMuscle(muscles[i], layout);
    std::vector<MuscleModel> others = muscles;
    others.erase(others.begin() + static_cast<std::ptrdiff_t>(i));
    t.relief = muscleRelief(muscles[i], layout, [&](double x, double theta, bool with) {
      return skinRadius(layout, with ? muscles : others, x, theta);
    });
    out.muscles.push_back(std::move(t));
  }
  validateCharacter(c);
  return out;
}

}  // namespace myoskin
