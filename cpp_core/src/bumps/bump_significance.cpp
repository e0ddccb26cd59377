// Stage 3c: which merged regions are muscle bumps. The semicircle rule alone turns any smooth convex
// section into a few large "bumps", so every merged region is measured against a smooth base shape:
//  - base: a robust lower-envelope Fourier fit of 1/radius^2 vs angle around the area centroid (asymmetric
//    least squares: points above the base get a small weight); 1/r^2 of a centred ellipse has harmonics 0
//    and 2 only, so an ellipse or any smooth, gently varying section is its own base and bumps stand out;
//  - residual = radius - base, lightly smoothed along the polygon (about 1 % of the perimeter);
//  - a region's apex is its highest residual; its protrusion is the apex's prominence inside the region:
//    apex minus the higher of the lowest residuals on either side of it within the arc. A region that
//    does not reach down to the valleys on both sides of a hill therefore scores low;
//  - significant when protrusion >= max(minProtrusion, minRelativeProtrusion * mean radius) and the arc
//    length is within [minWidthFraction, maxWidthFraction] of the perimeter;
//  - one bump per hill: significant regions whose apexes are not separated by a valley at least as deep
//    as the threshold are one group; the group keeps its smallest region that still has 85 % of the
//    group's best protrusion (the region that spans the hill from valley to valley); finally bumps whose
//    arcs overlap by more than half of the shorter one are deduplicated, keeping the most significant.
#include <algorithm>
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

constexpr double kPi = 3.14159265358979323846;
constexpr double kAboveWeight = 0.02;      // asymmetric least squares weight of points above the base
constexpr int kBaseIterations = 12;        // reweighting passes (stops earlier when the weights settle)
constexpr double kSmoothFraction = 0.01;   // residual smoothing: Gaussian sigma as a fraction of the perimeter
constexpr double kGroupKeep = 0.85;        // a group's representative keeps this share of its best protrusion
constexpr double kMaxOverlap = 0.5;        // bumps overlapping more than this share of the shorter arc merge

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

// Lower-envelope Fourier fit of r(theta) with `harmonics` harmonics; the residual, smoothed.
Profile measureProfile(const detail::SectionPolygon& s, int harmonics) {
  const int m = s.size();
  const int k = std::max(0, std::min(harmonics, (m - 1) / 4));
  const int nb = 2 * k + 1;
  Profile pr;
  std::vector<double> r(m), theta(m), span(m);
  for (int i = 0; i < m; ++i) {
    const Vec2 d = (s.points[i] - s.centroid) * s.scale;
    r[i] = d.norm();
    theta[i] = std::atan2(d.y(), d.x());
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
    span[i] = 0.5 * std::abs(std::remainder(theta[s.next(i)] - theta[s.prev(i)], 2.0 * kPi));
    spanSum += span[i];
  }
  const double floorSpan = 1e-3 * spanSum / m + 1e-300;
  for (double& w : span) w = std::max(w, floorSpan);

  // Basis: 1, cos(j t), sin(j t) for j = 1..k.
  Eigen::MatrixXd basis(m, nb);
  for (int i = 0; i < m; ++i) {
    basis(i, 0) = 1.0;
    const double c1 = std::cos(theta[i]), s1 = std::sin(theta[i]);
    double c = 1.0, sn = 0.0;
    for (int j = 1; j <= k; ++j) {
      const double cn = c * c1 - sn * s1;
      sn = sn * c1 + c * s1;
      c = cn;
      basis(i, 2 * j - 1) = c;
      basis(i, 2 * j) = sn;
    }
  }
  // The series is fitted to 1 / r^2, which for any ellipse centred at the centroid is exactly
  // cos^2/a^2 + sin^2/b^2 (harmonics 0 and 2): with 2 harmonics every such ellipse is its own base.
  std::vector<double> q(m);
  for (int i = 0; i < m; ++i) q[i] = 1.0 / std::max(r[i] * r[i], 1e-300);
  std::vector<double> base(m, 0.0);
  std::vector<char> above(m, 0);
  Eigen::MatrixXd normal(nb, nb);
  Eigen::VectorXd rhs(nb);
  for (int it = 0; it < kBaseIterations; ++it) {
    normal.setZero();
    rhs.setZero();
    for (int i = 0; i < m; ++i) {
      const double w = span[i] * (above[i] ? kAboveWeight : 1.0);
      const auto row = basis.row(i);
      normal.selfadjointView<Eigen::Lower>().rankUpdate(row.transpose(), w);
      rhs.noalias() += (w * q[i]) * row.transpose();
    }
    normal.diagonal().array() += 1e-12 * normal(0, 0);
    const Eigen::VectorXd coef = normal.selfadjointView<Eigen::Lower>().ldlt().solve(rhs);
    bool changed = false;
    for (int i = 0; i < m; ++i) {
      const double fit = basis.row(i).dot(coef);
      base[i] = fit > 0.0 ? 1.0 / std::sqrt(fit) : r[i];
      const char up = r[i] > base[i];
      changed |= up != above[i];
      above[i] = up;
    }
    if (!changed) break;
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
    int lv = i, rv = i;
    for (int j = s.prev(i), k = 0; k < m - 1 && e[j] <= e[i]; j = s.prev(j), ++k)
      if (e[j] < e[lv]) lv = j;
    for (int j = s.next(i), k = 0; k < m - 1 && e[j] <= e[i]; j = s.next(j), ++k)
      if (e[j] < e[rv]) rv = j;
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
                            const SectionTriangulation* triangulation) {
  const detail::SectionPolygon s = detail::cleanSection(polygon);
  SectionTriangulation own;
  if (!triangulation) {
    own = triangulateSection(polygon);
    triangulation = &own;
  }
  const detail::TriangleAdjacency adj = detail::buildAdjacency(s, triangulation->triangles);
  const std::vector<detail::MergedRegion> regions =
      detail::semicircleRegions(s, adj, std::max(0.0, options.semicircleTolerance), options.absorbJunctions);
  const Profile pr = measureProfile(s, options.baseHarmonics);
  const double threshold = std::max(options.minProtrusion, options.minRelativeProtrusion * pr.meanRadius);

  // Significant candidates, strongest first.
  std::vector<Candidate> cands;
  for (size_t r = 0; r < regions.size(); ++r) {
    Candidate c = measureCandidate(s, pr, regions[r].first, regions[r].last);
    c.region = static_cast<int>(r);
    if (c.length < 2 || c.width < options.minWidthFraction || c.width > options.maxWidthFraction) continue;
    if (!(c.protrusion >= threshold) || !(c.protrusion > 0.0)) continue;
    cands.push_back(c);
  }
  // Hills too: on densely sampled sections the semicircle rule stops early, before a region spans its hill.
  // A hill candidate belongs to the smallest merged region that holds its apex (its terminal triangle).
  for (Candidate c : hillCandidates(s, pr)) {
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
      if (cands[g.front()].apex == cands[c].apex || sameHill(s, pr, cands[g.front()].apex, cands[c].apex, threshold)) {
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
