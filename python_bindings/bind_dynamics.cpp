// Secondary motion: the jiggle track, the temporal filter, sculpt deltas and the (chunked) simulation into
// arrays or PC2 caches. Arrays are checked here (ValueError naming the argument); long calls release the GIL.
#include <algorithm>
#include <memory>
#include <mutex>
#include <optional>

#include "bindings.h"
#include "myoskin/character.h"
#include "myoskin/errors.h"
#include "myoskin/secondary_motion.h"
#include "myoskin/skin_solve.h"

namespace myoskin::python {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

// #F by #B by 4 by 4 posed bone matrices -> a sequence starting at startFrame.
PoseSequence sequenceArg(const DoubleArray& a, int numBones, double startFrame) {
  if (a.ndim() != 4 || a.shape(1) != numBones || a.shape(2) != 4 || a.shape(3) != 4)
    throw InputError("poses must be #F by " + std::to_string(numBones) + " by 4 by 4 (posed bone matrices per frame)");
  PoseSequence s;
  s.startFrame = startFrame;
  auto v = a.unchecked<4>();
  s.frames.resize(a.shape(0));
  for (py::ssize_t f = 0; f < a.shape(0); ++f) {
    s.frames[f].matrices.resize(numBones);
    for (int b = 0; b < numBones; ++b)
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) s.frames[f].matrices[b](r, c) = v(f, b, r, c);
  }
  return s;
}

// #V by 3 float64 points from any array of that shape.
Points dynamicsPointsArg(const DoubleArray& a, const char* name) {
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError(std::string(name) + " must be #V by 3");
  Points p(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), p.data());
  return p;
}

py::array_t<double> vecsToArray(const std::vector<Vec3>& v) {
  py::array_t<double> out({static_cast<py::ssize_t>(v.size()), py::ssize_t(3)});
  auto a = out.mutable_unchecked<2>();
  for (size_t i = 0; i < v.size(); ++i)
    for (int k = 0; k < 3; ++k) a(i, k) = v[i][k];
  return out;
}

JiggleOptions jiggleOptions(double timeStep, double frequency, double sizeExponent, double dampingRatio, double density,
                            double amount, double maxOffset) {
  JiggleOptions o;
  o.timeStep = timeStep;
  o.frequency = frequency;
  o.sizeExponent = sizeExponent;
  o.dampingRatio = dampingRatio;
  o.density = density;
  o.amount = amount;
  o.maxOffset = maxOffset;
  return o;
}

// #M by 3 (mass, stiffness, damping) or None.
std::vector<JiggleParams> paramsArg(const py::object& a) {
  std::vector<JiggleParams> p;
  if (a.is_none()) return p;
  const DoubleArray arr = a.cast<DoubleArray>();
  if (arr.ndim() != 2 || arr.shape(1) != 3) throw InputError("params must be #M by 3 (mass, stiffness, damping)");
  for (py::ssize_t i = 0; i < arr.shape(0); ++i) p.push_back({arr.at(i, 0), arr.at(i, 1), arr.at(i, 2)});
  return p;
}

std::vector<double> influenceArg(const py::object& a) {
  if (a.is_none()) return {};
  const DoubleArray arr = a.cast<DoubleArray>();
  if (arr.ndim() != 1) throw InputError("influence must be a #J array");
  return std::vector<double>(arr.data(), arr.data() + arr.size());
}

Triangles trianglesArg(const IntArray& a) {
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError("triangles must be #F by 3");
  Triangles t(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), t.data());
  return t;
}

// #V flags (nonzero: the delta is in the local frame).
std::vector<char> framedArg(const py::object& a, Eigen::Index numVertices) {
  const py::array_t<int32_t, py::array::c_style | py::array::forcecast> arr = a.cast<py::array_t<int32_t, py::array::c_style | py::array::forcecast>>();
  if (arr.ndim() != 1 || arr.shape(0) != numVertices)
    throw InputError("framed must be #V (" + std::to_string(numVertices) + ") flags");
  std::vector<char> f(numVertices);
  for (Eigen::Index v = 0; v < numVertices; ++v) f[v] = arr.at(v) != 0;
  return f;
}

// #F by #V by 3 offsets (None: none) -> one PointsF per frame; frames whose offsets are all zero stay empty.
std::vector<PointsF> shapeOffsetsArg(const py::object& a, size_t numFrames, Eigen::Index numVertices) {
  std::vector<PointsF> out;
  if (a.is_none()) return out;
  const FloatArray arr = a.cast<FloatArray>();
  if (arr.ndim() != 3 || static_cast<size_t>(arr.shape(0)) != numFrames || arr.shape(1) != numVertices ||
      arr.shape(2) != 3)
    throw InputError("shape_offsets must be #F (" + std::to_string(numFrames) + ", the poses) by #V (" +
                     std::to_string(numVertices) + ") by 3");
  out.resize(numFrames);
  const size_t stride = static_cast<size_t>(numVertices) * 3;
  for (size_t f = 0; f < numFrames; ++f) {
    const float* p = arr.data() + f * stride;
    if (std::all_of(p, p + stride, [](float x) { return x == 0.0f; })) continue;
    out[f].resize(numVertices, 3);
    std::copy(p, p + stride, out[f].data());
  }
  return out;
}

// The jiggle track with the rig and sequence it was built from (joint_matrices evaluates the rig per frame).
struct PyJiggle {
  std::shared_ptr<MuscleRig> rig;
  PoseSequence poses;
  double fps = 24.0;
  std::unique_ptr<JiggleTrack> track;
  MuscleRigState state;
  std::mutex mutex;

  std::vector<std::string> muscleNames() const {
    std::vector<std::string> names;
    for (const Muscle& m : rig->muscles()) names.push_back(m.name);
    return names;
  }
};

}  // namespace

void bindDynamics(py::module_& m) {
  const JiggleOptions jd;
  // ==========================================================================
  // Jiggle
  // ==========================================================================
  py::class_<PyJiggle>(m, "JiggleTrack",
                       "Jiggle of the muscle masses over a pose sequence: one damped spring per muscle on a fixed "
                       "time grid (the same result whatever frames are asked for, in any order).")
      .def(py::init([](const Character& c, const PyMuscleRig& rig, const DoubleArray& poses, double fps,
                       double startFrame, double timeStep, double frequency, double sizeExponent, double dampingRatio,
                       double density, double amount, double maxOffset, const py::object& params,
                       const py::object& influence) {
             if (rig.skeleton().numBones() != c.skeleton.numBones())
               throw InputError("JiggleTrack: the rig was built for another skeleton");
             auto j = std::make_unique<PyJiggle>();
             j->rig = std::make_shared<MuscleRig>(static_cast<const MuscleRig&>(rig));
             j->poses = sequenceArg(poses, c.skeleton.numBones(), startFrame);
             j->fps = fps;
             const JiggleOptions o =
                 jiggleOptions(timeStep, frequency, sizeExponent, dampingRatio, density, amount, maxOffset);
             std::vector<JiggleParams> p = paramsArg(params);
             std::vector<double> w = influenceArg(influence);
             py::gil_scoped_release release;
             j->track = std::make_unique<JiggleTrack>(*j->rig, j->poses, fps, o, std::move(p), std::move(w));
             j->state = j->rig->makeState();
             return j;
           }),
           py::arg("character"), py::arg("rig"), py::arg("poses"), py::arg("fps") = 24.0, py::arg("start_frame") = 1.0,
           py::kw_only(), py::arg("time_step") = jd.timeStep, py::arg("frequency") = jd.frequency,
           py::arg("size_exponent") = jd.sizeExponent, py::arg("damping_ratio") = jd.dampingRatio,
           py::arg("density") = jd.density, py::arg("amount") = jd.amount, py::arg("max_offset") = jd.maxOffset,
           py::arg("params") = py::none(), py::arg("influence") = py::none(),
           "poses: #F by #B by 4 by 4 posed bone matrices of frames start_frame, start_frame + 1, ... at fps. "
           "params: #M by 3 (mass, stiffness, damping) or None (defaults by muscle size); influence: #J or None "
           "(fading toward the tendons). time_step in seconds, frequency in Hz (of the median muscle), "
           "damping_ratio of critical, max_offset in muscle radii.")
      .def(
          "offsets",
          [](PyJiggle& j, double frame) {
            std::vector<Vec3> o;
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(j.mutex);
              j.track->offsets(frame, o);
            }
            return vecsToArray(o);
          },
          py::arg("frame"), "#M by 3 offsets of the muscles' masses at a frame (limited, times amount).")
      .def(
          "spring_offsets",
          [](PyJiggle& j, double frame) {
            std::vector<Vec3> o;
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(j.mutex);
              j.track->springOffsets(frame, o);
            }
            return vecsToArray(o);
          },
          py::arg("frame"), "#M by 3 offsets of the springs themselves (no limit, no amount).")
      .def(
          "joint_matrices",
          [](PyJiggle& j, int frame) {
            std::vector<Mat4> out;
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(j.mutex);
              const int i = frame - static_cast<int>(j.poses.startFrame);
              if (i < 0 || i >= static_cast<int>(j.poses.frames.size()))
                throw InputError("joint_matrices: frame " + std::to_string(frame) + " is outside the sequence");
              j.rig->evaluate(j.poses.frames[i], j.state);
              j.track->apply(frame, j.state);
              out = j.state.jointMatrices;
            }
            return matricesToArray(out);
          },
          py::arg("frame"),
          "#J by 4 by 4 muscle joint matrices of a frame moved by the jiggle (what a bake keys into the Action).")
      .def_property_readonly("params",
                             [](const PyJiggle& j) {
                               py::array_t<double> a({static_cast<py::ssize_t>(j.track->params().size()), py::ssize_t(3)});
                               auto v = a.mutable_unchecked<2>();
                               for (size_t i = 0; i < j.track->params().size(); ++i) {
                                 const JiggleParams& p = j.track->params()[i];
                                 v(i, 0) = p.mass, v(i, 1) = p.stiffness, v(i, 2) = p.damping;
                               }
                               return a;
                             },
                             "#M by 3: mass, stiffness, damping")
      .def_property_readonly("influence", [](const PyJiggle& j) { return j.track->influence(); })
      .def_property_readonly("first_frame", [](const PyJiggle& j) { return j.track->firstFrame(); })
      .def_property_readonly("last_frame", [](const PyJiggle& j) { return j.track->lastFrame(); })
      .def(
          "write_state",
          [](PyJiggle& j, const std::string& path, int frame) {
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(j.mutex);
            SimulationState s;
            s.frame = frame;
            s.fps = j.fps;
            s.timeStep = j.track->options().timeStep;
            s.startFrame = static_cast<int>(j.poses.startFrame);
            s.muscles = j.muscleNames();
            s.hasJiggle = true;
            s.jiggle = j.track->stateAt(frame);
            writeSimulationState(path, s);
          },
          py::arg("path"), py::arg("frame"),
          "Writes the state of a frame to a simulation state file (the format simulate's state_out writes), so a "
          "later chunk continues from it (restore_state).")
      .def(
          "restore_state",
          [](PyJiggle& j, const std::string& path) {
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(j.mutex);
            const SimulationState s = readSimulationState(path);
            const std::string why = path + ": the state was made ";
            if (!s.hasJiggle) throw InputError(why + "without jiggle");
            if (s.fps != j.fps) throw InputError(why + "at " + std::to_string(s.fps) + " fps, this track is at " + std::to_string(j.fps));
            if (s.startFrame != static_cast<int>(j.poses.startFrame))
              throw InputError(why + "for a simulation from frame " + std::to_string(s.startFrame));
            if (s.timeStep != j.track->options().timeStep) throw InputError(why + "with another jiggle time step");
            if (s.muscles != j.muscleNames()) throw InputError(why + "for other muscles");
            if (j.track->stepOf(s.frame) != s.jiggle.step)
              throw InputError(why + "for another frame than it says (grid step " + std::to_string(s.jiggle.step) + ")");
            j.track->restore(s.jiggle);
            return s.frame;
          },
          py::arg("path"),
          "Continues from a simulation state file (write_state's or simulate's state_out, same settings): frames "
          "from its frame on are computed from it, not replayed. Returns the state's frame.");

  // ==========================================================================
  // Temporal filter
  // ==========================================================================
  m.def(
      "temporal_filter",
      [](const FloatArray& frames, double lengthScale, double relativeTolerance, double absoluteTolerance) {
        if (frames.ndim() != 3 || frames.shape(2) != 3) throw InputError("frames must be #F by #V by 3");
        const py::ssize_t F = frames.shape(0), V = frames.shape(1);
        std::vector<PointsF> in(F, PointsF(V, 3)), out;
        for (py::ssize_t f = 0; f < F; ++f) std::copy(frames.data() + f * V * 3, frames.data() + (f + 1) * V * 3, in[f].data());
        TemporalFilterOptions o;
        o.relativeTolerance = relativeTolerance;
        o.absoluteTolerance = absoluteTolerance;
        int pulled = 0;
        {
          py::gil_scoped_release release;
          pulled = filterFrames(in, lengthScale, o, out);
        }
        py::array_t<float> result({F, V, py::ssize_t(3)});
        for (py::ssize_t f = 0; f < F; ++f) std::copy(out[f].data(), out[f].data() + V * 3, result.mutable_data() + f * V * 3);
        return py::make_tuple(result, pulled);
      },
      py::arg("frames"), py::arg("length_scale"), py::arg("relative_tolerance") = TemporalFilterOptions{}.relativeTolerance,
      py::arg("absolute_tolerance") = TemporalFilterOptions{}.absoluteTolerance,
      "(filtered #F by #V by 3 float32, vertices pulled back): each inner frame's vertices tested against the line "
      "through their previous and next positions; deviations past relative_tolerance x |next - previous| + "
      "absolute_tolerance x length_scale (the skin's mean edge length) are pulled back to it.");
  m.def(
      "mean_edge_length",
      [](const DoubleArray& v, const IntArray& t) {
        if (t.ndim() != 2 || t.shape(1) != 3) throw InputError("triangles must be #F by 3");
        Triangles tri(t.shape(0), 3);
        std::copy(t.data(), t.data() + t.size(), tri.data());
        return meanEdgeLength(dynamicsPointsArg(v, "vertices"), tri);
      },
      py::arg("vertices"), py::arg("triangles"), "The mesh's mean edge length (the temporal filter's length scale).");

  // ==========================================================================
  // Sculpt deltas
  // ==========================================================================
  py::class_<SculptDeltas>(m, "SculptDeltas",
                           "Detail sculpted on one frame, kept in the surface's local frame (normal, edge tangent) "
                           "and re-applied on any frame.")
      .def(py::init([](const DoubleArray& reference, const IntArray& triangles, const DoubleArray& sculpted) {
             const Points r = dynamicsPointsArg(reference, "reference"), s = dynamicsPointsArg(sculpted, "sculpted");
             const Triangles t = trianglesArg(triangles);
             py::gil_scoped_release release;
             return std::make_unique<SculptDeltas>(r, t, s);
           }),
           py::arg("reference"), py::arg("triangles"), py::arg("sculpted"))
      .def_static(
          "from_local",
          [](const IntArray& triangles, const DoubleArray& localDeltas, const py::object& framed) {
            const Points l = dynamicsPointsArg(localDeltas, "local_deltas");
            const Triangles t = trianglesArg(triangles);
            const std::vector<char> f = framedArg(framed, l.rows());
            py::gil_scoped_release release;
            return std::make_unique<SculptDeltas>(t, l, f);
          },
          py::arg("triangles"), py::arg("local_deltas"), py::arg("framed"),
          "Deltas captured before: local_deltas (#V by 3) and framed (#V, nonzero where the delta is in the local "
          "frame) as another SculptDeltas over the same mesh gave them.")
      .def_property_readonly("framed",
                             [](const SculptDeltas& d) {
                               const auto n = static_cast<py::ssize_t>(d.framed().size());
                               py::array_t<bool> a(py::array::ShapeContainer{n});  // not (n): see indexArray
                               for (size_t v = 0; v < d.framed().size(); ++v) a.mutable_at(v) = d.framed()[v] != 0;
                               return a;
                             },
                             "#V bools: the delta is in the local frame (else in world space)")
      .def(
          "apply",
          [](SculptDeltas& d, const DoubleArray& positions) {
            const Points p = dynamicsPointsArg(positions, "positions");
            Points out;
            {
              py::gil_scoped_release release;
              d.apply(p, out);
            }
            return out;
          },
          py::arg("positions"), "#V by 3 positions with the detail added in their own local frames.")
      .def_property_readonly("local_deltas", &SculptDeltas::localDeltas, "#V by 3 (tangent, binormal, normal)");

  // ==========================================================================
  // Simulation
  // ==========================================================================
  m.def(
      "simulate",
      [](const Character& c, const std::shared_ptr<Skinner>& skinner, const DoubleArray& poses, const py::object& rig,
         double fps, int startFrame, bool jiggle, bool filter, const py::object& sculpt, const py::object& sculptFrame,
         const py::object& frames, const py::object& stateIn, const py::object& stateOut, const py::object& pc2,
         double jiggleFrequency, double jiggleDamping, double jiggleAmount, const py::object& skinSolve,
         const py::object& jiggleParams, const py::object& jiggleInfluence, const py::object& jiggleVertexInfluence,
         const py::object& shapeOffsets, const py::object& sculptDeltas) {
        const PyMuscleRig* r = rig.is_none() ? nullptr : &rig.cast<const PyMuscleRig&>();
        std::optional<Eigen::VectorXd> goalWeights;
        if (!skinSolve.is_none()) {
          if (!r) throw InputError("simulate: skin_solve needs the rig");
          goalWeights = skinSolve.cast<Eigen::VectorXd>();
        }
        const PoseSequence seq = sequenceArg(poses, c.skeleton.numBones(), startFrame);
        SimulationOptions o;
        o.fps = fps;
        o.jiggle = jiggle;
        o.filter = filter;
        o.jiggleOptions.frequency = jiggleFrequency;
        o.jiggleOptions.dampingRatio = jiggleDamping;
        o.jiggleOptions.amount = jiggleAmount;
        o.jiggleParams = paramsArg(jiggleParams);
        o.jiggleInfluence = influenceArg(jiggleInfluence);
        o.jiggleVertexInfluence = influenceArg(jiggleVertexInfluence);
        std::vector<PointsF> offsets = shapeOffsetsArg(shapeOffsets, seq.frames.size(), c.mesh.numVertices());
        std::optional<SculptDeltas> deltas;
        if (!sculptDeltas.is_none()) {
          if (!sculpt.is_none()) throw InputError("simulate: give sculpt or sculpt_deltas, not both");
          const SculptDeltas& given = sculptDeltas.cast<const SculptDeltas&>();
          deltas.emplace(c.mesh.triangles, given.localDeltas(), given.framed());  // a copy of its own (buffers)
        }
        std::optional<Points> sculpted;
        if (!sculpt.is_none()) sculpted = dynamicsPointsArg(sculpt.cast<DoubleArray>(), "sculpt");
        int first = startFrame, last = startFrame + static_cast<int>(seq.frames.size()) - 1;
        if (!frames.is_none()) {
          const auto range = frames.cast<std::pair<int, int>>();
          first = range.first, last = range.second;
        }
        const int sculptAt = sculptFrame.is_none() ? startFrame : sculptFrame.cast<int>();
        const std::string inPath = stateIn.is_none() ? "" : stateIn.cast<std::string>();
        const std::string outPath = stateOut.is_none() ? "" : stateOut.cast<std::string>();
        const std::string pc2Path = pc2.is_none() ? "" : pc2.cast<std::string>();
        if (last < first) throw InputError("simulate: frames (first, last) with last >= first");
        py::array_t<float> result;
        float* data = nullptr;
        if (pc2Path.empty()) {
          result = py::array_t<float>({static_cast<py::ssize_t>(last - first + 1),
                                       static_cast<py::ssize_t>(c.mesh.numVertices()), py::ssize_t(3)});
          data = result.mutable_data();
        }
        {
          py::gil_scoped_release release;
          Simulation sim(c.mesh, c.skeleton, r, skinner, seq, o);
          if (!offsets.empty()) sim.setShapeOffsets(std::move(offsets));
          if (deltas) sim.setSculpt(std::move(*deltas));
          std::unique_ptr<SkinSolver> solver;
          Points solved;
          if (goalWeights) {
            solver = std::make_unique<SkinSolver>(c.mesh, *r, *goalWeights);
            sim.setSkinSolve([&](int, const Pose&, const MuscleRigState* state, PointsF& skin) {
              solver->solve(skin, *state, solved);
              skin = solved.cast<float>();
            });
          }
          if (sculpted) sim.setSculpt(*sculpted, sculptAt);
          std::optional<SimulationState> in;
          if (!inPath.empty()) in = readSimulationState(inPath);
          std::unique_ptr<PC2Writer> writer;
          if (!pc2Path.empty()) writer = std::make_unique<PC2Writer>(pc2Path, c.mesh.numVertices(), float(first), 1.0f);
          const size_t stride = static_cast<size_t>(c.mesh.numVertices()) * 3;
          const SimulationState end = sim.bake(
              first, last,
              [&](int f, const PointsF& p) {
                if (writer)
                  writer->writeFrame(p);
                else
                  std::copy(p.data(), p.data() + stride, data + (f - first) * stride);
              },
              in ? &*in : nullptr);
          if (writer) writer->close();
          if (!outPath.empty()) writeSimulationState(outPath, end);
        }
        if (pc2Path.empty()) return py::object(result);
        return py::object(py::none());
      },
      py::arg("character"), py::arg("skinner"), py::arg("poses"), py::arg("rig") = py::none(), py::arg("fps") = 24.0,
      py::arg("start_frame") = 1, py::kw_only(), py::arg("jiggle") = false, py::arg("filter") = false,
      py::arg("sculpt") = py::none(), py::arg("sculpt_frame") = py::none(), py::arg("frames") = py::none(),
      py::arg("state_in") = py::none(), py::arg("state_out") = py::none(), py::arg("pc2") = py::none(),
      py::arg("jiggle_frequency") = jd.frequency, py::arg("jiggle_damping") = jd.dampingRatio,
      py::arg("jiggle_amount") = jd.amount, py::arg("skin_solve") = py::none(), py::arg("jiggle_params") = py::none(),
      py::arg("jiggle_influence") = py::none(), py::arg("jiggle_vertex_influence") = py::none(),
      py::arg("shape_offsets") = py::none(), py::arg("sculpt_deltas") = py::none(),
      "Simulates the pose sequence (#F by #B by 4 by 4, frames start_frame ...) on the character through the "
      "skinner (built over its bones + the rig's joints): jiggle of the muscle masses, the temporal filter, "
      "sculpt (#V by 3, the skin sculpted on sculpt_frame). frames=(first, last) bakes a chunk; state_in / "
      "state_out are the state files that stitch chunks; skin_solve: #V goal weights "
      "(default_goal_weights) to solve the skin against the posed muscles every frame (SkinSolver); jiggle_params (#M by 3) and "
      "jiggle_influence (#J) as JiggleTrack's; jiggle_vertex_influence: #V in [0, 1], the share of the "
      "jiggle each skin vertex gets (0: plain skinning, 1: the full jiggle); shape_offsets: #F (the poses) by #V by 3 "
      "offsets of the rest mesh per frame (e.g. the shape key mix), skinned with each vertex's blended transform; "
      "sculpt_deltas: a SculptDeltas (e.g. SculptDeltas.from_local of stored deltas) applied on every frame. Returns #frames by #V by 3 float32, or writes pc2.");
}

}  // namespace myoskin::python
