// Self-intersecting triangle pairs of a deformed skin (a quality measure: LBS folds the skin through itself in
// a joint's crease), by CGAL's box-intersection self-intersection test.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
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
};

SelfIntersectionTest::SelfIntersectionTest(const Triangles& triangles, Eigen::Index numVertices,
                                           const std::vector<char>& faceMask)
    : impl_(std::make_unique<Impl>()) {
  const Eigen::Index nf = triangles.rows(), nv = numVertices;
  if (nv < 0) throw InputError("self intersections: " + std::to_string(nv) + " vertices");
  impl_->numVertices = nv;
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

std::vector<std::pair<int, int>> SelfIntersectionTest::pairs(const Points& vertices) {
  if (vertices.rows() != impl_->numVertices)
    throw InputError("self intersections: " + std::to_string(vertices.rows()) + " vertices for a test made for " +
                     std::to_string(impl_->numVertices));
  if (!vertices.allFinite()) throw InputError("self intersections: the vertices are not all finite");
  std::vector<std::pair<int, int>> out;
  SurfaceMesh& mesh = impl_->mesh;
  if (mesh.number_of_faces() == 0) return out;
  for (const SurfaceMesh::Vertex_index v : mesh.vertices()) {
    const int r = impl_->source[v.idx()];
    mesh.point(v) = Kernel::Point_3(vertices(r, 0), vertices(r, 1), vertices(r, 2));
  }
  std::vector<std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>> found;
  PMP::self_intersections(mesh, std::back_inserter(found));
  out.reserve(found.size());
  for (const auto& [a, b] : found) {  // the mesh's faces are the soup's, in order
    const int fa = impl_->faceOf[static_cast<size_t>(a.idx())], fb = impl_->faceOf[static_cast<size_t>(b.idx())];
    out.emplace_back(std::min(fa, fb), std::max(fa, fb));
  }
  std::sort(out.begin(), out.end());
  return out;
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
