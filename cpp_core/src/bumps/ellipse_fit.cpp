// The ellipse under a bump (paper: "Ellipse fitting"): a weighted least-squares ellipse through the bump's
// skin arc, axes along and across the bump's chord, weights highest at the apex; then moved under the skin.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "myoskin/bumps.h"
#include "myoskin/errors.h"

namespace myoskin {

namespace {

constexpr double kMaxAspect = 1.2;  // a : b of a fitted belly at most

// ============================================================================
// Helpers
// ============================================================================

bool insidePolygon(const Points2& poly, const Vec2& p) {
  bool inside = false;
  const Eigen::Index n = poly.rows();
  for (Eigen::Index i = 0, j = n - 1; i < n; j = i++) {
    const double yi = poly(i, 1), yj = poly(j, 1), xi = poly(i, 0), xj = poly(j, 0);
    if ((yi > p.y()) != (yj > p.y()) && p.x() < (xj - xi) * (p.y() - yi) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

// Distance from p to the polygon's boundary.
double boundaryDistance(const Points2& poly, const Vec2& p) {
  double best = INFINITY;
  const Eigen::Index n = poly.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Vec2 a = poly.row(i).transpose(), b = poly.row((i + 1) % n).transpose();
    const Vec2 d = b - a;
    const double t = d.squaredNorm() > 0 ? std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
    best = std::min(best, (a + t * d - p).norm());
  }
  return best;
}

// The ellipse lies inside the polygon: 48 points on it all inside, none closer than `gap` to the skin.
bool underSkin(const Points2& poly, const Ellipse2& e, double gap) {
  if (!insidePolygon(poly, e.center)) return false;
  const Vec2 u(std::cos(e.angle), std::sin(e.angle)), v(-u.y(), u.x());
  for (int k = 0; k < 48; ++k) {
    const double t = 2.0 * M_PI * k / 48;
    const Vec2 p = e.center + e.a * std::cos(t) * u + e.b * std::sin(t) * v;
    if (!insidePolygon(poly, p) || boundaryDistance(poly, p) < gap) return false;
  }
  return true;
}

}  // namespace

// ============================================================================
// Public
// ============================================================================

Ellipse2 fitBumpEllipse(const Points2& polygon, const Bump& bump, const SectionTriangulation& triangulation) {
  const int n = static_cast<int>(polygon.rows());
  if (n < 3) throw InputError("ellipse fit: the section has fewer than 3 points");
  if (!polygon.allFinite()) throw InputError("ellipse fit: the section has non-finite points");
  // The section's size: squares of its coordinates must stay finite and normal, and coincidence is judged relative
  // to it (points a few ulps apart are one point).
  const double size = (polygon.colwise().maxCoeff() - polygon.colwise().minCoeff()).norm();
  if (!(size > 1e-150 && size < 1e150))
    throw InputError("ellipse fit: the section's size is out of range (" + std::to_string(size) + ")");
  const double tiny = 1e-12 * size;
  if (bump.first < 0 || bump.first >= n || bump.last < 0 || bump.last >= n || bump.apex < 0 || bump.apex >= n)
    throw InputError("ellipse fit: bump indices outside the section");
  // The arc first -> last (counter-clockwise, wrapping) and its arc length.
  std::vector<Vec2> arc;
  int apexAt = 0;
  for (int i = bump.first;; i = (i + 1) % n) {
    if (i == bump.apex) apexAt = static_cast<int>(arc.size());
    arc.push_back(polygon.row(i).transpose());
    if (i == bump.last || static_cast<int>(arc.size()) > n) break;
  }
  if (arc.size() < 3) throw InputError("ellipse fit: the bump's arc has fewer than 3 points");
  std::vector<double> s(arc.size(), 0.0);
  for (size_t i = 1; i < arc.size(); ++i) s[i] = s[i - 1] + (arc[i] - arc[i - 1]).norm();
  // Frame: u along the chord (first -> last), v outward (the polygon is counter-clockwise: outward = right
  // of the direction of travel, i.e. the chord rotated by -90 degrees).
  Vec2 u = arc.back() - arc.front();
  if (u.norm() < 1e-12) u = arc[arc.size() / 2] - arc.front();
  u.normalize();
  const Vec2 v(u.y(), -u.x());
  const Vec2 apex = arc[apexAt];
  // The belly: the run of the arc around the apex standing at least 35 % of the apex's height above the
  // chord (wide, shallow flanks say little about the muscle under the bump). A point at the cut itself is in it,
  // within round-off: a flat facet resampled evenly puts points exactly there (the low-poly body's thigh, where
  // scaling the character by 1.5 moved one across the cut and dropped a muscle pair).
  std::vector<double> height(arc.size());
  for (size_t i = 0; i < arc.size(); ++i) height[i] = (arc[i] - arc.front()).dot(v);
  const double cut = 0.35 * height[apexAt] - 1e-9 * std::abs(height[apexAt]);
  size_t lo = apexAt, hi = apexAt;
  while (lo > 0 && height[lo - 1] >= cut) --lo;
  while (hi + 1 < arc.size() && height[hi + 1] >= cut) ++hi;
  if (hi - lo >= 4 && (arc[hi] - arc[lo]).norm() > tiny) {  // (a run of coincident points is no belly)
    arc = std::vector<Vec2>(arc.begin() + lo, arc.begin() + hi + 1);
    s = std::vector<double>(s.begin() + lo, s.begin() + hi + 1);
    const double s0 = s.front();  // (a copy: s.front() itself becomes 0 in the loop)
    for (double& x : s) x -= s0;
    apexAt -= static_cast<int>(lo);
  }
  const double length = s.back();
  const double coreHalf = 0.5 * (arc.back() - arc.front()).norm();
  // Weighted fit of x^2 + B y^2 + C x + D y + E = 0 in the (u, v) frame centred at the apex.
  const double sigma = std::max(0.3 * length, 1e-9);
  Eigen::MatrixXd A(arc.size(), 4);
  Eigen::VectorXd rhs(arc.size());
  for (size_t i = 0; i < arc.size(); ++i) {
    const Vec2 q = arc[i] - apex;
    const double x = q.dot(u), y = q.dot(v);
    const double w = std::exp(-0.5 * std::pow((s[i] - s[apexAt]) / sigma, 2));
    A.row(i) << w * y * y, w * x, w * y, w;
    rhs(i) = -w * x * x;
  }
  const Eigen::Vector4d c = A.colPivHouseholderQr().solve(rhs);
  Ellipse2 e;
  const double B = c(0), C = c(1), D = c(2), E = c(3);
  bool fitted = false;
  if (B > 1e-6 && std::isfinite(B)) {
    const double x0 = -C / 2.0, y0 = -D / (2.0 * B);
    const double k = x0 * x0 + B * y0 * y0 - E;
    if (k > 0) {
      const double au = std::sqrt(k), av = std::sqrt(k / B);
      e.center = apex + x0 * u + y0 * v;
      if (au >= av) e.a = au, e.b = av, e.angle = std::atan2(u.y(), u.x());
      else e.a = av, e.b = au, e.angle = std::atan2(v.y(), v.x());
      // A sane fit: the centre lies below the apex, inside, and the ellipse is not larger than the section.
      // The belly is about as deep as it is wide: a centre far deeper or an ellipse far wider than the
      // belly is a poor fit of a nearly flat arc.
      fitted = y0 < 0 && -y0 <= 1.5 * coreHalf && e.a <= 2.0 * coreHalf && std::isfinite(e.a) &&
               insidePolygon(polygon, e.center);
    }
  }
  if (!fitted) {
    // Fallback: a round belly half the chord wide, centred beneath the apex. The skin shows only the top of
    // a partly buried belly, so its height says little about the belly's depth. A bump whose ends coincide
    // (duplicate skin vertices) takes half its farthest point from the apex instead.
    double half = coreHalf;
    if (!(half > tiny))
      for (const Vec2& p : arc) half = std::max(half, 0.5 * (p - apex).norm());
    if (!(half > tiny))
      throw InputError("ellipse fit: the bump's arc has no extent (its points coincide)");
    e.center = apex - half * v;
    e.a = e.b = half;
    e.angle = std::atan2(u.y(), u.x());
  }
  // Bellies are round-ish: a fit flatter than maxAspect : 1 grows its b axis to it, keeping its top where it touches
  // the skin: the centre moves inward (-v) by as much as its extent along v grows (all of the growth when b lies along
  // v, none when b lies along the chord, where the sign of a round-off dot product once chose a side).
  if (e.b * kMaxAspect < e.a) {
    const Vec2 axisA(std::cos(e.angle), std::sin(e.angle)), axisB(-axisA.y(), axisA.x());
    const double grow = e.a / kMaxAspect - e.b;
    const double before = std::hypot(e.a * axisA.dot(v), e.b * axisB.dot(v));
    const double after = std::hypot(e.a * axisA.dot(v), (e.b + grow) * axisB.dot(v));
    e.center -= (after - before) * v;
    e.b += grow;
  }
  // Under the skin: shrink about the centre (and pull the centre inward) until the ellipse is inside.
  const double gap = 0.02 * e.b;
  for (int it = 0; it < 40 && !underSkin(polygon, e, gap); ++it) {
    e.a *= 0.93;
    e.b *= 0.93;
    if (!insidePolygon(polygon, e.center) || boundaryDistance(polygon, e.center) < e.b) e.center -= 0.1 * e.b * v;
  }
  if (e.b > e.a) std::swap(e.a, e.b), e.angle += M_PI / 2;
  if (!e.center.allFinite() || !std::isfinite(e.a) || !(e.b > 0))
    throw MyoskinError("ellipse fit failed to produce a finite ellipse");
  (void)triangulation;
  return e;
}

}  // namespace myoskin
