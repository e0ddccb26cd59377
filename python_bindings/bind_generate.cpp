// The procedural test characters with their ground-truth muscles.
#include "bindings.h"
#include "myoskin/errors.h"
#include "myoskin/synthetic_character.h"

namespace myoskin::python {

namespace {

py::list truthDicts(const std::vector<TrueMuscle>& muscles) {
  py::list truth;
  for (const TrueMuscle& t : muscles) {
    py::dict d;
    d["name"] = t.name;
    d["bone"] = t.bone;
    Points line(static_cast<Eigen::Index>(t.centerLine.size()), 3);
    for (size_t i = 0; i < t.centerLine.size(); ++i) line.row(i) = t.centerLine[i].transpose();
    d["center_line"] = line;
    d["radius"] = Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(t.radius.data(), t.radius.size()));
    d["peak_radius"] = t.peakRadius;
    d["relief"] = Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(t.relief.data(), t.relief.size()));
    truth.append(d);
  }
  return truth;
}

}  // namespace

void bindGenerate(py::module_& m) {
  m.def(
      "make_synthetic_arm",
      [](unsigned seed, double muscleScale, int ringsPerMetre, int segmentsAround) {
        SyntheticArmOptions o;
        o.seed = seed;
        o.muscleScale = muscleScale;
        o.ringsPerMetre = ringsPerMetre;
        o.segmentsAround = segmentsAround;
        SyntheticCharacter arm;
        {
          py::gil_scoped_release release;
          arm = makeSyntheticArm(o);
        }
        py::list truth = truthDicts(arm.muscles);
        return py::make_tuple(std::move(arm.character), truth);
      },
      py::arg("seed") = 1, py::arg("muscle_scale") = 1.0, py::arg("rings_per_metre") = SyntheticArmOptions{}.ringsPerMetre,
      py::arg("segments_around") = SyntheticArmOptions{}.segmentsAround,
      "The procedural muscular right arm: (Character, [true muscle dicts with name, bone, center_line #N by 3, "
      "radius #N, peak_radius, relief #N: how far the muscle raises the skin at each point]). Deterministic for the same arguments; muscle_scale=0 gives a smooth arm.");
  m.def(
      "make_synthetic_body",
      [](unsigned seed, const std::string& kind, double muscleScale, double scale, const std::string& naming, bool split,
         double cellSize) {
        SyntheticBodyOptions o;
        o.seed = seed;
        if (kind == "biped") o.kind = BodyKind::Biped;
        else if (kind == "quadruped") o.kind = BodyKind::Quadruped;
        else throw InputError("make_synthetic_body: kind must be 'biped' or 'quadruped', got '" + kind + "'");
        bool known = false;
        for (BoneNaming n : {BoneNaming::Rig, BoneNaming::BlenderDefault, BoneNaming::German, BoneNaming::Japanese,
                             BoneNaming::Unnamed})
          if (naming == boneNamingName(n)) o.naming = n, known = true;
        if (!known)
          throw InputError("make_synthetic_body: naming must be rig, blender, german, japanese or unnamed, got '" +
                           naming + "'");
        o.muscleScale = muscleScale;
        o.scale = scale;
        o.split = split;
        o.cellSize = cellSize;
        SyntheticCharacter body;
        {
          py::gil_scoped_release release;
          body = makeSyntheticBody(o);
        }
        py::list truth = truthDicts(body.muscles);
        return py::make_tuple(std::move(body.character), truth);
      },
      py::arg("seed") = 1, py::arg("kind") = "biped", py::arg("muscle_scale") = 1.0, py::arg("scale") = 1.0,
      py::arg("naming") = "rig", py::arg("split") = false, py::arg("cell_size") = 0.0,
      "A varied whole character (kind 'biped' or 'quadruped'; proportions from the seed; muscle_scale=0: smooth; scale: "
      "overall size; naming: 'rig', 'blender', 'german', 'japanese' or 'unnamed' bone names; split: several meshes "
      "welded as a loader does): (Character, [true muscle dicts as make_synthetic_arm's]).");
}

}  // namespace myoskin::python
