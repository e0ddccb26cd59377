// Hybrid skinning: the Equation 3 skinner, transforms, quality measures and PC2 point caches.
// Arrays are checked here so a wrong shape is a ValueError naming the argument (never a crash); long
// calls release the GIL.
#include <memory>
#include <optional>

#include "bindings.h"
#include "myoskin/character.h"
#include "myoskin/errors.h"
#include "myoskin/skinning.h"
#include "myoskin/volume_blend.h"

namespace myoskin::python {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

std::string shapeOf(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// #N by 3 float64 points from any array of that shape.
Points pointsArg(const DoubleArray& a, const char* name) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(std::string(name) + " must be #N by 3, got shape " + shapeOf(a));
  Points p(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), p.data());
  return p;
}

Triangles trianglesArg(const IntArray& a, const char* name, Eigen::Index numVertices) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(std::string(name) + " must be #F by 3, got shape " + shapeOf(a));
  Triangles t(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), t.data());
  for (Eigen::Index i = 0; i < t.size(); ++i)
    if (t.data()[i] < 0 || t.data()[i] >= numVertices)
      throw InputError(std::string(name) + ": triangle " + std::to_string(i / 3) + " uses vertex " +
                       std::to_string(t.data()[i]) + ", outside 0.." + std::to_string(numVertices - 1));
  return t;
}

}  // namespace

// #V by K joints + weights (the same shape; 1-D arrays are one influence per vertex).
SkinWeights weightsArg(const IntArray& joints, const DoubleArray& weights, Eigen::Index numVertices) {
  auto cols = [](const py::array& a) { return a.ndim() == 1 ? py::ssize_t(1) : a.shape(1); };
  if (joints.ndim() < 1 || joints.ndim() > 2 || weights.ndim() < 1 || weights.ndim() > 2)
    throw InputError("weight_joints and weight_values must be #V by K, got shapes " + shapeOf(joints) + " and " +
                     shapeOf(weights));
  if (joints.shape(0) != weights.shape(0) || cols(joints) != cols(weights))
    throw InputError("weight_joints " + shapeOf(joints) + " and weight_values " + shapeOf(weights) +
                     " must have the same shape");
  if (joints.shape(0) != numVertices)
    throw InputError("weights have " + std::to_string(joints.shape(0)) + " rows for " + std::to_string(numVertices) +
                     " vertices");
  SkinWeights w;
  w.joints.resize(joints.shape(0), cols(joints));
  w.weights.resize(weights.shape(0), cols(weights));
  std::copy(joints.data(), joints.data() + joints.size(), w.joints.data());
  std::copy(weights.data(), weights.data() + weights.size(), w.weights.data());
  return w;
}

DualQuatScale dualQuatScaleArg(const std::string& name) {
  if (name == "pivot") return DualQuatScale::Pivot;
  if (name == "blended") return DualQuatScale::Blended;
  throw InputError("dq_scale must be 'pivot' (Blender 4.x/5.x) or 'blended' (Blender 3.x), got '" + name + "'");
}

namespace {

// A face_mask argument (None or #F bools) as the core's mask (empty = every triangle).
std::vector<char> faceMaskArg(const std::optional<py::array_t<bool>>& faceMask) {
  std::vector<char> mask;
  if (!faceMask) return mask;
  if (faceMask->ndim() != 1) throw InputError("face_mask must be #F, got shape " + shapeOf(*faceMask));
  const auto m = faceMask->unchecked<1>();
  for (py::ssize_t f = 0; f < m.shape(0); ++f) mask.push_back(m(f) ? 1 : 0);
  return mask;
}

// Skinner options from the Python arguments; rest_matrices (None or #J by 4 by 4) only with preserve_volume.
// dqs_share (None or #V values in [0, 1]) the volume blend's per-vertex dual-quaternion shares; rest_matrices are
// then allowed too (they shape the dual-quaternion part).
SkinnerOptions skinnerOptions(int grainSize, int threads, double sumTolerance, bool preserveVolume,
                              const py::object& restMatrices, const std::string& dqScale,
                              const py::object& dqsShare = py::none()) {
  SkinnerOptions o{grainSize, threads, sumTolerance};
  o.preserveVolume = preserveVolume;
  o.dualQuatScale = dualQuatScaleArg(dqScale);
  if (!dqsShare.is_none()) {
    const DoubleArray a = dqsShare.cast<DoubleArray>();
    if (a.ndim() != 1) throw InputError("dqs_share must be #V values, got shape " + shapeOf(a));
    o.dqsShare.assign(a.data(), a.data() + a.size());
  }
  if (!restMatrices.is_none()) {
    if (!preserveVolume && o.dqsShare.empty())
      throw InputError("rest_matrices are only used with preserve_volume=True or dqs_share");
    o.jointRest = matricesFromArray(restMatrices.cast<DoubleArray>(), "rest_matrices");
  }
  return o;
}

py::array_t<float> newPointsF(int n) { return py::array_t<float>({static_cast<py::ssize_t>(n), py::ssize_t(3)}); }

}  // namespace

void bindSkinning(py::module_& m) {
  // ==========================================================================
  // Skinner
  // ==========================================================================
  py::class_<Skinner, std::shared_ptr<Skinner>>(
      m, "Skinner",
      "Equation 3 skinner built once from rest vertices and sparse weights (Blender's Armature modifier "
      "semantics: normalised at deform time, weight sum <= 1e-4 stays at rest); deform() per frame.")
      .def(py::init([](const DoubleArray& rest, const IntArray& joints, const DoubleArray& weights, int numJoints,
                       int grainSize, int threads, double sumTolerance, bool preserveVolume,
                       const py::object& restMatrices, const std::string& dqScale, const py::object& dqsShare) {
             const Points p = pointsArg(rest, "rest_vertices");
             const SkinWeights w = weightsArg(joints, weights, p.rows());
             const SkinnerOptions o =
                 skinnerOptions(grainSize, threads, sumTolerance, preserveVolume, restMatrices, dqScale, dqsShare);
             py::gil_scoped_release release;
             return std::make_shared<Skinner>(p, w, numJoints, o);
           }),
           py::arg("rest_vertices"), py::arg("weight_joints"), py::arg("weight_values"), py::arg("num_joints"),
           py::arg("grain_size") = SkinnerOptions{}.grainSize, py::arg("threads") = SkinnerOptions{}.threads,
           py::arg("sum_tolerance") = SkinnerOptions{}.sumTolerance, py::kw_only(),
           py::arg("preserve_volume") = false, py::arg("rest_matrices") = py::none(), py::arg("dq_scale") = "pivot",
           py::arg("dqs_share") = py::none(),
           "rest_vertices #V by 3, weight_joints/weight_values #V by K (joint -1 = empty slot) over num_joints "
           "combined joints. sum_tolerance > 0 requires every row to sum to 1 (else rows are normalised, like "
           "Blender). preserve_volume=True blends dual quaternions as Blender's Armature modifier does with "
           "Preserve Volume; rest_matrices (#J by 4 by 4, the joints' rest matrices: combined_rest_matrices) "
           "are needed for Blender's result on joints with scale, and dq_scale says which Blender's scale handling: "
           "'pivot' (4.x, 5.x) or 'blended' (3.x). dqs_share (#V values in [0, 1], compute_dqs_share) turns on the "
           "volume blend: each vertex (1 - s) * linear + s * dual quaternion, as Blender's linear Armature modifier "
           "followed by one with Preserve Volume and Multi Modifier over the vertex group of weight s (preserve_volume "
           "is then ignored). ValueError names the offending vertex and slot.")
      .def(
          "deform",
          [](const Skinner& s, const DoubleArray& transforms) {
            const std::vector<Mat4> t = matricesFromArray(transforms, "transforms");
            py::array_t<float> out = newPointsF(s.numVertices());
            float* data = static_cast<float*>(out.mutable_data());
            {
              py::gil_scoped_release release;
              s.deform(t, data);
            }
            return out;
          },
          py::arg("transforms"), "transforms: #J by 4 by 4 skinning transforms -> #V by 3 float32 positions.")
      .def(
          "deform_into",
          [](const Skinner& s, const DoubleArray& transforms, py::array out) {
            // A plain py::array (no forcecast): a float64 `out` must fail, not fill a temporary copy.
            if (!out.dtype().is(py::dtype::of<float>()) || out.ndim() != 2 || out.shape(0) != s.numVertices() ||
                out.shape(1) != 3 || !(out.flags() & py::array::c_style) || !out.writeable())
              throw InputError("out must be a writeable C-contiguous float32 array of shape (" +
                               std::to_string(s.numVertices()) + ", 3), got " + shapeOf(out));
            const std::vector<Mat4> t = matricesFromArray(transforms, "transforms");
            float* data = static_cast<float*>(out.mutable_data());
            py::gil_scoped_release release;
            s.deform(t, data);
          },
          py::arg("transforms"), py::arg("out"), "Like deform, into a preallocated #V by 3 float32 array.")
      .def_property_readonly("num_vertices", &Skinner::numVertices)
      .def_property_readonly("num_joints", &Skinner::numJoints)
      .def_property_readonly("influences", &Skinner::influences, "packed influence slots per vertex")
      .def_property_readonly("rest_vertices", &Skinner::restVertices, "vertices left at rest (weight sum <= 1e-4)")
      .def_property_readonly("bytes_per_frame", &Skinner::bytesPerFrame)
      .def_property(
          "threads", [](const Skinner& s) { return s.options().threads; },
          [](Skinner& s, int t) { SkinnerOptions o = s.options(); o.threads = t; s.setOptions(o); })
      .def_property_readonly("preserve_volume", [](const Skinner& s) { return s.options().preserveVolume; })
      .def_property_readonly("volume_blend", [](const Skinner& s) { return !s.options().dqsShare.empty(); },
                             "True when built with dqs_share")
      .def_property(
          "grain_size", [](const Skinner& s) { return s.options().grainSize; },
          [](Skinner& s, int g) { SkinnerOptions o = s.options(); o.grainSize = g; s.setOptions(o); });

  m.def(
      "skin",
      [](const DoubleArray& rest, const IntArray& joints, const DoubleArray& weights, const DoubleArray& transforms,
         bool preserveVolume, const py::object& restMatrices, const std::string& dqScale, const py::object& dqsShare) {
        const Points p = pointsArg(rest, "rest_vertices");
        const SkinWeights w = weightsArg(joints, weights, p.rows());
        const std::vector<Mat4> t = matricesFromArray(transforms, "transforms");
        const SkinnerOptions o = skinnerOptions(SkinnerOptions{}.grainSize, SkinnerOptions{}.threads, 0.0,
                                                preserveVolume, restMatrices, dqScale, dqsShare);
        py::gil_scoped_release release;
        return skin(p, w, t, o);
      },
      py::arg("rest_vertices"), py::arg("weight_joints"), py::arg("weight_values"), py::arg("transforms"),
      py::kw_only(), py::arg("preserve_volume") = false, py::arg("rest_matrices") = py::none(),
      py::arg("dq_scale") = "pivot", py::arg("dqs_share") = py::none(),
      "One-shot Equation 3 (or, preserve_volume=True, Blender's dual quaternion blend with the joints' "
      "rest_matrices and dq_scale 'pivot' | 'blended'; or, dqs_share, the volume blend of the two): #V by 3 float64 "
      "positions for #J by 4 by 4 skinning transforms.");

  m.def(
      "compute_dqs_share",
      [](const Character& c, double bendDegrees, double bandRadius, double keepTolerance, double minBlend,
         double unblendedShare, const py::object& up,
         bool withJoints) -> py::object {
        if (!c.hasWeights()) throw InputError("compute_dqs_share: character '" + c.name + "' has no skin weights");
        VolumeBlendOptions o;
        o.bendDegrees = bendDegrees;
        o.bandRadius = bandRadius;
        o.keepTolerance = keepTolerance;
        o.minBlend = minBlend;
        o.unblendedShare = unblendedShare;
        if (!up.is_none()) {
          const DoubleArray a = up.cast<DoubleArray>();
          if (a.size() != 3) throw InputError("up must be 3 numbers, got shape " + shapeOf(a));
          o.up = Vec3(a.data()[0], a.data()[1], a.data()[2]);
          if (!o.up.allFinite() || o.up.norm() == 0.0) throw InputError("up must be a finite non-zero vector");
        }
        Eigen::VectorXd share;
        std::vector<JointVolumeBlend> joints;
        {
          py::gil_scoped_release release;
          share = computeDqsShare(c.skeleton, c.weights, c.mesh, o, &joints);
        }
        if (!withJoints) return py::cast(share);
        py::list rows;
        for (const JointVolumeBlend& j : joints) {
          py::dict d;
          d["bone"] = c.skeleton.bones[j.bone].name;
          d["radius"] = j.radius;
          d["blended_vertices"] = j.blendedVertices;
          d["band_triangles"] = j.bandTriangles;
          d["share"] = j.share;
          d["linear_change"] = j.linearChange;
          d["dual_quat_change"] = j.dualQuatChange;
          d["blend_change"] = j.blendChange;
          d["axis"] = py::make_tuple(j.axis.x(), j.axis.y(), j.axis.z());
          rows.append(d);
        }
        return py::make_tuple(share, rows);
      },
      py::arg("character"), py::kw_only(), py::arg("bend_degrees") = VolumeBlendOptions{}.bendDegrees,
      py::arg("band_radius") = VolumeBlendOptions{}.bandRadius,
      py::arg("keep_tolerance") = VolumeBlendOptions{}.keepTolerance, py::arg("min_blend") = VolumeBlendOptions{}.minBlend,
      py::arg("unblended_share") = VolumeBlendOptions{}.unblendedShare, py::arg("up") = py::none(),
      py::arg("with_joints") = false,
      "Volume blend: #V dual-quaternion shares in [0, 1] (Skinner's dqs_share) from the character's skeleton, skeleton "
      "weights and rest skin: per real joint the share whose band (band_radius joint radii) keeps its volume at a "
      "flexion of bend_degrees (the largest within keep_tolerance x linear's change of the best; forward; backward at knees; up: the body's up axis, None = +Y if the skin is taller "
      "along Y than Z, else +Z; the character's left is +X), each vertex the blend-weighted mean over the joints its weights blend across (min_blend), "
      "1 across twist splits only or inside a joint's band, unblended_share (0: linear) elsewhere. with_joints=True also returns one dict per joint (bone, radius, share, linear_change, "
      "dual_quat_change, blend_change, ...).");

  m.def(
      "combined_rest_matrices",
      [](const Character& c, const py::object& rig) {
        if (rig.is_none()) {
          std::vector<Mat4> rest;
          for (const auto& b : c.skeleton.bones) rest.push_back(b.rest);
          return matricesToArray(rest);
        }
        const PyMuscleRig& r = rig.cast<const PyMuscleRig&>();
        if (r.skeleton().numBones() != c.skeleton.numBones())
          throw InputError("combined_rest_matrices: the rig has " + std::to_string(r.skeleton().numBones()) +
                           " bones, the character " + std::to_string(c.skeleton.numBones()));
        return matricesToArray(combinedRestMatrices(c.skeleton, r));
      },
      py::arg("character"), py::arg("rig") = py::none(),
      "#B (+ #J) rest matrices of the combined joints: the bones' rest matrices, then the rig's muscle joint "
      "bind matrices (Skinner's rest_matrices for preserve_volume).");

  // ==========================================================================
  // Poses and transforms
  // ==========================================================================
  m.def(
      "skeleton_transforms",
      [](const Character& c, const DoubleArray& poseMatrices) {
        std::vector<Mat4> t;
        skeletonTransforms(c.skeleton, poseFromArray(poseMatrices, c.skeleton.numBones()), t);
        return matricesToArray(t);
      },
      py::arg("character"), py::arg("pose_matrices"),
      "#B by 4 by 4 skinning transforms pose_i * rest_i^-1 (plain LBS) for #B by 4 by 4 posed matrices.");

  m.def(
      "skinning_transforms",
      [](const Character& c, const DoubleArray& poseMatrices, const PyMuscleRig& rig, const DoubleArray& jointMatrices) {
        const Pose pose = poseFromArray(poseMatrices, c.skeleton.numBones());
        MuscleRigState state;  // only the joint matrices are read (no copy of the rest surfaces)
        state.jointMatrices = matricesFromArray(jointMatrices, "joint_matrices");
        std::vector<Mat4> t;
        skinningTransforms(c.skeleton, pose, rig, state, t);
        return matricesToArray(t);
      },
      py::arg("character"), py::arg("pose_matrices"), py::arg("rig"), py::arg("joint_matrices"),
      "#B + #J combined skinning transforms: pose_i * rest_i^-1 for the bones, then joint_j * bind_j^-1 for "
      "the muscle joints (joint_matrices from rig.evaluate(pose_matrices)).");

  // ==========================================================================
  // Hybrid weights
  // ==========================================================================
  m.def(
      "hybrid_weights",
      [](const Character& c, const PyMuscleRig& rig, double dominance, const std::map<std::string, double>& perMuscle,
         int maxInfluences, double fullDistance, double falloffDistance, int smoothingIterations, double endTaper,
         double minWeight, double creaseRelief, double borderRelief, double smoothingDistance) {
        if (!c.hasWeights()) throw InputError("hybrid_weights: character '" + c.name + "' has no skin weights");
        if (rig.skeleton().numBones() != c.skeleton.numBones())
          throw InputError("hybrid_weights: the rig has " + std::to_string(rig.skeleton().numBones()) +
                           " bones, the character " + std::to_string(c.skeleton.numBones()));
        HybridWeightOptions o;
        o.dominance = dominance;
        o.muscleDominance = perMuscle;
        o.maxInfluences = maxInfluences;
        o.fullDistance = fullDistance;
        o.falloffDistance = falloffDistance;
        o.smoothingIterations = smoothingIterations;
        o.endTaper = endTaper;
        o.minWeight = minWeight;
        o.creaseRelief = creaseRelief;
        o.borderRelief = borderRelief;
        o.smoothingDistance = smoothingDistance;
        SkinWeights w;
        {
          py::gil_scoped_release release;
          w = computeHybridWeights(c.mesh, c.weights, rig, o);
        }
        return py::make_tuple(w.joints, w.weights);
      },
      py::arg("character"), py::arg("rig"), py::arg("dominance") = HybridWeightOptions{}.dominance,
      py::arg("muscle_dominance") = std::map<std::string, double>{},
      py::arg("max_influences") = HybridWeightOptions{}.maxInfluences,
      py::arg("full_distance") = HybridWeightOptions{}.fullDistance,
      py::arg("falloff_distance") = HybridWeightOptions{}.falloffDistance,
      py::arg("smoothing_iterations") = HybridWeightOptions{}.smoothingIterations,
      py::arg("end_taper") = HybridWeightOptions{}.endTaper,
      py::arg("min_weight") = HybridWeightOptions{}.minWeight,
      py::arg("crease_relief") = HybridWeightOptions{}.creaseRelief,
      py::arg("border_relief") = HybridWeightOptions{}.borderRelief,
      py::arg("smoothing_distance") = HybridWeightOptions{}.smoothingDistance,
      "Combined weights (joints #V by K over [0, #B + #J), weights #V by K; rows sum to 1) from the "
      "character's skeleton weights and the rig's muscles: distance to each muscle's surface and side, "
      "smoothed, split between neighbouring muscle joints; muscle weights below min_weight go back to the "
      "bones (continuous ramp); crease_relief: in the skeleton's joint crease (skin blended between bones) the "
      "muscles take this much less (0 = off); border_relief: a muscle acts fully on skin whose skeleton weight lies "
      "on the muscle's segments alone, and not at all where a share of border_relief or more lies on other bones "
      "(0 = off); smoothing_distance > 0: the smoothing's diffusion distance in muscle radii instead of "
      "smoothing_iterations passes (body-relative: a coarse and a fine mesh of a body get the same weights); dominance 0 gives the skeleton weights.");

  m.def(
      "slide_limits",
      [](const Character& c, const PyMuscleRig& rig, const IntArray& joints, const DoubleArray& weights, double margin) {
        if (rig.skeleton().numBones() != c.skeleton.numBones())
          throw InputError("slide_limits: the rig has " + std::to_string(rig.skeleton().numBones()) +
                           " bones, the character " + std::to_string(c.skeleton.numBones()));
        const SkinWeights w = weightsArg(joints, weights, c.mesh.numVertices());
        std::vector<std::array<double, 2>> limits;
        {
          py::gil_scoped_release release;
          limits = computeSlideLimits(c.mesh, w, rig, margin);
        }
        Eigen::MatrixXd out(limits.size(), 2);
        for (size_t j = 0; j < limits.size(); ++j) out(j, 0) = limits[j][0], out(j, 1) = limits[j][1];
        return out;
      },
      py::arg("character"), py::arg("rig"), py::arg("weight_joints"), py::arg("weight_values"),
      py::arg("margin") = 1.0,
      "#J by 2 slide limits (MuscleRig(..., slide_limits=)) for a bound skin (hybrid_weights' joints and values): "
      "how far each muscle joint may slide along its bone, towards its head and its tail, before the skin it carries "
      "folds where the muscle's weight fades (0 = no limit that way); margin: times this (1 = where it would fold). "
      "A rig made with joints_slide=False ignores them.");

  // ==========================================================================
  // Quality measures
  // ==========================================================================
  m.def(
      "vertex_normals",
      [](const DoubleArray& vertices, const IntArray& triangles) {
        const Points v = pointsArg(vertices, "vertices");
        return vertexNormals(v, trianglesArg(triangles, "triangles", v.rows()));
      },
      py::arg("vertices"), py::arg("triangles"), "#V by 3 unit area-weighted vertex normals.");
  m.def(
      "enclosed_volume",
      [](const DoubleArray& vertices, const IntArray& triangles) {
        const Points v = pointsArg(vertices, "vertices");
        return enclosedVolume(v, trianglesArg(triangles, "triangles", v.rows()));
      },
      py::arg("vertices"), py::arg("triangles"), "Signed enclosed volume (m^3) of a closed outward-oriented mesh.");
  m.def(
      "region_volume_change",
      [](const DoubleArray& rest, const DoubleArray& deformed, const IntArray& triangles, const IntArray& labels,
         int numRegions) {
        const Points r = pointsArg(rest, "rest"), d = pointsArg(deformed, "deformed");
        if (labels.ndim() != 1) throw InputError("labels must be #V, got shape " + shapeOf(labels));
        IndexVector l(labels.shape(0));
        std::copy(labels.data(), labels.data() + labels.size(), l.data());
        return regionVolumeChange(r, d, trianglesArg(triangles, "triangles", r.rows()), l, numRegions);
      },
      py::arg("rest"), py::arg("deformed"), py::arg("triangles"), py::arg("labels"), py::arg("num_regions"),
      "Per-region relative volume change; labels #V in [-1, num_regions) (a triangle counts when its three "
      "vertices share a label).");
  m.def(
      "self_intersections",
      [](const DoubleArray& vertices, const IntArray& triangles, std::optional<py::array_t<bool>> faceMask) {
        const Points v = pointsArg(vertices, "vertices");
        const Triangles t = trianglesArg(triangles, "triangles", v.rows());
        const std::vector<char> mask = faceMaskArg(faceMask);
        py::gil_scoped_release release;
        return selfIntersections(v, t, mask);
      },
      py::arg("vertices"), py::arg("triangles"), py::arg("face_mask") = py::none(),
      "Number of intersecting triangle pairs (neighbours sharing a vertex or edge do not count) among the "
      "triangles where face_mask (#F bools, default all) is set.");
  m.def(
      "self_intersecting_pairs",
      [](const DoubleArray& vertices, const IntArray& triangles, std::optional<py::array_t<bool>> faceMask) {
        const Points v = pointsArg(vertices, "vertices");
        const Triangles t = trianglesArg(triangles, "triangles", v.rows());
        const std::vector<char> mask = faceMaskArg(faceMask);
        std::vector<std::pair<int, int>> pairs;
        {
          py::gil_scoped_release release;
          pairs = selfIntersectingPairs(v, t, mask);
        }
        py::array_t<int32_t> out({static_cast<py::ssize_t>(pairs.size()), py::ssize_t{2}});
        auto o = out.mutable_unchecked<2>();
        for (size_t i = 0; i < pairs.size(); ++i) {
          o(i, 0) = pairs[i].first;
          o(i, 1) = pairs[i].second;
        }
        return out;
      },
      py::arg("vertices"), py::arg("triangles"), py::arg("face_mask") = py::none(),
      "#P by 2 rows of `triangles`: the intersecting pairs self_intersections counts (smaller row first, sorted), so "
      "a fold can be located.");
  m.def(
      "local_bulge",
      [](const DoubleArray& rest, const IntArray& triangles, const DoubleArray& deformed, const IntArray& joints,
         const DoubleArray& weights, const DoubleArray& skeletonTransforms) {
        const Points r = pointsArg(rest, "rest"), d = pointsArg(deformed, "deformed");
        const SkinWeights w = weightsArg(joints, weights, r.rows());
        return localBulge(r, trianglesArg(triangles, "triangles", r.rows()), d, w,
                          matricesFromArray(skeletonTransforms, "skeleton_transforms"));
      },
      py::arg("rest"), py::arg("triangles"), py::arg("deformed"), py::arg("weight_joints"), py::arg("weight_values"),
      py::arg("skeleton_transforms"),
      "#V displacement along the rest normal after undoing each vertex's dominant skeleton bone (plain LBS ~0 "
      "on rigid parts, > 0 where muscles bulge).");

  // ==========================================================================
  // PC2
  // ==========================================================================
  m.def(
      "write_pc2",
      [](const std::string& path, const FloatArray& frames, float startFrame, float sampleRate) {
        if (frames.ndim() != 3 || frames.shape(2) != 3 || frames.shape(0) < 1)
          throw InputError("frames must be #frames by #V by 3 with at least one frame, got shape " + shapeOf(frames));
        const float* data = frames.data();
        const int nv = static_cast<int>(frames.shape(1));
        const py::ssize_t nf = frames.shape(0);
        py::gil_scoped_release release;
        PC2Writer w(path, nv, startFrame, sampleRate);
        for (py::ssize_t f = 0; f < nf; ++f) w.writeFrame(data + f * 3 * nv);
        w.close();
      },
      py::arg("path"), py::arg("frames"), py::arg("start_frame") = 0.0f, py::arg("sample_rate") = 1.0f,
      "Write #frames by #V by 3 positions as a PC2 point cache (Blender's Mesh Cache modifier).");
  m.def(
      "read_pc2",
      [](const std::string& path) {
        PointCache c;
        {
          py::gil_scoped_release release;
          c = readPC2(path);
        }
        py::array_t<float> frames(
            {static_cast<py::ssize_t>(c.frames.size()), static_cast<py::ssize_t>(c.numPoints), py::ssize_t(3)});
        float* out = frames.mutable_data();
        for (size_t f = 0; f < c.frames.size(); ++f)
          std::copy(c.frames[f].data(), c.frames[f].data() + 3 * c.numPoints, out + f * 3 * c.numPoints);
        py::dict d;
        d["frames"] = frames;
        d["start_frame"] = c.startFrame;
        d["sample_rate"] = c.sampleRate;
        d["num_points"] = c.numPoints;
        return d;
      },
      py::arg("path"), "dict(frames #frames by #V by 3 float32, start_frame, sample_rate, num_points).");
}

}  // namespace myoskin::python
