// Volume-preserving bulge (Yang & Zhang 2006, "Muscle Deformation"; DESIGN.md section 5).
// A muscle stretched by lambda = L / L0 scales its sections by s(t) across the path. With the rest slice
// areas A(t) along the path and a shape g(t) = (A(t) / A_max)^(k / 2) (k = bulge factor):
//   s(t)^2 = (1 / lambda) * (1 + mu * (g(t) / g_mean - 1)),   g_mean = int A g / int A,
// so int A(t) s(t)^2 lambda dt = int A(t) dt for every mu: the volume is exact. mu = 1 - lambda keeps the
// thin ends (g -> 0) at their rest size and puts the change in the belly; k = 0 gives g = 1 and the
// uniform s = lambda^-1/2 of a generalised cylinder. mu is clamped so that s^2 stays positive.
#pragma once
#include <cmath>
#include <vector>

#include "myoskin/mesh.h"
#include "myoskin/types.h"

namespace myoskin::joints {

struct BulgeProfile {
  std::vector<double> ratio;  // #S g(t_j) / g_mean at the stations
  double ratioMax = 1.0;      // max of ratio
};

// Area of the cross-section of a closed mesh by the plane through `point` with unit normal `normal`.
double sliceArea(const Mesh& surface, const Vec3& point, const Vec3& normal);

// Profile from slice areas at stations spaced evenly along the path (trapezoid weights) and factor k.
BulgeProfile makeBulgeProfile(const std::vector<double>& areas, double k);

// The clamped mu for a stretch lambda.
double bulgeMu(const BulgeProfile& profile, double lambda);

// Section scale s at station j.
inline double bulgeScale(const BulgeProfile& profile, int j, double mu, double lambda) {
  return std::sqrt((1.0 + mu * (profile.ratio[j] - 1.0)) / lambda);
}

}  // namespace myoskin::joints
