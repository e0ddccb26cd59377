// Muscle weights for hybrid skinning: distance to each muscle's surface and the muscle's side, smoothed over
// the skin, split between neighbouring muscle joints; the skeleton weights fill the remainder.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "muscles/muscle_util.h"
#include "myoskin/errors.h"
#include "myoskin/memory_budget.h"
#include "myoskin/sections.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace {

struct MuscleEntry {
  int muscle;
  double weight;  // dominance * distance falloff * side, smoothed
};

// Minimum-weight ramp: 0 below c, then 2 (x - c) up to 2c, then x (continuous, the identity from 2c on).
double ramp(double x, double c) {
  if (x >= 2.0 * c) return x;
  return x < c ? 0.0 : 2.0 * (x - c);
}

// Vertex neighbours in CSR form (from the triangles' edges; duplicates are harmless for averaging).
void adjacency(const Mesh& skin, std::vector<int>& start, std::vector<int>& next) {
  const int nv = skin.numVertices();
  std::vector<int> count(nv + 1, 0);
  for (int f = 0; f < skin.numTriangles(); ++f)
    for (int c = 0; c < 3; ++c) count[skin.triangles(f, c) + 1] += 2;
  for (int v = 0; v < nv; ++v) count[v + 1] += count[v];
  start = count;
  next.assign(count[nv], 0);
  std::vector<int> fill(count.begin(), count.end() - 1);
  for (int f = 0; f < skin.numTriangles(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int a = skin.triangles(f, c);
      next[fill[a]++] = skin.triangles(f, (c + 1) % 3);
      next[fill[a]++] = skin.triangles(f, (c + 2) % 3);
    }
}

// 0 below 0, smoothly (C1) up to 1 at 1.
double smoothUnit(double x) {
  const double t = std::clamp(x, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// 1 up to d0, smoothly (C1) down to 0 at d1.
double falloff(double d, double d0, double d1) {
  if (d <= d0) return 1.0;
  if (d >= d1) return 0.0;
  const double t = (d - d0) / (d1 - d0);
  return 1.0 - t * t * (3.0 - 2.0 * t);
}

// Segment k and parameter t in [0, 1] of the point of the polyline nearest to p.
void projectOnPolyline(const std::vector<Vec3>& line, const Vec3& p, int& segment, double& t) {
  segment = 0;
  t = 0.0;
  if (line.size() < 2) return;
  double best = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k + 1 < line.size(); ++k) {
    const Vec3 d = line[k + 1] - line[k];
    const double len2 = d.squaredNorm();
    const double s = len2 > 0 ? std::clamp((p - line[k]).dot(d) / len2, 0.0, 1.0) : 0.0;
    const double dist = (line[k] + s * d - p).squaredNorm();
    if (dist < best) {
      best = dist;
      segment = static_cast<int>(k);
      t = s;
    }
  }
}

// Smoothing passes that diffuse a field over the vertices `near` (local[v] >= 0 inside) by an RMS distance L:
// 2 L^2 / <e^2>, <e^2> the mean squared length of the edges inside, rounded, at most kMaxSmoothingPasses.
int smoothingPasses(const Mesh& skin, const std::vector<int>& start, const std::vector<int>& next,
                    const std::vector<int>& near, const std::vector<int>& local, double distance) {
  double sum = 0.0;
  long count = 0;
  for (const int v : near)
    for (int e = start[v]; e < start[v + 1]; ++e)
      if (local[next[e]] >= 0) sum += (skin.vertices.row(v) - skin.vertices.row(next[e])).squaredNorm(), ++count;
  if (count == 0 || !(sum > 0.0)) return 0;
  const double passes = 2.0 * distance * distance / (sum / static_cast<double>(count));
  return static_cast<int>(std::lround(std::min(passes, static_cast<double>(kMaxSmoothingPasses))));
}

void checkOptions(const HybridWeightOptions& o, const MuscleRig& rig) {
  if (!(o.dominance >= 0.0 && o.dominance <= 1.0))
    throw InputError("hybrid weights: dominance must be in [0, 1], got " + std::to_string(o.dominance));
  for (const auto& [name, value] : o.muscleDominance) {
    bool known = false;
    for (const Muscle& m : rig.muscles()) known |= m.name == name;
    if (!known) throw InputError("hybrid weights: muscle dominance for unknown muscle '" + name + "'");
    if (!(value >= 0.0) || !std::isfinite(value))
      throw InputError("hybrid weights: muscle dominance of '" + name + "' must be >= 0");
  }
  if (o.maxInfluences < 1) throw InputError("hybrid weights: maxInfluences must be >= 1");
  if (!(o.fullDistance >= 0.0 && o.falloffDistance > o.fullDistance) || !std::isfinite(o.falloffDistance))
    throw InputError("hybrid weights: need 0 <= fullDistance < falloffDistance");
  if (o.smoothingIterations < 0) throw InputError("hybrid weights: smoothingIterations must be >= 0");
  if (!(o.smoothingDistance >= 0.0) || !std::isfinite(o.smoothingDistance))
    throw InputError("hybrid weights: smoothingDistance must be >= 0, got " + std::to_string(o.smoothingDistance));
  if (!(o.minWeight >= 0.0 && o.minWeight <= 0.25))
    throw InputError("hybrid weights: minWeight must be in [0, 0.25], got " + std::to_string(o.minWeight));
  if (!(o.endTaper >= 0.0 && o.endTaper <= 0.5)) throw InputError("hybrid weights: endTaper must be in [0, 0.5]");
  if (!(o.borderRelief >= 0.0 && o.borderRelief <= 1.0))
    throw InputError("hybrid weights: borderRelief must be in [0, 1], got " + std::to_string(o.borderRelief));
  if (!(o.creaseRelief >= 0.0 && o.creaseRelief <= 1.0))
    throw InputError("hybrid weights: creaseRelief must be in [0, 1], got " + std::to_string(o.creaseRelief));
}

}  // namespace

SkinWeights computeHybridWeights(const Mesh& skin, const SkinWeights& skeletonWeights, const MuscleRig& rig,
                                 const HybridWeightOptions& options) {
  validateMesh(skin, "skin");
  const int nv = skin.numVertices(), nb = rig.skeleton().numBones();
  validateSkinWeights(skeletonWeights, nv, nb);
  checkOptions(options, rig);
  for (int j = 0; j < rig.numJoints(); ++j)
    if (rig.jointParentBone()[j] < -1 || rig.jointParentBone()[j] >= nb)
      throw InputError("hybrid weights: the rig was built for another skeleton (joint '" + rig.jointNames()[j] + "')");
  requireMemory(hybridWeightsMemoryEstimate(nv, rig.numMuscles()),
                "binding " + std::to_string(rig.numMuscles()) + " muscles to " + std::to_string(nv) + " vertices");

  const Points normals = vertexNormals(skin.vertices, skin.triangles);
  std::vector<int> start, next;
  adjacency(skin, start, next);
  std::vector<std::vector<MuscleEntry>> entries(nv);
  std::vector<int> local(nv, -1);
  // Crease relief per vertex: 1 - creaseRelief * beta, beta = 2 (1 - the largest bone share) in [0, 1].
  std::vector<double> relief(nv, 1.0);
  if (options.creaseRelief > 0.0)
    for (int v = 0; v < nv; ++v) {
      double sum = 0.0, largest = 0.0;
      for (int k = 0; k < skeletonWeights.influences(); ++k)
        if (skeletonWeights.joints(v, k) >= 0)
          sum += skeletonWeights.weights(v, k), largest = std::max(largest, skeletonWeights.weights(v, k));
      if (sum > kRestWeightThreshold) relief[v] = 1.0 - options.creaseRelief * std::clamp(2.0 * (1.0 - largest / sum), 0.0, 1.0);
    }

  // A muscle takes its weight only from the skeleton weights of the bones it spans (the chain from its
  // origin bone to its insertion bone): skin that the skeleton blends with other bones (near a joint the
  // muscle does not cross) keeps that blend.
  const Skeleton& skeleton = rig.skeleton();
  std::vector<std::vector<char>> spans(rig.numMuscles(), std::vector<char>(nb, 0));
  for (int m = 0; m < rig.numMuscles(); ++m) {
    const int o = skeleton.find(rig.muscles()[m].origin.bone), i = skeleton.find(rig.muscles()[m].insertion.bone);
    std::vector<char> aboveO(nb, 0);
    for (int b = o; b >= 0; b = skeleton.bones[b].parent) aboveO[b] = 1;
    int common = i;
    while (common >= 0 && !aboveO[common]) spans[m][common] = 1, common = skeleton.bones[common].parent;
    for (int b = o; b >= 0 && b != common; b = skeleton.bones[b].parent) spans[m][b] = 1;
    if (common >= 0) spans[m][common] = 1;
  }
  // Across a real joint the skin stays with the skeleton's blend: a muscle takes weight only from the bones of
  // the segment its belly lies on (a bone with its twist-split neighbours, twistSplits), so the share the skin
  // has on the far side of a joint the muscle crosses keeps following that bone.
  // crossed[m]: (joint position, the child bone's direction) of each real joint muscle m crosses.
  std::vector<std::vector<std::pair<Vec3, Vec3>>> crossed(rig.numMuscles());
  std::vector<std::vector<float>> spanShare;  // #M by #V, empty when borderRelief is 0
  {
    const std::vector<char> twist = twistSplits(skeleton, skeletonWeights);
    std::vector<int> segment(nb);
    for (int b = 0; b < nb; ++b) {
      int r = b;
      while (twist[r] && skeleton.bones[r].parent >= 0) r = skeleton.bones[r].parent;
      segment[b] = r;
    }
    // Border relief: the share of each vertex's skeleton weight on the segments a muscle spans (the bones from its
    // origin to its insertion with their twist-split neighbours, before the belly-segment rule below); skin the
    // skeleton shares with other bones (the border of the trunk and a limb) follows the muscle only as much as it
    // belongs to the muscle's segments (share^borderRelief).
    if (options.borderRelief > 0.0) {
      spanShare.assign(rig.numMuscles(), std::vector<float>(nv, 1.0f));
      std::vector<char> spannedSegment(nb);
      for (int m = 0; m < rig.numMuscles(); ++m) {
        std::fill(spannedSegment.begin(), spannedSegment.end(), 0);
        for (int b = 0; b < nb; ++b)
          if (spans[m][b]) spannedSegment[segment[b]] = 1;
        for (int v = 0; v < nv; ++v) {
          double sum = 0.0, spanned = 0.0;
          for (int k = 0; k < skeletonWeights.influences(); ++k) {
            const int b = skeletonWeights.joints(v, k);
            if (b < 0) continue;
            sum += skeletonWeights.weights(v, k);
            if (spannedSegment[segment[b]]) spanned += skeletonWeights.weights(v, k);
          }
          if (sum > kRestWeightThreshold) spanShare[m][v] = static_cast<float>(spanned / sum);
        }
      }
    }
    for (int m = 0; m < rig.numMuscles(); ++m) {
      const Muscle& muscle = rig.muscles()[m];
      if (muscle.sections.empty()) continue;  // (a muscle read from a file with a surface but no sections)
      const Vec3 belly = muscle.sections[muscle.sections.size() / 2].center;
      int nearest = -1;
      double best = std::numeric_limits<double>::infinity();
      for (int b = 0; b < nb; ++b) {
        if (!spans[m][b]) continue;
        const Bone& bone = skeleton.bones[b];
        const double dist = (detail::closestOnSegment(belly, bone.head, bone.tail) - belly).norm();
        if (dist < best) best = dist, nearest = b;
      }
      if (nearest < 0) continue;
      for (int b = 0; b < nb; ++b) {
        if (!spans[m][b]) continue;
        // A real joint the muscle crosses: b's head when b starts a segment and its parent is spanned too.
        const int parent = skeleton.bones[b].parent;
        if (segment[b] == b && parent >= 0 && spans[m][parent]) {
          const Vec3 axis = skeleton.bones[b].tail - skeleton.bones[b].head;
          if (axis.norm() > 0) crossed[m].push_back({skeleton.bones[b].head, axis.normalized()});
        }
      }
      for (int b = 0; b < nb; ++b)
        if (spans[m][b] && segment[b] != segment[nearest]) spans[m][b] = 0;
    }
  }
  // ==========================================================================
  // Per muscle: distance + side on the vertices near it, then smoothing over the skin
  // ==========================================================================
  for (int m = 0; m < rig.numMuscles(); ++m) {
    const Muscle& muscle = rig.muscles()[m];
    double dominance = options.dominance;
    if (auto it = options.muscleDominance.find(muscle.name); it != options.muscleDominance.end()) dominance *= it->second;
    if (dominance <= 0.0 || muscle.sections.empty() || rig.jointCount(m) < 1) continue;
    const Mesh& surface = rig.restSurface(m);
    double radius = 0.0;
    for (const MuscleSection& s : muscle.sections) radius += std::sqrt(std::max(s.a, 0.0) * std::max(s.b, 0.0));
    radius /= static_cast<double>(muscle.sections.size());
    const double d0 = options.fullDistance * radius, d1 = options.falloffDistance * radius;
    const Vec3 origin = muscle.origin.position, path = muscle.insertion.position - muscle.origin.position;
    const double pathLength2 = path.squaredNorm();
    Vec3 lo, hi;
    boundingBox(surface.vertices, lo, hi);
    lo.array() -= d1;
    hi.array() += d1;
    std::vector<int> near;
    for (int v = 0; v < nv; ++v) {
      const Vec3 p = skin.vertices.row(v).transpose();
      if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all()) {
        local[v] = static_cast<int>(near.size());
        near.push_back(v);
      }
    }
    if (near.empty()) continue;
    std::vector<double> value(near.size(), 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, near.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const Vec3 p = skin.vertices.row(near[i]).transpose();
        double best = std::numeric_limits<double>::infinity();
        Eigen::Index q = 0;
        for (Eigen::Index s = 0; s < surface.vertices.rows(); ++s) {
          const double d2 = (surface.vertices.row(s).transpose() - p).squaredNorm();
          if (d2 < best) {
            best = d2;
            q = s;
          }
        }
        const double d = std::sqrt(best);
        const double f = falloff(d, d0, d1);
        if (f <= 0.0) continue;
        // Side: the skin must face away from the muscle (its normal along the muscle -> skin direction).
        const Vec3 away = p - surface.vertices.row(q).transpose();
        const double cosine = d > 1e-9 ? away.dot(normals.row(near[i]).transpose()) / d : 1.0;
        const double side = std::clamp(2.0 * cosine, 0.0, 1.0);
        const double border = spanShare.empty() ? 1.0 : smoothUnit((spanShare[m][near[i]] - 1.0) / options.borderRelief + 1.0);
        value[i] = dominance * f * side * relief[near[i]] * border;
      }
    });
    const int passes = options.smoothingDistance > 0.0
                           ? smoothingPasses(skin, start, next, near, local, options.smoothingDistance * radius)
                           : options.smoothingIterations;
    std::vector<double> smoothed(value.size());
    for (int it = 0; it < passes; ++it) {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, near.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const int v = near[i];
          double sum = 0.0;
          const int n = start[v + 1] - start[v];
          for (int e = start[v]; e < start[v + 1]; ++e) sum += local[next[e]] >= 0 ? value[local[next[e]]] : 0.0;
          smoothed[i] = n > 0 ? 0.5 * value[i] + 0.5 * sum / n : value[i];
        }
      });
      value.swap(smoothed);
    }
    // Fade towards the attachments along the rest action path, and to 0 at the plane of each real joint the
    // muscle crosses (over the muscle's reach, falloffDistance radii), after the smoothing so that the skin over the tendons and in the
    // joints' creases keeps following the bones.
    for (size_t i = 0; i < near.size(); ++i) {
      const Vec3 p = skin.vertices.row(near[i]).transpose();
      for (const auto& [joint, axis] : crossed[m]) {
        const double e = std::min(std::abs((p - joint).dot(axis)) / d1, 1.0);
        value[i] *= e * e * (3.0 - 2.0 * e);
      }
      if (options.endTaper > 0.0 && pathLength2 > 0.0) {
        const double u = std::clamp((p - origin).dot(path) / pathLength2, 0.0, 1.0);
        const double e = std::min(u, 1.0 - u) / options.endTaper;
        value[i] *= e >= 1.0 ? 1.0 : e * e * (3.0 - 2.0 * e);
      }
      if (value[i] > 1e-6) entries[near[i]].push_back({m, std::min(value[i], 1.0)});
      local[near[i]] = -1;
    }
  }

  // ==========================================================================
  // Per vertex: muscle share split between joints, skeleton fills the rest, strongest maxInfluences kept
  // ==========================================================================
  std::vector<std::vector<Vec3>> jointLine(rig.numMuscles());
  for (int m = 0; m < rig.numMuscles(); ++m)
    for (int k = 0; k < rig.jointCount(m); ++k)
      jointLine[m].push_back(rig.bindMatrices()[rig.jointOffset(m) + k].block<3, 1>(0, 3));
  const int K = options.maxInfluences;
  SkinWeights out;
  out.joints = IndexMatrix::Constant(nv, K, -1);
  out.weights = WeightMatrix::Zero(nv, K);
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 1024), [&](const tbb::blocked_range<int>& r) {
    std::vector<std::pair<double, int>> row;
    std::vector<double> muscleShare, take, boneWeight(skeletonWeights.influences());
    for (int v = r.begin(); v != r.end(); ++v) {
      double skeletonSum = 0.0;
      for (int k = 0; k < skeletonWeights.influences(); ++k)
        if (skeletonWeights.joints(v, k) >= 0) skeletonSum += skeletonWeights.weights(v, k);
      if (skeletonSum <= kRestWeightThreshold) continue;
      // Each bone's (normalised) weight w_b gives up the fraction 1 - prod(1 - e_m) over the muscles m
      // spanning it, shared among those muscles in proportion to e_m (take[q][k]: what muscle q takes from
      // slot k's bone).
      row.clear();
      muscleShare.assign(entries[v].size(), 0.0);
      take.assign(entries[v].size() * skeletonWeights.influences(), 0.0);
      const int S = skeletonWeights.influences();
      for (int k = 0; k < S; ++k) {
        const int b = skeletonWeights.joints(v, k);
        const double w = skeletonWeights.weights(v, k) / skeletonSum;
        boneWeight[k] = 0.0;
        if (b < 0 || w <= 0.0) continue;
        double keep = 1.0, claim = 0.0;
        for (const MuscleEntry& e : entries[v])
          if (spans[e.muscle][b]) keep *= 1.0 - e.weight, claim += e.weight;
        for (size_t q = 0; q < entries[v].size(); ++q)
          if (spans[entries[v][q].muscle][b]) {
            take[q * S + k] = w * (1.0 - keep) * entries[v][q].weight / claim;
            muscleShare[q] += take[q * S + k];
          }
        boneWeight[k] = w * keep;
      }
      // A muscle's share below minWeight goes back to the bones it came from (ramped, see minWeight).
      for (size_t q = 0; q < entries[v].size(); ++q) {
        const double share = muscleShare[q];
        if (share <= 0.0) continue;
        const double back = 1.0 - ramp(share, options.minWeight) / share;
        if (back <= 0.0) continue;
        for (int k = 0; k < S; ++k) boneWeight[k] += back * take[q * S + k];
        muscleShare[q] -= back * share;
      }
      for (int k = 0; k < S; ++k) {
        const int b = skeletonWeights.joints(v, k);
        if (b < 0 || skeletonWeights.weights(v, k) <= 0.0) continue;
        bool merged = false;
        for (auto& [rw, rj] : row)
          if (rj == b) rw += boneWeight[k], merged = true;
        if (!merged) row.push_back({boneWeight[k], b});
      }
      const Vec3 p = skin.vertices.row(v).transpose();
      for (size_t q = 0; q < entries[v].size(); ++q) {
        const MuscleEntry& e = entries[v][q];
        const double share = muscleShare[q];
        if (share <= 0.0) continue;
        const int first = nb + rig.jointOffset(e.muscle);
        int segment;
        double t;
        projectOnPolyline(jointLine[e.muscle], p, segment, t);
        // The smaller part of the split below minWeight goes to the other joint (ramped).
        const double small = share * std::min(t, 1.0 - t), kept = ramp(small, options.minWeight);
        const double second = t <= 0.5 ? kept : share - kept;
        if (share - second > 0.0) row.push_back({share - second, first + segment});
        if (second > 0.0) row.push_back({second, first + segment + 1});
      }
      std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
      const int used = std::min<int>(K, static_cast<int>(row.size()));
      double kept = 0.0;
      for (int k = 0; k < used; ++k) kept += row[k].first;
      for (int k = 0; k < used; ++k) {
        out.joints(v, k) = row[k].second;
        out.weights(v, k) = row[k].first / kept;
      }
    }
  });
  return out;
}

}  // namespace myoskin
