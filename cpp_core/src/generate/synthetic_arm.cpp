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

namespace myoskin {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

constexpr double kFat = 0.003;             // fat layer over the limb core (metres)
constexpr double kSkinThickness = 0.003;   // skin over a muscle belly
constexpr double kSoftness = 0.007;        // smooth-max width where a belly meets the muscle-free limb
constexpr double kValleySoftness = 0.0025; // smooth-max width where two bellies meet (keeps the valley)
constexpr double kTendonDive = 0.006;      // extra depth of the centre line towards the tendons
constexpr double kBlendWidth = 0.04;       // skin-weight blend across each joint
constexpr int kCapRings = 8;               // rings of each rounded end cap (pole excluded)
constexpr int kCenterLinePoints = 32;      // points per ground-truth centre line
constexpr double kTruthCutoff = 0.1;       // the centre line covers the belly where radius > 10 % of peak
constexpr double kBellyExponent = 0.5;     // belly profile sin(pi s)^0.7

// ============================================================================
// Deterministic perturbation
// ============================================================================

// Seed 0 gives the canonical arm; other seeds perturb values. Every call draws one number, so the
// sequence of draws depends only on the seed (std::mt19937 is portable; std distributions are not).
class Jitter {
 public:
  explicit Jitter(unsigned seed) : canonical_(seed == 0), rng_(seed) {}

  // A factor in [1 - relative, 1 + relative].
  double factor(double relative) { return 1.0 + offset(relative); }

  // An offset in [-range, range].
  double offset(double range) {
    const double u = static_cast<double>(rng_()) / 4294967296.0;
    return canonical_ ? 0.0 : range * (2.0 * u - 1.0);
  }

 private:
  bool canonical_;
  std::mt19937 rng_;
};

// ============================================================================
// Smooth helpers
// ============================================================================

// Polynomial smooth maximum (C1): equals max(a, b) when |a - b| >= k.
double smoothMax(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::max(a, b) + h * h * k * 0.25;
}

// Cubic smoothstep of t clamped to [0, 1].
double smoothStep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Monotone cubic (Fritsch-Carlson) interpolation through stations; constant outside them.
class MonotoneCurve {
 public:
  MonotoneCurve() = default;
  MonotoneCurve(std::vector<double> xs, std::vector<double> ys) : x_(std::move(xs)), y_(std::move(ys)) {
    const size_t n = x_.size();
    std::vector<double> delta(n - 1);
    for (size_t i = 0; i + 1 < n; ++i) delta[i] = (y_[i + 1] - y_[i]) / (x_[i + 1] - x_[i]);
    m_.assign(n, 0.0);  // zero slope at both ends
    for (size_t i = 1; i + 1 < n; ++i)
      if (delta[i - 1] * delta[i] > 0.0) {
        const double w1 = 2.0 * (x_[i + 1] - x_[i]) + (x_[i] - x_[i - 1]);
        const double w2 = (x_[i + 1] - x_[i]) + 2.0 * (x_[i] - x_[i - 1]);
        m_[i] = (w1 + w2) / (w1 / delta[i - 1] + w2 / delta[i]);
      }
  }

  double operator()(double x) const {
    if (x <= x_.front()) return y_.front();
    if (x >= x_.back()) return y_.back();
    const size_t i = static_cast<size_t>(std::upper_bound(x_.begin(), x_.end(), x) - x_.begin()) - 1;
    const double h = x_[i + 1] - x_[i], t = (x - x_[i]) / h;
    const double t2 = t * t, t3 = t2 * t;
    return (2 * t3 - 3 * t2 + 1) * y_[i] + (t3 - 2 * t2 + t) * h * m_[i] + (-2 * t3 + 3 * t2) * y_[i + 1] +
           (t3 - t2) * h * m_[i + 1];
  }

 private:
  std::vector<double> x_, y_, m_;
};

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

// A muscle belly: an ellipse in each plane x = const, semi-axis a tangential and b radial, whose
// centre lies at depth under the muscle-free skin so that the bump stands `protrusion` out at its peak.
struct MuscleModel {
  std::string name, bone;
  double x0 = 0.0, x1 = 0.0;          // belly extent along X (profile zero at both ends)
  double theta0 = 0.0, theta1 = 0.0;  // centre angle at x0 and x1 (linear in between)
  double a = 0.0, b = 0.0;            // peak semi-axes (tangential, radial)
  double protrusion = 0.0;            // peak height of the skin over the muscle-free arm
  double peakAt = 0.5;                // position of the belly's peak, fraction of the length

  double gamma() const { return std::log(0.5) / std::log(peakAt); }
  // Belly profile in [0, 1]: sin(pi s^gamma)^0.7, peak 1 at s = peakAt, zero at the tendons.
  double profile(double s) const {
    if (s <= 0.0 || s >= 1.0) return 0.0;
    return std::pow(std::sin(kPi * std::pow(s, gamma())), kBellyExponent);
  }
  // Depth of the centre under the muscle-free skin: at the peak the bump stands `protrusion` out; towards
  // the tendons the centre dives (by kTendonDive) so the thin ends stay buried under the limb.
  double depth(double s) const {
    const double rest = 1.0 - profile(s);
    return kSkinThickness + b - protrusion + kTendonDive * rest * rest;
  }
};

// One cross-section of a muscle: centre (polar), angle and semi-axes.
struct MuscleSlice {
  double theta = 0.0, rho = 0.0, a = 0.0, b = 0.0;
};

MuscleSlice sliceAt(const MuscleModel& m, const ArmLayout& layout, double s) {
  MuscleSlice slice;
  const double x = m.x0 + s * (m.x1 - m.x0);
  const double p = m.profile(s);
  slice.theta = m.theta0 + s * (m.theta1 - m.theta0);
  slice.rho = layout.baseRadius(x, slice.theta) - m.depth(s);
  slice.a = m.a * p;
  slice.b = m.b * p;
  return slice;
}

// Distance from the axis where the ray at angle theta leaves the slice's ellipse. Past the silhouette
// (complex roots) it continues as (B - sqrt(-disc)) / A, which falls away continuously from the grazing
// point, so the envelope never jumps; -inf when facing away from the ellipse.
double rayExit(const MuscleSlice& e, double theta) {
  constexpr double kMiss = -std::numeric_limits<double>::infinity();
  if (e.a < 1e-6 || e.b < 1e-6) return kMiss;
  const double ut = std::sin(theta - e.theta), ur = std::cos(theta - e.theta);
  const double A = ut * ut / (e.a * e.a) + ur * ur / (e.b * e.b);
  const double B = ur * e.rho / (e.b * e.b);
  const double C = e.rho * e.rho / (e.b * e.b) - 1.0;
  const double disc = B * B - A * C;
  const double exit = (B + (disc >= 0.0 ? std::sqrt(disc) : -std::sqrt(-disc))) / A;
  return exit > 0.0 ? exit : kMiss;
}

// Distance from the axis of the two points where rays from the axis graze the ellipse (its silhouette).
double silhouetteRadius(const MuscleSlice& e) {
  if (e.rho <= e.b) return 0.0;  // the axis is inside the ellipse: no silhouette
  const double q = e.b * e.b / e.rho;
  return std::sqrt(e.a * e.a * (1.0 - e.b * e.b / (e.rho * e.rho)) + (e.rho - q) * (e.rho - q));
}

// True if, along the whole belly, the silhouette plus the skin layer stays a softness width (and a
// margin) below the muscle-free skin in the silhouette's direction.
bool silhouettesHidden(const MuscleModel& m, const ArmLayout& layout) {
  for (int k = 1; k < 200; ++k) {
    const double s = k / 200.0;
    const MuscleSlice e = sliceAt(m, layout, s);
    if (e.b < 1e-6 || e.rho <= e.b) continue;
    const double x = m.x0 + s * (m.x1 - m.x0);
    const double side = e.a * std::sqrt(1.0 - e.b * e.b / (e.rho * e.rho));
    const double angle = std::atan2(side, e.rho - e.b * e.b / e.rho);
    const double need = silhouetteRadius(e) + kSkinThickness + kSoftness + 0.0005;
    if (need > layout.baseRadius(x, e.theta - angle) || need > layout.baseRadius(x, e.theta + angle)) return false;
  }
  return true;
}

// Canonical muscles (angles in degrees, canonical x) with seeded perturbation of sizes, angles, extents.
std::vector<MuscleModel> makeMuscles(const ArmLayout& layout, double scale, Jitter& jitter) {
  struct Spec {
    const char* name;
    const char* bone;
    double x0, x1, theta0, theta1, a, b, protrusion, peakAt;
  };
  const Spec specs[] = {
      {"deltoid", "upper_arm", 0.08, 0.36, 90, 160, 0.040, 0.024, 0.0110, 0.40},
      {"biceps", "upper_arm", 0.25, 0.47, 90, 90, 0.030, 0.020, 0.0110, 0.55},
      {"triceps", "upper_arm", 0.21, 0.46, 270, 270, 0.034, 0.017, 0.0090, 0.42},
      {"brachialis", "upper_arm", 0.34, 0.50, 148, 148, 0.018, 0.013, 0.0070, 0.60},
      {"forearm_flexors", "forearm", 0.49, 0.66, 25, 25, 0.025, 0.015, 0.0080, 0.35},
      {"forearm_extensors", "forearm", 0.49, 0.67, 205, 205, 0.023, 0.014, 0.0075, 0.35},
  };
  std::vector<MuscleModel> muscles;
  for (const Spec& spec : specs) {
    // Always draw the same numbers in the same order (determinism does not depend on muscleScale).
    const double length = (spec.x1 - spec.x0) * jitter.factor(0.15);
    const double middle = 0.5 * (spec.x0 + spec.x1) + jitter.offset(0.05) * (spec.x1 - spec.x0);
    const double turn = jitter.offset(12.0);
    const double sizeA = jitter.factor(0.15), sizeB = jitter.factor(0.15), height = jitter.factor(0.15);
    const double peakShift = jitter.offset(0.08);
    if (scale <= 0.0) continue;
    MuscleModel m;
    m.name = spec.name;
    m.bone = spec.bone;
    m.x0 = layout.mapX(middle - 0.5 * length);
    m.x1 = layout.mapX(middle + 0.5 * length);
    m.theta0 = (spec.theta0 + turn) * kDeg;
    m.theta1 = (spec.theta1 + turn) * kDeg;
    m.a = spec.a * sizeA;
    m.b = spec.b * sizeB;
    m.protrusion = std::min(spec.protrusion * height, 0.8 * m.b);
    m.peakAt = spec.peakAt + peakShift;
    // Keep the silhouette (where rays from the axis graze the ellipse) hidden under the muscle-free skin at
    // full size, so the bump's flanks are smooth: narrow the belly if needed.
    if (!silhouettesHidden(m, layout)) {
      const double full = m.a;
      double lo = 0.3, hi = 1.0;
      for (int it = 0; it < 30; ++it) {
        m.a = full * 0.5 * (lo + hi);
        (silhouettesHidden(m, layout) ? lo : hi) = 0.5 * (lo + hi);
      }
      m.a = full * lo;
    }
    // Scale after narrowing, so sizes and protrusion are exactly proportional to muscleScale.
    m.a *= scale;
    m.b *= scale;
    m.protrusion *= scale;
    muscles.push_back(m);
  }
  return muscles;
}

// Skin radius at (x, theta): the bellies (plus skin) merged with each other by a narrow smooth maximum
// (valleys between them stay), then with the muscle-free limb by a wider one (soft edges).
double skinRadius(const ArmLayout& layout, const std::vector<MuscleModel>& muscles, double x, double theta) {
  double bellies = -std::numeric_limits<double>::infinity();
  for (const MuscleModel& m : muscles) {
    if (x <= m.x0 || x >= m.x1) continue;
    const double exit = rayExit(sliceAt(m, layout, (x - m.x0) / (m.x1 - m.x0)), theta);
    if (!std::isfinite(exit)) continue;
    bellies = std::isfinite(bellies) ? smoothMax(bellies, exit + kSkinThickness, kValleySoftness)
                                     : exit + kSkinThickness;
  }
  const double base = layout.baseRadius(x, theta);
  return std::isfinite(bellies) ? smoothMax(base, bellies, kSoftness) : base;
}

// Ground truth: the ellipse centres and mean radii sqrt(a b) where the radius exceeds 10 % of its peak.
TrueMuscle trueMuscle(const MuscleModel& m, const ArmLayout& layout) {
  TrueMuscle t;
  t.name = m.name;
  t.bone = m.bone;
  const double q = std::asin(std::pow(kTruthCutoff, 1.0 / kBellyExponent)) / kPi;
  const double g = m.gamma();
  const double sLo = std::pow(q, 1.0 / g), sHi = std::pow(1.0 - q, 1.0 / g);
  for (int k = 0; k < kCenterLinePoints; ++k) {
    const double s = sLo + (sHi - sLo) * k / (kCenterLinePoints - 1);
    const MuscleSlice e = sliceAt(m, layout, s);
    t.centerLine.emplace_back(m.x0 + s * (m.x1 - m.x0), e.rho * std::cos(e.theta), e.rho * std::sin(e.theta));
    t.radius.push_back(std::sqrt(e.a * e.b));
  }
  t.peakRadius = std::sqrt(m.a * m.b);  // the profile's maximum is 1
  return t;
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
  for (const MuscleModel& m : muscles) out.muscles.push_back(trueMuscle(m, layout));
  validateCharacter(c);
  return out;
}

}  // namespace myoskin
