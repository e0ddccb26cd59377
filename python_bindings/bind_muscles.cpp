// Muscles: the in-memory model and the muscles JSON contract (format "myoskin.muscles", version 1).
#include "bindings.h"
#include "myoskin/errors.h"
#include "myoskin/io.h"

namespace myoskin::python {

namespace {

// #N by 3 array from a list of points.
Points toPoints(const std::vector<Vec3>& pts) {
  Points p(static_cast<Eigen::Index>(pts.size()), 3);
  for (size_t i = 0; i < pts.size(); ++i) p.row(i) = pts[i].transpose();
  return p;
}

// #S by 3 array of one Vec3 field of every section.
Points sectionField(const Muscle& m, Vec3 MuscleSection::*f) {
  Points p(static_cast<Eigen::Index>(m.sections.size()), 3);
  for (size_t i = 0; i < m.sections.size(); ++i) p.row(i) = (m.sections[i].*f).transpose();
  return p;
}

// #S vector of one scalar field of every section.
Eigen::VectorXd sectionScalar(const Muscle& m, double MuscleSection::*f) {
  Eigen::VectorXd v(static_cast<Eigen::Index>(m.sections.size()));
  for (size_t i = 0; i < m.sections.size(); ++i) v[i] = m.sections[i].*f;
  return v;
}

}  // namespace

void bindMuscles(py::module_& m) {
  py::class_<Muscle>(m, "Muscle", "A muscle: root curve, elliptical sections, attachments, wrap, bulge, joints.")
      .def(py::init<>())
      .def_readwrite("name", &Muscle::name)
      .def_readwrite("region", &Muscle::region)
      .def_property(
          "origin_bone", [](const Muscle& mu) { return mu.origin.bone; },
          [](Muscle& mu, const std::string& b) { mu.origin.bone = b; })
      .def_property(
          "origin", [](const Muscle& mu) { return mu.origin.position; },
          [](Muscle& mu, const Vec3& p) { mu.origin.position = p; }, "origin position (mesh space, metres)")
      .def_property(
          "insertion_bone", [](const Muscle& mu) { return mu.insertion.bone; },
          [](Muscle& mu, const std::string& b) { mu.insertion.bone = b; })
      .def_property(
          "insertion", [](const Muscle& mu) { return mu.insertion.position; },
          [](Muscle& mu, const Vec3& p) { mu.insertion.position = p; }, "insertion position (mesh space, metres)")
      .def_property(
          "root_curve", [](const Muscle& mu) { return toPoints(mu.rootCurve); },
          [](Muscle& mu, const Points& p) {
            mu.rootCurve.clear();
            for (Eigen::Index i = 0; i < p.rows(); ++i) mu.rootCurve.push_back(p.row(i).transpose());
          },
          "#N by 3 centre line, origin to insertion")
      .def_property_readonly("num_sections", [](const Muscle& mu) { return mu.sections.size(); })
      .def_property_readonly("section_u", [](const Muscle& mu) { return sectionScalar(mu, &MuscleSection::u); })
      .def_property_readonly("section_a", [](const Muscle& mu) { return sectionScalar(mu, &MuscleSection::a); })
      .def_property_readonly("section_b", [](const Muscle& mu) { return sectionScalar(mu, &MuscleSection::b); })
      .def_property_readonly("section_centers", [](const Muscle& mu) { return sectionField(mu, &MuscleSection::center); })
      .def_property_readonly("section_axis_a", [](const Muscle& mu) { return sectionField(mu, &MuscleSection::axisA); })
      .def_property_readonly("section_normals", [](const Muscle& mu) { return sectionField(mu, &MuscleSection::normal); })
      .def(
          "add_section",
          [](Muscle& mu, double u, const Vec3& center, const Vec3& axisA, double a, double b, const Vec3& normal) {
            mu.sections.push_back(MuscleSection{u, center, axisA, a, b, normal});
          },
          py::arg("u"), py::arg("center"), py::arg("axis_a"), py::arg("a"), py::arg("b"), py::arg("normal"))
      .def_property(
          "wrap_type", [](const Muscle& mu) { return std::string(wrapTypeName(mu.wrap.type)); },
          [](Muscle& mu, const std::string& t) { mu.wrap.type = wrapTypeFromName(t); }, "'none', 'joint' or 'bone'")
      .def_property(
          "wrap_bone", [](const Muscle& mu) { return mu.wrap.bone; },
          [](Muscle& mu, const std::string& b) { mu.wrap.bone = b; })
      .def_property(
          "wrap_radius", [](const Muscle& mu) { return mu.wrap.radius; },
          [](Muscle& mu, double r) { mu.wrap.radius = r; })
      .def_property(
          "wrap_side", [](const Muscle& mu) { return mu.wrap.side; },
          [](Muscle& mu, int s) { mu.wrap.side = s < 0 ? -1 : 1; })
      .def_readwrite("bulge", &Muscle::bulge)
      .def_readwrite("joints", &Muscle::joints)
      .def_readwrite("confidence", &Muscle::confidence)
      .def_property_readonly(
          "surface_vertices", [](const Muscle& mu) -> const Points& { return mu.surface.vertices; },
          py::return_value_policy::reference_internal)
      .def_property_readonly(
          "surface_triangles", [](const Muscle& mu) -> const Triangles& { return mu.surface.triangles; },
          py::return_value_policy::reference_internal)
      .def("__repr__", [](const Muscle& mu) {
        return "<myoskin.Muscle '" + mu.name + "': " + std::to_string(mu.sections.size()) + " sections>";
      });

  m.def("muscles_to_json", &musclesToJson, py::arg("muscles"), py::arg("indent") = 1,
        "Serialise muscles to the muscles JSON format (myoskin.muscles, version 1).");
  m.def("muscles_from_json", &musclesFromJson, py::arg("text"),
        "Parse and validate muscles JSON. Raises ValueError naming the muscle and field.");
  m.def("read_muscles", &readMusclesJson, py::arg("path"));
  m.def("write_muscles", &writeMusclesJson, py::arg("path"), py::arg("muscles"));
  m.def("validate_muscles", &validateMuscles, py::arg("muscles"));
}

}  // namespace myoskin::python
