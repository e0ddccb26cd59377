// Stage 7: loft the section ellipses into a closed, watertight, outward-oriented triangle mesh that reads as a
// muscle: single outlying centres and radii are removed (median of three), the rings' planes, ellipse axes and radii
// are smoothed along the muscle (the ellipse angle unwrapped, so
// neighbouring rings turn smoothly), a ring that would cut through its neighbour is laid parallel to it (or left
// out), and each end tapers from its last ring to a pole on the root curve ahead of it (or a rounded cap).
#include <algorithm>
#include <cmath>

#include "muscles/muscle_util.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"

namespace myoskin {

namespace {


// One ring to loft: an ellipse of semi-axes a, b whose axis a lies at `angle` from `ref` in the plane (center, normal).
struct Ring {
  Vec3 center, normal, ref;
  double angle = 0.0, a = 0.0, b = 0.0;
};

// Ring vertices: vertex k in direction cos(phi) ref + sin(phi) (normal x ref), at the ellipse's radius there.
std::vector<Vec3> ringPoints(const Ring& r, int count, double scale = 1.0) {
  const Vec3 ref2 = r.normal.cross(r.ref);
  const double a = std::max(r.a, 1e-12), b = std::max(r.b, 1e-12);
  std::vector<Vec3> ring(count);
  for (int k = 0; k < count; ++k) {
    const double phi = 2 * kPi * k / count, alpha = phi - r.angle;
    const double radius = a * b / std::hypot(b * std::cos(alpha), a * std::sin(alpha));
    ring[k] = r.center + scale * radius * (std::cos(phi) * r.ref + std::sin(phi) * ref2);
  }
  return ring;
}

// One pass of a 1-2-1 filter over the inner values (the ends kept).
template <class T>
void smooth121(std::vector<T>& v) {
  if (v.size() < 3) return;
  std::vector<T> out = v;
  for (size_t i = 1; i + 1 < v.size(); ++i) out[i] = 0.25 * v[i - 1] + 0.5 * v[i] + 0.25 * v[i + 1];
  v = std::move(out);
}

// Median of three over the inner values (the ends kept): removes a single outlier, keeps a step.
void median3(std::vector<double>& v) {
  if (v.size() < 3) return;
  std::vector<double> out = v;
  for (size_t i = 1; i + 1 < v.size(); ++i) out[i] = std::max(std::min(v[i - 1], v[i]), std::min(std::max(v[i - 1], v[i]), v[i + 1]));
  v = std::move(out);
}

// True when every point of `pts` lies strictly on the `side` of the plane (c, n), by margin eps.
bool onSide(const std::vector<Vec3>& pts, const Vec3& c, const Vec3& n, double side, double eps) {
  for (const Vec3& p : pts)
    if (side * (p - c).dot(n) <= eps) return false;
  return true;
}

}  // namespace

Mesh loftMuscleSurface(const Muscle& muscle, const SurfaceOptions& options) {
  const int n = static_cast<int>(muscle.sections.size());
  if (n == 0) throw InputError("loftMuscleSurface: muscle '" + muscle.name + "' has no sections");
  const int M = std::max(3, options.ringVertices);
  const int K = std::max(0, options.capRings);
  const int passes = std::max(0, options.smoothingPasses);

  // Section planes, their normals oriented alike (with the middle section's, then origin -> insertion). Sections
  // that do not advance along the muscle (a section of another plane family behind its neighbours) are left out:
  // the kept ones are the longest run whose centres advance along the mean normal (a longest increasing
  // subsequence). The kept normals are then smoothed along the muscle.
  const Vec3 dirOI = muscle.insertion.position - muscle.origin.position;
  std::vector<Vec3> allNormals(n);
  {
    const Vec3 mid = muscle.sections[n / 2].normal.normalized();
    Vec3 sum = Vec3::Zero();
    for (int i = 0; i < n; ++i) {
      Vec3 nn = muscle.sections[i].normal.normalized();
      if (nn.dot(mid) < 0) nn = -nn;
      allNormals[i] = nn;
      sum += nn;
    }
    const Vec3 overall = dirOI.norm() > 1e-12 ? dirOI : Vec3(muscle.sections[n - 1].center - muscle.sections[0].center);
    if (sum.dot(overall) < 0)
      for (Vec3& nn : allNormals) nn = -nn;
  }
  Vec3 axis = Vec3::Zero();
  for (const Vec3& nn : allNormals) axis += nn;
  axis = axis.norm() > 1e-12 ? Vec3(axis.normalized()) : allNormals[0];
  std::vector<int> order;  // indices of the kept sections
  {
    std::vector<double> p(n);
    for (int i = 0; i < n; ++i) p[i] = muscle.sections[i].center.dot(axis);
    std::vector<int> len(n, 1), prev(n, -1);
    int best = 0;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < i; ++j)
        if (p[j] < p[i] && len[j] + 1 > len[i]) len[i] = len[j] + 1, prev[i] = j;
      if (len[i] > len[best]) best = i;
    }
    for (int i = best; i >= 0; i = prev[i]) order.push_back(i);
    std::reverse(order.begin(), order.end());
  }
  const int nk0 = static_cast<int>(order.size());
  std::vector<Vec3> centers(nk0), normals(nk0);
  for (int i = 0; i < nk0; ++i) centers[i] = muscle.sections[order[i]].center, normals[i] = allNormals[order[i]];
  if (passes > 0)  // a centre jumping sideways out of line with both neighbours (componentwise median of three)
    for (int c = 0; c < 3; ++c) {
      std::vector<double> x(nk0);
      for (int i = 0; i < nk0; ++i) x[i] = centers[i][c];
      median3(x);
      for (int i = 0; i < nk0; ++i) centers[i][c] = x[i];
    }
  for (int p = 0; p < passes; ++p) {
    std::vector<Vec3> next = normals;
    for (int i = 0; i < nk0; ++i)
      next[i] = normals[std::max(i - 1, 0)] + 2 * normals[i] + normals[std::min(i + 1, nk0 - 1)];
    for (int i = 0; i < nk0; ++i) normals[i] = next[i].norm() > 1e-12 ? Vec3(next[i].normalized()) : normals[i];
  }

  // Ellipses in a frame transported along the planes; the axis angle unwrapped (an ellipse is the same turned by
  // 180 degrees, or by 90 with its axes swapped: the turn nearest the previous ring's is taken), then angle and
  // semi-axes smoothed along the muscle.
  std::vector<Ring> rings(nk0);
  Vec3 ref = detail::perpendicularTo(muscle.sections[order[0]].axisA, normals[0]);
  for (int i = 0; i < nk0; ++i) {
    const MuscleSection& s = muscle.sections[order[i]];
    Ring& r = rings[i];
    r.center = centers[i], r.normal = normals[i];
    ref = detail::perpendicularTo(ref, normals[i]);
    r.ref = ref;
    const Vec3 axA = detail::perpendicularTo(s.axisA, normals[i]);
    double angle = std::atan2(axA.dot(normals[i].cross(ref)), axA.dot(ref));
    double a = std::max(s.a, 1e-12), b = std::max(s.b, 1e-12);
    if (i > 0) {
      const double prev = rings[i - 1].angle;
      auto nearest = [&](double x) { return x + kPi * std::round((prev - x) / kPi); };
      const double same = nearest(angle), swapped = nearest(angle + kPi / 2);
      if (std::abs(swapped - prev) < std::abs(same - prev)) angle = swapped, std::swap(a, b);
      else angle = same;
    }
    r.angle = angle, r.a = a, r.b = b;
  }
  {
    std::vector<double> angle(nk0), a(nk0), b(nk0);
    for (int i = 0; i < nk0; ++i) angle[i] = rings[i].angle, a[i] = rings[i].a, b[i] = rings[i].b;
    if (passes > 0) median3(a), median3(b);  // a single section fitted far too large or small is an outlier
    for (int p = 0; p < passes; ++p) smooth121(angle), smooth121(a), smooth121(b);
    for (int i = 0; i < nk0; ++i) rings[i].angle = angle[i], rings[i].a = a[i], rings[i].b = b[i];
  }

  // Neighbouring rings must not cut through each other: a ring that reaches behind its predecessor's plane (or
  // has its predecessor reach ahead of its own) is laid parallel to the predecessor, or left out when its centre
  // does not lie ahead of it.
  std::vector<Ring> kept{rings[0]};
  std::vector<std::vector<Vec3>> points{ringPoints(rings[0], M)};
  for (int i = 1; i < nk0; ++i) {
    const Ring& prev = kept.back();
    Ring r = rings[i];
    std::vector<Vec3> pts = ringPoints(r, M);
    const double eps = 1e-9 * (1.0 + prev.a + r.a);
    if (!onSide(pts, prev.center, prev.normal, 1.0, eps) || !onSide(points.back(), r.center, r.normal, -1.0, eps)) {
      if ((r.center - prev.center).dot(prev.normal) <= eps) continue;
      r.normal = prev.normal;  // parallel: the same frame, angle and axes carried over
      r.ref = detail::perpendicularTo(prev.ref, r.normal);
      pts = ringPoints(r, M);
    }
    kept.push_back(r);
    points.push_back(std::move(pts));
  }

  // Caps: rings parallel to the end ring, stepping towards the pole (offset t h along the outward normal, sideways
  // by the smooth step 3t^2 - 2t^3) and shrinking by the Hermite taper 1 - 3t^2 + 2t^3 (tangent continuous at the
  // end ring, a spindle's point at the pole). The pole is the root curve point beyond the end (or the attachment) farthest ahead of the end ring; when
  // none lies at least half the ring's mean radius ahead, a dome (half an ellipsoid) of that height on the normal.
  const int nk = static_cast<int>(kept.size());
  auto capOf = [&](const Ring& end, const std::vector<Vec3>& endPoints, const Vec3& outward, bool originSide,
                   Vec3& pole) {
    const double radius = std::sqrt(end.a * end.b);
    const auto& curve = muscle.rootCurve;
    int nearest = -1;
    double bestD = INFINITY;
    for (size_t j = 0; j < curve.size(); ++j) {
      const double d = (curve[j] - end.center).squaredNorm();
      if (d < bestD) bestD = d, nearest = static_cast<int>(j);
    }
    double h = -INFINITY;
    pole = end.center;
    std::vector<Vec3> candidates{originSide ? muscle.origin.position : muscle.insertion.position};
    for (int j = 0; j < static_cast<int>(curve.size()); ++j)
      if (originSide ? j < nearest : j > nearest) candidates.push_back(curve[j]);
    for (const Vec3& q : candidates) {
      const double off = (q - end.center).dot(outward);
      if (std::isfinite(off) && off > h) h = off, pole = q;
    }
    const bool dome = !(h >= 0.5 * radius);
    if (dome) h = 0.5 * radius, pole = end.center + h * outward;
    const double reach = options.maxCapLength * radius;  // a long tendon: the cap stops short of its pole
    if (!dome && reach > 0 && h > reach) pole = end.center + (reach / h) * (pole - end.center), h = reach;
    const Vec3 side = pole - end.center - h * outward;
    std::vector<std::vector<Vec3>> caps;
    for (int j = 1; j <= K; ++j) {
      const double w = double(j) / (K + 1);  // a dome: half an ellipsoid, rings evenly spaced in its angle
      const double t = dome ? std::sin(0.5 * kPi * w) : w;
      const Vec3 shift = t * h * outward + (3 * t * t - 2 * t * t * t) * side;
      const double s = dome ? std::cos(0.5 * kPi * w) : 1 - 3 * t * t + 2 * t * t * t;
      std::vector<Vec3> ring(M);
      for (int k = 0; k < M; ++k) ring[k] = end.center + shift + s * (endPoints[k] - end.center);
      caps.push_back(std::move(ring));
    }
    return caps;
  };
  Vec3 poleOrigin, poleInsertion;
  const auto originCap = capOf(kept[0], points[0], -kept[0].normal, true, poleOrigin);
  const auto insertionCap = capOf(kept[nk - 1], points[nk - 1], kept[nk - 1].normal, false, poleInsertion);

  // All rings from the origin to the insertion.
  std::vector<const std::vector<Vec3>*> all;
  for (int j = K - 1; j >= 0; --j) all.push_back(&originCap[j]);
  for (int i = 0; i < nk; ++i) all.push_back(&points[i]);
  for (int j = 0; j < K; ++j) all.push_back(&insertionCap[j]);
  const int R = static_cast<int>(all.size());

  Mesh mesh;
  mesh.vertices.resize(R * M + 2, 3);
  for (int r = 0; r < R; ++r)
    for (int k = 0; k < M; ++k) mesh.vertices.row(r * M + k) = (*all[r])[k].transpose();
  mesh.vertices.row(R * M) = poleOrigin.transpose();
  mesh.vertices.row(R * M + 1) = poleInsertion.transpose();
  detail::closeRingTube(mesh, R, M);
  return mesh;
}

}  // namespace myoskin
