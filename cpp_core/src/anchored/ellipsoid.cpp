// Closest point on an ellipsoid by a safeguarded Newton-Raphson iteration (Arabaci 2001, Eqs. 3.11-3.17).
#include <algorithm>
#include <cmath>
#include <string>

#include "myoskin/anchored_skin.h"
#include "myoskin/errors.h"

namespace myoskin {

// ============================================================================
// Closest point
// ============================================================================

// The nearest point on the ellipsoid with radii r to p. With m = min r_i^2 and s = t + m (t the Lagrange
// parameter of x_i = r_i^2 p_i / (r_i^2 + t)), d_i = r_i^2 - m + s and g(s) = sum (r_i p_i / d_i)^2; the nearest
// point has the largest root of g = 1, in s > 0. Newton runs on phi(s) = 1/sqrt(g) - 1, which is close to linear
// both near the pole (s -> 0) and far from it, inside a bracket [lo, hi] with phi(lo) <= 0 <= phi(hi).
EllipsoidClosest closestPointOnEllipsoid(const Vec3& radii, const Vec3& p, const EllipsoidSolverOptions& options) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(radii[i]) || radii[i] <= 0.0)
      throw InputError("ellipsoid radius " + std::to_string(i) + " is " + std::to_string(radii[i]) +
                       " (radii must be positive and finite)");
  if (!p.allFinite()) throw InputError("closest point on an ellipsoid: the point is not finite");
  if (options.maxIterations < 1 || !(options.tolerance > 0.0))
    throw InputError("ellipsoid solver: maxIterations must be >= 1 and tolerance > 0");
  const Vec3 r2 = radii.cwiseProduct(radii);
  const double m = r2.minCoeff();
  const double rmax2 = r2.maxCoeff();
  // Axes whose radius equals the smallest (within rounding): their terms have the pole at s = 0.
  bool smallest[3];
  double ps2 = 0.0;
  for (int i = 0; i < 3; ++i) {
    smallest[i] = r2[i] - m <= 1e-14 * m;
    if (smallest[i]) ps2 += p[i] * p[i];
  }
  const double rmin = std::sqrt(m);
  EllipsoidClosest result;
  // Evolute case: p has no component along the smallest axes and g stays <= 1 at the pole: s = 0, and the
  // nearest point leaves p's plane along the first smallest axis (the centre and points on the long axes).
  if (ps2 <= (1e-300)) {
    double g0 = 0.0;
    Vec3 x = Vec3::Zero();
    for (int i = 0; i < 3; ++i)
      if (!smallest[i]) {
        x[i] = r2[i] * p[i] / (r2[i] - m);
        g0 += (x[i] / radii[i]) * (x[i] / radii[i]);
      }
    if (g0 <= 1.0) {
      int first = 0;
      while (!smallest[first]) ++first;
      x[first] = rmin * std::sqrt(std::max(0.0, 1.0 - g0));
      result.point = x;
      result.distance = (p - x).norm();
      return result;
    }
  }
  const Vec3 rp = radii.cwiseProduct(p);
  double lo = rmin * std::sqrt(ps2);  // the smallest axes' terms alone reach 1 here: phi(lo) <= 0
  double hi = m + rp.norm();          // every d_i >= |r p| here: g <= 1, phi(hi) >= 0
  auto evaluate = [&](double s, double& phi, double& dphi) {
    double g = 0.0, dg = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double d = r2[i] - m + s;
      if (rp[i] == 0.0) continue;
      const double q = rp[i] / d;
      g += q * q;
      dg += q * q / d;  // -g'/2
    }
    if (g <= 0.0) {  // cannot happen inside the bracket unless p = 0 (handled above)
      phi = 1.0;
      dphi = 0.0;
      return;
    }
    const double inv = 1.0 / std::sqrt(g);
    phi = inv - 1.0;
    dphi = inv * inv * inv * dg;  // d/ds g^-1/2 = -1/2 g^-3/2 g' = g^-3/2 dg
  };
  double s = lo;
  const double tol = options.tolerance * rmax2;
  result.converged = false;
  for (int it = 0; it < options.maxIterations; ++it) {
    double phi, dphi;
    evaluate(s, phi, dphi);
    ++result.iterations;
    if (phi == 0.0) {
      result.converged = true;
      break;
    }
    if (phi < 0.0)
      lo = s;
    else
      hi = s;
    double next = dphi > 0.0 ? s - phi / dphi : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const double step = std::abs(next - s);
    s = next;
    if (step <= tol || hi - lo <= tol) {
      result.converged = true;
      break;
    }
  }
  Vec3 x;
  for (int i = 0; i < 3; ++i) {
    const double d = r2[i] - m + s;
    x[i] = d > 0.0 ? r2[i] * p[i] / d : 0.0;
  }
  // Onto the surface exactly (a relative correction of the order of the tolerance).
  const double level = std::sqrt((x.array() / radii.array()).square().sum());
  if (level > 0.0) x /= level;
  result.point = x;
  result.distance = (p - x).norm();
  return result;
}

double ellipsoidVolume(const Vec3& radii) { return 4.0 / 3.0 * M_PI * radii[0] * radii[1] * radii[2]; }

}  // namespace myoskin
