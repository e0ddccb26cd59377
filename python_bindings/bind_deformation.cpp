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
                       bool distributeTwist, bool twistFollowsBones, bool jointsSlide,
                       const std::vector<std::array<double, 2>>& slideLimits) {
             MuscleRigOptions o;
             o.jointsOverride = jointsOverride;
             o.distributeTwist = distributeTwist;
             o.twistFollowsBones = twistFollowsBones;
             o.jointsSlide = jointsSlide;
             o.slideLimits = slideLimits;
             return std::make_unique<PyMuscleRig>(c.skeleton, muscles, o);
           }),
           py::arg("character"), py::arg("muscles"), py::arg("joints_override") = 0,
           py::arg("distribute_twist") = MuscleRigOptions{}.distributeTwist,
           py::arg("twist_follows_bones") = MuscleRigOptions{}.twistFollowsBones,
           py::arg("joints_slide") = MuscleRigOptions{}.jointsSlide,
           py::arg("slide_limits") = std::vector<std::array<double, 2>>{},
           "distribute_twist: the insertion bone's roll turns the joints about the path; twist_follows_bones: "
           "shared as the skeleton shares it (by each joint's rest distance to the two bones), else linearly in "
           "arc length; joints_slide: a joint's motion along its bone follows the muscle (default True; False: "
           "the bone's, so a shortening belly does not carry the skin along the limb); slide_limits: #J by 2 how far each "
           "joint may slide along its bone towards its head and its tail (mesh units, 0 = no limit; "
           "slide_limits(character, rig, weight_joints, weight_values) computes them for a bound skin). "
           "Raises ValueError naming the "
           "muscle: unknown bones, origin = insertion, bad wrap radius, "
           "origin/insertion inside the wrap sphere or cylinder, joints outside [1, 64].")
      .def_property_readonly("joints_slide", &MuscleRig::jointsSlide)
      .def_property_readonly("slide_limits", [](const PyMuscleRig& r) {
        Eigen::MatrixXd out(r.numJoints(), 2);
        for (int j = 0; j < r.numJoints(); ++j) out(j, 0) = r.slideLimits()[j][0], out(j, 1) = r.slideLimits()[j][1];
        return out;
      }, "#J by 2 how far each joint may slide along its bone, towards its head and its tail (0 = no limit)")
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
  m.def(
      "pose_from_channels",
      [](const Character& c, const Points& location, const std::vector<int>& modes,
         const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>& rotation, const Points& scale) {
        const Eigen::Index nb = c.skeleton.numBones();
        if (location.rows() != nb || rotation.rows() != nb || scale.rows() != nb ||
            static_cast<Eigen::Index>(modes.size()) != nb)
          throw InputError("pose_from_channels: need " + std::to_string(nb) + " rows of location (3), modes, " +
                           "rotation (4) and scale (3), got " + std::to_string(location.rows()) + ", " +
                           std::to_string(modes.size()) + ", " + std::to_string(rotation.rows()) + ", " +
                           std::to_string(scale.rows()));
        std::vector<BoneChannels> channels(nb);
        for (Eigen::Index b = 0; b < nb; ++b) {
          if (modes[b] < -1 || modes[b] > 6)
            throw InputError("pose_from_channels: bone '" + c.skeleton.bones[b].name + "' has rotation mode " +
                             std::to_string(modes[b]) + " (use -1 axis-angle, 0 quaternion, 1-6 Euler XYZ..ZYX)");
          channels[b].location = location.row(b).transpose();
          channels[b].mode = static_cast<RotationMode>(modes[b]);
          channels[b].rotation = rotation.row(b).transpose();
          channels[b].scale = scale.row(b).transpose();
        }
        return matricesToArray(poseFromChannels(c.skeleton, channels).matrices);
      },
      py::arg("character"), py::arg("location"), py::arg("modes"), py::arg("rotation"), py::arg("scale"),
      "Forward kinematics from Blender's pose-bone channels (full inheritance): location #B by 3, modes #B "
      "(Blender's rotation_mode codes: -1 axis-angle, 0 quaternion, 1-6 Euler XYZ, XZY, YXZ, YZX, ZXY, ZYX), "
      "rotation #B by 4 (quaternion w, x, y, z / angle, axis / Euler x, y, z, unused), scale #B by 3 -> #B by "
      "4 by 4 posed matrices (PoseBone.matrix, armature space).");
  m.def(
      "pose_channels",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& restToParent,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& parentPose,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& matrices) {
        const char* labels[3] = {"rest_to_parent", "parent_pose", "matrices"};
        const py::array_t<double, py::array::c_style | py::array::forcecast>* in[3] = {&restToParent, &parentPose,
                                                                                        &matrices};
        const py::ssize_t n = matrices.ndim() == 3 ? matrices.shape(0) : -1;
        for (int a = 0; a < 3; ++a)
          if (in[a]->ndim() != 3 || in[a]->shape(0) != n || in[a]->shape(1) != 4 || in[a]->shape(2) != 4)
            throw InputError(std::string("pose_channels: ") + labels[a] + " must be #J by 4 by 4 like matrices");
        py::array_t<double> location({n, py::ssize_t(3)}), quaternion({n, py::ssize_t(4)}), scale({n, py::ssize_t(3)});
        auto loc = location.mutable_unchecked<2>();
        auto quat = quaternion.mutable_unchecked<2>();
        auto size = scale.mutable_unchecked<2>();
        for (py::ssize_t j = 0; j < n; ++j) {
          Mat4 m[3];
          for (int a = 0; a < 3; ++a) {
            m[a] = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(in[a]->data(j, 0, 0));
            if (!m[a].allFinite())
              throw InputError(std::string("pose_channels: ") + labels[a] + " " + std::to_string(j) +
                               " has a NaN or infinite value");
          }
          const BoneChannels c = channelsFromBasis(m[0] * m[1].inverse() * m[2]);
          for (int k = 0; k < 3; ++k) loc(j, k) = c.location[k], size(j, k) = c.scale[k];
          for (int k = 0; k < 4; ++k) quat(j, k) = c.rotation[k];
        }
        return py::make_tuple(location, quaternion, scale);
      },
      py::arg("rest_to_parent"), py::arg("parent_pose"), py::arg("matrices"),
      "Quaternion-mode pose channels that give bone j the posed matrix matrices[j] (#J by 4 by 4): basis = "
      "rest_to_parent[j] @ inv(parent_pose[j]) @ matrices[j] (rest_to_parent = inv(rest_j) @ rest_parent, "
      "Blender's full inheritance), decomposed like PoseBone.matrix_basis -> (location #J by 3, quaternion #J "
      "by 4 (w, x, y, z), scale #J by 3).");
}

}  // namespace myoskin::python
