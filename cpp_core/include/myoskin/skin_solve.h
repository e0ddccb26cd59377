// The per-frame skin solve against the muscles (Gray & Hutchinson, "Procedural Muscle and Skin Simulation",
// section 4: "ideal initial conditions every frame"): each frame starts from the skinned pose (Eq. 3) as the
// goal and runs a fixed iteration budget of
//   goal attraction   x <- g x_goal + (1 - g) x_spring  with a per-vertex goal weight g (low where skin slides),
//   edge springs      x_spring = mean over the edge ring of (x_n + L0 (x - x_n) / |x - x_n|), rest lengths L0,
//   collision         push-out of the union of the posed muscle surfaces (closed meshes), so the skin stays on
//                     or outside them and slides over them.
// Nothing is carried from one frame to the next (no drift); the same goal and muscles give the same skin.
//
// Allowed region (the rest-pose subtlety): extracted muscles may poke slightly out of the skin at rest, yet the
// rest pose must return the skin exactly. Chosen rule: at build time every skin vertex's depth inside the
// muscle union at rest is measured (0 when outside); a frame pushes a vertex out only as far as it goes deeper
// than that rest depth (to the rest depth, minus a small margin when that is 0). A vertex outside every muscle
// at rest therefore stays outside every posed muscle, and at rest nothing moves (returned exactly: the springs
// and goal are at rest, no vertex is deeper than allowed).
//
// Containment and depth: each muscle surface keeps a bounding volume hierarchy built once on its rest topology
// and refitted every frame (posed surfaces keep topology); a point's closest surface point gives its distance,
// and the sign comes from the angle-weighted pseudo-normal of the closest feature (face, edge or vertex), which
// is exact on closed, consistently oriented, manifold meshes that do not cross themselves (Baerentzen & Aanaes
// 2005). A muscle whose rest surface crosses itself (lofted sections that overlap where a muscle turns: MakeHuman's
// pectorals and quadriceps) is signed by ray parity instead (majority of three skew rays), as CGAL's
// Side_of_triangle_mesh does. Overlapping muscles are handled as a union: a vertex pushed out of one muscle into
// another is pushed again, up to SkinSolveOptions::collisionRounds times, then it escapes along the way out of the
// muscle that still holds it in doubling steps (up to 8 radii) until it is outside all of them.
//
// Regions: only vertices whose goal weight is below 1 relax; they split into connected pieces of the skin
// (right arm, left leg...), each solved against only the muscles within its reach, pieces in parallel. Vertices
// with goal weight 1 keep the goal unless they went into a muscle, then they are pushed out as above (a last pass
// over the whole skin), so the no-penetration guarantee holds everywhere.
//
// Bad input: a muscle surface that is not closed, not manifold or oriented inwards is an InputError at build
// (naming the muscle); so are goal weights of the wrong size, NaN or outside [0, 1]. Per frame a NaN or wrongly
// sized goal, a state without surfaces or with a NaN vertex is an InputError (a NaN pose is refused by
// MuscleRig::evaluate before); the solver stays usable. Muscles that intersect each other at rest are not an
// error: they collide as a union (report().overlappingMuscles lists them).
//
// Thresholds are relative: the skin's mean edge length and each muscle's mean section radius.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "myoskin/deformation.h"
#include "myoskin/mesh.h"
#include "myoskin/skin_weights.h"
#include "myoskin/skinning.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Options
// ============================================================================

struct SkinSolveOptions {
  int iterations = 10;  // fixed budget per frame: relaxation sweeps (Jacobi)
  // Collision after every collideEvery-th sweep and always after the last (1 = after each; 2 halves the queries).
  int collideEvery = 2;
  // Default goal weight from the skin weights: g = 1 - slide * min(1, share / fullShare), share = the muscle
  // joints' part of the vertex's weight, so skin over a muscle's belly slides most and skin the bones alone move
  // keeps the skinned pose (g = 1). The goal weight blends each iteration: x <- g x_goal + (1 - g) x_spring.
  double slide = 0.95;
  // Muscle share from which the skin slides fully (MakeHuman's skin over the biceps' belly carries 0.25-0.5).
  double fullShare = 0.25;
  // Springs' pull in [0, 1]: the spring target is x + springStiffness (x_spring - x) before the goal blend.
  double springStiffness = 1.0;
  // Margin a pushed-out vertex keeps from a muscle surface, in mean skin edge lengths.
  double pushMargin = 1e-3;
  // A muscle is tested against a region during the iterations when its rest surface comes within reach * its mean
  // section radius of one of the region's rest skin vertices (the last pass tests every vertex against every muscle).
  double reach = 1.0;
  // Projection rounds per collision pass (overlapping muscles: pushed out of one into another).
  int collisionRounds = 3;
  int grainSize = 512;  // vertices per parallel task inside a region
  int threads = 0;      // worker threads; 0 = all cores
};

// What the build found (for reports and tests).
struct SkinSolveReport {
  int regions = 0;              // connected pieces of sliding skin (goal weight < 1)
  int slidingVertices = 0;      // vertices with goal weight < 1
  int insideAtRest = 0;         // skin vertices inside the muscle union at rest (allowed to stay that deep)
  double maxRestDepth = 0.0;    // deepest of those, metres
  double meanEdgeLength = 0.0;  // of the skin at rest, metres
  std::vector<std::pair<int, int>> overlappingMuscles;  // muscle pairs whose rest surfaces intersect
  std::vector<int> selfCrossingMuscles;                 // muscles whose rest surface crosses itself (ray parity)
  std::vector<int> regionSize;                          // vertices per region
  std::vector<std::vector<int>> regionMuscles;          // muscles each region collides with
};

// ============================================================================
// Goal weights
// ============================================================================

// #V goal weights from combined skin weights (#V by K over [0, numBones + #J), computeHybridWeights): g = 1 -
// slide * min(1, share / fullShare), share = (weight on joints >= numBones) / (row sum). A row with no weight gets
// 1. Throws InputError on a bad slide (outside [0, 1]), fullShare (outside (0, 1]) or numBones < 0.
Eigen::VectorXd defaultGoalWeights(const SkinWeights& combinedWeights, int numBones, double slide = 0.95,
                                   double fullShare = 0.25);

// ============================================================================
// The stateful solver: built once (topology, adjacency, regions, rest depths, muscle hierarchies), then
// solve(goal, muscles) per frame without allocation
// ============================================================================

class SkinSolver {
 public:
  // skin: the rest skin (#V, triangles #F by 3); rig: the muscles (their rest surfaces collide; each must be closed
  // and manifold); goalWeights: #V in [0, 1] (defaultGoalWeights). Throws InputError on mismatched sizes,
  // non-finite or out-of-range weights, a muscle surface that is empty, open, non-manifold or inconsistently
  // oriented (naming the muscle), or bad options.
  SkinSolver(const Mesh& skin, const MuscleRig& rig, const Eigen::VectorXd& goalWeights,
             const SkinSolveOptions& options = {});
  ~SkinSolver();
  SkinSolver(SkinSolver&&) noexcept;
  SkinSolver& operator=(SkinSolver&&) noexcept;

  int numVertices() const;
  int numMuscles() const;
  const SkinSolveReport& report() const;
  const Eigen::VectorXd& goalWeights() const;  // #V
  const Eigen::VectorXd& restDepth() const;    // #V depth inside the muscle union at rest (0 outside), metres
  const SkinSolveOptions& options() const;

  // One frame. goal: #V by 3 skinned positions; state: the rig evaluated at the frame's pose with surfaces
  // (MuscleRig::evaluate(pose, state, true)); out: #V by 3 (resized only if its size differs). Throws InputError
  // on a wrong size, non-finite goal or muscle vertex, or a state without surfaces. Not thread-safe (uses the
  // solver's scratch buffers); no allocation once out has its size.
  void solve(const Points& goal, const MuscleRigState& state, Points& out);
  void solve(const PointsF& goal, const MuscleRigState& state, Points& out);
  // In place on float32 positions, the shape of Simulation's SkinSolveHook (secondary_motion.h): skin holds the
  // goal on entry and the solved skin on exit, e.g. sim.setSkinSolve([&](int, const Pose&, const MuscleRigState* rig,
  // PointsF& skin) { if (rig) solver.solveInPlace(skin, *rig); }) with the rig evaluated with surfaces.
  void solveInPlace(PointsF& skin, const MuscleRigState& state);

  // Signed distance of a point to the muscle union as last refitted (rest at build, then the last solve's pose):
  // negative inside. For tests and tools.
  double signedDistance(const Vec3& p) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// One-shot: build a solver with default goal weights from combinedWeights and solve one frame.
Points solveSkin(const Mesh& skin, const MuscleRig& rig, const SkinWeights& combinedWeights, const Points& goal,
                 const MuscleRigState& state, const SkinSolveOptions& options = {});

}  // namespace myoskin
