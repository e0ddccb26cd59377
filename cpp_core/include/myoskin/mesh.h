// Triangle mesh and the checks every pipeline stage relies on (finite, closed, manifold).
#pragma once
#include <string>
#include <vector>

#include "myoskin/types.h"

namespace myoskin {

// A triangle mesh in metres. vertices: #V by 3, triangles: #F by 3 (0-based, counter-clockwise = outward).
struct Mesh {
  Points vertices;
  Triangles triangles;

  int numVertices() const { return static_cast<int>(vertices.rows()); }
  int numTriangles() const { return static_cast<int>(triangles.rows()); }
};

// What analyzeTopology found. A skin for extraction needs closed() && manifold().
struct TopologyReport {
  int boundaryEdges = 0;      // edges used by exactly one triangle
  int nonManifoldEdges = 0;   // edges used by three or more triangles
  int inconsistentEdges = 0;  // edges whose two triangles traverse them in the same direction
  int components = 0;         // connected components over triangles
  int degenerateTriangles = 0;  // triangles with a repeated vertex index
  bool closed() const { return boundaryEdges == 0; }
  bool manifold() const { return nonManifoldEdges == 0 && degenerateTriangles == 0; }
  bool oriented() const { return inconsistentEdges == 0; }
};

// Throws InputError if the mesh is empty, has a NaN/inf coordinate, or an index out of range.
void validateMesh(const Mesh& mesh, const std::string& what = "mesh");

// Edge-based topology statistics of a mesh (indices must be valid).
TopologyReport analyzeTopology(const Mesh& mesh);

// Merge vertices closer than `tolerance` (metres). Returns the welded mesh; weldMap (size #V of the
// input) receives for each input vertex its welded index. Triangles that collapse are dropped.
Mesh weldByPosition(const Mesh& mesh, double tolerance, std::vector<int>& weldMap);

// Axis-aligned bounds; min and max are 3-vectors. Mesh must be non-empty.
void boundingBox(const Points& points, Vec3& min, Vec3& max);

// The points' largest extent along their principal axes (the range of their projections on each eigenvector of
// their covariance, the largest of the three): a body's height or span, independent of how it is rotated or placed.
// Points must be non-empty.
double principalExtent(const Points& points);

// Signed enclosed volume (divergence theorem); positive for a closed outward-oriented mesh.
double enclosedVolume(const Points& vertices, const Triangles& triangles);

}  // namespace myoskin
