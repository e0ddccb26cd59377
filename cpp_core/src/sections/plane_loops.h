// Plane-mesh intersection into closed loops (internal to the sections stage).
#pragma once
#include <array>
#include <vector>

#include "myoskin/mesh.h"

namespace myoskin::detail {

// One intersection curve: points where the plane crosses mesh edges, in order along the curve.
struct PlaneLoop {
  std::vector<Vec3> points;              // #L crossing points
  std::vector<std::array<int, 2>> edges;  // #L mesh edges (vertex pairs) the points lie on
  bool closed = true;                    // false when the curve runs into a mesh boundary
};

// The curves where the plane (origin, unit normal) cuts the mesh. Vertices exactly on the plane count as
// above it, so every crossing is inside an edge. `distanceScratch` is reused (#V signed distances).
std::vector<PlaneLoop> planeLoops(const Mesh& mesh, const Vec3& origin, const Vec3& normal,
                                  std::vector<double>& distanceScratch);

}  // namespace myoskin::detail
