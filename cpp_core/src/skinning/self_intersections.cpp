// Self-intersecting triangle pairs of a deformed skin (a quality measure: LBS folds the skin through itself in
// a joint's crease), by CGAL's box-intersection self-intersection test.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Box_intersection_d/Box_with_info_d.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <memory>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace PMP = CGAL::Polygon_mesh_processing;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

// ============================================================================
// SelfIntersectionTest
// ============================================================================

struct SelfIntersectionTest::Impl {
  SurfaceMesh mesh;
  std::vector<int> source;  // mesh vertex -> row of the vertices (the soup's split vertices share their row)
  std::vector<int> faceOf;  // mesh face -> row of the triangles
  Eigen::Index numVertices = 0;
  Eigen::Index numTriangles = 0;
};

SelfIntersectionTest::SelfIntersectionTest(const Triangles& triangles, Eigen::Index numVertices,
                                           const std::vector<char>& faceMask)
    : impl_(std::make_unique<Impl>()) {
  const Eigen::Index nf = triangles.rows(), nv = numVertices;
  if (nv < 0) throw InputError("self intersections: " + std::to_string(nv) + " vertices");
  impl_->numVertices = nv;
  impl_->numTriangles = nf;
  if (!faceMask.empty() && static_cast<Eigen::Index>(faceMask.size()) != nf)
    throw InputError("self intersections: the face mask has " + std::to_string(faceMask.size()) + " entries for " +
                     std::to_string(nf) + " triangles");
  // Only the masked triangles are tested (against each other); the soup is made a mesh with non-manifold
  // vertices split, so neighbours keep sharing their vertices and edges (CGAL does not count those). Orienting is
  // combinatorial: the soup's points carry their vertex rows, read back after the split.
  std::vector<Kernel::Point_3> points;
  std::vector<int> slot(static_cast<size_t>(nv), -1);
  std::vector<std::array<std::size_t, 3>> faces;
  for (Eigen::Index f = 0; f < nf; ++f) {
    if (!faceMask.empty() && !faceMask[f]) continue;
    std::array<std::size_t, 3> face;
    for (int c = 0; c < 3; ++c) {
      const int v = triangles(f, c);
      if (v < 0 || v >= nv) throw InputError("self intersections: triangle " + std::to_string(f) + " uses vertex " +
                                             std::to_string(v) + ", outside 0.." + std::to_string(nv - 1));
      if (slot[v] < 0) {
        slot[v] = static_cast<int>(points.size());
        points.emplace_back(v, 0.0, 0.0);
      }
      face[c] = static_cast<std::size_t>(slot[v]);
    }
    if (face[0] == face[1] || face[1] == face[2] || face[0] == face[2]) continue;  // degenerate by index
    faces.push_back(face);
    impl_->faceOf.push_back(static_cast<int>(f));
  }
  if (faces.empty()) return;
  PMP::orient_polygon_soup(points, faces);
  PMP::polygon_soup_to_polygon_mesh(points, faces, impl_->mesh);
  if (impl_->mesh.number_of_faces() != faces.size())  // faceOf maps the soup's faces in order
    throw InputError("self intersections: the oriented soup did not become a mesh of its " +
                     std::to_string(faces.size()) + " triangles");
  impl_->source.resize(impl_->mesh.number_of_vertices());
  for (const SurfaceMesh::Vertex_index v : impl_->mesh.vertices())
    impl_->source[v.idx()] = static_cast<int>(impl_->mesh.point(v).x());
}

SelfIntersectionTest::~SelfIntersectionTest() = default;

namespace {

using FacePair = std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>;

// The mesh's face pairs as rows of the triangles, (smaller, larger), sorted.
std::vector<std::pair<int, int>> asRows(const std::vector<FacePair>& found, const std::vector<int>& faceOf) {
  std::vector<std::pair<int, int>> out;
  out.reserve(found.size());
  for (const auto& [a, b] : found) {  // the mesh's faces are the soup's, in order
    const int fa = faceOf[static_cast<size_t>(a.idx())], fb = faceOf[static_cast<size_t>(b.idx())];
    out.emplace_back(std::min(fa, fb), std::max(fa, fb));
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Calls visit(a, b) once for every pair of boxes that overlap (closed: touching counts, as CGAL's box intersection)
// with a in `focus` and b in `focus` (a before b) or in `others`. A uniform grid of cells three times the focus boxes'
// median extent: each box is listed in the cells it overlaps (one spanning more than kMaxCellsAcross in a direction is
// tested against every box), and a pair is visited in the one cell holding the largest of its lower corners. False
// (nothing visited) when the bounds are too large for the grid's arithmetic (coordinates near the double range).
template <class Box, class Visit>
bool forOverlappingBoxes(const std::vector<Box>& focus, const std::vector<Box>& others, const CGAL::Bbox_3& bounds,
                         Visit&& visit) {
  if (focus.empty()) return true;
  constexpr int kMaxCellsAcross = 4;
  constexpr double kCellsPerAxisMax = 1 << 20;  // cell coordinates fit in 21 bits
  std::vector<double> extents;
  extents.reserve(focus.size());
  for (const Box& b : focus)
    extents.push_back(std::max({b.max_coord(0) - b.min_coord(0), b.max_coord(1) - b.min_coord(1),
                                b.max_coord(2) - b.min_coord(2)}));
  std::nth_element(extents.begin(), extents.begin() + static_cast<std::ptrdiff_t>(extents.size() / 2), extents.end());
  double cell = 3.0 * extents[extents.size() / 2];
  for (int d = 0; d < 3; ++d) cell = std::max(cell, (bounds.max(d) - bounds.min(d)) / (kCellsPerAxisMax - 2.0));
  if (!std::isfinite(cell)) return false;
  if (!(cell > 0.0)) cell = 1.0;  // every focus box a point at one place: one cell
  auto overlap = [](const Box& a, const Box& b) {
    for (int d = 0; d < 3; ++d)
      if (a.min_coord(d) > b.max_coord(d) || b.min_coord(d) > a.max_coord(d)) return false;
    return true;
  };
  auto cellOf = [&](double x, int d) {  // clamped to the focus bounds' cells (every overlap lies inside them)
    const double c = std::floor((std::clamp(x, bounds.min(d), bounds.max(d)) - bounds.min(d)) / cell);
    return c > 0.0 ? static_cast<uint64_t>(std::min(c, kCellsPerAxisMax - 1.0)) : uint64_t{0};
  };
  auto key = [](uint64_t i, uint64_t j, uint64_t k) { return (i << 42) | (j << 21) | k; };
  // (cell key, box): focus boxes numbered 0..F-1, the others F.. ; big boxes aside.
  const size_t nf = focus.size();
  auto boxAt = [&](size_t i) -> const Box& { return i < nf ? focus[i] : others[i - nf]; };
  std::vector<std::pair<uint64_t, uint32_t>> entries;
  std::vector<size_t> big;
  entries.reserve(4 * (nf + others.size()));
  for (size_t i = 0; i < nf + others.size(); ++i) {
    const Box& b = boxAt(i);
    if (i >= nf && !CGAL::do_overlap(b.bbox(), bounds)) continue;
    uint64_t lo[3], hi[3];
    bool isBig = false;
    for (int d = 0; d < 3; ++d) {
      lo[d] = cellOf(b.min_coord(d), d);
      hi[d] = cellOf(b.max_coord(d), d);
      isBig = isBig || hi[d] - lo[d] >= static_cast<uint64_t>(kMaxCellsAcross);
    }
    if (isBig) {
      big.push_back(i);
      continue;
    }
    for (uint64_t x = lo[0]; x <= hi[0]; ++x)
      for (uint64_t y = lo[1]; y <= hi[1]; ++y)
        for (uint64_t z = lo[2]; z <= hi[2]; ++z) entries.emplace_back(key(x, y, z), static_cast<uint32_t>(i));
  }
  std::sort(entries.begin(), entries.end());
  auto visitPair = [&](size_t i, size_t j) {  // i < j in numbering; at least one in the focus
    const Box &a = boxAt(i), &b = boxAt(j);
    if (overlap(a, b)) visit(a, b);
  };
  for (size_t first = 0; first < entries.size();) {
    size_t last = first;
    while (last < entries.size() && entries[last].first == entries[first].first) ++last;
    const uint64_t here = entries[first].first;
    for (size_t p = first; p < last; ++p) {
      const size_t i = entries[p].second;
      if (i >= nf) break;  // sorted: the focus boxes come first in a cell
      for (size_t q = p + 1; q < last; ++q) {
        const size_t j = entries[q].second;
        const Box &a = boxAt(i), &b = boxAt(j);
        if (!overlap(a, b)) continue;
        if (key(cellOf(std::max(a.min_coord(0), b.min_coord(0)), 0), cellOf(std::max(a.min_coord(1), b.min_coord(1)), 1),
                cellOf(std::max(a.min_coord(2), b.min_coord(2)), 2)) == here)
          visit(a, b);
      }
    }
    first = last;
  }
  // Big boxes against every box (each pair once: a big box meets the small ones, and the big ones after it).
  std::vector<char> isBig(nf + others.size(), 0);
  for (size_t i : big) isBig[i] = 1;
  for (size_t i : big)
    for (size_t j = 0; j < nf + others.size(); ++j) {
      if (j == i || (isBig[j] && j < i) || (i >= nf && j >= nf)) continue;
      if (j >= nf && !CGAL::do_overlap(boxAt(j).bbox(), bounds)) continue;
      visitPair(std::min(i, j), std::max(i, j));
    }
  return true;
}

}  // namespace

void SelfIntersectionTest::movePoints(const Points& vertices) {
  if (vertices.rows() != impl_->numVertices)
    throw InputError("self intersections: " + std::to_string(vertices.rows()) + " vertices for a test made for " +
                     std::to_string(impl_->numVertices));
  if (!vertices.allFinite()) throw InputError("self intersections: the vertices are not all finite");
  SurfaceMesh& mesh = impl_->mesh;
  for (const SurfaceMesh::Vertex_index v : mesh.vertices()) {
    const int r = impl_->source[v.idx()];
    mesh.point(v) = Kernel::Point_3(vertices(r, 0), vertices(r, 1), vertices(r, 2));
  }
}

std::vector<std::pair<int, int>> SelfIntersectionTest::pairs(const Points& vertices) {
  movePoints(vertices);
  SurfaceMesh& mesh = impl_->mesh;
  if (mesh.number_of_faces() == 0) return {};
  std::vector<FacePair> found;
  PMP::self_intersections(mesh, std::back_inserter(found));
  return asRows(found, impl_->faceOf);
}

std::vector<std::pair<int, int>> SelfIntersectionTest::pairs(const Points& vertices, const std::vector<char>& focus) {
  if (static_cast<Eigen::Index>(focus.size()) != impl_->numTriangles)
    throw InputError("self intersections: the focus has " + std::to_string(focus.size()) + " entries for " +
                     std::to_string(impl_->numTriangles) + " triangles");
  movePoints(vertices);
  const SurfaceMesh& mesh = impl_->mesh;
  std::vector<FacePair> found;
  // PMP::self_intersections' test (a box per face, CGAL's strict face test: neighbours sharing a vertex or an edge
  // intersect only past it; a collinear face is a pair with itself), with the focus faces' boxes intersected among
  // themselves and with the others' (those outside the focus boxes' bounds cannot meet them).
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, SurfaceMesh::Face_index,
                                                         CGAL::Box_intersection_d::ID_FROM_BOX_ADDRESS>;
  std::vector<Box> focusBoxes, otherBoxes;
  CGAL::Bbox_3 bounds;
  for (const SurfaceMesh::Face_index f : mesh.faces()) {
    const auto h = mesh.halfedge(f);
    const Kernel::Point_3 &p = mesh.point(mesh.target(h)), &q = mesh.point(mesh.target(mesh.next(h))),
                          &r = mesh.point(mesh.target(mesh.prev(h)));
    const bool inFocus = focus[static_cast<size_t>(impl_->faceOf[f.idx()])] != 0;
    if (inFocus && CGAL::collinear(p, q, r)) {
      found.emplace_back(f, f);
      continue;
    }
    if (!inFocus && CGAL::collinear(p, q, r)) continue;
    const CGAL::Bbox_3 box = p.bbox() + q.bbox() + r.bbox();
    if (inFocus) {
      focusBoxes.emplace_back(box, f);
      bounds += box;
    } else {
      otherBoxes.emplace_back(box, f);
    }
  }
  // CGAL's own face test (internal, the same functor and signature in CGAL 5.5 and 6.0, the two Debian releases built).
  const PMP::internal::Strict_intersect_faces<Box, SurfaceMesh, SurfaceMesh::Property_map<SurfaceMesh::Vertex_index,
                                                                                         Kernel::Point_3>,
                                              Kernel, std::back_insert_iterator<std::vector<FacePair>>>
      test(mesh, mesh.points(), Kernel(), std::back_inserter(found));
  if (!forOverlappingBoxes(focusBoxes, otherBoxes, bounds, [&](const Box& a, const Box& b) { test(&a, &b); })) {
    std::vector<std::pair<int, int>> all = pairs(vertices), kept;  // coordinates past the grid: the whole test
    for (const auto& pr : all)
      if (focus[static_cast<size_t>(pr.first)] || focus[static_cast<size_t>(pr.second)]) kept.push_back(pr);
    return kept;
  }
  return asRows(found, impl_->faceOf);
}

std::vector<std::pair<int, int>> selfIntersectingPairs(const Points& vertices, const Triangles& triangles,
                                                       const std::vector<char>& faceMask) {
  if (!vertices.allFinite()) throw InputError("self intersections: the vertices are not all finite");
  return SelfIntersectionTest(triangles, vertices.rows(), faceMask).pairs(vertices);
}

int selfIntersections(const Points& vertices, const Triangles& triangles, const std::vector<char>& faceMask) {
  return static_cast<int>(selfIntersectingPairs(vertices, triangles, faceMask).size());
}

}  // namespace myoskin
