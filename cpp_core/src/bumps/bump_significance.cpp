// Stage 3c: which merged regions are muscle bumps. The semicircle rule alone turns any smooth convex
// section into a few large "bumps", so every merged region is measured against a smooth base shape:
//  - base: a conic (any ellipse, any centre) fitted to the section points around the area centroid. The
//    candidates are the robust lower envelope (asymmetric least squares: points above it weigh little),
//    it refitted to the skin it explains, and the lower-envelope circle refitted to the skin it explains
//    (as a circle, then as a conic). Each is scored by the share of the section it explains within a
//    tolerance, minus the share where the skin lies inside it (muscles only raise the skin), minus a
//    small roundness prior; the best wins. On a clipped profile (a shoulder's, or a trunk's cut through the
//    arms, closed by a straight chord) the bases explain only a fifth to a quarter of it, so one vertex at the
//    tolerance would decide between refits: there a vertex's share of the support fades linearly over +-10 %
//    of the tolerance, and support and score change continuously with the skin. An ellipse or any smooth oval
//    section is its own base; two opposite bellies (biceps and triceps), which make the lower envelope an
//    oval through the valleys between them, get the circle through the skin between them, so both stay bumps;
//  - residual = radius - base, lightly smoothed along the polygon (about 1 % of the perimeter);
//  - a region's apex is its highest residual; its protrusion is the apex's prominence inside the region:
//    apex minus the higher of the lowest residuals on either side of it within the arc. A region that
//    does not reach down to the valleys on both sides of a hill therefore scores low;
//  - significant when protrusion >= max(minProtrusion, minRelativeProtrusion * mean radius) and the arc
//    length is within [minWidthFraction, maxWidthFraction] of the perimeter;
//  - one bump per hill: significant regions whose apexes are not separated by a valley at least as deep
//    as the threshold are one group; the group keeps its smallest region that still has 85 % of the
//    group's best protrusion (the region that spans the hill from valley to valley); finally bumps whose
//    arcs overlap by more than half of the shorter one are deduplicated, keeping the most significant;
//  - a triangulation split along a diagonal (a trunk section's mirror axis) keeps its sides apart: no region
//    bounded by the split is a bump and hills on its two sides are never grouped.
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include "bumps/bumps_internal.h"
#include "myoskin/bumps.h"
#include "myoskin/errors.h"

namespace myoskin {

namespace {

constexpr double kAboveWeight = 0.02;      // lower envelope: least squares weight of points above the base
constexpr int kBaseIterations = 12;        // reweighting passes (stops earlier when the weights settle)
constexpr double kSmoothFraction = 0.01;   // residual smoothing: Gaussian sigma as a fraction of the perimeter
constexpr double kGroupKeep = 0.85;        // a group's representative keeps this share of its best protrusion
constexpr double kMaxOverlap = 0.5;        // bumps overlapping more than this share of the shorter arc merge
constexpr int kSupportIterations = 6;      // refits of the base to the skin it explains
constexpr double kSupportMargin = 0.02;    // another candidate must score this much higher than the lower envelope
constexpr double kTwinTolerance = 1e-12;  // metres: residuals this close count as equally high (hill spans)
constexpr double kRoundness = 0.5;         // score penalty per unit of (longest / shortest base radius - 1)
constexpr double kClippedRamp = 0.1;       // clipped profiles: support fades over +-this share of the tolerance

// Residual of each cleaned polygon vertex above the section's smooth base shape.
struct Profile {
  std::vector<double> residual;  // smoothed radius - base radius
  std::vector<double> arcAt;     // arc length from vertex 0 to each vertex
  double perimeter = 0.0;
  double meanRadius = 0.0;
};

// ============================================================================
// Base shape and residual
// ============================================================================

// Conic base shapes, points relative to the area centroid: Q(p) = c . f(p) = 1 with features
// f = (x^2, xy, y^2, x, y) for a general conic (any ellipse, any centre) or (x^2 + y^2, x, y) for a circle.
// Returns the number of features of the model.
int conicFeatures(bool circle, const Vec2& p, double* f) {
  if (circle) {
    f[0] = p.squaredNorm(), f[1] = p.x(), f[2] = p.y();
    return 3;
  }
  f[0] = p.x() * p.x(), f[1] = p.x() * p.y(), f[2] = p.y() * p.y(), f[3] = p.x(), f[4] = p.y();
  return 5;
}

// Base shape fits, the residual of the chosen base, smoothed. `supportTolerance` in metres; harmonics > 0
// makes the base a radial Fourier series of that order (trunk sections) instead of a conic; `clipped`: the
// support fades over +-kClippedRamp of the tolerance instead of ending at it.
Profile measureProfile(const detail::SectionPolygon& s, double supportTolerance, int harmonics, bool clipped) {
  const int m = s.size();
  Profile pr;
  std::vector<double> r(m), span(m);
  std::vector<Vec2> d(m), u(m);
  for (int i = 0; i < m; ++i) {
    d[i] = (s.points[i] - s.centroid) * s.scale;
    r[i] = d[i].norm();
    u[i] = r[i] > 0.0 ? Vec2(d[i] / r[i]) : Vec2(1.0, 0.0);
  }
  pr.arcAt.resize(m);
  double arc = 0.0, radiusSum = 0.0;
  for (int i = 0; i < m; ++i) {
    pr.arcAt[i] = arc / s.scale;
    const double len = (s.points[s.next(i)] - s.points[i]).norm() * s.scale;
    arc += len;
    radiusSum += 0.5 * (r[i] + r[s.next(i)]) * len;
  }
  pr.perimeter = arc / s.scale;
  pr.meanRadius = arc > 0.0 ? radiusSum / arc / s.scale : 0.0;
  // Angular span of each vertex, so that the fit is uniform in angle however the points are spaced.
  double spanSum = 0.0;
  for (int i = 0; i < m; ++i) {
    const double t0 = std::atan2(d[s.prev(i)].y(), d[s.prev(i)].x()), t1 = std::atan2(d[s.next(i)].y(), d[s.next(i)].x());
    span[i] = 0.5 * std::abs(std::remainder(t1 - t0, 2.0 * kPi));
    spanSum += span[i];
  }
  const double floorSpan = 1e-3 * spanSum / m + 1e-300;
  for (double& w : span) w = std::max(w, floorSpan);

  // Weighted algebraic least squares of Q(p) = 1, then the base radius on each vertex's ray from the
  // centroid: Q(t u) = a t^2 + b t = 1, t = 2 / (b + sqrt(b^2 + 4 a)). False when degenerate or when a ray
  // misses the conic (strict), else such vertices keep their own radius.
  auto fit = [&](bool circle, const std::vector<double>& weight, std::vector<double>& base, bool strict) {
    double f[5];
    const int nb = conicFeatures(circle, Vec2(1, 0), f);
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(nb, nb);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nb);
    for (int i = 0; i < m; ++i) {
      const double w = span[i] * weight[i];
      if (w <= 0.0) continue;
      conicFeatures(circle, d[i], f);
      const Eigen::Map<const Eigen::VectorXd> row(f, nb);
      normal.selfadjointView<Eigen::Lower>().rankUpdate(row, w);
      rhs.noalias() += w * row;
    }
    if (!(normal.diagonal().maxCoeff() > 0.0)) return false;
    normal.diagonal().array() += 1e-12 * normal.diagonal().maxCoeff();
    const Eigen::VectorXd c = normal.selfadjointView<Eigen::Lower>().ldlt().solve(rhs);
    for (int i = 0; i < m; ++i) {
      const Vec2& e = u[i];
      const double qa = circle ? c[0] : c[0] * e.x() * e.x() + c[1] * e.x() * e.y() + c[2] * e.y() * e.y();
      const double qb = circle ? c[1] * e.x() + c[2] * e.y() : c[3] * e.x() + c[4] * e.y();
      const double disc = qb * qb + 4.0 * qa;
      const double den = disc >= 0.0 ? qb + std::sqrt(disc) : -1.0;
      if (!(den > 0.0) || !std::isfinite(den)) {
        if (strict) return false;
        base[i] = r[i];
      } else {
        base[i] = 2.0 / den;
      }
    }
    return true;
  };
  // Radial Fourier series r(theta) = c0 + sum_k (c_k cos k theta + s_k sin k theta), weighted least
  // squares of the vertex radii: the smooth base of a trunk section (an oval, a bean, a rounded rectangle),
  // which no conic follows; bellies narrower than a 1/(2 harmonics) share of the turn stand out of it.
  std::vector<double> theta(m);
  for (int i = 0; i < m; ++i) theta[i] = std::atan2(d[i].y(), d[i].x());
  auto fitFourier = [&](const std::vector<double>& weight, std::vector<double>& base) {
    const int nb = 1 + 2 * harmonics;
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(nb, nb);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nb), f(nb);
    auto features = [&](double t) {
      f[0] = 1.0;
      for (int k = 1; k <= harmonics; ++k) f[2 * k - 1] = std::cos(k * t), f[2 * k] = std::sin(k * t);
    };
    for (int i = 0; i < m; ++i) {
      const double w = span[i] * weight[i];
      if (w <= 0.0) continue;
      features(theta[i]);
      normal.selfadjointView<Eigen::Lower>().rankUpdate(f, w);
      rhs.noalias() += w * r[i] * f;
    }
    if (!(normal(0, 0) > 0.0)) return false;
    normal.diagonal().array() += 1e-12 * normal.diagonal().maxCoeff();
    const Eigen::VectorXd c = normal.selfadjointView<Eigen::Lower>().ldlt().solve(rhs);
    for (int i = 0; i < m; ++i) {
      features(theta[i]);
      base[i] = std::max(c.dot(f), 0.0);
    }
    return true;
  };
  auto fitModel = [&](bool circle, const std::vector<double>& weight, std::vector<double>& base, bool strict) {
    return harmonics > 0 ? fitFourier(weight, base) : fit(circle, weight, base, strict);
  };

  // Lower envelope: asymmetric least squares (points above the base weigh little).
  auto lowerEnvelope = [&](bool circle) {
    std::vector<double> base(r), weight(m, 1.0);
    std::vector<char> above(m, 0);
    for (int it = 0; it < kBaseIterations; ++it) {
      if (!fitModel(circle, weight, base, false)) return r;
      bool changed = false;
      for (int i = 0; i < m; ++i) {
        const char up = r[i] > base[i];
        changed |= up != above[i];
        above[i] = up;
        weight[i] = up ? kAboveWeight : 1.0;
      }
      if (!changed) break;
    }
    return base;
  };
  // Share of the angle where the skin lies within the tolerance of a base (fading over the ramp).
  const double tol = supportTolerance * s.scale;
  const double ramp = clipped ? kClippedRamp * tol : 0.0;
  // A vertex's share of the support: 1 within the tolerance, else 0; on a clipped profile 1 up to tol - ramp,
  // 0 from tol + ramp, linear between (NaN gives 0).
  auto within = [&](double residual) {
    if (!(ramp > 0.0)) return std::abs(residual) <= tol ? 1.0 : 0.0;
    return std::min(1.0, std::max(0.0, (tol + ramp - std::abs(residual)) / (2.0 * ramp)));
  };
  auto support = [&](const std::vector<double>& base) {
    double sum = 0.0;
    for (int i = 0; i < m; ++i) sum += within(r[i] - base[i]) * span[i];
    return sum / spanSum;
  };
  // A base's score: the share it explains minus the share where the skin lies inside it (muscles only
  // raise the skin above the muscle-free limb, so skin well inside a base speaks against it).
  auto score = [&](const std::vector<double>& base) {
    double sum = 0.0;
    for (int i = 0; i < m; ++i) {
      const double w = within(r[i] - base[i]);
      sum += (w - (r[i] < base[i] ? 1.0 - w : 0.0)) * span[i];
    }
    const auto [lo, hi] = std::minmax_element(base.begin(), base.end());
    return sum / spanSum - kRoundness * (*hi / std::max(*lo, 1e-300) - 1.0);
  };
  // Refit to the vertices the base explains (within the tolerance) while that explains more.
  auto refine = [&](std::vector<double> base, bool circle) {
    std::vector<double> weight(m), next(m);
    for (int it = 0; it < kSupportIterations; ++it) {
      int count = 0;
      // The Fourier base keeps a small weight on the rest, so a wide gap in its support cannot swing it away.
      const double outside = harmonics > 0 ? kAboveWeight : 0.0;
      for (int i = 0; i < m; ++i) {
        const double w = within(r[i] - base[i]);
        weight[i] = std::max(w, outside);
        count += w >= 0.5;
      }
      if (count < 10 || !fitModel(circle, weight, next, true) || !(support(next) >= support(base))) break;
      base.swap(next);
    }
    return base;
  };
  // Candidates: the conic lower envelope; it refined to its support; the lower-envelope circle refined to
  // its support as a circle and then as a conic. Opposite bellies (biceps and triceps) make the envelope an
  // oval through the four valleys between them; a circle refined to the skin between the bellies explains
  // more of the section and keeps them as bumps. The candidate that explains most of the section wins.
  std::vector<double> base = lowerEnvelope(false);
  if (harmonics > 0) {
    if (tol > 0.0) {
      std::vector<double> cand = refine(base, false);
      if (score(cand) > score(base) + kSupportMargin) base.swap(cand);
    }
  } else if (tol > 0.0) {
    double best = score(base);
    const std::vector<double> circle = refine(lowerEnvelope(true), true);
    for (std::vector<double> cand : {refine(base, false), circle, refine(circle, false)}) {
      const double sup = score(cand);
      if (sup > best + kSupportMargin) best = sup, base.swap(cand);
    }
  }

  // Smooth the residual with repeated [1 2 1] / 4 passes (each adds half a sample's variance).
  std::vector<double> e(m), tmp(m);
  for (int i = 0; i < m; ++i) e[i] = std::isfinite(base[i]) ? (r[i] - base[i]) / s.scale : 0.0;
  const double sigmaSamples = kSmoothFraction * m;
  const int passes = std::min(m, static_cast<int>(std::lround(2.0 * sigmaSamples * sigmaSamples)));
  for (int p = 0; p < passes; ++p) {
    for (int i = 0; i < m; ++i) tmp[i] = 0.25 * (e[s.prev(i)] + 2.0 * e[i] + e[s.next(i)]);
    e.swap(tmp);
  }
  pr.residual = std::move(e);
  return pr;
}

// ============================================================================
// Candidates, groups and selection
// ============================================================================

// A merged region measured against the base.
struct Candidate {
  int region = -1;
  int first = 0, last = 0, apex = 0;  // cleaned indices
  int length = 0;                     // edges along the arc
  double protrusion = 0.0;
  double width = 0.0;  // arc length / perimeter
};

// Apex and prominence of the apex inside the arc first..last.
Candidate measureCandidate(const detail::SectionPolygon& s, const Profile& pr, int first, int last) {
  Candidate c;
  c.first = first;
  c.last = last;
  c.length = s.forward(first, last);
  c.apex = first;
  for (int i = first;; i = s.next(i)) {
    if (pr.residual[i] > pr.residual[c.apex]) c.apex = i;
    if (i == last) break;
  }
  double leftMin = pr.residual[c.apex], rightMin = pr.residual[c.apex];
  for (int i = first; i != c.apex; i = s.next(i)) leftMin = std::min(leftMin, pr.residual[i]);
  for (int i = c.apex; i != last; i = s.next(i)) rightMin = std::min(rightMin, pr.residual[i]);
  rightMin = std::min(rightMin, pr.residual[last]);
  c.protrusion = pr.residual[c.apex] - std::max(leftMin, rightMin);
  double arc = pr.arcAt[last] - pr.arcAt[first];
  if (arc < 0.0 || (arc == 0.0 && c.length > 0)) arc += pr.perimeter;
  c.width = pr.perimeter > 0.0 ? arc / pr.perimeter : 0.0;
  return c;
}

// True if no valley at least `depth` deep (below the lower apex) separates apexes a and b (shorter way).
bool sameHill(const detail::SectionPolygon& s, const Profile& pr, int a, int b, double depth) {
  if (s.forward(a, b) > s.forward(b, a)) std::swap(a, b);
  const double floor = std::min(pr.residual[a], pr.residual[b]) - depth;
  for (int i = a; i != b; i = s.next(i))
    if (pr.residual[i] <= floor) return false;
  return true;
}

// Shared vertices of two arcs (edges counted from first), as a share of the shorter arc.
double overlapShare(const detail::SectionPolygon& s, const Candidate& x, const Candidate& y) {
  int shared = 0;
  for (int i = x.first;; i = s.next(i)) {
    shared += s.forward(y.first, i) <= y.length;
    if (i == x.last) break;
  }
  return static_cast<double>(shared) / (std::min(x.length, y.length) + 1);
}

// Hills of the residual: each local maximum spans from the lowest point before a higher residual on its
// left to the same on its right (its key cols), so its prominence is measured over the whole section.
std::vector<Candidate> hillCandidates(const detail::SectionPolygon& s, const Profile& pr) {
  const int m = s.size();
  const std::vector<double>& e = pr.residual;
  std::vector<Candidate> out;
  for (int i = 0; i < m; ++i) {
    if (!(e[i] >= e[s.prev(i)] && e[i] > e[s.next(i)])) continue;
    // A residual within rounding of the apex's counts as higher, so twin peaks (a mirror-symmetric section's
    // two sides) each stop at the other instead of one of them spanning the whole section; of equally low
    // valleys the nearest is the key col, so twins pick mirrored ones.
    const double top = e[i] - kTwinTolerance;
    int lv = i, rv = i;
    for (int j = s.prev(i), k = 0; k < m - 1 && e[j] < top; j = s.prev(j), ++k)
      if (e[j] < e[lv] - kTwinTolerance) lv = j;  // equally low valleys: the nearest
    for (int j = s.next(i), k = 0; k < m - 1 && e[j] < top; j = s.next(j), ++k)
      if (e[j] < e[rv] - kTwinTolerance) rv = j;
    if (lv == i || rv == i || lv == rv) continue;
    Candidate c = measureCandidate(s, pr, lv, rv);
    c.apex = i;
    c.protrusion = e[i] - std::max(e[lv], e[rv]);
    out.push_back(c);
  }
  return out;
}

}  // namespace

// ============================================================================
// Bumps
// ============================================================================

// Semicircle regions from every terminal triangle, measured against the base shape and kept when significant.
std::vector<Bump> findBumps(const Points2& polygon, const BumpOptions& options,
                            const SectionTriangulation* triangulation, const std::vector<char>* onSkin) {
  const detail::SectionPolygon s = detail::cleanSection(polygon);
  if (onSkin && static_cast<int>(onSkin->size()) != polygon.rows())
    throw InputError("findBumps: onSkin has " + std::to_string(onSkin->size()) + " entries for " +
                     std::to_string(polygon.rows()) + " polygon points");
  const bool clipped = onSkin && std::find(onSkin->begin(), onSkin->end(), 0) != onSkin->end();
  SectionTriangulation own;
  if (!triangulation) {
    own = triangulateSection(polygon);
    triangulation = &own;
  }
  const detail::TriangleAdjacency adj = detail::buildAdjacency(s, triangulation->triangles);
  std::vector<std::array<int, 2>> splits;  // forced diagonals, cleaned indices
  for (const auto& d : triangulation->diagonals) splits.push_back({s.cleanedOf[d[0]], s.cleanedOf[d[1]]});
  const std::vector<detail::MergedRegion> regions = detail::semicircleRegions(
      s, adj, std::max(0.0, options.semicircleTolerance), options.absorbJunctions, splits);
  // Side of a vertex relative to each split: 0 on it, 1 or 2 on either side. A split is no chord of the skin:
  // a region bounded by it is no bump, and hills on its two sides are never one.
  auto isSplit = [&](int a, int b) {
    for (const auto& d : splits)
      if ((d[0] == a && d[1] == b) || (d[0] == b && d[1] == a)) return true;
    return false;
  };
  auto acrossSplit = [&](int a, int b) {
    for (const auto& d : splits) {
      auto side = [&](int v) { return v == d[0] || v == d[1] ? 0 : s.forward(d[0], v) < s.forward(d[0], d[1]) ? 1 : 2; };
      const int sa = side(a), sb = side(b);
      if (sa && sb && sa != sb) return true;
    }
    return false;
  };
  double meanRadius = 0.0;  // the threshold needs the mean radius first
  {
    double arc = 0.0;
    for (int i = 0; i < s.size(); ++i) {
      const double len = (s.points[s.next(i)] - s.points[i]).norm();
      arc += len;
      meanRadius += 0.5 * ((s.points[i] - s.centroid).norm() + (s.points[s.next(i)] - s.centroid).norm()) * len;
    }
    meanRadius = arc > 0.0 ? meanRadius / arc : 0.0;
  }
  const double threshold = std::max(options.minProtrusion, options.minRelativeProtrusion * meanRadius);
  if (options.baseHarmonics < 0 || options.baseHarmonics > 16)
    throw InputError("bump options: baseHarmonics must be in [0, 16], got " + std::to_string(options.baseHarmonics));
  const Profile pr = measureProfile(s, options.supportTolerance * threshold, options.baseHarmonics, clipped);

  // Significant candidates, strongest first.
  std::vector<Candidate> cands;
  for (size_t r = 0; r < regions.size(); ++r) {
    Candidate c = measureCandidate(s, pr, regions[r].first, regions[r].last);
    c.region = static_cast<int>(r);
    if (isSplit(c.first, c.last)) continue;
    if (c.length < 2 || c.width < options.minWidthFraction || c.width > options.maxWidthFraction) continue;
    if (!(c.protrusion >= threshold) || !(c.protrusion > 0.0)) continue;
    cands.push_back(c);
  }
  // Hills too: on densely sampled sections the semicircle rule stops early, before a region spans its hill.
  // A hill candidate belongs to the smallest merged region that holds its apex (its terminal triangle).
  for (Candidate c : hillCandidates(s, pr)) {
    if (isSplit(c.first, c.last)) continue;
    if (c.length < 2 || c.width < options.minWidthFraction || c.width > options.maxWidthFraction) continue;
    if (!(c.protrusion >= threshold) || !(c.protrusion > 0.0)) continue;
    int best = -1;
    for (size_t r = 0; r < regions.size(); ++r) {
      const int len = s.forward(regions[r].first, regions[r].last);
      if (s.forward(regions[r].first, c.apex) <= len &&
          (best < 0 || len < s.forward(regions[best].first, regions[best].last)))
        best = static_cast<int>(r);
    }
    if (best < 0) continue;
    c.region = best;
    cands.push_back(c);
  }
  std::stable_sort(cands.begin(), cands.end(),
                   [](const Candidate& a, const Candidate& b) { return a.protrusion > b.protrusion; });

  // Group by hill; each group keeps its smallest candidate with most of the group's protrusion.
  std::vector<std::vector<int>> groups;
  for (int c = 0; c < static_cast<int>(cands.size()); ++c) {
    bool joined = false;
    for (auto& g : groups)
      if (cands[g.front()].apex == cands[c].apex ||
          (!acrossSplit(cands[g.front()].apex, cands[c].apex) &&
           sameHill(s, pr, cands[g.front()].apex, cands[c].apex, threshold))) {
        g.push_back(c);
        joined = true;
        break;
      }
    if (!joined) groups.push_back({c});
  }
  std::vector<Candidate> reps;
  for (const auto& g : groups) {
    const double best = cands[g.front()].protrusion;
    int pick = g.front();
    for (int c : g)
      if (cands[c].protrusion >= kGroupKeep * best && cands[c].length < cands[pick].length) pick = c;
    reps.push_back(cands[pick]);
    reps.back().protrusion = std::max(reps.back().protrusion, 0.0);
  }
  std::stable_sort(reps.begin(), reps.end(),
                   [](const Candidate& a, const Candidate& b) { return a.protrusion > b.protrusion; });
  std::vector<Candidate> kept;
  for (const Candidate& c : reps) {
    bool dup = false;
    for (const Candidate& k : kept) dup |= overlapShare(s, c, k) > kMaxOverlap;
    if (!dup) kept.push_back(c);
  }

  // Report in polygon order; the terminal triangle of the region whose tip is nearest the apex.
  std::sort(kept.begin(), kept.end(), [](const Candidate& a, const Candidate& b) { return a.first < b.first; });
  std::vector<Bump> bumps;
  for (const Candidate& c : kept) {
    const detail::MergedRegion& reg = regions[c.region];
    Bump b;
    b.first = s.original[c.first];
    b.last = s.original[c.last];
    b.apex = s.original[c.apex];
    b.protrusion = c.protrusion;
    b.significance = threshold > 0.0 ? c.protrusion / threshold : 1.0;
    int bestDist = -1;
    for (int t : reg.terminals) {
      int tip = -1;
      for (int k = 0; k < 3; ++k)
        if (adj.neighbours[t][k] >= 0) tip = adj.vertices[t][k];
      if (tip < 0 || s.forward(c.first, tip) > c.length) continue;
      const int d = std::min(s.forward(tip, c.apex), s.forward(c.apex, tip));
      if (bestDist < 0 || d < bestDist) bestDist = d, b.terminalTriangle = t;
    }
    if (b.terminalTriangle < 0) b.terminalTriangle = reg.terminal;
    bumps.push_back(b);
  }
  return bumps;
}

}  // namespace myoskin
