// Inside/outside the skin: the generalized winding number of the skin's triangles, summed over a bounding-volume
// tree whose far clusters count as one dipole (Barill et al. 2018, "Fast Winding Numbers for Soups and Clouds",
// first order), plus the unsigned distance to the nearest triangle over the same tree.
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/muscle_shape.h"

namespace myoskin {

namespace {

constexpr int kLeafSize = 8;
constexpr double kFarFactor = 5.0;  // a cluster counts as one dipole beyond this times its radius (error ~ its square)
constexpr int kMaxDepth = 64;

// Closest point on triangle (a, b, c) to p (Ericson, Real-Time Collision Detection 5.1.5).
Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace

struct SkinWinding::Impl {
  struct Node {
    Vec3 lo, hi;            // bounding box
    Vec3 center;            // area-weighted centroid of its triangles
    Vec3 areaNormal;        // sum of its triangles' area vectors
    double radius = 0.0;    // farthest triangle corner from center
    int left = -1, right = -1;
    int first = 0, count = 0;  // triangle range in order (leaves)
  };
  std::vector<std::array<Vec3, 3>> tris;  // in tree order
  std::vector<Node> nodes;

  int build(std::vector<int>& ids, const std::vector<Vec3>& centroids, const std::vector<std::array<Vec3, 3>>& in,
            int first, int count, int depth) {
    Node node;
    node.lo = Vec3::Constant(INFINITY), node.hi = Vec3::Constant(-INFINITY);
    node.areaNormal.setZero();
    Vec3 weighted = Vec3::Zero(), mean = Vec3::Zero();
    double area = 0.0;
    for (int i = first; i < first + count; ++i) {
      const auto& t = in[ids[i]];
      for (const Vec3& v : t) node.lo = node.lo.cwiseMin(v), node.hi = node.hi.cwiseMax(v);
      const Vec3 an = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]);
      node.areaNormal += an;
      weighted += an.norm() * centroids[ids[i]];
      area += an.norm();
      mean += centroids[ids[i]];
    }
    node.center = area > 0 ? Vec3(weighted / area) : Vec3(mean / count);
    for (int i = first; i < first + count; ++i)
      for (const Vec3& v : in[ids[i]]) node.radius = std::max(node.radius, (v - node.center).norm());
    const int index = static_cast<int>(nodes.size());
    nodes.push_back(node);
    if (count <= kLeafSize || depth >= kMaxDepth - 2) {
      nodes[index].first = static_cast<int>(tris.size());
      nodes[index].count = count;
      for (int i = first; i < first + count; ++i) tris.push_back(in[ids[i]]);
      return index;
    }
    int axis = 0;
    (node.hi - node.lo).maxCoeff(&axis);
    const int half = count / 2;
    std::nth_element(ids.begin() + first, ids.begin() + first + half, ids.begin() + first + count,
                     [&](int x, int y) { return centroids[x][axis] < centroids[y][axis]; });
    const int left = build(ids, centroids, in, first, half, depth + 1);
    const int right = build(ids, centroids, in, first + half, count - half, depth + 1);
    nodes[index].left = left, nodes[index].right = right;
    return index;
  }
};

SkinWinding::SkinWinding(const Points& vertices, const Triangles& triangles) {
  if (triangles.rows() == 0 || vertices.rows() == 0) throw InputError("skin winding: the skin has no triangles");
  if (!vertices.allFinite()) throw InputError("skin winding: the skin's vertices are not all finite");
  auto impl = std::make_shared<Impl>();
  std::vector<std::array<Vec3, 3>> in;
  std::vector<Vec3> centroids;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    std::array<Vec3, 3> t;
    for (int c = 0; c < 3; ++c) {
      const int v = triangles(f, c);
      if (v < 0 || v >= vertices.rows())
        throw InputError("skin winding: triangle " + std::to_string(f) + " uses vertex " + std::to_string(v) +
                         ", outside 0.." + std::to_string(vertices.rows() - 1));
      t[c] = vertices.row(v).transpose();
    }
    in.push_back(t);
    centroids.push_back((t[0] + t[1] + t[2]) / 3.0);
  }
  std::vector<int> ids(in.size());
  std::iota(ids.begin(), ids.end(), 0);
  impl->nodes.reserve(4 * in.size() / kLeafSize + 8);
  impl->build(ids, centroids, in, 0, static_cast<int>(in.size()), 0);
  impl_ = impl;
}

double SkinWinding::windingNumber(const Vec3& q) const {
  const Impl& im = *impl_;
  std::array<int, 2 * kMaxDepth + 2> stack;
  int top = 0;
  stack[top++] = 0;
  double omega = 0.0;  // solid angle
  while (top > 0) {
    const Impl::Node& n = im.nodes[stack[--top]];
    const Vec3 d = n.center - q;
    const double dist = d.norm();
    if (dist > kFarFactor * n.radius) {
      omega += n.areaNormal.dot(d) / (dist * dist * dist);
      continue;
    }
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i) {  // exact (Van Oosterom and Strackee 1983)
        const Vec3 a = im.tris[i][0] - q, b = im.tris[i][1] - q, c = im.tris[i][2] - q;
        const double la = a.norm(), lb = b.norm(), lc = c.norm();
        const double det = a.dot(b.cross(c));
        const double div = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
        omega += 2.0 * std::atan2(det, div);
      }
      continue;
    }
    stack[top++] = n.left;
    stack[top++] = n.right;
  }
  return omega / (4.0 * kPi);
}

double SkinWinding::distance(const Vec3& q) const {
  const Impl& im = *impl_;
  auto boxDistance = [&](const Impl::Node& n) {
    const Vec3 e = (n.lo - q).cwiseMax(q - n.hi).cwiseMax(Vec3::Zero());
    return e.norm();
  };
  std::array<int, 2 * kMaxDepth + 2> stack;
  int top = 0;
  stack[top++] = 0;
  double best = INFINITY;
  while (top > 0) {
    const Impl::Node& n = im.nodes[stack[--top]];
    if (boxDistance(n) >= best) continue;
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i)
        best = std::min(best, (closestOnTriangle(q, im.tris[i][0], im.tris[i][1], im.tris[i][2]) - q).norm());
      continue;
    }
    const Impl::Node& l = im.nodes[n.left];
    const Impl::Node& r = im.nodes[n.right];
    if (boxDistance(l) < boxDistance(r)) {  // nearer child on top
      stack[top++] = n.right;
      stack[top++] = n.left;
    } else {
      stack[top++] = n.left;
      stack[top++] = n.right;
    }
  }
  return best;
}

}  // namespace myoskin
