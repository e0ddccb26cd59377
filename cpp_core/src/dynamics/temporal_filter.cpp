// Temporal filter for point caches (Gray & Hutchinson's "periodic filtering"): each vertex is tested against
// the segment between its positions on the previous and next frames (the paper's spring between them); a
// deviation within the tolerance (smooth motion curving) passes unchanged, a larger one (jitter) is pulled back to
// the tolerance.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include "myoskin/errors.h"
#include "myoskin/secondary_motion.h"

namespace myoskin {

namespace {

void checkOptions(const TemporalFilterOptions& o, double lengthScale) {
  if (!(o.relativeTolerance >= 0.0) || !std::isfinite(o.relativeTolerance))
    throw InputError("temporal filter: relativeTolerance must be >= 0");
  if (!(o.absoluteTolerance >= 0.0) || !std::isfinite(o.absoluteTolerance))
    throw InputError("temporal filter: absoluteTolerance must be >= 0");
  if (o.grainSize < 1) throw InputError("temporal filter: grainSize must be >= 1");
  if (!(lengthScale > 0.0) || !std::isfinite(lengthScale))
    throw InputError("temporal filter: the length scale must be > 0 (the skin's mean edge length)");
}

}  // namespace

// ============================================================================
// One frame
// ============================================================================

namespace {

// How far p lies from the segment a-b past the tolerance (<= 0: within it), with the nearest point and tolerance.
double excess(const Vec3& a, const Vec3& p, const Vec3& b, double relative, double absolute, Vec3& onSegment,
              double& tol) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  // Nearest point on the segment from a to b (a itself when they coincide): a spike along the motion, past the
  // neighbours, is caught as well as one across it.
  const double s = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  onSegment = a + ab * s;
  tol = relative * std::sqrt(len2) + absolute;
  return (p - onSegment).norm() - tol;
}

Vec3 row(const PointsF& m, Eigen::Index v) { return m.row(v).cast<double>().transpose(); }

}  // namespace

int filterFrame(const PointsF* before, const PointsF& previous, const PointsF& current, const PointsF& next,
                const PointsF* after, double lengthScale, const TemporalFilterOptions& options, PointsF& out) {
  checkOptions(options, lengthScale);
  const Eigen::Index V = current.rows();
  if (previous.rows() != V || next.rows() != V || (before && before->rows() != V) || (after && after->rows() != V))
    throw InputError("temporal filter: the frames have different vertex counts (" + std::to_string(previous.rows()) +
                     ", " + std::to_string(V) + ", " + std::to_string(next.rows()) + ")");
  if (&out == &previous || &out == &current || &out == &next || &out == before || &out == after)
    throw InputError("temporal filter: the output may not be one of the input frames");
  out.resize(V, 3);
  const double absolute = options.absoluteTolerance * lengthScale, relative = options.relativeTolerance;
  std::atomic<int> pulled{0};
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, V, options.grainSize), [&](const auto& range) {
    int local = 0;
    for (Eigen::Index v = range.begin(); v < range.end(); ++v) {
      const Vec3 a = row(previous, v), p = row(current, v), b = row(next, v);
      Vec3 onSegment, unused;
      double tol, t2;
      const double over = excess(a, p, b, relative, absolute, onSegment, tol);
      // Anomalous: past the tolerance, and (where the frames two away are given) further out than either neighbour
      // is from its own neighbours, so the frames next to a spike, which see the spike, are left alone.
      bool anomalous = over > 0.0;
      if (anomalous && before) anomalous = over > excess(row(*before, v), a, p, relative, absolute, unused, t2);
      if (anomalous && after) anomalous = over > excess(p, b, row(*after, v), relative, absolute, unused, t2);
      if (!anomalous) {
        out.row(v) = current.row(v);
        continue;
      }
      // Pulled back to the tolerance, and along the segment toward its middle by the share of the deviation that
      // was past it (continuous: nothing moves at the tolerance itself).
      const double dev = over + tol, keep = tol / dev;
      const Vec3 toward = onSegment + (0.5 * (a + b) - onSegment) * (1.0 - keep);
      out.row(v) = (toward + (p - onSegment) * keep).cast<float>().transpose();
      ++local;
    }
    pulled += local;
  });
  return pulled.load();
}

int filterFrame(const PointsF& previous, const PointsF& current, const PointsF& next, double lengthScale,
                const TemporalFilterOptions& options, PointsF& out) {
  return filterFrame(nullptr, previous, current, next, nullptr, lengthScale, options, out);
}

// ============================================================================
// A whole cache
// ============================================================================

int filterFrames(const std::vector<PointsF>& frames, double lengthScale, const TemporalFilterOptions& options,
                 std::vector<PointsF>& out) {
  checkOptions(options, lengthScale);
  if (&out == &frames) throw InputError("temporal filter: the output may not be the input cache");
  for (size_t f = 1; f < frames.size(); ++f)
    if (frames[f].rows() != frames[0].rows())
      throw InputError("temporal filter: frame " + std::to_string(f) + " has " + std::to_string(frames[f].rows()) +
                       " vertices, frame 0 has " + std::to_string(frames[0].rows()));
  out.resize(frames.size());
  int pulled = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    if (f == 0 || f + 1 == frames.size())
      out[f] = frames[f];
    else
      pulled += filterFrame(f >= 2 ? &frames[f - 2] : nullptr, frames[f - 1], frames[f], frames[f + 1],
                            f + 2 < frames.size() ? &frames[f + 2] : nullptr, lengthScale, options, out[f]);
  }
  return pulled;
}

double meanEdgeLength(const Points& vertices, const Triangles& triangles) {
  if (vertices.rows() == 0 || triangles.rows() == 0) throw InputError("mean edge length: the mesh is empty");
  double sum = 0.0;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = triangles(f, k), j = triangles(f, (k + 1) % 3);
      if (i < 0 || j < 0 || i >= vertices.rows() || j >= vertices.rows())
        throw InputError("mean edge length: triangle " + std::to_string(f) + " has a vertex index out of range");
      sum += (vertices.row(i) - vertices.row(j)).norm();
    }
  const double mean = sum / (3.0 * static_cast<double>(triangles.rows()));
  if (!std::isfinite(mean)) throw InputError("mean edge length: the mesh has non-finite vertices");
  return mean;
}

}  // namespace myoskin
