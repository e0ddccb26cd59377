// Midpoint subdivision of a character's skin and weights (subdivide.h).
#include "myoskin/subdivide.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

#include "myoskin/errors.h"

namespace myoskin {

namespace {

// ============================================================================
// One level
// ============================================================================

// Mean of two vertices' sparse weights, keeping the K strongest influences, renormalised.
void blendWeights(const SkinWeights& in, int a, int b, SkinWeights& out, int row) {
  const int k = in.influences();
  std::vector<std::pair<int, double>> acc;
  acc.reserve(2 * k);
  for (int v : {a, b})
    for (int s = 0; s < k; ++s) {
      const int j = in.joints(v, s);
      if (j < 0) continue;
      auto it = std::find_if(acc.begin(), acc.end(), [j](const auto& p) { return p.first == j; });
      if (it == acc.end()) acc.emplace_back(j, 0.5 * in.weights(v, s));
      else it->second += 0.5 * in.weights(v, s);
    }
  std::stable_sort(acc.begin(), acc.end(), [](const auto& x, const auto& y) {
    return x.second != y.second ? x.second > y.second : x.first < y.first;
  });
  double total = 0.0;
  for (int s = 0; s < k && s < static_cast<int>(acc.size()); ++s) total += acc[s].second;
  for (int s = 0; s < k; ++s) {
    const bool used = s < static_cast<int>(acc.size());
    out.joints(row, s) = used ? acc[s].first : -1;
    out.weights(row, s) = used ? (total > 0 ? acc[s].second / total : 0.0) : 0.0;
  }
}

Character subdivideOnce(const Character& c) {
  const int nv = c.mesh.numVertices(), nf = c.mesh.numTriangles();
  // Unique edges: (min, max, face*3+corner) sorted, so each edge gets one new vertex, deterministically.
  std::vector<std::pair<uint64_t, int>> edges(3 * static_cast<size_t>(nf));
  for (int f = 0; f < nf; ++f)
    for (int e = 0; e < 3; ++e) {
      const uint64_t a = static_cast<uint32_t>(c.mesh.triangles(f, e)), b = static_cast<uint32_t>(c.mesh.triangles(f, (e + 1) % 3));
      edges[3 * f + e] = {std::min(a, b) << 32 | std::max(a, b), 3 * f + e};
    }
  std::sort(edges.begin(), edges.end());
  std::vector<int> midpoint(edges.size());
  int next = nv;
  std::vector<uint64_t> keys;
  for (size_t i = 0; i < edges.size(); ++i) {
    if (i == 0 || edges[i].first != edges[i - 1].first) keys.push_back(edges[i].first), ++next;
    midpoint[edges[i].second] = next - 1;
  }
  Character out;
  out.name = c.name;
  out.skeleton = c.skeleton;
  out.mesh.vertices.resize(next, 3);
  out.mesh.vertices.topRows(nv) = c.mesh.vertices;
  const bool weighted = c.hasWeights();
  if (weighted) {
    out.weights.joints.resize(next, c.weights.influences());
    out.weights.weights.resize(next, c.weights.influences());
    out.weights.joints.topRows(nv) = c.weights.joints;
    out.weights.weights.topRows(nv) = c.weights.weights;
  }
  for (size_t i = 0; i < keys.size(); ++i) {
    const int a = static_cast<int>(keys[i] >> 32), b = static_cast<int>(keys[i] & 0xffffffffu), row = nv + static_cast<int>(i);
    out.mesh.vertices.row(row) = 0.5 * (c.mesh.vertices.row(a) + c.mesh.vertices.row(b));
    if (weighted) blendWeights(c.weights, a, b, out.weights, row);
  }
  out.mesh.triangles.resize(4 * static_cast<Eigen::Index>(nf), 3);
  for (int f = 0; f < nf; ++f) {
    const int v0 = c.mesh.triangles(f, 0), v1 = c.mesh.triangles(f, 1), v2 = c.mesh.triangles(f, 2);
    const int m01 = midpoint[3 * f], m12 = midpoint[3 * f + 1], m20 = midpoint[3 * f + 2];
    out.mesh.triangles.row(4 * f + 0) << v0, m01, m20;
    out.mesh.triangles.row(4 * f + 1) << m01, v1, m12;
    out.mesh.triangles.row(4 * f + 2) << m20, m12, v2;
    out.mesh.triangles.row(4 * f + 3) << m01, m12, m20;
  }
  out.sourceVertexCount = next;
  out.sourceToWelded.resize(next);
  std::iota(out.sourceToWelded.begin(), out.sourceToWelded.end(), 0);
  return out;
}

}  // namespace

// ============================================================================
// Public
// ============================================================================

Character subdivideMidpoint(const Character& character, int levels) {
  if (levels < 0) throw InputError("subdivision levels must be >= 0, got " + std::to_string(levels));
  validateCharacter(character);
  Character c = character;
  for (int i = 0; i < levels; ++i) c = subdivideOnce(c);
  return c;
}

}  // namespace myoskin
