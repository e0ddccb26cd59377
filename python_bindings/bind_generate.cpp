// The procedural test characters with their ground-truth muscles.
#include "bindings.h"
#include "myoskin/synthetic_character.h"

namespace myoskin::python {

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
        py::list truth;
        for (const TrueMuscle& t : arm.muscles) {
          py::dict d;
          d["name"] = t.name;
          d["bone"] = t.bone;
          Points line(static_cast<Eigen::Index>(t.centerLine.size()), 3);
          for (size_t i = 0; i < t.centerLine.size(); ++i) line.row(i) = t.centerLine[i].transpose();
          d["center_line"] = line;
          d["radius"] = Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(t.radius.data(), t.radius.size()));
          d["peak_radius"] = t.peakRadius;
          truth.append(d);
        }
        return py::make_tuple(std::move(arm.character), truth);
      },
      py::arg("seed") = 1, py::arg("muscle_scale") = 1.0, py::arg("rings_per_metre") = SyntheticArmOptions{}.ringsPerMetre,
      py::arg("segments_around") = SyntheticArmOptions{}.segmentsAround,
      "The procedural muscular right arm: (Character, [true muscle dicts with name, bone, center_line #N by 3, "
      "radius #N, peak_radius]). Deterministic for the same arguments; muscle_scale=0 gives a smooth arm.");
}

}  // namespace myoskin::python
