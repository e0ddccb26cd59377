// Slide limits from a bound skin (skinning.h computeSlideLimits): how far each muscle joint may carry its skin
// along the bone before the skin folds where the muscle's weight fades.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "myoskin/deformation.h"
#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

std::vector<std::array<double, 2>> computeSlideLimits(const Mesh& skin, const SkinWeights& weights,
                                                     const MuscleRig& rig, double margin) {
  const int V = skin.numVertices(), B = rig.skeleton().numBones(), J = rig.numJoints();
  if (weights.numVertices() != V)
    throw InputError("computeSlideLimits: the weights have " + std::to_string(weights.numVertices()) +
                     " rows, the skin " + std::to_string(V) + " vertices");
  if (!(margin > 0) || !std::isfinite(margin))
    throw InputError("computeSlideLimits: margin must be positive, got " + std::to_string(margin));
  // Each vertex's weight per muscle (W, summed over its joints) and which of its joints touch it (sparse rows).
  const std::vector<int>& jointMuscle = rig.jointMuscle();
  std::vector<std::vector<std::pair<int, double>>> muscleWeight(V);  // (muscle, W) per vertex
  std::vector<std::vector<int>> vertexJoints(V);
  for (int v = 0; v < V; ++v)
    for (int k = 0; k < weights.influences(); ++k) {
      const int c = weights.joints(v, k);
      const double w = weights.weights(v, k);
      if (c >= B + J) throw InputError("computeSlideLimits: vertex " + std::to_string(v) + " names joint " +
                                       std::to_string(c) + ", past the " + std::to_string(B + J) + " combined joints");
      if (c < 0 || !(w > 0)) continue;
      if (c < B) continue;
      vertexJoints[v].push_back(c - B);
      const int m = jointMuscle[c - B];
      auto it = std::find_if(muscleWeight[v].begin(), muscleWeight[v].end(), [&](const auto& e) { return e.first == m; });
      if (it == muscleWeight[v].end()) muscleWeight[v].push_back({m, w});
      else it->second += w;
    }
  auto weightOf = [&](int v, int m) {
    for (const auto& [mm, w] : muscleWeight[v])
      if (mm == m) return w;
    return 0.0;
  };
  // Largest gradient of W along each joint's axis, per sign, over the triangles the joint touches.
  std::vector<std::array<double, 2>> steepest(J, {0.0, 0.0});
  const std::vector<Vec3>& axes = rig.slideAxes();
  std::vector<int> touching;
  for (int f = 0; f < skin.numTriangles(); ++f) {
    const int a = skin.triangles(f, 0), b = skin.triangles(f, 1), c = skin.triangles(f, 2);
    touching.clear();
    for (int v : {a, b, c}) touching.insert(touching.end(), vertexJoints[v].begin(), vertexJoints[v].end());
    if (touching.empty()) continue;
    std::sort(touching.begin(), touching.end());
    touching.erase(std::unique(touching.begin(), touching.end()), touching.end());
    const Vec3 p0 = skin.vertices.row(a).transpose();
    const Vec3 e1 = skin.vertices.row(b).transpose() - p0, e2 = skin.vertices.row(c).transpose() - p0;
    const double a11 = e1.dot(e1), a12 = e1.dot(e2), a22 = e2.dot(e2), det = a11 * a22 - a12 * a12;
    if (!(det > 1e-6 * a11 * a22)) continue;  // a sliver (sin^2 of its angle under 1e-6) has no gradient to trust
    int lastMuscle = -1;
    Vec3 g = Vec3::Zero();
    for (int j : touching) {  // joints of one muscle are consecutive: one gradient per muscle
      const int m = jointMuscle[j];
      if (m != lastMuscle) {
        const double w0 = weightOf(a, m), d1 = weightOf(b, m) - w0, d2 = weightOf(c, m) - w0;
        g = ((a22 * d1 - a12 * d2) / det) * e1 + ((a11 * d2 - a12 * d1) / det) * e2;  // in-plane: g.e1 = d1, g.e2 = d2
        lastMuscle = m;
      }
      const double along = g.dot(axes[j]);
      steepest[j][0] = std::max(steepest[j][0], along);    // sliding towards the head folds where W rises to the tail
      steepest[j][1] = std::max(steepest[j][1], -along);   // towards the tail, where it falls
    }
  }
  std::vector<std::array<double, 2>> limits(J, {0.0, 0.0});
  for (int j = 0; j < J; ++j)
    for (int side = 0; side < 2; ++side)
      if (steepest[j][side] > 0) limits[j][side] = margin / steepest[j][side];
  return limits;
}

}  // namespace myoskin
