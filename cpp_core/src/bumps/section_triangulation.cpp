// Stage 3a: the constrained Delaunay triangulation of a section polygon (CGAL), its inside triangles and
// their kinds (terminal, sleeve, junction), plus the validation and cleaning shared by the bump stage.
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/exceptions.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "bumps/bumps_internal.h"
#include "myoskin/errors.h"

namespace myoskin {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<int, Kernel>;  // cleaned polygon index
using FaceInfoBase = CGAL::Triangulation_face_base_with_info_2<int, Kernel>;  // 0 unvisited, 1 outside
using FaceBase = CGAL::Constrained_triangulation_face_base_2<Kernel, FaceInfoBase>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::No_constraint_intersection_tag>;
using CgalPoint = Kernel::Point_2;

constexpr double kMaxCoordinate = 1e150;  // squares and products of coordinates stay finite

}  // namespace

namespace detail {

// ============================================================================
// Validation and cleaning
// ============================================================================

// Checks the polygon, merges consecutive exact duplicates and computes orientation, area and centroid.
SectionPolygon cleanSection(const Points2& polygon) {
  const int n = static_cast<int>(polygon.rows());
  if (n < 3) throw InputError("section polygon has " + std::to_string(n) + " points, needs at least 3");
  double maxAbs = 0.0;
  for (int i = 0; i < n; ++i) {
    const double x = polygon(i, 0), y = polygon(i, 1);
    if (!std::isfinite(x) || !std::isfinite(y))
      throw InputError("section polygon has a non-finite coordinate at point " + std::to_string(i));
    maxAbs = std::max({maxAbs, std::abs(x), std::abs(y)});
  }
  if (maxAbs > kMaxCoordinate) throw InputError("section polygon coordinates are out of range (> 1e150)");

  SectionPolygon s;
  s.cleanedOf.assign(n, 0);
  for (int i = 0; i < n; ++i) {
    const Vec2 p = polygon.row(i).transpose();
    if (s.points.empty() || p != s.points.back()) {
      s.points.push_back(p);
      s.original.push_back(i);
    }
    s.cleanedOf[i] = static_cast<int>(s.points.size()) - 1;
  }
  // Closing duplicates of the first point (a repeated start point) belong to point 0.
  while (s.points.size() > 1 && s.points.back() == s.points.front()) {
    const int dropped = static_cast<int>(s.points.size()) - 1;
    for (int i = 0; i < n; ++i)
      if (s.cleanedOf[i] == dropped) s.cleanedOf[i] = 0;
    s.points.pop_back();
    s.original.pop_back();
  }
  const int m = s.size();
  if (m < 3) throw InputError("section polygon has fewer than 3 distinct points");

  int exponent = 0;
  std::frexp(maxAbs, &exponent);
  s.scale = std::ldexp(1.0, -std::max(-1000, std::min(1000, exponent)));

  // Area and centroid in scaled coordinates relative to point 0 (well conditioned), mapped back.
  const Vec2 o = s.points[0];
  double a2 = 0.0;
  Vec2 c = Vec2::Zero();
  for (int i = 0; i < m; ++i) {
    const Vec2 p = (s.points[i] - o) * s.scale, q = (s.points[s.next(i)] - o) * s.scale;
    const double cr = p.x() * q.y() - p.y() * q.x();
    a2 += cr;
    c += cr * (p + q);
  }
  if (!(std::abs(a2) > 0.0) || !std::isfinite(a2)) throw InputError("section polygon has zero area");
  s.orientation = a2 > 0.0 ? 1 : -1;
  s.area = 0.5 * std::abs(a2) / (s.scale * s.scale);
  s.centroid = o + c / (3.0 * a2) / s.scale;
  if (!s.centroid.allFinite()) s.centroid = o;
  return s;
}

}  // namespace detail

// ============================================================================
// Triangulation
// ============================================================================

// CDT of the polygon; inside faces by flood fill from the infinite face across unconstrained edges.
SectionTriangulation triangulateSection(const Points2& polygon, const std::vector<std::array<int, 2>>& diagonals) {
  const detail::SectionPolygon s = detail::cleanSection(polygon);
  const int m = s.size();

  // Coordinates scaled by a power of two: exact, so every predicate gives the same answer as unscaled.
  std::vector<std::pair<CgalPoint, int>> input;
  input.reserve(m);
  for (int i = 0; i < m; ++i) {
    const Vec2 p = s.points[i] * s.scale;
    input.emplace_back(CgalPoint(p.x(), p.y()), i);
  }
  Cdt cdt;
  try {
    cdt.insert(input.begin(), input.end());
  } catch (const CGAL::Failure_exception& e) {
    throw InputError(std::string("section polygon could not be triangulated: ") + e.what());
  }
  std::vector<Cdt::Vertex_handle> handle(m);
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) handle[v->info()] = v;
  for (int i = 0; i < m; ++i)
    if (handle[i] == Cdt::Vertex_handle())
      throw InputError("section polygon touches itself (point " + std::to_string(s.original[i]) + " is repeated)");

  try {
    for (int i = 0; i < m; ++i) cdt.insert_constraint(handle[i], handle[s.next(i)]);
  } catch (const Cdt::Intersection_of_constraints_exception&) {
    throw InputError("section polygon intersects itself");
  } catch (const CGAL::Failure_exception& e) {  // a CGAL check on degenerate input (checks are on in debug)
    throw InputError(std::string("section polygon could not be triangulated: ") + e.what());
  }
  if (cdt.dimension() != 2) throw InputError("section polygon has zero area (all points collinear)");

  // A simple polygon gives exactly m constrained edges, two at every vertex (a vertex lying on another
  // edge splits that edge and gets four).
  std::vector<int> constrainedAt(m, 0);
  int constrained = 0;
  for (auto e = cdt.finite_edges_begin(); e != cdt.finite_edges_end(); ++e) {
    if (!cdt.is_constrained(*e)) continue;
    ++constrained;
    ++constrainedAt[e->first->vertex(Cdt::cw(e->second))->info()];
    ++constrainedAt[e->first->vertex(Cdt::ccw(e->second))->info()];
  }
  bool simple = constrained == m;
  for (int i = 0; i < m && simple; ++i) simple = constrainedAt[i] == 2;
  if (!simple) throw InputError("section polygon intersects or touches itself");

  // Forced diagonals: proper inner diagonals only (exact predicates), then constrained like the boundary.
  std::vector<std::array<int, 2>> used;  // cleaned indices
  for (const auto& dg : diagonals) {
    if (dg[0] < 0 || dg[1] < 0 || dg[0] >= static_cast<int>(polygon.rows()) || dg[1] >= static_cast<int>(polygon.rows()))
      continue;
    const int i = s.cleanedOf[dg[0]], j = s.cleanedOf[dg[1]];
    if (i == j || s.next(i) == j || s.next(j) == i) continue;
    const CgalPoint pi = handle[i]->point(), pj = handle[j]->point();
    const Kernel::Segment_2 seg(pi, pj);
    bool ok = true;
    // It must enter the polygon's interior at both ends ...
    for (int e : {i, j}) {
      const CgalPoint v = handle[e]->point(), q = e == i ? pj : pi;
      CgalPoint prev = handle[s.prev(e)]->point(), next = handle[s.next(e)]->point();
      if (s.orientation < 0) std::swap(prev, next);
      const bool convex = CGAL::orientation(prev, v, next) == CGAL::LEFT_TURN;
      const bool afterNext = CGAL::orientation(v, next, q) == CGAL::LEFT_TURN;  // left of v -> next
      const bool beforePrev = CGAL::orientation(v, q, prev) == CGAL::LEFT_TURN;  // right of v -> prev
      ok &= convex ? afterNext && beforePrev
                   : !(CGAL::orientation(v, prev, q) != CGAL::RIGHT_TURN && CGAL::orientation(v, q, next) != CGAL::RIGHT_TURN);
    }
    // ... and meet no boundary edge or vertex, nor another forced diagonal, on the way.
    for (int a = 0; a < m && ok; ++a) {
      const int b = s.next(a);
      const CgalPoint pa = handle[a]->point(), pb = handle[b]->point();
      if (a == i || a == j || b == i || b == j) {
        for (int k : {a, b})
          if (k != i && k != j && seg.has_on(handle[k]->point())) ok = false;
      } else if (CGAL::do_intersect(seg, Kernel::Segment_2(pa, pb))) {
        ok = false;
      }
    }
    for (const auto& u : used)
      if (ok && u[0] != i && u[0] != j && u[1] != i && u[1] != j &&
          CGAL::do_intersect(seg, Kernel::Segment_2(handle[u[0]]->point(), handle[u[1]]->point())))
        ok = false;
    if (!ok) continue;
    try {
      cdt.insert_constraint(handle[i], handle[j]);
    } catch (const std::exception&) {
      continue;
    }
    used.push_back({i, j});
  }

  // Outside = reachable from the infinite face without crossing a constraint.
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = 0;
  std::vector<Cdt::Face_handle> stack{cdt.infinite_face()};
  cdt.infinite_face()->info() = 1;
  while (!stack.empty()) {
    const Cdt::Face_handle f = stack.back();
    stack.pop_back();
    for (int k = 0; k < 3; ++k) {
      if (f->is_constrained(k)) continue;
      const Cdt::Face_handle g = f->neighbor(k);
      if (g->info() == 0) {
        g->info() = 1;
        stack.push_back(g);
      }
    }
  }

  SectionTriangulation t;
  t.triangles.resize(m - 2, 3);
  t.kinds.reserve(m - 2);
  int count = 0;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (f->info() != 0) continue;
    if (count == m - 2) throw InputError("section polygon intersects itself (too many inside triangles)");
    int boundary = 0;
    for (int k = 0; k < 3; ++k) {
      const int a = f->vertex(k)->info(), b = f->vertex((k + 1) % 3)->info();
      t.triangles(count, k) = s.original[a];
      boundary += (s.next(a) == b || s.next(b) == a);
    }
    // A lone triangle (a 3-point polygon) has 3 boundary edges; it counts as terminal.
    t.kinds.push_back(static_cast<TriangleKind>(std::min(boundary, 2)));
    ++count;
  }
  if (count != m - 2) throw InputError("section polygon is degenerate (inside triangles do not cover it)");
  for (const auto& u : used) t.diagonals.push_back({s.original[u[0]], s.original[u[1]]});
  {
    // Order by the vertices' distances along the polygon from the first diagonal's first end (else from vertex 0):
    // invariant under the reflection that swaps the split's sides, and the same for a polygon and its mirror image
    // resampled from the same axis point, so mirrored sections merge in the same order.
    const int root = used.empty() ? 0 : used.front()[0];
    auto key = [&](Eigen::Index r) {
      std::array<int, 3> k;
      for (int c = 0; c < 3; ++c) {
        const int v = s.cleanedOf[t.triangles(r, c)];
        k[c] = std::min(s.forward(root, v), s.forward(v, root));
      }
      std::sort(k.begin(), k.end());
      return k;
    };
    std::vector<Eigen::Index> order(m - 2);
    for (int r = 0; r < m - 2; ++r) order[r] = r;
    std::vector<std::array<int, 3>> keys(m - 2);
    for (int r = 0; r < m - 2; ++r) keys[r] = key(r);
    std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return keys[a] < keys[b]; });
    SectionTriangulation sorted;
    sorted.triangles.resize(m - 2, 3);
    for (int r = 0; r < m - 2; ++r) {
      sorted.triangles.row(r) = t.triangles.row(order[r]);
      sorted.kinds.push_back(t.kinds[order[r]]);
    }
    sorted.diagonals = std::move(t.diagonals);
    return sorted;
  }
  return t;
}

}  // namespace myoskin

namespace myoskin {

// ============================================================================
// Mirror axis
// ============================================================================

// The vertices nearest the polygon's crossings of the +y and -y half axes (the crossings nearest the origin).
std::array<int, 2> axisDiagonal(const Points2& polygon) {
  const int n = static_cast<int>(polygon.rows());
  int best[2] = {-1, -1};
  double bestY[2] = {INFINITY, INFINITY};  // |y| of the crossing
  for (int k = 0; k < n; ++k) {
    const int l = (k + 1) % n;
    const double x0 = polygon(k, 0), x1 = polygon(l, 0);
    if (!((x0 <= 0.0 && x1 > 0.0) || (x0 > 0.0 && x1 <= 0.0) || (x0 == 0.0 && x1 == 0.0))) continue;
    const double t = x0 == x1 ? 0.0 : x0 / (x0 - x1);
    const double y = polygon(k, 1) + t * (polygon(l, 1) - polygon(k, 1));
    if (!std::isfinite(y) || y == 0.0) continue;
    const int side = y > 0.0 ? 0 : 1;
    if (std::abs(y) < bestY[side]) bestY[side] = std::abs(y), best[side] = t <= 0.5 ? k : l;
  }
  if (best[0] < 0 || best[1] < 0) return {-1, -1};
  return {best[0], best[1]};
}

}  // namespace myoskin
