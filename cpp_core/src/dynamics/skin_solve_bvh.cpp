// Triangle BVH with refit and signed closest-point queries (skin_solve_bvh.h).
#include "dynamics/skin_solve_bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

namespace myoskin::detail {

namespace {

constexpr int kLeafSize = 4;
constexpr int kMaxStack = 128;

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5) and its feature:
// 0, 1, 2 = vertex a, b, c; 3, 4, 5 = edge ab, bc, ca; 6 = the face.
Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, int& feature) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) { feature = 0; return a; }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) { feature = 1; return b; }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    feature = 3;
    const double den = d1 - d3;
    return den > 0 ? Vec3(a + (d1 / den) * ab) : a;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) { feature = 2; return c; }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    feature = 5;
    const double den = d2 - d6;
    return den > 0 ? Vec3(a + (d2 / den) * ac) : a;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    feature = 4;
    const double den = (d4 - d3) + (d5 - d6);
    return den > 0 ? Vec3(b + ((d4 - d3) / den) * (c - b)) : b;
  }
  const double sum = va + vb + vc;
  if (!(sum > 0)) {  // degenerate triangle: nearest of its vertices
    feature = 0;
    return a;
  }
  feature = 6;
  const double v = vb / sum, w = vc / sum;
  return a + ab * v + ac * w;
}

// atan2(y, x) for y >= 0 (an angle in [0, pi]) by a minimax polynomial, error under 1e-5 rad: the corner angles
// of the vertex pseudo-normals, a quarter of the cost of std::atan2.
double cornerAngle(double y, double x) {
  const double ax = std::abs(x);
  const bool swap = y > ax;
  const double t = swap ? (y > 0 ? ax / y : 0.0) : (ax > 0 ? y / ax : 0.0);
  const double t2 = t * t;
  double a = t * (0.99997726 + t2 * (-0.33262347 + t2 * (0.19354346 + t2 * (-0.11643287 + t2 * (0.05265332 +
                                                                                             t2 * -0.01172120)))));
  if (swap) a = 1.5707963267948966 - a;
  return x < 0 ? 3.141592653589793 - a : a;
}

double boxDistance2(const Eigen::AlignedBox3d& box, const Vec3& p) {
  return (p - p.cwiseMax(box.min()).cwiseMin(box.max())).squaredNorm();
}

}  // namespace

// ============================================================================
// Build
// ============================================================================

// Recursive median split of order[begin, end) on the largest axis of the centroids' bounds.
int TriangleBvh::buildNode(std::vector<int>& order, int begin, int end, const std::vector<Vec3>& centroid) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  if (end - begin <= kLeafSize) {
    nodes_[index].first = begin;
    nodes_[index].count = end - begin;
    return index;
  }
  Eigen::AlignedBox3d cb;
  for (int i = begin; i < end; ++i) cb.extend(centroid[order[i]]);
  int axis = 0;
  cb.sizes().maxCoeff(&axis);
  const int mid = (begin + end) / 2;
  std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                   [&](int a, int b) { return centroid[a][axis] < centroid[b][axis]; });
  const int left = buildNode(order, begin, mid, centroid);
  const int right = buildNode(order, mid, end, centroid);
  nodes_[index].first = left;
  nodes_[index].count = 0;
  nodes_[index].right = right;
  return index;
}

void TriangleBvh::build(const Points& vertices, const Triangles& triangles) {
  tri_ = triangles;
  const int nf = static_cast<int>(triangles.rows());
  std::vector<Vec3> centroid(nf);
  for (int f = 0; f < nf; ++f)
    centroid[f] = (vertices.row(tri_(f, 0)) + vertices.row(tri_(f, 1)) + vertices.row(tri_(f, 2))).transpose() / 3.0;
  order_.resize(nf);
  for (int f = 0; f < nf; ++f) order_[f] = f;
  nodes_.clear();
  nodes_.reserve(2 * nf / kLeafSize + 8);
  buildNode(order_, 0, nf, centroid);
  // Face across each edge (closed manifold: exactly one, traversed the other way).
  std::map<std::pair<int, int>, int> edgeFace;
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) edgeFace[{tri_(f, k), tri_(f, (k + 1) % 3)}] = f;
  neighbour_.assign(3 * static_cast<size_t>(nf), -1);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const auto it = edgeFace.find({tri_(f, (k + 1) % 3), tri_(f, k)});
      neighbour_[3 * f + k] = it == edgeFace.end() ? f : it->second;
    }
  faceNormal_.resize(nf);
  vertexNormal_.resize(vertices.rows());
  v_.resize(vertices.rows(), 3);
  refit(vertices);
}

// ============================================================================
// Refit (per frame)
// ============================================================================

void TriangleBvh::refit(const Points& vertices) {
  v_ = vertices;  // same size: no allocation
  const int nf = static_cast<int>(tri_.rows());
  for (auto& n : vertexNormal_) n.setZero();
  for (int f = 0; f < nf; ++f) {
    const int i[3] = {tri_(f, 0), tri_(f, 1), tri_(f, 2)};
    const Vec3 p[3] = {v_.row(i[0]).transpose(), v_.row(i[1]).transpose(), v_.row(i[2]).transpose()};
    const Vec3 n = (p[1] - p[0]).cross(p[2] - p[0]);
    const double len = n.norm();
    faceNormal_[f] = len > 0 ? Vec3(n / len) : Vec3::Zero();
    for (int k = 0; k < 3; ++k) {  // angle at corner k
      const Vec3 e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
      const double angle = cornerAngle(e1.cross(e2).norm(), e1.dot(e2));
      vertexNormal_[i[k]] += angle * faceNormal_[f];
    }
  }
  // Children come after their parent: refit from the back.
  for (int n = static_cast<int>(nodes_.size()) - 1; n >= 0; --n) {
    Node& node = nodes_[n];
    node.box.setEmpty();
    if (node.count > 0) {
      for (int s = node.first; s < node.first + node.count; ++s)
        for (int k = 0; k < 3; ++k) node.box.extend(v_.row(tri_(order_[s], k)).transpose());
    } else {
      node.box.extend(nodes_[node.first].box);
      node.box.extend(nodes_[node.right].box);
    }
  }
}

// ============================================================================
// Query
// ============================================================================

SurfaceHit TriangleBvh::closest(const Vec3& p, int hint) const {
  double best = std::numeric_limits<double>::infinity();
  int bestFace = -1, bestFeature = 6;
  Vec3 bestPoint = Vec3::Zero();
  if (hint >= 0 && hint < tri_.rows()) {
    bestPoint = closestOnTriangle(p, v_.row(tri_(hint, 0)).transpose(), v_.row(tri_(hint, 1)).transpose(),
                                  v_.row(tri_(hint, 2)).transpose(), bestFeature);
    best = (bestPoint - p).squaredNorm();
    bestFace = hint;
  }
  int stack[kMaxStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (boxDistance2(node.box, p) >= best) continue;
    if (node.count > 0) {
      for (int s = node.first; s < node.first + node.count; ++s) {
        const int f = order_[s];
        int feature = 6;
        const Vec3 q = closestOnTriangle(p, v_.row(tri_(f, 0)).transpose(), v_.row(tri_(f, 1)).transpose(),
                                         v_.row(tri_(f, 2)).transpose(), feature);
        const double d2 = (q - p).squaredNorm();
        if (d2 < best) {
          best = d2;
          bestFace = f;
          bestFeature = feature;
          bestPoint = q;
        }
      }
      continue;
    }
    // Nearer child last (popped first).
    const int a = node.first, b = node.right;
    const double da = boxDistance2(nodes_[a].box, p), db = boxDistance2(nodes_[b].box, p);
    if (top + 2 > kMaxStack) {  // cannot happen for a median-split tree under 2^60 triangles; stay safe
      stack[top++] = da < db ? a : b;
      continue;
    }
    if (da < db) {
      stack[top++] = b;
      stack[top++] = a;
    } else {
      stack[top++] = a;
      stack[top++] = b;
    }
  }
  SurfaceHit hit;
  if (bestFace < 0) return hit;
  Vec3 normal;
  if (bestFeature == 6) {
    normal = faceNormal_[bestFace];
  } else if (bestFeature < 3) {
    normal = vertexNormal_[tri_(bestFace, bestFeature)];
  } else {
    const int k = bestFeature - 3;
    normal = faceNormal_[bestFace] + faceNormal_[neighbour_[3 * bestFace + k]];
  }
  const double nn = normal.norm();
  hit.normal = nn > 0 ? Vec3(normal / nn) : Vec3::Zero();
  hit.point = bestPoint;
  hit.face = bestFace;
  const double d = std::sqrt(best);
  const bool in = selfCrossing_ ? inside(p) : (p - bestPoint).dot(hit.normal) < 0.0;
  hit.distance = in ? -d : d;
  return hit;
}

// Triangles crossed by the ray p + t dir, t > 0 (Moeller-Trumbore).
int TriangleBvh::crossings(const Vec3& p, const Vec3& dir) const {
  const Vec3 inv = dir.cwiseInverse();
  int count = 0;
  int stack[kMaxStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    // Slab test (dir has no zero component).
    const Vec3 t0 = (node.box.min() - p).cwiseProduct(inv), t1 = (node.box.max() - p).cwiseProduct(inv);
    const double tmin = t0.cwiseMin(t1).maxCoeff(), tmax = t0.cwiseMax(t1).minCoeff();
    if (tmax < 0 || tmin > tmax) continue;
    if (node.count == 0) {
      if (top + 2 <= kMaxStack) {
        stack[top++] = node.first;
        stack[top++] = node.right;
      }
      continue;
    }
    for (int s = node.first; s < node.first + node.count; ++s) {
      const int f = order_[s];
      const Vec3 a = v_.row(tri_(f, 0)).transpose();
      const Vec3 e1 = v_.row(tri_(f, 1)).transpose() - a, e2 = v_.row(tri_(f, 2)).transpose() - a;
      const Vec3 h = dir.cross(e2);
      const double det = e1.dot(h);
      if (det == 0.0) continue;
      const double invDet = 1.0 / det;
      const Vec3 q = p - a;
      const double u = q.dot(h) * invDet;
      if (u < 0.0 || u > 1.0) continue;
      const Vec3 qe = q.cross(e1);
      const double v = dir.dot(qe) * invDet;
      if (v < 0.0 || u + v > 1.0) continue;
      if (e2.dot(qe) * invDet > 0.0) ++count;
    }
  }
  return count;
}

bool TriangleBvh::inside(const Vec3& p) const {
  if (!bounds().contains(p)) return false;
  static const Vec3 dirs[3] = {Vec3(1.0, 0.3141592, 0.2718281).normalized(),
                               Vec3(-0.2718281, 1.0, 0.1414213).normalized(),
                               Vec3(0.1732050, -0.3141592, 1.0).normalized()};
  const int a = crossings(p, dirs[0]) % 2, b = crossings(p, dirs[1]) % 2;
  return a == b ? a == 1 : crossings(p, dirs[2]) % 2 == 1;
}

}  // namespace myoskin::detail
