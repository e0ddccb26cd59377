// Muscle deformation: MuscleRig (action paths, bulge, muscle joints) and pose helpers.
#include <memory>
#include <mutex>

#include "bindings.h"
#include "myoskin/character.h"
#include "myoskin/deformation.h"
#include "myoskin/errors.h"

namespace myoskin::python {

void bindDeformation(py::module_& m) {
  py::class_<PyMuscleRig>(m, "MuscleRig",
                        "Muscles on a skeleton: built once, then evaluate(pose) gives every muscle joint's matrix "
                        "(mesh space; Y = path tangent; translation * rotation * diag(s, stretch, s)).")
      .def(py::init([](const Character& c, const std::vector<Muscle>& muscles, int jointsOverride,
                       bool distributeTwist, bool twistFollowsBones) {
             MuscleRigOptions o;
             o.jointsOverride = jointsOverride;
             o.distributeTwist = distributeTwist;
             o.twistFollowsBones = twistFollowsBones;
             return std::make_unique<PyMuscleRig>(c.skeleton, muscles, o);
           }),
           py::arg("character"), py::arg("muscles"), py::arg("joints_override") = 0,
           py::arg("distribute_twist") = MuscleRigOptions{}.distributeTwist,
           py::arg("twist_follows_bones") = MuscleRigOptions{}.twistFollowsBones,
           "distribute_twist: the insertion bone's roll turns the joints about the path; twist_follows_bones: "
           "shared as the skeleton shares it (by each joint's rest distance to the two bones), else linearly in "
           "arc length. Raises ValueError naming the muscle: unknown bones, origin = insertion, bad wrap radius, "
           "origin/insertion inside the wrap sphere or cylinder, joints outside [1, 64].")
      .def_property_readonly("num_muscles", &MuscleRig::numMuscles)
      .def_property_readonly("num_joints", &MuscleRig::numJoints)
      .def_property_readonly("joint_names", &MuscleRig::jointNames)
      .def_property_readonly("joint_muscle", [](const PyMuscleRig& r) { return IndexVector(Eigen::Map<const Eigen::VectorXi>(r.jointMuscle().data(), r.numJoints()).cast<int32_t>()); })
      .def_property_readonly("joint_parent_bone", [](const PyMuscleRig& r) { return IndexVector(Eigen::Map<const Eigen::VectorXi>(r.jointParentBone().data(), r.numJoints()).cast<int32_t>()); })
      .def_property_readonly("bind_matrices", [](const PyMuscleRig& r) { return matricesToArray(r.bindMatrices()); },
                             "#J by 4 by 4 rest joint matrices (rigid): a Blender bone's matrix_local")
      .def_property_readonly("rest_lengths", [](const PyMuscleRig& r) {
        return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(r.restLengths().data(), r.numMuscles()));
      })
      .def("joint_offset", &MuscleRig::jointOffset, py::arg("muscle"))
      .def("joint_count", &MuscleRig::jointCount, py::arg("muscle"))
      .def_property_readonly("muscles", &MuscleRig::muscles)
      .def(
          "rest_surface",
          [](const PyMuscleRig& r, int i) {
            if (i < 0 || i >= r.numMuscles()) throw InputError("rest_surface: no muscle " + std::to_string(i));
            return py::make_tuple(r.restSurface(i).vertices, r.restSurface(i).triangles);
          },
          py::arg("muscle"), "(vertices #V by 3, triangles #F by 3) of the surface evaluate() deforms")
      .def(
          "evaluate",
          [](PyMuscleRig& r, const MatrixStack& poseMatrices, bool withSurfaces) {
            const Pose pose = poseFromArray(poseMatrices, r.skeleton().numBones());
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(r.mutex);
            r.evaluate(pose, r.state, withSurfaces);
            py::gil_scoped_acquire acquire;
            const MuscleRigState& state = r.state;
            py::dict d;
            d["joint_matrices"] = matricesToArray(state.jointMatrices);
            d["length"] = Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(state.length.data(), r.numMuscles()));
            d["stretch"] = Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(state.stretch.data(), r.numMuscles()));
            py::list wrapped, surfaces;
            for (int i = 0; i < r.numMuscles(); ++i) {
              wrapped.append(bool(state.wrapped[i]));
              if (withSurfaces) surfaces.append(state.surfaces[i]);
            }
            d["wrapped"] = wrapped;
            if (withSurfaces) d["surfaces"] = surfaces;
            return d;
          },
          py::arg("pose_matrices"), py::arg("with_surfaces") = false,
          "pose_matrices: #B by 4 by 4 posed bone matrices (Blender's PoseBone.matrix, armature space). Returns "
          "{'joint_matrices': #J by 4 by 4, 'length': #M, 'stretch': #M, 'wrapped': [bool] * #M, "
          "'surfaces': [#V_m by 3] when with_surfaces}. ValueError on a wrong size or NaN.")
      .def("__repr__", [](const PyMuscleRig& r) {
        return "<myoskin.MuscleRig: " + std::to_string(r.numMuscles()) + " muscles, " + std::to_string(r.numJoints()) +
               " joints>";
      });

  m.def(
      "rest_pose", [](const Character& c) { return matricesToArray(restPose(c.skeleton).matrices); },
      py::arg("character"), "#B by 4 by 4: every bone at rest (posed matrix = rest matrix)");
  m.def(
      "pose_from_rotations",
      [](const Character& c, const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>& q) {
        if (q.rows() != c.skeleton.numBones())
          throw InputError("pose_from_rotations: need one quaternion (w, x, y, z) per bone (" +
                           std::to_string(c.skeleton.numBones()) + ")");
        std::vector<Eigen::Quaterniond> rot(q.rows());
        for (Eigen::Index b = 0; b < q.rows(); ++b) {
          if (!q.row(b).allFinite() || q.row(b).norm() < 1e-12)
            throw InputError("pose_from_rotations: quaternion of bone '" + c.skeleton.bones[b].name + "' is not usable");
          rot[b] = Eigen::Quaterniond(q(b, 0), q(b, 1), q(b, 2), q(b, 3)).normalized();
        }
        return matricesToArray(poseFromLocalRotations(c.skeleton, rot).matrices);
      },
      py::arg("character"), py::arg("rotations"),
      "Forward kinematics: rotations #B by 4 quaternions (w, x, y, z) about each bone's head in its rest frame "
      "(Blender's rotation_quaternion) -> #B by 4 by 4 posed matrices.");
}

}  // namespace myoskin::python
