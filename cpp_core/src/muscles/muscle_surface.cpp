// Stage 7: loft the section ellipses into a closed, watertight, outward-oriented triangle mesh whose
// ends taper to the origin and insertion along cubic Hermite curves (one pole vertex per end).
#include <algorithm>
#include <cmath>

#include "muscles/muscle_util.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"

namespace myoskin {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Ring of an ellipse in its plane: vertex k lies in direction cos(phi) ref + sin(phi) (n x ref).
std::vector<Vec3> ellipseRing(const MuscleSection& s, const Vec3& n, const Vec3& ref, int count) {
  const Vec3 axA = detail::perpendicularTo(s.axisA, n);
  const Vec3 axB = n.cross(axA);
  const Vec3 ref2 = n.cross(ref);
  const double a = std::max(s.a, 1e-9), b = std::max(s.b, 1e-9);
  std::vector<Vec3> ring(count);
  for (int k = 0; k < count; ++k) {
    const double phi = 2 * kPi * k / count;
    const Vec3 d = std::cos(phi) * ref + std::sin(phi) * ref2;
    const double alpha = std::atan2(d.dot(axB), d.dot(axA));
    const double r = a * b / std::sqrt(std::pow(b * std::cos(alpha), 2) + std::pow(a * std::sin(alpha), 2));
    ring[k] = s.center + r * d;
  }
  return ring;
}

}  // namespace

Mesh loftMuscleSurface(const Muscle& muscle, const SurfaceOptions& options) {
  const int n = static_cast<int>(muscle.sections.size());
  if (n == 0) throw InputError("loftMuscleSurface: muscle '" + muscle.name + "' has no sections");
  const int M = std::max(3, options.ringVertices);
  const int K = std::max(0, options.capRings);

  // Curve directions at the centres (origin -> insertion), frames transported along them.
  std::vector<Vec3> centers(n), normals(n);
  for (int i = 0; i < n; ++i) centers[i] = muscle.sections[i].center;
  const Vec3 dirOI = muscle.insertion.position - muscle.origin.position;
  for (int i = 0; i < n; ++i) {
    Vec3 along = n > 1 ? centers[std::min(i + 1, n - 1)] - centers[std::max(i - 1, 0)] : dirOI;
    Vec3 nn = muscle.sections[i].normal.normalized();
    if (along.norm() > 1e-12 && nn.dot(along) < 0) nn = -nn;
    normals[i] = nn;
  }
  std::vector<std::vector<Vec3>> sectionRings(n);
  Vec3 ref = detail::perpendicularTo(muscle.sections[0].axisA, normals[0]);
  for (int i = 0; i < n; ++i) {
    ref = detail::perpendicularTo(ref, normals[i]);
    sectionRings[i] = ellipseRing(muscle.sections[i], normals[i], ref, M);
  }

  // Cap rings: the end ring, rotated to the Hermite tangent, moved along the Hermite curve from the end
  // centre to the pole and scaled by the Hermite taper s(t) = 1 - 3t^2 + 2t^3 (s'(0) = 0: tangent continuous).
  auto capRings = [&](int end, const Vec3& pole, const Vec3& outward) {
    std::vector<std::vector<Vec3>> rings;
    const Vec3& c = centers[end];
    const double L = (pole - c).norm();
    const Vec3 m0 = L * outward;
    const Vec3 m1 = L > 1e-12 ? Vec3(pole - c) : m0;
    for (int j = 1; j <= K; ++j) {
      const double t = double(j) / (K + 1);
      const Vec3 p = hermite(c, m0, pole, m1, t);
      const double t2 = t * t;
      Vec3 tangent = 6 * (t2 - t) * c + (3 * t2 - 4 * t + 1) * m0 + 6 * (t - t2) * pole + (3 * t2 - 2 * t) * m1;
      if (tangent.norm() < 1e-12) tangent = outward;
      const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(outward, tangent.normalized());
      const double s = 1 - 3 * t2 + 2 * t2 * t;
      std::vector<Vec3> ring(M);
      for (int k = 0; k < M; ++k) ring[k] = p + s * (q * (sectionRings[end][k] - c));
      rings.push_back(std::move(ring));
    }
    return rings;
  };
  const auto originCap = capRings(0, muscle.origin.position, -normals[0]);
  const auto insertionCap = capRings(n - 1, muscle.insertion.position, normals[n - 1]);

  // All rings from the origin to the insertion.
  std::vector<const std::vector<Vec3>*> rings;
  for (int j = K - 1; j >= 0; --j) rings.push_back(&originCap[j]);
  for (int i = 0; i < n; ++i) rings.push_back(&sectionRings[i]);
  for (int j = 0; j < K; ++j) rings.push_back(&insertionCap[j]);
  const int R = static_cast<int>(rings.size());

  Mesh mesh;
  mesh.vertices.resize(R * M + 2, 3);
  for (int r = 0; r < R; ++r)
    for (int k = 0; k < M; ++k) mesh.vertices.row(r * M + k) = (*rings[r])[k].transpose();
  const int poleO = R * M, poleI = R * M + 1;
  mesh.vertices.row(poleO) = muscle.origin.position.transpose();
  mesh.vertices.row(poleI) = muscle.insertion.position.transpose();
  mesh.triangles.resize(2 * M * (R - 1) + 2 * M, 3);
  int t = 0;
  for (int r = 0; r + 1 < R; ++r)
    for (int k = 0; k < M; ++k) {
      const int a = r * M + k, b = r * M + (k + 1) % M, c = (r + 1) * M + (k + 1) % M, d = (r + 1) * M + k;
      mesh.triangles.row(t++) << a, b, c;
      mesh.triangles.row(t++) << a, c, d;
    }
  for (int k = 0; k < M; ++k) {
    mesh.triangles.row(t++) << poleO, (k + 1) % M, k;
    mesh.triangles.row(t++) << poleI, (R - 1) * M + k, (R - 1) * M + (k + 1) % M;
  }
  // Outward orientation: flip when the enclosed volume comes out negative.
  if (enclosedVolume(mesh.vertices, mesh.triangles) < 0)
    for (int i = 0; i < mesh.numTriangles(); ++i) std::swap(mesh.triangles(i, 1), mesh.triangles(i, 2));
  return mesh;
}

}  // namespace myoskin
