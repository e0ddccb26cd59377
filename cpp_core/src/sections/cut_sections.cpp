// Profiles: the skin loop around the bone on each cutting plane, checked against the plane's skin region,
// counter-clockwise and evenly resampled (sections.h).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/sections.h"
#include "sections/plane_loops.h"

namespace myoskin {

namespace {

// ============================================================================
// Loop selection
// ============================================================================

struct Loop2 {
  std::vector<Vec2> points;
  std::vector<std::array<int, 2>> edges;
  double area = 0.0;  // signed
};

// Signed area of a closed polygon (counter-clockwise positive).
double signedArea(const std::vector<Vec2>& pts) {
  double area = 0.0;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Vec2 &a = pts[i], &b = pts[(i + 1) % pts.size()];
    area += 0.5 * (a.x() * b.y() - b.x() * a.y());
  }
  return area;
}

// Length of a closed polygon.
double loopLength(const std::vector<Vec2>& pts) {
  double length = 0.0;
  for (size_t i = 0; i < pts.size(); ++i) length += (pts[(i + 1) % pts.size()] - pts[i]).norm();
  return length;
}

// Appends the straight chord from a to b (both ends excluded), about `spacing` apart, to a clipped loop: its
// points lie on mesh edge `ea` over the first half and `eb` over the second, and off the skin. The ends are
// copies: they may be points of `pts`, which grows.
void appendChord(const Vec2 a, const Vec2 b, double spacing, std::array<int, 2> ea, std::array<int, 2> eb,
                 std::vector<Vec2>& pts, std::vector<std::array<int, 2>>& edges, std::vector<char>& skin) {
  // Bounded, so a tiny spacing cannot flood the loop (far beyond any chord at a useful spacing).
  const int steps = static_cast<int>(std::clamp(std::ceil((b - a).norm() / spacing), 2.0, 1e5));
  for (int k = 1; k < steps; ++k) {
    pts.push_back(a + (b - a) * (static_cast<double>(k) / steps));
    edges.push_back(k * 2 < steps ? ea : eb);
    skin.push_back(0);
  }
}

Loop2 toPlane(const detail::PlaneLoop& loop, const CuttingPlane& p) {
  Loop2 l;
  l.edges = loop.edges;
  for (const Vec3& q : loop.points) l.points.emplace_back((q - p.origin).dot(p.xAxis), (q - p.origin).dot(p.yAxis));
  l.area = signedArea(l.points);
  return l;
}

// Crossing-number test of the plane origin (0, 0).
bool enclosesOrigin(const std::vector<Vec2>& pts) {
  bool inside = false;
  for (size_t i = 0, j = pts.size() - 1; i < pts.size(); j = i++) {
    const Vec2 &a = pts[i], &b = pts[j];
    if ((a.y() > 0) != (b.y() > 0) && 0.0 < (b.x() - a.x()) * (0.0 - a.y()) / (b.y() - a.y()) + a.x()) inside = !inside;
  }
  return inside;
}

// ============================================================================
// Resampling
// ============================================================================

// N points evenly spaced by arc length along the closed CCW loop, starting where it crosses the +Y axis
// (nearest the origin). The +Y axis is where mirrored limbs' frames agree (their X axes are mirrored and
// negated), so a mirrored section is resampled at exactly the mirrored points.
// `source` receives, per output point, the loop index of the segment it lies on.
Points2 resample(const std::vector<Vec2>& pts, int count, std::vector<int>& source) {
  const size_t n = pts.size();
  size_t start = 0;
  double bestY = INFINITY;
  for (size_t i = 0; i < n; ++i) {
    const Vec2 &a = pts[i], &b = pts[(i + 1) % n];
    if (a.x() > 0 && b.x() <= 0) {
      const double y = a.y() + (b.y() - a.y()) * a.x() / (a.x() - b.x());
      if (y > 0 && y < bestY) bestY = y, start = i;
    }
  }
  std::vector<Vec2> ring;
  std::vector<int> ringIndex;
  const Vec2 &a0 = pts[start], &b0 = pts[(start + 1) % n];
  const double t0 = std::isfinite(bestY) && b0.x() != a0.x() ? a0.x() / (a0.x() - b0.x()) : 0.0;
  ring.push_back(a0 + t0 * (b0 - a0));
  ringIndex.push_back(static_cast<int>(start));
  for (size_t k = 1; k <= n; ++k) {
    const size_t i = (start + k) % n;
    ring.push_back(pts[i]);
    ringIndex.push_back(static_cast<int>(i));
  }
  ring.push_back(ring.front());
  ringIndex.push_back(static_cast<int>(start));
  std::vector<double> acc(ring.size(), 0.0);
  for (size_t i = 1; i < ring.size(); ++i) acc[i] = acc[i - 1] + (ring[i] - ring[i - 1]).norm();
  const double total = acc.back();
  Points2 out(count, 2);
  source.assign(count, 0);
  size_t seg = 0;
  for (int k = 0; k < count; ++k) {
    const double s = total * k / count;
    while (seg + 2 < ring.size() && acc[seg + 1] < s) ++seg;
    const double len = acc[seg + 1] - acc[seg];
    const double t = len > 0 ? (s - acc[seg]) / len : 0.0;
    out.row(k) = (ring[seg] + t * (ring[seg + 1] - ring[seg])).transpose();
    source[k] = ringIndex[seg];
  }
  return out;
}

// ============================================================================
// One section
// ============================================================================

// The actual sample spacing of a resampled profile (its loop's length over its samples; 0 when it has none): mirrored
// samples within it count as matching (the resampling's own resolution).
double actualSpacing(const SectionProfile& p) {
  return p.polygon.rows() > 0 ? p.perimeter / static_cast<double>(p.polygon.rows()) : 0.0;
}

SectionProfile cutOne(const Character& c, const CuttingPlane& plane, const ProfileOptions& o,
                      const std::vector<int>& dominant, const std::vector<char>* mask) {
  SectionProfile prof;
  prof.plane = plane;
  std::vector<double> scratch;
  const std::vector<detail::PlaneLoop> loops = detail::planeLoops(c.mesh, plane.origin, plane.normal, scratch);
  int best = -1;
  bool openNearby = false;
  std::vector<Loop2> flat;
  for (const detail::PlaneLoop& l : loops) flat.push_back(toPlane(l, plane));
  for (size_t i = 0; i < loops.size(); ++i) {
    if (!loops[i].closed) {
      openNearby = true;
      continue;
    }
    if (flat[i].points.size() >= 3 && enclosesOrigin(flat[i].points) &&
        (best < 0 || std::abs(flat[i].area) < std::abs(flat[best].area)))
      best = static_cast<int>(i);
  }
  if (best < 0) {
    prof.skipReason = openNearby ? "the skin is open here (the cut runs into a hole)" : "no skin loop encloses the bone here";
    return prof;
  }
  Loop2 loop = flat[best];
  const size_t n = loop.points.size();
  double perimeter = 0.0, onRegion = 0.0;
  std::vector<char> region;
  if (!plane.region.empty() && !dominant.empty()) {
    region.assign(c.skeleton.numBones(), 0);
    for (int b : plane.region) region[b] = 1;
  }
  auto inRegion = [&](size_t i) {
    if (region.empty()) return true;
    for (int v : loop.edges[i])
      if (dominant[v] >= 0 && region[dominant[v]]) return true;
    return false;
  };
  for (size_t i = 0; i < n; ++i) {
    const double len = (loop.points[(i + 1) % n] - loop.points[i]).norm();
    perimeter += len;
    if (inRegion(i) && inRegion((i + 1) % n)) onRegion += len;
  }
  if (loop.area < 0) {
    std::reverse(loop.points.begin(), loop.points.end());
    std::reverse(loop.edges.begin(), loop.edges.end());
  }
  std::vector<char> skin;  // per loop point: 0 on the closing chord of a clipped profile
  if (plane.clipRadius > 0) {
    // Shoulder planes cut the whole side of the torso: keep the longest run on the region near the origin.
    std::vector<char> keep(n);
    for (size_t i = 0; i < n; ++i) keep[i] = loop.points[i].norm() <= plane.clipRadius && inRegion(i);
    size_t bestStart = 0, bestLen = 0;
    bool all = true;
    for (size_t i = 0; i < n; ++i) all &= keep[i] != 0;
    if (!all) {
      for (size_t i = 0; i < n; ++i) {
        if (!keep[i] || keep[(i + n - 1) % n]) continue;  // runs start after a dropped point
        size_t len = 0;
        while (len < n && keep[(i + len) % n]) ++len;
        if (len > bestLen) bestLen = len, bestStart = i;
      }
      std::vector<Vec2> pts;
      std::vector<std::array<int, 2>> edges;
      double arc = 0.0;
      for (size_t k = 0; k < bestLen; ++k) {
        const size_t i = (bestStart + k) % n;
        if (k > 0) arc += (loop.points[i] - pts.back()).norm();
        pts.push_back(loop.points[i]);
        edges.push_back(loop.edges[i]);
        skin.push_back(1);
      }
      if (bestLen < 3 || arc < plane.clipRadius) {
        prof.perimeter = perimeter;
        prof.skipReason = "too little skin near the shoulder on this plane's region (" + std::to_string(arc) + " m)";
        return prof;
      }
      // The chord back to the start, about as finely sampled as the skin.
      appendChord(pts.back(), pts.front(), std::max(arc / bestLen, 1e-6), edges.back(), edges.front(), pts, edges,
                  skin);
      loop.points = std::move(pts);
      loop.edges = std::move(edges);
      if (!(signedArea(loop.points) > 0)) {
        prof.perimeter = perimeter;
        prof.skipReason = "the skin near the shoulder does not bound a region on this plane";
        return prof;
      }
      perimeter = onRegion = loopLength(loop.points);
    }
  }
  if (plane.mirrorAxis && skin.empty() && onRegion < o.minRegionShare * perimeter &&
      onRegion >= o.trunkClipShare * perimeter && o.trunkClipShare > 0) {
    // A trunk plane through the shoulders or hips cuts the arms' or legs' skin too: every run off the region
    // becomes a straight chord, so the trunk's own skin (chest, back) is kept.
    size_t start = 0;  // a point on the region, so runs do not wrap
    while (start < n && !inRegion(start)) ++start;
    std::vector<Vec2> pts;
    std::vector<std::array<int, 2>> edges;
    for (size_t k = 0; k <= n; ++k) {
      const size_t i = (start + k) % n;
      if (!inRegion(i)) continue;
      if (!pts.empty() && k > 0 && !inRegion((i + n - 1) % n))  // the chord from the last kept point, sampled
        appendChord(pts.back(), loop.points[i], o.sampleSpacing, edges.back(), loop.edges[i], pts, edges, skin);
      if (k == n) break;
      pts.push_back(loop.points[i]);
      edges.push_back(loop.edges[i]);
      skin.push_back(1);
    }
    if (pts.size() < 3 || !(signedArea(pts) > 0) || !enclosesOrigin(pts)) {
      prof.perimeter = perimeter;
      prof.skipReason = "the trunk's own skin does not bound a region around the spine on this plane (" +
                        std::to_string(static_cast<int>(100 * onRegion / perimeter)) + " % of the loop on it)";
      return prof;
    }
    perimeter = onRegion = loopLength(pts);
    loop.points = std::move(pts);
    loop.edges = std::move(edges);
  }
  prof.perimeter = perimeter;
  if (perimeter < o.minPerimeter) {
    prof.skipReason = "the loop around the bone is too small (" + std::to_string(perimeter) + " m)";
    return prof;
  }
  if (skin.empty() && onRegion < o.minRegionShare * perimeter) {
    prof.skipReason = "the loop leaves the bone's skin region (armpit, groin or a neighbouring part): " +
                      std::to_string(static_cast<int>(100 * onRegion / perimeter)) + " % on it";
    return prof;
  }
  // One sample every sampleSpacing, 48..400 (clamped before the cast: a tiny spacing cannot overflow).
  int count =
      o.samples > 0 ? o.samples : static_cast<int>(std::clamp(std::round(perimeter / o.sampleSpacing), 48.0, 400.0));
  if (plane.mirrorAxis && o.samples <= 0) count += count % 2;  // the -Y crossing is then a sample too
  std::vector<int> source;
  prof.polygon = resample(loop.points, count, source);
  prof.segment = source;
  prof.loopPoints = static_cast<int>(loop.points.size());
  const bool trunkClipped = plane.mirrorAxis && !skin.empty();
  if (plane.mirrorAxis && count % 2 == 0) {
    // Sample k mirrors sample count - k (both start on the +Y axis and run the same arc length): when every pair
    // matches within one sample spacing, average each pair so the two sides are exact mirror images.
    double worst = 0.0;
    for (int k = 0; k <= count / 2; ++k) {
      const int j = (count - k) % count;
      worst = std::max(worst, std::hypot(prof.polygon(k, 0) + prof.polygon(j, 0), prof.polygon(k, 1) - prof.polygon(j, 1)));
    }
    if (worst <= actualSpacing(prof)) {
      for (int k = 0; k <= count / 2; ++k) {
        const int j = (count - k) % count;
        const double x = 0.5 * (prof.polygon(k, 0) - prof.polygon(j, 0)), y = 0.5 * (prof.polygon(k, 1) + prof.polygon(j, 1));
        prof.polygon.row(k) << x, y;
        prof.polygon.row(j) << -x, y;  // k == j on the axis: x is then exactly 0
      }
      prof.symmetric = true;
    }
  }
  prof.inMask.assign(count, 1);
  if (!skin.empty()) {  // a resampled point is on the skin when the loop segment it lies on is
    prof.onSkin.assign(count, 1);
    for (int k = 0; k < count; ++k)
      prof.onSkin[k] = skin[source[k]] && skin[(source[k] + 1) % skin.size()];
    if (trunkClipped && prof.symmetric)  // mirrored samples: on the skin when both are
      for (int k = 0; k <= count / 2; ++k) {
        const int j = (count - k) % count;
        prof.onSkin[k] = prof.onSkin[j] = prof.onSkin[k] && prof.onSkin[j];
      }
  }
  if (mask) {
    bool any = false;
    for (int k = 0; k < count; ++k) {
      const auto& e = loop.edges[source[k]];
      prof.inMask[k] = (*mask)[e[0]] || (*mask)[e[1]];
      any |= prof.inMask[k] != 0;
    }
    if (!any) {
      prof.polygon.resize(0, 2);
      prof.inMask.clear();
      prof.skipReason = "outside the vertex mask";
      return prof;
    }
  }
  prof.ok = true;
  return prof;
}

// ============================================================================
// Mirrored twins
// ============================================================================

// A left and a right plane of one family and order whose frames mirror each other about the skeleton's mirror
// plane (skeletonMirrorPlane: its left-right axis, whichever axis of the rig that is; mirrored limbs' X axes are
// mirrored and negated, as makeCuttingPlanes orients them) give profiles where sample k of one mirrors sample N - k
// of the other in plane coordinates, (x, y) -> (-x, y). When the planes' origins and every pair match within one sample
// spacing of the first profile, both become the average, exact mirror images.
void mirrorTwins(const std::vector<CuttingPlane>& planes, std::vector<SectionProfile>& out) {
  Vec3 c, n;
  if (!skeletonMirrorPlane(planes, c, n)) return;
  auto point = [&](const Vec3& p) { return Vec3(p - 2.0 * (p - c).dot(n) * n); };
  auto direction = [&](const Vec3& d) { return Vec3(d - 2.0 * d.dot(n) * n); };
  std::vector<char> taken(planes.size(), 0);
  for (size_t i = 0; i < planes.size(); ++i) {
    const CuttingPlane& a = planes[i];
    if (a.mirrorAxis || taken[i] || !out[i].ok || !out[i].onSkin.empty() || out[i].polygon.rows() == 0) continue;
    const double tolerance = actualSpacing(out[i]);
    for (size_t j = i + 1; j < planes.size(); ++j) {
      const CuttingPlane& b = planes[j];
      if (taken[j] || b.family != a.family || b.familyIndex == a.familyIndex || b.order != a.order) continue;
      if ((point(a.origin) - b.origin).norm() > tolerance || (direction(a.normal) - b.normal).norm() > 1e-3 ||
          (direction(a.xAxis) + b.xAxis).norm() > 1e-3)
        continue;
      taken[j] = 1;
      SectionProfile &p = out[i], &q = out[j];
      const Eigen::Index count = p.polygon.rows();
      if (!q.ok || !q.onSkin.empty() || q.polygon.rows() != count) break;
      double worst = 0.0;
      for (Eigen::Index k = 0; k < count; ++k) {
        const Eigen::Index m = (count - k) % count;
        worst = std::max(worst, std::hypot(p.polygon(k, 0) + q.polygon(m, 0), p.polygon(k, 1) - q.polygon(m, 1)));
      }
      if (worst > tolerance) break;
      for (Eigen::Index k = 0; k < count; ++k) {
        const Eigen::Index m = (count - k) % count;
        const double x = 0.5 * (p.polygon(k, 0) - q.polygon(m, 0)), y = 0.5 * (p.polygon(k, 1) + q.polygon(m, 1));
        p.polygon.row(k) << x, y;
        q.polygon.row(m) << -x, y;
      }
      p.symmetric = q.symmetric = true;
      break;
    }
  }
}

}  // namespace

// ============================================================================
// Public
// ============================================================================

std::vector<SectionProfile> cutSections(const Character& character, const std::vector<CuttingPlane>& planes,
                                        const ProfileOptions& options, const std::vector<char>* vertexMask) {
  const int nv = character.mesh.numVertices();
  if (vertexMask && static_cast<int>(vertexMask->size()) != nv)
    throw InputError("section vertex mask has " + std::to_string(vertexMask->size()) + " entries, the skin has " +
                     std::to_string(nv) + " vertices");
  if (!(options.sampleSpacing > 0 && std::isfinite(options.sampleSpacing)))
    throw InputError("profile options: sampleSpacing must be finite and > 0, got " +
                     std::to_string(options.sampleSpacing));
  // Each vertex's dominant bone (-1 without weights).
  std::vector<int> dominant;
  if (character.hasWeights()) {
    dominant.assign(nv, -1);
    for (int v = 0; v < nv; ++v) {
      double w = 0.0;
      for (int s = 0; s < character.weights.influences(); ++s)
        if (character.weights.joints(v, s) >= 0 && character.weights.weights(v, s) > w)
          w = character.weights.weights(v, s), dominant[v] = character.weights.joints(v, s);
    }
  }
  std::vector<SectionProfile> out(planes.size());
  tbb::parallel_for(size_t(0), planes.size(), [&](size_t i) {
    try {
      out[i] = cutOne(character, planes[i], options, dominant, vertexMask);
    } catch (const std::exception& e) {
      out[i] = SectionProfile{};
      out[i].plane = planes[i];
      out[i].skipReason = std::string("cutting failed: ") + e.what();
    }
  });
  if (options.mirrorLimbs) mirrorTwins(planes, out);
  return out;
}

}  // namespace myoskin
