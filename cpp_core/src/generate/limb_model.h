// The limb machinery of the procedural characters (internal): seeded jitter, smooth helpers, elliptical muscle
// bellies under a star-shaped generalized cylinder, and their ground truth. Shared by the synthetic arm
// (synthetic_arm.cpp) and the varied bodies (synthetic_body.cpp). A Layout provides mapX(canonical x) -> x and
// baseRadius(x, theta), the muscle-free skin's radius around the limb axis (x along the axis, theta around it).
#pragma once
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "myoskin/synthetic_character.h"

namespace myoskin::limb {

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
inline double smoothMax(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::max(a, b) + h * h * k * 0.25;
}

// Cubic smoothstep of t clamped to [0, 1].
inline double smoothStep(double t) {
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

template <class Layout>
MuscleSlice sliceAt(const MuscleModel& m, const Layout& layout, double s) {
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
inline double rayExit(const MuscleSlice& e, double theta) {
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
inline double silhouetteRadius(const MuscleSlice& e) {
  if (e.rho <= e.b) return 0.0;  // the axis is inside the ellipse: no silhouette
  const double q = e.b * e.b / e.rho;
  return std::sqrt(e.a * e.a * (1.0 - e.b * e.b / (e.rho * e.rho)) + (e.rho - q) * (e.rho - q));
}

// True if, along the whole belly, the silhouette plus the skin layer stays a softness width (and a
// margin) below the muscle-free skin in the silhouette's direction.
template <class Layout>
bool silhouettesHidden(const MuscleModel& m, const Layout& layout) {
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

// A muscle in canonical coordinates: angles in degrees, x in the layout's canonical frame (mapX).
struct MuscleSpec {
  const char* name;
  const char* bone;
  double x0, x1, theta0, theta1, a, b, protrusion, peakAt;
};

// Muscles from their canonical specs with seeded perturbation of sizes, angles, extents (six draws each, also when
// scale is 0). Layout: mapX(canonical x) and baseRadius(x, theta) of the muscle-free limb.
// minWidth > 0 (the varied bodies; the synthetic arm keeps 0): a belly whose silhouette stays exposed unless it is
// narrowed below minWidth of its width is kept at minWidth and made shallower instead (its protrusion lowered until the
// silhouette hides; at most down to 0.2 of it): a shallow belly high on its limb otherwise shows sharp flanks as a
// sliver of its width.
template <class Layout>
std::vector<MuscleModel> makeMuscles(const Layout& layout, double scale, Jitter& jitter, const std::vector<MuscleSpec>& specs,
                                     double minWidth = 0.0) {
  std::vector<MuscleModel> muscles;
  for (const MuscleSpec& spec : specs) {
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
      if (lo < minWidth) {
        m.a = full * minWidth;
        const double height = m.protrusion;
        double qlo = 0.2, qhi = 1.0;
        for (int it = 0; it < 30; ++it) {
          m.protrusion = height * 0.5 * (qlo + qhi);
          (silhouettesHidden(m, layout) ? qlo : qhi) = 0.5 * (qlo + qhi);
        }
        m.protrusion = height * qlo;
      }
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
template <class Layout>
double skinRadius(const Layout& layout, const std::vector<MuscleModel>& muscles, double x, double theta) {
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

// The belly fractions s of the ground-truth centre-line points (kCenterLinePoints, where the radius exceeds 10 % of
// its peak).
inline std::vector<double> truthStations(const MuscleModel& m) {
  const double q = std::asin(std::pow(kTruthCutoff, 1.0 / kBellyExponent)) / kPi;
  const double g = m.gamma();
  const double sLo = std::pow(q, 1.0 / g), sHi = std::pow(1.0 - q, 1.0 / g);
  std::vector<double> out;
  for (int k = 0; k < kCenterLinePoints; ++k) out.push_back(sLo + (sHi - sLo) * k / (kCenterLinePoints - 1));
  return out;
}

// Relief of a muscle at its truth stations (TrueMuscle::relief): how far the skin stands out along the ray from the
// limb axis through the centre-line point, skin(x, theta, true) with every muscle minus skin(x, theta, false) without
// this one (never below 0). SkinAt: (x along the limb axis, theta around it, with the muscle?) -> skin distance.
template <class Layout, class SkinAt>
std::vector<double> muscleRelief(const MuscleModel& m, const Layout& layout, const SkinAt& skinAt) {
  std::vector<double> out;
  for (double s : truthStations(m)) {
    const double x = m.x0 + s * (m.x1 - m.x0), theta = sliceAt(m, layout, s).theta;
    out.push_back(std::max(0.0, skinAt(x, theta, true) - skinAt(x, theta, false)));
  }
  return out;
}

// Ground truth: the ellipse centres and mean radii sqrt(a b) where the radius exceeds 10 % of its peak (relief left
// empty: the generators fill it, muscleRelief).
template <class Layout>
TrueMuscle trueMuscle(const MuscleModel& m, const Layout& layout) {
  TrueMuscle t;
  t.name = m.name;
  t.bone = m.bone;
  for (double s : truthStations(m)) {
    const MuscleSlice e = sliceAt(m, layout, s);
    t.centerLine.emplace_back(m.x0 + s * (m.x1 - m.x0), e.rho * std::cos(e.theta), e.rho * std::sin(e.theta));
    t.radius.push_back(std::sqrt(e.a * e.b));
  }
  t.peakRadius = std::sqrt(m.a * m.b);  // the profile's maximum is 1
  return t;
}

}  // namespace myoskin::limb
