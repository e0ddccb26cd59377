// Stage 3b: the paper's semicircle rule. From each terminal triangle, its internal edge is the diameter of
// a semicircle on the region's side; while every vertex of the merged region lies on or inside it, the
// edge is removed and the neighbouring triangle merged; merging stops at a junction triangle or when a
// vertex falls outside. The region's boundary arc is a candidate bump.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "bumps/bumps_internal.h"
#include "myoskin/errors.h"

namespace myoskin::detail {

// ============================================================================
// Adjacency
// ============================================================================

// Neighbours across each edge by sorting edge keys; validates that the triangles tile the polygon.
TriangleAdjacency buildAdjacency(const SectionPolygon& section, const Triangles& triangles) {
  const int m = section.size();
  const int nt = static_cast<int>(triangles.rows());
  const int np = static_cast<int>(section.cleanedOf.size());
  if (nt != m - 2)
    throw InputError("triangulation has " + std::to_string(nt) + " triangles, the polygon needs " +
                     std::to_string(m - 2));
  TriangleAdjacency adj;
  adj.vertices.resize(nt);
  adj.neighbours.assign(nt, {-1, -1, -1});
  adj.boundaryEdges.assign(nt, 0);
  std::vector<std::pair<int64_t, int>> edges;  // (key, triangle * 3 + k) for internal edges
  edges.reserve(3 * nt);
  for (int t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int r = triangles(t, k);
      if (r < 0 || r >= np) throw InputError("triangulation index out of range");
      adj.vertices[t][k] = section.cleanedOf[r];
    }
    const auto& v = adj.vertices[t];
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) throw InputError("triangulation has a degenerate triangle");
    // Counter-clockwise in space.
    const Vec2 e1 = section.points[v[1]] - section.points[v[0]], e2 = section.points[v[2]] - section.points[v[0]];
    if (e1.x() * e2.y() - e1.y() * e2.x() < 0.0) std::swap(adj.vertices[t][1], adj.vertices[t][2]);
    for (int k = 0; k < 3; ++k) {
      const int a = v[(k + 1) % 3], b = v[(k + 2) % 3];
      if (section.next(a) == b || section.next(b) == a) {
        ++adj.boundaryEdges[t];
      } else {
        edges.emplace_back(static_cast<int64_t>(std::min(a, b)) * m + std::max(a, b), 3 * t + k);
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  for (size_t i = 0; i < edges.size();) {
    if (i + 1 >= edges.size() || edges[i + 1].first != edges[i].first ||
        (i + 2 < edges.size() && edges[i + 2].first == edges[i].first))
      throw InputError("triangulation does not tile the polygon (an inner edge is not shared by two triangles)");
    const int t0 = edges[i].second / 3, k0 = edges[i].second % 3;
    const int t1 = edges[i + 1].second / 3, k1 = edges[i + 1].second % 3;
    adj.neighbours[t0][k0] = t1;
    adj.neighbours[t1][k1] = t0;
    i += 2;
  }
  return adj;
}

// ============================================================================
// Semicircle rule
// ============================================================================

namespace {

// True if every arc vertex strictly between first and last lies in the half-disc on the chord first-last
// on the region's side (the arc side), within `tolerance` times the radius.
bool insideSemicircle(const SectionPolygon& s, int first, int last, double tolerance) {
  const Vec2 a = s.points[first], b = s.points[last];
  const Vec2 mid = 0.5 * (a + b), d = b - a;
  const double r = 0.5 * d.norm();
  if (!(r > 0.0)) return false;
  const double r2 = (r * (1.0 + tolerance)) * (r * (1.0 + tolerance));
  const double slack = tolerance * r * 2.0 * r;  // cross products are scaled by |d| = 2r
  // For a counter-clockwise polygon the forward arc from first to last lies right of first -> last.
  const double side = -static_cast<double>(s.orientation);
  for (int i = s.next(first); i != last; i = s.next(i)) {
    const Vec2 p = s.points[i];
    if ((p - mid).squaredNorm() > r2) return false;
    const Vec2 q = p - a;
    if (side * (d.x() * q.y() - d.y() * q.x()) < -slack) return false;
  }
  return true;
}

}  // namespace

// Merges from every terminal triangle (queue order = triangle order, so the result is deterministic).
std::vector<MergedRegion> semicircleRegions(const SectionPolygon& s, const TriangleAdjacency& adj, double tolerance,
                                            bool absorbJunctions, const std::vector<std::array<int, 2>>& splits) {
  auto isSplit = [&](int a, int b) {
    for (const auto& d : splits)
      if ((d[0] == a && d[1] == b) || (d[0] == b && d[1] == a)) return true;
    return false;
  };
  const int nt = static_cast<int>(adj.vertices.size());
  struct Growing {
    MergedRegion region;
    int across = -1;  // the triangle across the current diameter
  };
  std::vector<Growing> growing;
  std::vector<int> owner(nt, -1);               // growing region that merged each triangle
  std::vector<std::vector<int>> parked(nt);     // junction -> growing regions that stopped at it
  std::vector<int> stateOf;                     // growing region -> index of its stopped state in `out`
  std::vector<MergedRegion> out;
  for (int t = 0; t < nt; ++t) {
    if (adj.boundaryEdges[t] != 2) continue;
    int k = 0;
    while (k < 3 && adj.neighbours[t][k] < 0) ++k;
    if (k == 3) continue;
    Growing g;
    g.region.terminal = t;
    g.region.terminals = {t};
    g.region.tip = adj.vertices[t][k];
    g.region.first = s.prev(g.region.tip);
    g.region.last = s.next(g.region.tip);
    g.region.triangles = 1;
    g.across = adj.neighbours[t][k];
    owner[t] = static_cast<int>(growing.size());
    growing.push_back(std::move(g));
  }

  for (size_t q = 0; q < growing.size(); ++q) {
    MergedRegion reg = growing[q].region;
    int across = growing[q].across;
    bool resolved = false;
    while (true) {
      if (!insideSemicircle(s, reg.first, reg.last, tolerance)) {
        reg.stop = MergedRegion::Stop::Outside;
        break;
      }
      if (owner[across] >= 0 || isSplit(reg.first, reg.last)) {
        reg.stop = MergedRegion::Stop::Met;
        break;
      }
      if (adj.boundaryEdges[across] == 0) {
        reg.stop = MergedRegion::Stop::Junction;
        reg.junction = across;
        if (absorbJunctions) {
          parked[across].push_back(static_cast<int>(q));
          resolved = parked[across].size() == 2;
        }
        break;
      }
      if (adj.boundaryEdges[across] != 1) {  // the other terminal: the region would be the whole polygon
        reg.stop = MergedRegion::Stop::Met;
        break;
      }
      const auto& v = adj.vertices[across];
      int x = -1;
      for (int j = 0; j < 3; ++j)
        if (v[j] != reg.first && v[j] != reg.last) x = v[j];
      if (x == s.prev(reg.first)) {
        reg.first = x;
      } else if (x == s.next(reg.last)) {
        reg.last = x;
      } else {
        reg.stop = MergedRegion::Stop::Met;  // not a sleeve of this region (inconsistent input)
        break;
      }
      owner[across] = static_cast<int>(q);
      ++reg.triangles;
      // The sleeve's remaining internal edge is the new diameter: opposite the vertex not on it.
      int next = -1;
      for (int j = 0; j < 3; ++j)
        if (v[j] != reg.first && v[j] != reg.last) next = adj.neighbours[across][j];
      if (next < 0) {
        reg.stop = MergedRegion::Stop::Met;
        break;
      }
      across = next;
    }
    stateOf.resize(growing.size(), -1);
    stateOf[q] = static_cast<int>(out.size());
    out.push_back(reg);
    if (!resolved) continue;

    // Two branches reached junction J inside their semicircles: J and both merge on across J's third edge.
    const int j = reg.junction;
    const MergedRegion& a = out[stateOf[parked[j][0]]];
    const MergedRegion& b = out[stateOf[parked[j][1]]];
    Growing g;
    if (a.last == b.first) {
      g.region.first = a.first, g.region.last = b.last;
    } else if (b.last == a.first) {
      g.region.first = b.first, g.region.last = a.last;
    } else {
      continue;  // not adjacent branches (inconsistent input)
    }
    const auto& v = adj.vertices[j];
    for (int k = 0; k < 3; ++k) {
      const int p = v[(k + 1) % 3], r = v[(k + 2) % 3];
      if ((p == g.region.first && r == g.region.last) || (r == g.region.first && p == g.region.last))
        g.across = adj.neighbours[j][k];
    }
    if (g.across < 0) continue;
    g.region.terminal = a.terminal;
    g.region.terminals = a.terminals;
    g.region.terminals.insert(g.region.terminals.end(), b.terminals.begin(), b.terminals.end());
    g.region.tip = a.tip;
    g.region.triangles = a.triangles + b.triangles + 1;
    out[stateOf[parked[j][0]]].absorbed = true;
    out[stateOf[parked[j][1]]].absorbed = true;
    owner[j] = static_cast<int>(growing.size());
    growing.push_back(std::move(g));
  }
  return out;
}

}  // namespace myoskin::detail
