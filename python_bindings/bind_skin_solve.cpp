// The per-frame skin solve against the muscles (skin_solve.h): SkinSolver and default_goal_weights.
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "bindings.h"
#include "myoskin/character.h"
#include "myoskin/errors.h"
#include "myoskin/skin_solve.h"

namespace myoskin::python {

namespace {


// #V by K joints and weights (same shape) -> SkinWeights.
SkinWeights combinedWeightsArg(const IntArray& joints, const DoubleArray& weights) {
  if (joints.ndim() != 2 || weights.ndim() != 2 || joints.shape(0) != weights.shape(0) ||
      joints.shape(1) != weights.shape(1))
    throw InputError("default_goal_weights: joints and weights must be #V by K arrays of the same shape");
  SkinWeights w;
  w.joints.resize(joints.shape(0), joints.shape(1));
  w.weights.resize(weights.shape(0), weights.shape(1));
  std::copy(joints.data(), joints.data() + joints.size(), w.joints.data());
  std::copy(weights.data(), weights.data() + weights.size(), w.weights.data());
  return w;
}

// The solver with its output buffer; the mutex serialises callers (solve runs without the GIL).
struct PySkinSolver {
  std::unique_ptr<SkinSolver> solver;
  Points goal, out;
  std::mutex mutex;
};

}  // namespace

void bindSkinSolve(py::module_& m) {
  m.def(
      "default_goal_weights",
      [](const IntArray& joints, const DoubleArray& weights, int numBones, double slide, double fullShare) {
        const SkinWeights w = combinedWeightsArg(joints, weights);
        return defaultGoalWeights(w, numBones, slide, fullShare);
      },
      py::arg("joints"), py::arg("weights"), py::arg("num_bones"), py::arg("slide") = SkinSolveOptions{}.slide,
      py::arg("full_share") = SkinSolveOptions{}.fullShare,
      "#V goal weights from combined skin weights (hybrid_weights: #V by K over bones then muscle joints): "
      "1 - slide * min(1, share / full_share), share = the muscle joints' part of each vertex's weight.");

  py::class_<PySkinSolver>(m, "SkinSolver",
                           "The per-frame skin solve (Gray & Hutchinson): from the skinned pose as goal, a fixed budget "
                           "of goal attraction, edge springs and push-out of the posed muscles. Built once, then "
                           "solve(goal, rig) per frame.")
      .def(py::init([](const Character& c, PyMuscleRig& rig, const Eigen::VectorXd& goalWeights, int iterations,
                       double slide, double springStiffness, double pushMargin, double reach, int collisionRounds,
                       int collideEvery, int grainSize, int threads) {
             SkinSolveOptions o;
             o.iterations = iterations;
             o.slide = slide;
             o.springStiffness = springStiffness;
             o.pushMargin = pushMargin;
             o.reach = reach;
             o.collisionRounds = collisionRounds;
             o.collideEvery = collideEvery;
             o.grainSize = grainSize;
             o.threads = threads;
             auto p = std::make_unique<PySkinSolver>();
             py::gil_scoped_release release;
             p->solver = std::make_unique<SkinSolver>(c.mesh, rig, goalWeights, o);
             return p;
           }),
           py::arg("character"), py::arg("rig"), py::arg("goal_weights"),
           py::arg("iterations") = SkinSolveOptions{}.iterations, py::arg("slide") = SkinSolveOptions{}.slide,
           py::arg("spring_stiffness") = SkinSolveOptions{}.springStiffness,
           py::arg("push_margin") = SkinSolveOptions{}.pushMargin, py::arg("reach") = SkinSolveOptions{}.reach,
           py::arg("collision_rounds") = SkinSolveOptions{}.collisionRounds,
           py::arg("collide_every") = SkinSolveOptions{}.collideEvery,
           py::arg("grain_size") = SkinSolveOptions{}.grainSize, py::arg("threads") = SkinSolveOptions{}.threads,
           "goal_weights: #V in [0, 1] (default_goal_weights). ValueError on a muscle surface that is not closed, "
           "weights of the wrong size or out of range, bad options.")
      .def(
          "solve",
          [](PySkinSolver& s, const DoubleArray& goal, PyMuscleRig& rig, const py::object& poseMatrices) {
            if (goal.ndim() != 2 || goal.shape(1) != 3) throw InputError("solve: goal must be #V by 3");
            s.goal.resize(goal.shape(0), 3);
            std::copy(goal.data(), goal.data() + goal.size(), s.goal.data());
            std::optional<Pose> pose;
            if (!poseMatrices.is_none())
              pose = poseFromArray(poseMatrices.cast<MatrixStack>(), rig.skeleton().numBones());
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lockRig(rig.mutex);
              std::lock_guard<std::mutex> lock(s.mutex);
              if (pose) rig.evaluate(*pose, rig.state, true);
              s.solver->solve(s.goal, rig.state, s.out);
            }
            return Points(s.out);
          },
          py::arg("goal"), py::arg("rig"), py::arg("pose_matrices") = py::none(),
          "goal: #V by 3 skinned positions (Skinner.deform). With pose_matrices (#B by 4 by 4) the rig is evaluated "
          "with surfaces first; without, the rig's last evaluate(..., with_surfaces=True) is used. Returns #V by 3.")
      .def_property_readonly("report",
                             [](const PySkinSolver& s) {
                               const SkinSolveReport& r = s.solver->report();
                               py::dict d;
                               d["regions"] = r.regions;
                               d["sliding_vertices"] = r.slidingVertices;
                               d["inside_at_rest"] = r.insideAtRest;
                               d["max_rest_depth"] = r.maxRestDepth;
                               d["mean_edge_length"] = r.meanEdgeLength;
                               d["overlapping_muscles"] = r.overlappingMuscles;
                               d["region_size"] = r.regionSize;
                               d["region_muscles"] = r.regionMuscles;
                               return d;
                             })
      .def_property_readonly("goal_weights", [](const PySkinSolver& s) { return s.solver->goalWeights(); })
      .def_property_readonly("rest_depth", [](const PySkinSolver& s) { return s.solver->restDepth(); },
                             "#V depth inside the muscle union at rest (0 outside)")
      .def(
          "signed_distance",
          [](const PySkinSolver& s, const DoubleArray& points) {
            if (points.ndim() != 2 || points.shape(1) != 3) throw InputError("signed_distance: points must be #P by 3");
            Eigen::VectorXd d(points.shape(0));
            for (py::ssize_t i = 0; i < points.shape(0); ++i)
              d[i] = s.solver->signedDistance(Vec3(points.at(i, 0), points.at(i, 1), points.at(i, 2)));
            return d;
          },
          py::arg("points"), "#P signed distances to the muscle union as last solved (negative inside)");
}

}  // namespace myoskin::python
