// Anchored skin (issue 17): the second deformer, numpy in and out, the GIL released while it evaluates.
#include <memory>
#include <mutex>

#include "bindings.h"
#include "myoskin/anchored_skin.h"
#include "myoskin/character.h"
#include "myoskin/errors.h"

namespace myoskin::python {

namespace {

// The deformer with its output buffer; the mutex serialises callers (the deformer's scratch is its own).
struct PyAnchoredSkin {
  std::unique_ptr<AnchoredSkin> skin;
  std::vector<std::string> boneNames;
  std::mutex mutex;
};

ComponentKind kindFromName(const std::string& name) {
  for (ComponentKind k : {ComponentKind::MuscleEllipsoid, ComponentKind::MuscleCylinder, ComponentKind::Stuffing,
                          ComponentKind::BoneCapsule, ComponentKind::JointSphere})
    if (name == componentKindName(k)) return k;
  throw InputError("unknown component kind '" + name +
                   "' (muscle_ellipsoid, muscle_cylinder, stuffing, bone_capsule, joint_sphere)");
}

int boneArg(const Character& c, const py::dict& d, const char* key) {
  if (!d.contains(key)) throw InputError(std::string("component needs '") + key + "'");
  const std::string name = py::cast<std::string>(d[key]);
  const int b = c.skeleton.find(name);
  if (b < 0) throw InputError(std::string("component: ") + key + " '" + name + "' is not a bone of the character");
  return b;
}

Vec3 vecArg(const py::dict& d, const char* key, const Vec3& fallback) {
  return d.contains(key) ? py::cast<Vec3>(d[key]) : fallback;
}

// An authored component from a dict: {"kind": "stuffing", "name", "bone", "center", "radii", "axes" (3x3 columns,
// optional)} or {"kind": "muscle_ellipsoid", "name", "origin_bone", "origin", "insertion_bone", "insertion",
// "start_ratio", "end_ratio", "radius_x", "radius_z", "bulge" (1), "x_hint" ((0, 0, 1))}.
AnchoredComponent componentFromDict(const Character& c, const py::dict& d) {
  const ComponentKind kind = kindFromName(d.contains("kind") ? py::cast<std::string>(d["kind"]) : "stuffing");
  const std::string name = d.contains("name") ? py::cast<std::string>(d["name"]) : std::string("authored");
  if (kind == ComponentKind::MuscleEllipsoid) {
    auto num = [&](const char* key, double fallback) { return d.contains(key) ? py::cast<double>(d[key]) : fallback; };
    return makeEllipsoidMuscle(name, boneArg(c, d, "origin_bone"), vecArg(d, "origin", Vec3::Zero()),
                               boneArg(c, d, "insertion_bone"), vecArg(d, "insertion", Vec3::Zero()),
                               num("start_ratio", 0.2), num("end_ratio", 0.8), num("radius_x", 0.0),
                               num("radius_z", 0.0), vecArg(d, "x_hint", Vec3::UnitZ()), num("bulge", 1.0));
  }
  if (kind != ComponentKind::Stuffing) throw InputError("authored components are stuffing or muscle_ellipsoid");
  AnchoredComponent a;
  a.kind = kind;
  a.name = name;
  a.bone = boneArg(c, d, "bone");
  a.center = vecArg(d, "center", Vec3::Zero());
  a.radii = vecArg(d, "radii", Vec3::Zero());
  if (d.contains("axes")) a.axes = py::cast<Mat3>(d["axes"]);
  return a;
}

py::dict componentToDict(const AnchoredComponent& a, const std::vector<std::string>& names) {
  py::dict d;
  d["kind"] = componentKindName(a.kind);
  d["name"] = a.name;
  d["bone"] = a.bone >= 0 ? names[a.bone] : std::string();
  d["insertion_bone"] = a.insertionBone >= 0 ? names[a.insertionBone] : std::string();
  d["center"] = a.center;
  d["axes"] = a.axes;
  d["radii"] = a.radii;
  d["half_length"] = a.halfLength;
  d["origin"] = a.origin;
  d["insertion"] = a.insertion;
  d["start_ratio"] = a.startRatio;
  d["end_ratio"] = a.endRatio;
  d["bulge"] = a.bulge;
  d["sections"] = static_cast<int>(a.sections.size());
  return d;
}

}  // namespace

void bindAnchored(py::module_& m) {
  m.def(
      "closest_point_on_ellipsoid",
      [](const Vec3& radii, const Vec3& point, double tolerance, int maxIterations) {
        EllipsoidSolverOptions o{tolerance, maxIterations};
        const EllipsoidClosest c = closestPointOnEllipsoid(radii, point, o);
        return py::make_tuple(c.point, c.distance, c.iterations);
      },
      py::arg("radii"), py::arg("point"), py::arg("tolerance") = EllipsoidSolverOptions{}.tolerance,
      py::arg("max_iterations") = EllipsoidSolverOptions{}.maxIterations,
      "Nearest point on the axis-aligned ellipsoid with these radii to point (its own frame), by Newton-Raphson: "
      "(point, distance, iterations). ValueError on a non-positive radius or a non-finite point.");

  py::class_<PyAnchoredSkin>(
      m, "AnchoredSkin",
      "The anchored-skin deformer (Schneider & Wilhelms 1998; Arabaci 2001): the skin anchored once to the "
      "nearest muscle ellipsoid (or deformable cylinder), stuffing, bone capsule or joint sphere; evaluate(pose) "
      "per frame; relaxation toward the rest edge lengths at seams.")
      .def(py::init([](const Character& c, const std::vector<Muscle>& muscles, bool muscleCylinders,
                       bool boneCapsules, bool jointSpheres, double capsuleRadius, double jointSphereRadius,
                       double muscleBulge, const py::list& stuffing, double weightShare, double bellyReach, double muscleRigidShare, double muscleAim,
                       int relaxRings, int relaxIterations, double relaxTolerance, double relaxStep, bool relaxTangential,
                       const std::vector<int>& pinned, double tolerance, int maxIterations, int grainSize, int threads) {
             if (!c.hasWeights()) throw InputError("AnchoredSkin: the character has no skin weights");
             ComponentOptions co;
             co.muscleCylinders = muscleCylinders;
             co.muscleEllipsoids = !muscleCylinders;
             co.boneCapsules = boneCapsules;
             co.jointSpheres = jointSpheres;
             co.capsuleRadius = capsuleRadius;
             co.jointSphereRadius = jointSphereRadius;
             co.muscleBulge = muscleBulge;
             for (const py::handle& h : stuffing) co.stuffing.push_back(componentFromDict(c, py::cast<py::dict>(h)));
             AnchoredSkinOptions o;
             o.weightShare = weightShare;
             o.bellyReach = bellyReach;
             o.muscleRigidShare = muscleRigidShare;
             o.muscleAim = muscleAim;
             o.relaxRings = relaxRings;
             o.relaxIterations = relaxIterations;
             o.relaxTolerance = relaxTolerance;
             o.relaxStep = relaxStep;
             o.relaxTangential = relaxTangential;
             o.pinned = pinned;
             o.solver = {tolerance, maxIterations};
             o.grainSize = grainSize;
             o.threads = threads;
             auto out = std::make_unique<PyAnchoredSkin>();
             for (const Bone& b : c.skeleton.bones) out->boneNames.push_back(b.name);
             py::gil_scoped_release release;
             const AnchoredComponents comps = deriveComponents(c.skeleton, muscles, c.mesh, c.weights, co);
             out->skin = std::make_unique<AnchoredSkin>(c.mesh, c.weights, comps, c.skeleton, o);
             return out;
           }),
           py::arg("character"), py::arg("muscles") = std::vector<Muscle>{}, py::kw_only(),
           py::arg("muscle_cylinders") = ComponentOptions{}.muscleCylinders,
           py::arg("bone_capsules") = ComponentOptions{}.boneCapsules,
           py::arg("joint_spheres") = ComponentOptions{}.jointSpheres,
           py::arg("capsule_radius") = ComponentOptions{}.capsuleRadius,
           py::arg("joint_sphere_radius") = ComponentOptions{}.jointSphereRadius,
           py::arg("muscle_bulge") = ComponentOptions{}.muscleBulge, py::arg("stuffing") = py::list(),
           py::arg("weight_share") = AnchoredSkinOptions{}.weightShare,
           py::arg("belly_reach") = AnchoredSkinOptions{}.bellyReach,
           py::arg("muscle_rigid_share") = AnchoredSkinOptions{}.muscleRigidShare,
           py::arg("muscle_aim") = AnchoredSkinOptions{}.muscleAim,
           py::arg("relax_rings") = AnchoredSkinOptions{}.relaxRings,
           py::arg("relax_iterations") = AnchoredSkinOptions{}.relaxIterations,
           py::arg("relax_tolerance") = AnchoredSkinOptions{}.relaxTolerance,
           py::arg("relax_step") = AnchoredSkinOptions{}.relaxStep,
           py::arg("relax_tangential") = AnchoredSkinOptions{}.relaxTangential, py::arg("pinned") = std::vector<int>{},
           py::arg("tolerance") = EllipsoidSolverOptions{}.tolerance,
           py::arg("max_iterations") = EllipsoidSolverOptions{}.maxIterations,
           py::arg("grain_size") = AnchoredSkinOptions{}.grainSize, py::arg("threads") = AnchoredSkinOptions{}.threads,
           "Components derived from the character and its muscles (one ellipsoid, or with muscle_cylinders a "
           "deformable cylinder, per muscle; a capsule per deform bone; a sphere per joint) plus `stuffing` (dicts: "
           "{'kind': 'stuffing', 'name', 'bone', 'center', 'radii', 'axes'} or {'kind': 'muscle_ellipsoid', 'name', "
           "'origin_bone', 'origin', 'insertion_bone', 'insertion', 'start_ratio', 'end_ratio', 'radius_x', "
           "'radius_z', 'bulge'}). ValueError on bad components, options or sizes.")
      .def(
          "evaluate",
          [](PyAnchoredSkin& s, const MatrixStack& poseMatrices, bool withTrace) -> py::object {
            const Pose pose = poseFromArray(poseMatrices, static_cast<int>(s.boneNames.size()));
            py::array_t<double> a({static_cast<py::ssize_t>(s.skin->numVertices()), py::ssize_t(3)});
            double* data = a.mutable_data();
            RelaxationTrace trace;
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(s.mutex);
              s.skin->evaluate(pose, data, withTrace ? &trace : nullptr);
            }
            if (!withTrace) return std::move(a);
            return py::make_tuple(a, trace.energy);
          },
          py::arg("pose"), py::arg("trace") = false,
          "pose: #B by 4 by 4 posed bone matrices -> #V by 3 float64 skin; with trace=True (skin, relaxation "
          "energies per iteration).")
      .def(
          "evaluate_into",
          [](PyAnchoredSkin& s, const MatrixStack& poseMatrices, py::array out) {
            if (!out.dtype().is(py::dtype::of<double>()) || out.ndim() != 2 || out.shape(0) != s.skin->numVertices() ||
                out.shape(1) != 3 || !(out.flags() & py::array::c_style) || !out.writeable())
              throw InputError("out must be a writeable C-contiguous float64 array of shape (" +
                               std::to_string(s.skin->numVertices()) + ", 3)");
            const Pose pose = poseFromArray(poseMatrices, static_cast<int>(s.boneNames.size()));
            double* data = static_cast<double*>(out.mutable_data());
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(s.mutex);
            s.skin->evaluate(pose, data);
          },
          py::arg("pose"), py::arg("out"), "Like evaluate, into a preallocated #V by 3 float64 array.")
      .def(
          "posed_components",
          [](PyAnchoredSkin& s, const MatrixStack& poseMatrices) {
            const Pose pose = poseFromArray(poseMatrices, static_cast<int>(s.boneNames.size()));
            std::vector<AnchoredComponent> posed;
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(s.mutex);
              s.skin->posedComponents(pose, posed);
            }
            py::list l;
            for (const AnchoredComponent& a : posed) l.append(componentToDict(a, s.boneNames));
            return l;
          },
          py::arg("pose"), "The components as posed (centre, axes, radii; muscles stretched at constant volume).")
      .def(
          "write_pc2",
          [](PyAnchoredSkin& s, const std::string& path, const MatrixStack& poses, float startFrame) {
            if (poses.ndim() != 4 || poses.shape(1) != static_cast<py::ssize_t>(s.boneNames.size()) ||
                poses.shape(2) != 4 || poses.shape(3) != 4)
              throw InputError("poses must be #F by #B by 4 by 4 (#B = " + std::to_string(s.boneNames.size()) + ")");
            std::vector<Pose> seq(poses.shape(0));
            const double* d = poses.data();
            for (auto& p : seq) {
              p.matrices.resize(s.boneNames.size());
              for (auto& mtx : p.matrices) {
                for (int r = 0; r < 4; ++r)
                  for (int col = 0; col < 4; ++col) mtx(r, col) = *d++;
              }
            }
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(s.mutex);
            writeAnchoredPC2(path, *s.skin, seq, startFrame);
          },
          py::arg("path"), py::arg("poses"), py::arg("start_frame") = 1.0f,
          "Writes the skin of each pose (#F by #B by 4 by 4) to a PC2 for Blender's Mesh Cache modifier.")
      .def_property_readonly("num_vertices", [](const PyAnchoredSkin& s) { return s.skin->numVertices(); })
      .def_property_readonly("num_components", [](const PyAnchoredSkin& s) { return s.skin->numComponents(); })
      .def_property_readonly("components",
                             [](const PyAnchoredSkin& s) {
                               py::list l;
                               for (const AnchoredComponent& a : s.skin->components().components)
                                 l.append(componentToDict(a, s.boneNames));
                               return l;
                             })
      .def_property_readonly("vertex_component",
                             [](const PyAnchoredSkin& s) {
                               const auto& v = s.skin->report().vertexComponent;
                               return IndexVector(Eigen::Map<const Eigen::VectorXi>(v.data(), v.size()).cast<int32_t>());
                             })
      .def_property_readonly("report", [](const PyAnchoredSkin& s) {
        const AnchoringReport& r = s.skin->report();
        py::dict d;
        d["vertices_per_component"] = r.verticesPerComponent;
        d["seam_vertices"] = r.seamVertices;
        d["fallback_vertices"] = r.fallbackVertices;
        d["ties"] = r.ties;
        d["max_solver_iterations"] = r.maxSolverIterations;
        d["scale"] = r.scale;
        return d;
      });
}

}  // namespace myoskin::python
