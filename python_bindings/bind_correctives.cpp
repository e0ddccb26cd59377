// Pose-space correctives: rest-space offsets of a sculpt, bone local rotations, the per-bone radial basis
// functions (their kernels and coefficients, which the add-on writes as Blender drivers) and their weights; the
// volume blend's joint volume keys (shape keys driven by a joint's swing) and their weights.
#include <memory>

#include "bindings.h"
#include "myoskin/character.h"
#include "myoskin/correctives.h"
#include "myoskin/errors.h"
#include "myoskin/skinning.h"
#include "myoskin/volume_blend.h"

namespace myoskin::python {

namespace {

// #N by 3 float64 points, ValueError naming `name` on another shape.
Points pointsOf(const DoubleArray& a, const char* name) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(std::string(name) + " must be #V by 3");
  Points p(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), p.data());
  return p;
}

// #B by 4 (w, x, y, z) quaternions.
std::vector<Eigen::Quaterniond> quaternionsOf(const DoubleArray& a) {
  if (a.ndim() != 2 || a.shape(1) != 4) throw InputError("local_rotations must be #B by 4 (w, x, y, z)");
  std::vector<Eigen::Quaterniond> q(a.shape(0));
  auto v = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    q[i] = Eigen::Quaterniond(v(i, 0), v(i, 1), v(i, 2), v(i, 3));
    if (!q[i].coeffs().allFinite()) throw InputError("local_rotations: row " + std::to_string(i) + " is not finite");
  }
  return q;
}

py::array_t<double> quaternionsToArray(const std::vector<Eigen::Quaterniond>& q) {
  py::array_t<double> out({static_cast<py::ssize_t>(q.size()), py::ssize_t(4)});
  auto a = out.mutable_unchecked<2>();
  for (size_t i = 0; i < q.size(); ++i) {
    a(i, 0) = q[i].w();
    a(i, 1) = q[i].x();
    a(i, 2) = q[i].y();
    a(i, 3) = q[i].z();
  }
  return out;
}

py::array_t<double> pointsToArray(const Points& p) {
  py::array_t<double> out({static_cast<py::ssize_t>(p.rows()), py::ssize_t(3)});
  std::copy(p.data(), p.data() + p.size(), out.mutable_data());
  return out;
}

}  // namespace

void bindCorrectives(py::module_& m) {
  m.def(
      "vertex_transforms",
      [](const Skinner& s, const DoubleArray& transforms) {
        const std::vector<Mat4> t = matricesFromArray(transforms, "transforms");
        VertexTransforms out;
        {
          py::gil_scoped_release release;
          s.vertexTransforms(t, out);
        }
        py::array_t<double> a({static_cast<py::ssize_t>(out.rows()), py::ssize_t(3), py::ssize_t(4)});
        std::copy(out.data(), out.data() + out.size(), a.mutable_data());
        return a;
      },
      py::arg("skinner"), py::arg("transforms"),
      "#V by 3 by 4: per vertex the affine map [A | b] the skinner's deform applies to its input position "
      "(linear blend or Blender's dual quaternions, as the skinner does).");
  m.def(
      "rest_space_offsets",
      [](const Skinner& s, const DoubleArray& transforms, const DoubleArray& input, const DoubleArray& target) {
        const std::vector<Mat4> t = matricesFromArray(transforms, "transforms");
        const Points in = pointsOf(input, "input");
        const Points tg = pointsOf(target, "target");
        Points out;
        {
          py::gil_scoped_release release;
          out = restSpaceOffsets(s, t, in, tg);
        }
        return pointsToArray(out);
      },
      py::arg("skinner"), py::arg("transforms"), py::arg("input"), py::arg("target"),
      "#V by 3 offsets d such that the skinner, given input + d (#V by 3, what it skins: rest plus the shape keys "
      "already on), lands on target (#V by 3, the sculpt) under transforms: d = A^-1 (target - b) - input per "
      "vertex. ValueError on a vertex count mismatch, NaN, or a vertex whose transform collapses.");
  m.def(
      "bone_local_rotations",
      [](const Character& c, const DoubleArray& poseMatrices) {
        const Pose pose = poseFromArray(poseMatrices, c.skeleton.numBones());
        std::vector<Eigen::Quaterniond> q;
        boneLocalRotations(c.skeleton, pose, q);
        return quaternionsToArray(q);
      },
      py::arg("character"), py::arg("pose"),
      "#B by 4 (w, x, y, z): each bone's rotation relative to its parent and its rest frame (what a Blender driver "
      "reads as the bone's Local Space quaternion).");
  m.def(
      "bone_direction",
      [](const std::array<double, 4>& q) {
        const Vec3 d = boneDirection(Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized());
        return std::array<double, 3>{d[0], d[1], d[2]};
      },
      py::arg("local_rotation"), "The bone's Y axis (x, y, z) in its rest frame for a local rotation (w, x, y, z).");

  py::class_<CorrectiveDrivers, std::shared_ptr<CorrectiveDrivers>>(
      m, "CorrectiveDrivers",
      "The radial basis functions that drive pose-space correctives by their bones' directions: per bone a kernel "
      "max(k0 + k1 (xy - wz) + k2 (xx + zz) + k3 (yz + wx), 0)^3 per sample (the rest direction, then each pose) and "
      "coefficients, weight = sum_j c_j phi_j.")
      .def(py::init([](const py::list& poses, double falloff, double minSeparation) {
             std::vector<CorrectivePose> p;
             for (const py::handle& item : poses) {
               const py::dict d = item.cast<py::dict>();
               CorrectivePose cp;
               cp.name = d["name"].cast<std::string>();
               cp.bone = d["bone"].cast<int>();
               const auto dir = d["direction"].cast<std::array<double, 3>>();
               cp.direction = Vec3(dir[0], dir[1], dir[2]);
               cp.falloff = d.contains("falloff") ? d["falloff"].cast<double>() : 0.0;
               p.push_back(std::move(cp));
             }
             CorrectiveOptions o;
             o.falloff = falloff;
             o.minSeparation = minSeparation;
             return std::make_shared<CorrectiveDrivers>(std::move(p), o);
           }),
           py::arg("poses"), py::arg("falloff") = CorrectiveOptions{}.falloff,
           py::arg("min_separation") = CorrectiveOptions{}.minSeparation,
           "poses: [{'name', 'bone' (index), 'direction' (bone_direction at the sculpted pose), 'falloff' (radians, "
           "optional)}]; falloff: the default angular radius (60 degrees); min_separation: closer samples of one "
           "bone are the same pose (0.5 degrees). ValueError on identical poses, a pose at rest, bad values.")
      .def_property_readonly("num_correctives", &CorrectiveDrivers::numCorrectives)
      .def_property_readonly("names",
                             [](const CorrectiveDrivers& d) {
                               std::vector<std::string> n;
                               for (const CorrectivePose& p : d.poses()) n.push_back(p.name);
                               return n;
                             })
      .def_property_readonly(
          "bones",
          [](const CorrectiveDrivers& d) {
            py::list out;
            for (const BoneCorrectiveRbf& r : d.bones()) {
              py::dict b;
              b["bone"] = r.bone;
              b["correctives"] = r.correctives;
              py::array_t<double> k({static_cast<py::ssize_t>(r.kernels.size()), py::ssize_t(4)});
              for (size_t j = 0; j < r.kernels.size(); ++j)
                for (int c = 0; c < 4; ++c) k.mutable_at(j, c) = r.kernels[j][c];
              b["kernels"] = k;
              b["coefficients"] = Eigen::MatrixXd(r.coefficients);
              out.append(b);
            }
            return out;
          },
          "per driving bone: {'bone', 'correctives' (indices), 'kernels' (1 + n by 4, rest first), 'coefficients' "
          "(1 + n by n)}")
      .def(
          "weights",
          [](const CorrectiveDrivers& d, const DoubleArray& rotations) {
            Eigen::VectorXd w;
            d.weights(quaternionsOf(rotations), w);
            return w;
          },
          py::arg("local_rotations"), "One weight per corrective from #B by 4 local rotations (bone_local_rotations).");
  // ==========================================================================
  // Volume keys
  // ==========================================================================
  m.def(
      "compute_volume_keys",
      [](const Character& c, const DoubleArray& share, const std::vector<double>& sampleDegrees, double maxOffset,
         double bandRadius, double minBlend, const py::object& up, const py::object& rig,
         const py::object& weightJoints, const py::object& weightValues, const std::string& dqScale) {
        if (!c.hasWeights()) throw InputError("compute_volume_keys: character '" + c.name + "' has no skin weights");
        if (share.ndim() != 1) throw InputError("share must be #V values");
        Eigen::VectorXd s(share.shape(0));
        std::copy(share.data(), share.data() + share.size(), s.data());
        VolumeBlendOptions o;
        o.bandRadius = bandRadius;
        o.minBlend = minBlend;
        if (!up.is_none()) {
          const auto a = up.cast<std::array<double, 3>>();
          o.up = Vec3(a[0], a[1], a[2]);
          if (!o.up.allFinite() || o.up.norm() == 0.0) throw InputError("up must be a finite non-zero vector");
        }
        VolumeKeyOptions ko;
        ko.sampleDegrees = sampleDegrees;
        ko.maxOffset = maxOffset;
        ko.dualQuatScale = dualQuatScaleArg(dqScale);
        if (rig.is_none() != weightJoints.is_none() || rig.is_none() != weightValues.is_none())
          throw InputError("compute_volume_keys: rig, weight_joints and weight_values come together (Bind's skin)");
        const PyMuscleRig* muscleRig = rig.is_none() ? nullptr : &rig.cast<const PyMuscleRig&>();
        SkinWeights hybrid;
        if (muscleRig)
          hybrid = weightsArg(weightJoints.cast<IntArray>(), weightValues.cast<DoubleArray>(), c.mesh.numVertices());
        std::vector<VolumeKey> keys;
        {
          py::gil_scoped_release release;
          keys = computeVolumeKeys(c.skeleton, c.weights, c.mesh, s, o, ko, muscleRig, muscleRig ? &hybrid : nullptr);
        }
        py::list rows;
        for (const VolumeKey& k : keys) {
          py::dict d;
          d["bone"] = c.skeleton.bones[k.bone].name;
          d["bone_index"] = k.bone;
          d["vertices"] = indexArray(k.vertices);
          d["offsets"] = pointsToArray(k.offsets);
          d["k1"] = k.k1;
          d["k2"] = k.k2;
          d["swing"] = py::make_tuple(k.swing.x(), k.swing.y());
          d["axis"] = py::make_tuple(k.axis.x(), k.axis.y(), k.axis.z());
          d["sample_degrees"] = k.sampleDegrees;
          d["change_without"] = k.changeWithout;
          d["change_with"] = k.changeWith;
          rows.append(d);
        }
        return rows;
      },
      py::arg("character"), py::arg("share"), py::kw_only(),
      py::arg("sample_degrees") = VolumeKeyOptions{}.sampleDegrees,
      py::arg("max_offset") = VolumeKeyOptions{}.maxOffset, py::arg("band_radius") = VolumeBlendOptions{}.bandRadius,
      py::arg("min_blend") = VolumeBlendOptions{}.minBlend, py::arg("up") = py::none(), py::arg("rig") = py::none(),
      py::arg("weight_joints") = py::none(), py::arg("weight_values") = py::none(), py::arg("dq_scale") = "pivot",
      "Volume keys of the volume blend (share: compute_dqs_share's #V shares): one dict per key of a limb joint whose "
      "band still changes volume as it bends, outward where it loses, inward where it gains (bone, bone_index, vertices, offsets #n by 3 in rest space at weight 1, "
      "k1, k2, swing (x, z) or (0, 0), axis; weight = clamp(s (k1 + k2 s) g, -1, 1), s = x^2 + z^2 of the bone's local "
      "rotation quaternion, g the directional factor of volume_blend.h; sample_degrees with the band's change_without "
      "and change_with the key). rig, weight_joints and weight_values come together (the MuscleRig and its "
      "hybrid_weights, #V by K): the bends are then Bind's skin, the muscle joints included, their scale carried as "
      "dq_scale says ('pivot': Blender 4.x/5.x, 'blended': 3.x); without them the skeleton's blend.");
  m.def(
      "volume_key_weights",
      [](const py::list& keys, const DoubleArray& localRotations) {
        const std::vector<Eigen::Quaterniond> q = quaternionsOf(localRotations);
        std::vector<double> out;
        for (const auto& item : keys) {
          const py::dict d = item.cast<py::dict>();
          VolumeKey k;
          k.bone = d["bone_index"].cast<int>();
          k.k1 = d["k1"].cast<double>();
          k.k2 = d["k2"].cast<double>();
          if (d.contains("swing")) {
            const auto sw = d["swing"].cast<std::array<double, 2>>();
            k.swing = Eigen::Vector2d(sw[0], sw[1]);
          }
          if (k.bone < 0 || k.bone >= static_cast<int>(q.size()))
            throw InputError("volume key of bone " + std::to_string(k.bone) + ": no local rotation for it");
          out.push_back(volumeKeyWeight(k, q[static_cast<size_t>(k.bone)]));
        }
        return out;
      },
      py::arg("keys"), py::arg("local_rotations"),
      "One weight per volume key (compute_volume_keys' dicts) from #B by 4 local rotations (bone_local_rotations).");
}

}  // namespace myoskin::python
