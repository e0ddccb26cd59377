// Self-intersecting triangle pairs of a deformed skin (a quality measure: LBS folds the skin through itself in
// a joint's crease), by CGAL's box-intersection self-intersection test.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <array>
#include <iterator>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace PMP = CGAL::Polygon_mesh_processing;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

int selfIntersections(const Points& vertices, const Triangles& triangles, const std::vector<char>& faceMask) {
  const Eigen::Index nf = triangles.rows(), nv = vertices.rows();
  if (!faceMask.empty() && static_cast<Eigen::Index>(faceMask.size()) != nf)
    throw InputError("self intersections: the face mask has " + std::to_string(faceMask.size()) + " entries for " +
                     std::to_string(nf) + " triangles");
  if (!vertices.allFinite()) throw InputError("self intersections: the vertices are not all finite");
  // Only the masked triangles are tested (against each other); the soup is made a mesh with non-manifold
  // vertices split, so neighbours keep sharing their vertices and edges (CGAL does not count those).
  std::vector<Kernel::Point_3> points;
  std::vector<int> slot(nv, -1);
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
        points.emplace_back(vertices(v, 0), vertices(v, 1), vertices(v, 2));
      }
      face[c] = static_cast<std::size_t>(slot[v]);
    }
    if (face[0] == face[1] || face[1] == face[2] || face[0] == face[2]) continue;  // degenerate by index
    faces.push_back(face);
  }
  if (faces.empty()) return 0;
  PMP::orient_polygon_soup(points, faces);
  SurfaceMesh mesh;
  PMP::polygon_soup_to_polygon_mesh(points, faces, mesh);
  std::vector<std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>> pairs;
  PMP::self_intersections(mesh, std::back_inserter(pairs));
  return static_cast<int>(pairs.size());
}

}  // namespace myoskin
