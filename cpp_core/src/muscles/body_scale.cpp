// What extraction looks at and at what size: the body's limb radius (the scale every default length is stated
// for) and the skin components that are body surface (eyes, teeth, props and rigid parts left out).
#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "muscles/muscle_util.h"
#include "myoskin/extraction.h"

namespace myoskin {

namespace {

// Dominant bone of each vertex (largest weight), -1 when it has none.
std::vector<int> dominantBones(const Character& character, std::vector<double>* dominantWeight = nullptr) {
  const int nv = character.mesh.numVertices();
  std::vector<int> bone(nv, -1);
  if (dominantWeight) dominantWeight->assign(nv, 0.0);
  if (!character.hasWeights()) return bone;
  const SkinWeights& w = character.weights;
  for (int v = 0; v < nv; ++v) {
    double best = 0.0, sum = 0.0;
    for (int k = 0; k < w.influences(); ++k) {
      if (w.joints(v, k) < 0) continue;
      const double x = w.weights(v, k);
      sum += x;
      if (x > best) best = x, bone[v] = w.joints(v, k);
    }
    if (dominantWeight) (*dominantWeight)[v] = sum > 0 ? best / sum : 0.0;
  }
  return bone;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  return values[mid];
}

}  // namespace

// ============================================================================
// Limb radius
// ============================================================================

double bodyLimbRadius(const Character& character, const std::vector<BoneRole>& roles) {
  const Mesh& mesh = character.mesh;
  const std::vector<int> dominant = dominantBones(character);
  std::vector<double> limb, any;
  for (int v = 0; v < mesh.numVertices(); ++v) {
    const int b = dominant[v];
    if (b < 0 || b >= character.skeleton.numBones()) continue;
    const Bone& bone = character.skeleton.bones[b];
    const Vec3 p = mesh.vertices.row(v).transpose();
    const double d = (p - detail::closestOnSegment(p, bone.head, bone.tail)).norm();
    any.push_back(d);
    if (b < static_cast<int>(roles.size()) && roles[b] == BoneRole::Limb) limb.push_back(d);
  }
  double r = median(limb.size() >= 16 ? limb : any);
  if (!(r > 0) && mesh.numVertices() > 0) r = principalExtent(mesh.vertices) / 40.0;
  return r;
}

// ============================================================================
// Body surface
// ============================================================================

std::vector<char> bodySurfaceMask(const Character& character, std::vector<ExcludedComponent>& excluded,
                                  double smallShare) {
  excluded.clear();
  const Mesh& mesh = character.mesh;
  const int nv = mesh.numVertices();
  // Components over triangles (union-find on vertices).
  std::vector<int> parent(nv);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int f = 0; f < mesh.numTriangles(); ++f)
    for (int c = 0; c < 2; ++c) {
      const int a = find(mesh.triangles(f, c)), b = find(mesh.triangles(f, c + 1));
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  std::vector<char> used(nv, 0);
  for (int f = 0; f < mesh.numTriangles(); ++f)
    for (int c = 0; c < 3; ++c) used[mesh.triangles(f, c)] = 1;
  // Per component (indexed by its root, the lowest vertex): bounds, count, single rigid bone.
  std::vector<double> dominantWeight;
  const std::vector<int> dominant = dominantBones(character, &dominantWeight);
  struct Component {
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
    int count = 0;
    int bone = -2;  // -2 unset, -1 not rigid, else the one bone
  };
  std::vector<Component> comp(nv);
  std::vector<int> roots;
  for (int v = 0; v < nv; ++v) {
    if (!used[v]) continue;
    const int r = find(v);
    Component& c = comp[r];
    if (c.count++ == 0) roots.push_back(r);
    const Vec3 p = mesh.vertices.row(v).transpose();
    c.lo = c.lo.cwiseMin(p), c.hi = c.hi.cwiseMax(p);
    const int rigidBone = dominantWeight[v] >= 0.99 ? dominant[v] : -1;
    if (c.bone == -2) c.bone = rigidBone;
    else if (c.bone != rigidBone) c.bone = -1;
  }
  std::vector<char> mask(nv, 1);
  if (roots.size() <= 1) return mask;
  int largest = roots[0];
  for (int r : roots)
    if (comp[r].count > comp[largest].count) largest = r;
  const double largestDiagonal = (comp[largest].hi - comp[largest].lo).norm();
  std::vector<char> drop(nv, 0);
  for (int r : roots) {
    if (r == largest) continue;
    const Component& c = comp[r];
    const bool small = (c.hi - c.lo).norm() < smallShare * largestDiagonal;
    const bool rigid = c.bone >= 0 && character.hasWeights();
    if (!small && !rigid) continue;
    drop[r] = 1;
    ExcludedComponent e;
    e.vertices = c.count;
    e.firstVertex = r;
    e.reason = small ? "small" : "rigid";
    if (c.bone >= 0) e.bone = character.skeleton.bones[c.bone].name;
    excluded.push_back(e);
  }
  for (int v = 0; v < nv; ++v)
    if (used[v] && drop[find(v)]) mask[v] = 0;
  return mask;
}

}  // namespace myoskin
