// A bounding volume hierarchy over one closed triangle mesh whose topology is fixed (a muscle surface): built
// once on the rest surface, refitted per frame without allocation; closest point, signed by the angle-weighted
// pseudo-normal of the closest feature (Baerentzen & Aanaes 2005: exact on closed, oriented, manifold meshes that
// do not cross themselves), or, for a surface that crosses itself (setSelfCrossing: extracted pectorals and
// quadriceps do at rest), by ray parity (the majority of three rays in fixed, skew directions), which stays defined.
#pragma once
#include <Eigen/Geometry>
#include <vector>

#include "myoskin/types.h"

namespace myoskin::detail {

// What a closest-point query found.
struct SurfaceHit {
  Vec3 point = Vec3::Zero();   // closest point on the surface
  Vec3 normal = Vec3::Zero();  // pseudo-normal of the closest feature (unit, outward)
  double distance = 0.0;       // signed: negative inside
  int face = -1;               // the triangle the closest point lies on
};

class TriangleBvh {
 public:
  // Topology (node tree from the rest positions, face-edge adjacency). Mesh must be closed and manifold
  // (checked by the caller). Allocates.
  void build(const Points& vertices, const Triangles& triangles);
  // New vertex positions, same count: boxes, face, edge and vertex pseudo-normals. No allocation.
  void refit(const Points& vertices);
  // Closest surface point to p (any distance), signed (pseudo-normal, or ray parity when self-crossing). hint: a
  // triangle likely near p (e.g. the last answer for a point that moved a little), tried first to prune the
  // search; the answer does not depend on it. No allocation.
  SurfaceHit closest(const Vec3& p, int hint = -1) const;
  // Whether p lies inside: an odd number of crossings along at least two of three rays. No allocation.
  bool inside(const Vec3& p) const;
  // Sign closest() by ray parity instead of the pseudo-normal.
  void setSelfCrossing(bool on) { selfCrossing_ = on; }
  bool selfCrossing() const { return selfCrossing_; }
  // Bounds of the surface as last refitted.
  const Eigen::AlignedBox3d& bounds() const { return nodes_.front().box; }
  int numTriangles() const { return static_cast<int>(tri_.rows()); }

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    int first = 0;   // leaf: first slot in order_; inner: left child (right = left + 1... see build)
    int count = 0;   // leaf: triangles; inner: 0
    int right = -1;  // inner: right child
  };
  int crossings(const Vec3& p, const Vec3& dir) const;
  int buildNode(std::vector<int>& order, int begin, int end, const std::vector<Vec3>& centroid);

  bool selfCrossing_ = false;
  Triangles tri_;
  std::vector<Node> nodes_;
  std::vector<int> order_;           // triangles in leaf order
  std::vector<int> neighbour_;       // 3 per face: the face across local edge k (vertices k, k+1)
  Points v_;                         // current positions
  std::vector<Vec3> faceNormal_;     // unit
  std::vector<Vec3> vertexNormal_;   // angle-weighted
};

}  // namespace myoskin::detail
