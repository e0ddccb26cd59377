// The per-frame skin solve against the muscles (skin_solve.h): build (adjacency, regions, rest depths) and solve.
#include "myoskin/skin_solve.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "dynamics/skin_solve_bvh.h"
#include "myoskin/errors.h"

namespace myoskin {

namespace {

using OmMesh = OpenMesh::TriMesh_ArrayKernelT<>;

std::string muscleLabel(const MuscleRig& rig, int m) { return "muscle '" + rig.muscles()[m].name + "'"; }

// Mean section radius sqrt(a b) of a muscle (its size for thresholds); falls back to its surface's extent.
double muscleRadius(const Muscle& muscle, const Mesh& surface) {
  double sum = 0.0;
  int n = 0;
  for (const MuscleSection& s : muscle.sections)
    if (s.a > 0 && s.b > 0) {
      sum += std::sqrt(s.a * s.b);
      ++n;
    }
  if (n > 0) return sum / n;
  Vec3 lo, hi;
  boundingBox(surface.vertices, lo, hi);
  return 0.25 * (hi - lo).minCoeff();
}

// Undirected edges of the skin through OpenMesh's half-edge mesh; the faces OpenMesh refuses (non-manifold
// fans) add their three edges directly, so every triangle edge is a spring.
std::vector<std::pair<int, int>> skinEdges(const Mesh& skin) {
  OmMesh mesh;
  std::vector<OmMesh::VertexHandle> vh(skin.numVertices());
  for (int v = 0; v < skin.numVertices(); ++v)
    vh[v] = mesh.add_vertex(OmMesh::Point(skin.vertices(v, 0), skin.vertices(v, 1), skin.vertices(v, 2)));
  std::vector<std::pair<int, int>> edges;
  for (int f = 0; f < skin.numTriangles(); ++f) {
    const int a = skin.triangles(f, 0), b = skin.triangles(f, 1), c = skin.triangles(f, 2);
    if (a == b || b == c || a == c) continue;
    if (!mesh.add_face(vh[a], vh[b], vh[c]).is_valid())
      for (int k = 0; k < 3; ++k) {
        const int i = skin.triangles(f, k), j = skin.triangles(f, (k + 1) % 3);
        edges.emplace_back(std::min(i, j), std::max(i, j));
      }
  }
  for (const auto& e : mesh.edges()) {
    const int i = e.v0().idx(), j = e.v1().idx();
    edges.emplace_back(std::min(i, j), std::max(i, j));
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

}  // namespace

// ============================================================================
// Goal weights
// ============================================================================

Eigen::VectorXd defaultGoalWeights(const SkinWeights& combinedWeights, int numBones, double slide,
                                   double fullShare) {
  if (!(slide >= 0.0 && slide <= 1.0)) throw InputError("skin solve: slide must lie in [0, 1]");
  if (!(fullShare > 0.0 && fullShare <= 1.0)) throw InputError("skin solve: fullShare must lie in (0, 1]");
  if (numBones < 0) throw InputError("skin solve: numBones must be >= 0");
  const int nv = combinedWeights.numVertices();
  if (combinedWeights.weights.rows() != nv || combinedWeights.weights.cols() != combinedWeights.joints.cols())
    throw InputError("skin solve: joints and weights of the skin weights differ in shape");
  Eigen::VectorXd g = Eigen::VectorXd::Ones(nv);
  for (int v = 0; v < nv; ++v) {
    double total = 0.0, muscle = 0.0;
    for (int k = 0; k < combinedWeights.influences(); ++k) {
      const double w = combinedWeights.weights(v, k);
      const int j = combinedWeights.joints(v, k);
      if (j < 0 || !(w > 0.0)) continue;
      if (!std::isfinite(w)) throw InputError("skin solve: vertex " + std::to_string(v) + " has a non-finite weight");
      total += w;
      if (j >= numBones) muscle += w;
    }
    if (total > 0.0) g[v] = 1.0 - slide * std::min(1.0, muscle / total / fullShare);
  }
  return g;
}

// ============================================================================
// State
// ============================================================================

struct SkinSolver::Impl {
  // What a projection measured at its final point (outside every muscle of its list): the muscle with the smallest
  // lower bound on its distance, that bound, and the smallest bound over the others (0 when unknown or inside).
  struct Clearance {
    int nearest = -1;
    double near = 0.0, far = 0.0;
    int face = -1;  // the nearest muscle's triangle closest to the point (a hint for the next query)
  };
  SkinSolveOptions options;
  SkinSolveReport report;
  int nv = 0;
  Eigen::VectorXd goalWeight, restDepth;
  // Springs: CSR edge rings with rest lengths.
  std::vector<int> ringStart, ring;
  std::vector<double> ringRest;
  // Regions of sliding vertices and the muscles each one collides with.
  std::vector<std::vector<int>> regionVertices;
  std::vector<std::vector<int>> regionMuscles;
  std::vector<std::vector<int>> otherMuscles;  // per region: the muscles not in regionMuscles
  std::vector<int> vertexRegion;               // #V region of a sliding vertex, -1 otherwise
  // Muscles.
  std::vector<detail::TriangleBvh> bvh;
  std::vector<double> radius;
  std::vector<int> muscleVertices;
  std::vector<int> allMuscles;
  double margin = 0.0;     // push-out margin (metres)
  double tolerance = 0.0;  // depth beyond the allowed one that triggers a push (metres)
  // Scratch.
  Points buffer[2];
  Points goal;
  Points result;  // solveInPlace's double-precision output
  // Per sliding vertex, this frame: within near of anchorNear its nearest muscle cannot hold it, within far of
  // anchorFar no other muscle of its region can (muscles do not move within a frame), so queries are skipped.
  Points anchorNear, anchorFar;
  std::vector<Clearance> clearance;
  std::unique_ptr<tbb::task_arena> arena;

  // Pushes p out of the muscles list[0..count) to at most its allowed depth; true if it moved. clear (if not
  // null) receives the clearances at the final p.
  bool project(Vec3& p, double allowed, const int* list, int count, Clearance* clear = nullptr) const;
  bool project(Vec3& p, double allowed, const std::vector<int>& list) const {
    return project(p, allowed, list.data(), static_cast<int>(list.size()));
  }
  // Refits every muscle's hierarchy to the state's surfaces (validated).
  void refit(const MuscleRigState& state);
  // The iteration budget on one region (buffers hold the goal everywhere at start).
  void solveRegion(int r);
  void run();
};

bool SkinSolver::Impl::project(Vec3& p, double allowed, const int* list, int count, Clearance* clearOut) const {
  bool moved = false;
  for (int round = 0; round < options.collisionRounds; ++round) {
    bool any = false;
    Clearance c;
    c.near = c.far = std::numeric_limits<double>::infinity();
    const int hintMuscle = clearOut ? clearOut->nearest : -1, hintFace = clearOut ? clearOut->face : -1;
    auto bound = [&](int m, double d, int face) {  // keep the smallest and the second smallest bound
      if (d < c.near) {
        c.far = c.near;
        c.near = d;
        c.nearest = m;
        c.face = face;
      } else {
        c.far = std::min(c.far, d);
      }
    };
    for (int i = 0; i < count; ++i) {
      const int m = list[i];
      const Eigen::AlignedBox3d& box = bvh[m].bounds();
      if (!box.contains(p)) {  // outside the box: outside the muscle, at least the box's distance away
        bound(m, (p - p.cwiseMax(box.min()).cwiseMin(box.max())).norm(), -1);
        continue;
      }
      const detail::SurfaceHit hit = bvh[m].closest(p, m == hintMuscle ? hintFace : -1);
      if (-hit.distance <= allowed + tolerance) {
        bound(m, std::max(hit.distance, 0.0), hit.face);
        continue;
      }
      // Move along the way out (the closest point's direction, or its normal on the surface) to the allowed depth.
      const Vec3 d = hit.point - p;
      const double len = d.norm();
      const Vec3 out = len > 1e-12 * radius[m] ? Vec3(d / len) : hit.normal;
      p = hit.point + out * (allowed > 0.0 ? -allowed : margin);
      // Still inside (the nearest sheet was a fold of a surface that crosses itself): go on outwards from the
      // closest point in doubling steps until outside, at most 4 muscle radii.
      for (double step = std::max(2.0 * margin, 0.01 * radius[m]); allowed <= 0.0 && step < 4.0 * radius[m] &&
                                                                    bvh[m].closest(p).distance < 0.0;
           step *= 2.0)
        p = hit.point + out * step;
      any = true;
      bound(m, 0.0, hit.face);
    }
    if (clearOut) {
      *clearOut = c;
      if (allowed > 0.0 || any) clearOut->near = clearOut->far = 0.0;
    }
    if (!any) return moved;
    moved = true;
  }
  // Rounds used up: pushed back and forth between overlapping muscles. Escape the union along the way out of the
  // first muscle that still holds p, in doubling steps (at most 8 of its radii).
  if (allowed > 0.0) return moved;
  auto insideAny = [&](const Vec3& q) {
    for (int i = 0; i < count; ++i)
      if (bvh[list[i]].bounds().contains(q) && bvh[list[i]].closest(q).distance < 0.0) return true;
    return false;
  };
  for (int i = 0; i < count; ++i) {
    const int m = list[i];
    if (!bvh[m].bounds().contains(p) || !(bvh[m].closest(p).distance < 0.0)) continue;
    const detail::SurfaceHit hit = bvh[m].closest(p);
    const Vec3 d = hit.point - p;
    const double len = d.norm();
    const Vec3 out = len > 1e-12 * radius[m] ? Vec3(d / len) : hit.normal;
    for (double step = std::max(2.0 * margin, 0.01 * radius[m]); step < 8.0 * radius[m]; step *= 2.0) {
      const Vec3 q = hit.point + out * step;
      if (!insideAny(q)) {
        p = q;
        break;
      }
    }
    break;
  }
  return moved;
}

void SkinSolver::Impl::refit(const MuscleRigState& state) {
  const int nm = static_cast<int>(bvh.size());
  if (static_cast<int>(state.surfaces.size()) != nm)
    throw InputError("skin solve: the rig state has " + std::to_string(state.surfaces.size()) + " surfaces for " +
                     std::to_string(nm) + " muscles (evaluate with withSurfaces = true)");
  for (int m = 0; m < nm; ++m) {
    if (state.surfaces[m].rows() != muscleVertices[m])
      throw InputError("skin solve: posed surface " + std::to_string(m) + " has " +
                       std::to_string(state.surfaces[m].rows()) + " vertices, its rest surface " +
                       std::to_string(muscleVertices[m]));
    if (!state.surfaces[m].allFinite())
      throw InputError("skin solve: posed surface " + std::to_string(m) + " has a NaN or infinite vertex");
  }
  tbb::parallel_for(0, nm, [&](int m) { bvh[m].refit(state.surfaces[m]); });
}

void SkinSolver::Impl::solveRegion(int r) {
  const std::vector<int>& verts = regionVertices[r];
  const std::vector<int>& muscles = regionMuscles[r];
  const int n = static_cast<int>(verts.size());
  const double k = options.springStiffness;
  for (int it = 0; it < options.iterations; ++it) {
    const Points& cur = buffer[it % 2];
    Points& next = buffer[(it + 1) % 2];
    const bool collide = (it + 1) % options.collideEvery == 0 || it + 1 == options.iterations;
    tbb::parallel_for(tbb::blocked_range<int>(0, n, options.grainSize), [&](const tbb::blocked_range<int>& range) {
      for (int i = range.begin(); i < range.end(); ++i) {
        const int v = verts[i];
        const Vec3 x = cur.row(v).transpose();
        Vec3 sum = Vec3::Zero();
        int count = 0;
        for (int e = ringStart[v]; e < ringStart[v + 1]; ++e) {
          const Vec3 xn = cur.row(ring[e]).transpose();
          const Vec3 d = x - xn;
          const double len = d.norm();
          sum += len > 0.0 ? Vec3(xn + d * (ringRest[e] / len)) : x;
          ++count;
        }
        const Vec3 spring = count > 0 ? Vec3(x + k * (sum / count - x)) : x;
        const double g = goalWeight[v];
        Vec3 p = g * goal.row(v).transpose() + (1.0 - g) * spring;
        if (!collide) {
          next.row(v) = p.transpose();
          continue;
        }
        // Within the clearances measured this frame no muscle of the region can hold p: query only what it left.
        Clearance& c = clearance[v];
        const bool farClear = c.far > 0.0 && (p - anchorFar.row(v).transpose()).norm() < c.far;
        if (farClear && (p - anchorNear.row(v).transpose()).norm() < c.near) {
          // nothing to test
        } else if (farClear) {
          Clearance one;
          one.nearest = c.nearest;
          one.face = c.face;
          project(p, restDepth[v], &c.nearest, 1, &one);
          if ((p - anchorFar.row(v).transpose()).norm() < c.far) {
            c.near = one.near;
            c.face = one.face;
            anchorNear.row(v) = p.transpose();
          } else {
            project(p, restDepth[v], muscles.data(), static_cast<int>(muscles.size()), &c);
            anchorNear.row(v) = anchorFar.row(v) = p.transpose();
          }
        } else {
          project(p, restDepth[v], muscles.data(), static_cast<int>(muscles.size()), &c);
          anchorNear.row(v) = anchorFar.row(v) = p.transpose();
        }
        next.row(v) = p.transpose();
      }
    });
  }
}

void SkinSolver::Impl::run() {
  std::fill(clearance.begin(), clearance.end(), Clearance());
  tbb::parallel_for(0, static_cast<int>(regionVertices.size()), [&](int r) { solveRegion(r); });
  // Every vertex against every muscle (goal-weight-1 skin, and sliding skin near muscles of other regions).
  Points& result = buffer[options.iterations % 2];
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, options.grainSize), [&](const tbb::blocked_range<int>& range) {
    for (int v = range.begin(); v < range.end(); ++v) {
      Vec3 p = result.row(v).transpose();
      // A sliding vertex was just projected against its region's muscles (or kept its clearance from them).
      const int r = vertexRegion[v];
      if (project(p, restDepth[v], r >= 0 ? otherMuscles[r] : allMuscles)) {
        if (r >= 0) project(p, restDepth[v], allMuscles);
        result.row(v) = p.transpose();
      }
    }
  });
}

// ============================================================================
// Build
// ============================================================================

SkinSolver::SkinSolver(const Mesh& skin, const MuscleRig& rig, const Eigen::VectorXd& goalWeights,
                       const SkinSolveOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  validateMesh(skin, "skin");
  if (options.iterations < 0 || options.iterations > 10000)
    throw InputError("skin solve: iterations must lie in [0, 10000]");
  if (!(options.slide >= 0.0 && options.slide <= 1.0)) throw InputError("skin solve: slide must lie in [0, 1]");
  if (!(options.springStiffness >= 0.0 && options.springStiffness <= 1.0))
    throw InputError("skin solve: springStiffness must lie in [0, 1]");
  if (!(options.pushMargin >= 0.0 && options.pushMargin <= 1.0))
    throw InputError("skin solve: pushMargin must lie in [0, 1] edge lengths");
  if (!(options.reach >= 0.0 && std::isfinite(options.reach))) throw InputError("skin solve: reach must be >= 0");
  if (options.collideEvery < 1) throw InputError("skin solve: collideEvery must be >= 1");
  if (options.collisionRounds < 1 || options.collisionRounds > 100)
    throw InputError("skin solve: collisionRounds must lie in [1, 100]");
  if (options.grainSize < 1) throw InputError("skin solve: grainSize must be >= 1");
  if (options.threads < 0) throw InputError("skin solve: threads must be >= 0");
  s.options = options;
  s.nv = skin.numVertices();
  if (goalWeights.size() != s.nv)
    throw InputError("skin solve: " + std::to_string(goalWeights.size()) + " goal weights for " +
                     std::to_string(s.nv) + " skin vertices");
  for (int v = 0; v < s.nv; ++v)
    if (!(goalWeights[v] >= 0.0 && goalWeights[v] <= 1.0))
      throw InputError("skin solve: goal weight of vertex " + std::to_string(v) + " is not in [0, 1]");
  s.goalWeight = goalWeights;
  if (options.threads > 0) s.arena = std::make_unique<tbb::task_arena>(options.threads);

  // Springs.
  const std::vector<std::pair<int, int>> edges = skinEdges(skin);
  s.ringStart.assign(s.nv + 1, 0);
  for (const auto& e : edges) {
    ++s.ringStart[e.first + 1];
    ++s.ringStart[e.second + 1];
  }
  for (int v = 0; v < s.nv; ++v) s.ringStart[v + 1] += s.ringStart[v];
  s.ring.resize(2 * edges.size());
  s.ringRest.resize(2 * edges.size());
  std::vector<int> fill(s.ringStart.begin(), s.ringStart.end() - 1);
  double total = 0.0;
  for (const auto& [a, b] : edges) {
    const double len = (skin.vertices.row(a) - skin.vertices.row(b)).norm();
    total += len;
    s.ring[fill[a]] = b;
    s.ringRest[fill[a]++] = len;
    s.ring[fill[b]] = a;
    s.ringRest[fill[b]++] = len;
  }
  const double meanEdge = edges.empty() ? 0.0 : total / edges.size();
  s.report.meanEdgeLength = meanEdge;
  {
    Vec3 lo, hi;
    boundingBox(skin.vertices, lo, hi);
    const double size = (hi - lo).norm();
    s.margin = options.pushMargin * (meanEdge > 0 ? meanEdge : size);
    s.tolerance = 1e-9 * size;
  }

  // Muscles: closed, manifold, outward surfaces.
  const int nm = rig.numMuscles();
  s.bvh.resize(nm);
  s.radius.resize(nm);
  s.muscleVertices.resize(nm);
  for (int m = 0; m < nm; ++m) {
    const Mesh& surface = rig.restSurface(m);
    if (surface.numVertices() == 0 || surface.numTriangles() == 0)
      throw InputError("skin solve: " + muscleLabel(rig, m) + " has no surface");
    validateMesh(surface, muscleLabel(rig, m) + " surface");
    const TopologyReport t = analyzeTopology(surface);
    if (!t.closed())
      throw InputError("skin solve: the surface of " + muscleLabel(rig, m) + " is not closed (" +
                       std::to_string(t.boundaryEdges) + " boundary edges); a collision surface must be closed");
    if (!t.manifold() || !t.oriented())
      throw InputError("skin solve: the surface of " + muscleLabel(rig, m) +
                       " is not a consistently oriented manifold mesh");
    if (!(enclosedVolume(surface.vertices, surface.triangles) > 0.0))
      throw InputError("skin solve: the surface of " + muscleLabel(rig, m) + " is oriented inwards or flat");
    s.bvh[m].build(surface.vertices, surface.triangles);
    if (selfIntersections(surface.vertices, surface.triangles) > 0) {
      s.bvh[m].setSelfCrossing(true);
      s.report.selfCrossingMuscles.push_back(m);
    }
    s.radius[m] = muscleRadius(rig.muscles()[m], surface);
    s.muscleVertices[m] = surface.numVertices();
    s.allMuscles.push_back(m);
  }

  // Rest depth inside the union, and muscles that overlap at rest.
  s.restDepth = Eigen::VectorXd::Zero(s.nv);
  tbb::parallel_for(tbb::blocked_range<int>(0, s.nv, 1024), [&](const tbb::blocked_range<int>& range) {
    for (int v = range.begin(); v < range.end(); ++v) {
      const Vec3 p = skin.vertices.row(v).transpose();
      for (int m = 0; m < nm; ++m)
        if (s.bvh[m].bounds().contains(p)) s.restDepth[v] = std::max(s.restDepth[v], -s.bvh[m].closest(p).distance);
    }
  });
  for (int v = 0; v < s.nv; ++v)
    if (s.restDepth[v] > 0.0) {
      ++s.report.insideAtRest;
      s.report.maxRestDepth = std::max(s.report.maxRestDepth, s.restDepth[v]);
    }
  for (int a = 0; a < nm; ++a)
    for (int b = 0; b < nm; ++b) {
      if (a == b || !s.bvh[a].bounds().intersects(s.bvh[b].bounds())) continue;
      const Points& va = rig.restSurface(a).vertices;
      bool inside = false;
      for (Eigen::Index i = 0; i < va.rows() && !inside; ++i) {
        const Vec3 p = va.row(i).transpose();
        inside = s.bvh[b].bounds().contains(p) && s.bvh[b].closest(p).distance < 0.0;
      }
      if (inside) s.report.overlappingMuscles.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(s.report.overlappingMuscles.begin(), s.report.overlappingMuscles.end());
  s.report.overlappingMuscles.erase(
      std::unique(s.report.overlappingMuscles.begin(), s.report.overlappingMuscles.end()),
      s.report.overlappingMuscles.end());

  // Regions: connected pieces of sliding skin (goal weight < 1) over the springs.
  std::vector<int> region(s.nv, -1);
  for (int seed = 0; seed < s.nv; ++seed) {
    if (region[seed] >= 0 || !(s.goalWeight[seed] < 1.0)) continue;
    const int r = static_cast<int>(s.regionVertices.size());
    s.regionVertices.emplace_back();
    std::vector<int>& verts = s.regionVertices.back();
    region[seed] = r;
    verts.push_back(seed);
    for (size_t i = 0; i < verts.size(); ++i)
      for (int e = s.ringStart[verts[i]]; e < s.ringStart[verts[i] + 1]; ++e) {
        const int n = s.ring[e];
        if (region[n] < 0 && s.goalWeight[n] < 1.0) {
          region[n] = r;
          verts.push_back(n);
        }
      }
    std::sort(verts.begin(), verts.end());
  }
  // Each region collides with the muscles whose rest surface comes within reach radii of one of its vertices.
  for (const std::vector<int>& verts : s.regionVertices) {
    s.regionMuscles.emplace_back();
    for (int m = 0; m < nm; ++m) {
      const double reach = options.reach * s.radius[m];
      Eigen::AlignedBox3d box = s.bvh[m].bounds();
      box.extend(box.min() - Vec3::Constant(reach));
      box.extend(box.max() + Vec3::Constant(reach));
      for (int v : verts) {
        const Vec3 p = skin.vertices.row(v).transpose();
        if (box.contains(p) && s.bvh[m].closest(p).distance < reach) {
          s.regionMuscles.back().push_back(m);
          break;
        }
      }
    }
    s.report.slidingVertices += static_cast<int>(verts.size());
    s.report.regionSize.push_back(static_cast<int>(verts.size()));
  }
  s.report.regions = static_cast<int>(s.regionVertices.size());
  s.vertexRegion = region;
  for (const std::vector<int>& list : s.regionMuscles) {
    s.otherMuscles.emplace_back();
    for (int m = 0; m < nm; ++m)
      if (!std::binary_search(list.begin(), list.end(), m)) s.otherMuscles.back().push_back(m);
  }
  s.report.regionMuscles = s.regionMuscles;

  s.buffer[0] = skin.vertices;
  s.buffer[1] = skin.vertices;
  s.goal = skin.vertices;
  s.anchorNear = skin.vertices;
  s.anchorFar = skin.vertices;
  s.clearance.assign(s.nv, Impl::Clearance());
}

SkinSolver::~SkinSolver() = default;
SkinSolver::SkinSolver(SkinSolver&&) noexcept = default;
SkinSolver& SkinSolver::operator=(SkinSolver&&) noexcept = default;

int SkinSolver::numVertices() const { return impl_->nv; }
int SkinSolver::numMuscles() const { return static_cast<int>(impl_->bvh.size()); }
const SkinSolveReport& SkinSolver::report() const { return impl_->report; }
const Eigen::VectorXd& SkinSolver::goalWeights() const { return impl_->goalWeight; }
const Eigen::VectorXd& SkinSolver::restDepth() const { return impl_->restDepth; }
const SkinSolveOptions& SkinSolver::options() const { return impl_->options; }

// ============================================================================
// Solve (per frame)
// ============================================================================

void SkinSolver::solve(const Points& goal, const MuscleRigState& state, Points& out) {
  Impl& s = *impl_;
  if (goal.rows() != s.nv)
    throw InputError("skin solve: the goal has " + std::to_string(goal.rows()) + " vertices, the skin " +
                     std::to_string(s.nv));
  if (!goal.allFinite()) throw InputError("skin solve: the goal has a NaN or infinite position");
  s.goal = goal;
  auto body = [&] {
    s.refit(state);
    s.buffer[0] = s.goal;
    s.buffer[1] = s.goal;
    s.run();
  };
  if (s.arena)
    s.arena->execute(body);
  else
    body();
  out = s.buffer[s.options.iterations % 2];
}

void SkinSolver::solve(const PointsF& goal, const MuscleRigState& state, Points& out) {
  Impl& s = *impl_;
  if (goal.rows() != s.nv)
    throw InputError("skin solve: the goal has " + std::to_string(goal.rows()) + " vertices, the skin " +
                     std::to_string(s.nv));
  s.goal = goal.cast<double>();
  solve(s.goal, state, out);
}

void SkinSolver::solveInPlace(PointsF& skin, const MuscleRigState& state) {
  Impl& s = *impl_;
  solve(skin, state, s.result);
  skin = s.result.cast<float>();
}

double SkinSolver::signedDistance(const Vec3& p) const {
  double outside = std::numeric_limits<double>::infinity(), inside = 0.0;
  for (const detail::TriangleBvh& b : impl_->bvh) {
    const double d = b.closest(p).distance;
    if (d < 0)
      inside = std::min(inside, d);
    else
      outside = std::min(outside, d);
  }
  return inside < 0 ? inside : outside;
}

Points solveSkin(const Mesh& skin, const MuscleRig& rig, const SkinWeights& combinedWeights, const Points& goal,
                 const MuscleRigState& state, const SkinSolveOptions& options) {
  SkinSolver solver(skin, rig,
                    defaultGoalWeights(combinedWeights, rig.skeleton().numBones(), options.slide, options.fullShare),
                    options);
  Points out;
  solver.solve(goal, state, out);
  return out;
}

}  // namespace myoskin
