// Character, mesh checks and loaders. Arrays are returned as read-only numpy views of the C++ data.
#include "bindings.h"
#include "myoskin/errors.h"
#include "myoskin/io.h"
#include "myoskin/mesh.h"

namespace myoskin::python {

namespace {

using RowMat4 = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;

py::dict topologyToDict(const TopologyReport& t) {
  py::dict d;
  d["boundary_edges"] = t.boundaryEdges;
  d["non_manifold_edges"] = t.nonManifoldEdges;
  d["inconsistent_edges"] = t.inconsistentEdges;
  d["components"] = t.components;
  d["degenerate_triangles"] = t.degenerateTriangles;
  d["closed"] = t.closed();
  d["manifold"] = t.manifold();
  d["oriented"] = t.oriented();
  return d;
}

// #B by 4 by 4 array of the bones' rest matrices.
py::array_t<double> restMatrices(const Skeleton& s) {
  py::array_t<double> out({static_cast<py::ssize_t>(s.numBones()), py::ssize_t(4), py::ssize_t(4)});
  auto a = out.mutable_unchecked<3>();
  for (int b = 0; b < s.numBones(); ++b)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) a(b, r, c) = s.bones[b].rest(r, c);
  return out;
}

// #B by 3 array of one Vec3 field of every bone.
template <typename Getter>
Points boneVectors(const Skeleton& s, Getter get) {
  Points p(s.numBones(), 3);
  for (int b = 0; b < s.numBones(); ++b) p.row(b) = get(s.bones[b]).transpose();
  return p;
}

// Builds and validates a Character from arrays (the add-on's route from Blender data).
Character characterFromArrays(const std::string& name, const Points& vertices, const Triangles& triangles,
                              const std::vector<std::string>& boneNames, const IndexVector& boneParents,
                              const Points& boneHeads, const Points& boneTails, py::array_t<double> boneRest,
                              const IndexMatrix& weightJoints, const WeightMatrix& weightValues) {
  const auto nb = static_cast<Eigen::Index>(boneNames.size());
  if (boneParents.rows() != nb || boneHeads.rows() != nb || boneTails.rows() != nb)
    throw InputError("character: bone_parents, bone_heads and bone_tails need one row per bone name (" +
                     std::to_string(nb) + ")");
  if (boneRest.ndim() != 3 || boneRest.shape(0) != nb || boneRest.shape(1) != 4 || boneRest.shape(2) != 4)
    throw InputError("character: bone_rest must be #B by 4 by 4");
  Character c;
  c.name = name;
  c.mesh.vertices = vertices;
  c.mesh.triangles = triangles;
  auto rest = boneRest.unchecked<3>();
  for (Eigen::Index b = 0; b < nb; ++b) {
    Bone bone;
    bone.name = boneNames[b];
    bone.parent = boneParents[b];
    bone.head = boneHeads.row(b).transpose();
    bone.tail = boneTails.row(b).transpose();
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 4; ++k) bone.rest(r, k) = rest(b, r, k);
    c.skeleton.bones.push_back(bone);
  }
  c.weights.joints = weightJoints;
  c.weights.weights = weightValues;
  c.sourceVertexCount = c.mesh.numVertices();
  c.sourceToWelded.resize(c.sourceVertexCount);
  for (int i = 0; i < c.sourceVertexCount; ++i) c.sourceToWelded[i] = i;
  validateCharacter(c);
  return c;
}

}  // namespace

void bindCharacter(py::module_& m) {
  py::class_<Character>(m, "Character", "A rigged character: welded skin mesh, skeleton and skin weights.")
      .def_readonly("name", &Character::name)
      .def_property_readonly(
          "vertices", [](const Character& c) -> const Points& { return c.mesh.vertices; },
          py::return_value_policy::reference_internal, "#V by 3 float64 rest positions (metres), read-only view")
      .def_property_readonly(
          "triangles", [](const Character& c) -> const Triangles& { return c.mesh.triangles; },
          py::return_value_policy::reference_internal, "#F by 3 int32 vertex indices, read-only view")
      .def_property_readonly(
          "weight_joints", [](const Character& c) -> const IndexMatrix& { return c.weights.joints; },
          py::return_value_policy::reference_internal, "#V by K int32 bone indices (-1 = empty slot)")
      .def_property_readonly(
          "weight_values", [](const Character& c) -> const WeightMatrix& { return c.weights.weights; },
          py::return_value_policy::reference_internal, "#V by K float64 weights")
      .def_property_readonly("source_to_welded",
                             [](const Character& c) { return indexArray(c.sourceToWelded); })
      .def_readonly("source_vertex_count", &Character::sourceVertexCount)
      .def_property_readonly("pieces",
                             [](const Character& c) {
                               py::list out;
                               for (const MeshPiece& p : c.pieces)
                                 out.append(py::make_tuple(p.name, p.firstVertex, p.vertexCount));
                               return out;
                             },
                             "[(name, first source vertex, vertex count)] of the meshes it was loaded from")
      .def_property_readonly("num_vertices", [](const Character& c) { return c.mesh.numVertices(); })
      .def_property_readonly("num_triangles", [](const Character& c) { return c.mesh.numTriangles(); })
      .def_property_readonly("num_bones", [](const Character& c) { return c.skeleton.numBones(); })
      .def_property_readonly("has_weights", &Character::hasWeights)
      .def_property_readonly("bone_names",
                             [](const Character& c) {
                               std::vector<std::string> n;
                               for (const Bone& b : c.skeleton.bones) n.push_back(b.name);
                               return n;
                             })
      .def_property_readonly("bone_parents",
                             [](const Character& c) {
                               IndexVector p(c.skeleton.numBones());
                               for (int b = 0; b < c.skeleton.numBones(); ++b) p[b] = c.skeleton.bones[b].parent;
                               return p;
                             })
      .def_property_readonly("bone_heads",
                             [](const Character& c) { return boneVectors(c.skeleton, [](const Bone& b) { return b.head; }); })
      .def_property_readonly("bone_tails",
                             [](const Character& c) { return boneVectors(c.skeleton, [](const Bone& b) { return b.tail; }); })
      .def_property_readonly("bone_rest", [](const Character& c) { return restMatrices(c.skeleton); },
                             "#B by 4 by 4 rest matrices (bone space -> mesh space, like Bone.matrix_local)")
      .def("topology", [](const Character& c) { return topologyToDict(analyzeTopology(c.mesh)); })
      .def("volume", [](const Character& c) { return enclosedVolume(c.mesh.vertices, c.mesh.triangles); })
      .def("bounding_box",
           [](const Character& c) {
             Vec3 lo, hi;
             boundingBox(c.mesh.vertices, lo, hi);
             return py::make_tuple(lo, hi);
           })
      .def("__repr__", [](const Character& c) {
        return "<myoskin.Character '" + c.name + "': " + std::to_string(c.mesh.numVertices()) + " vertices, " +
               std::to_string(c.skeleton.numBones()) + " bones>";
      });

  m.def(
      "load_character",
      [](const std::string& path, double weldTolerance, bool requireWeights, const std::string& skeletonPath,
         const std::string& mesh) {
        LoadOptions o;
        o.weldTolerance = weldTolerance;
        o.requireWeights = requireWeights;
        o.meshName = mesh;
        return loadCharacter(path, o, skeletonPath);
      },
      py::arg("path"), py::arg("weld_tolerance") = LoadOptions{}.weldTolerance, py::arg("require_weights") = false,
      py::arg("skeleton_path") = "", py::arg("mesh") = "", py::call_guard<py::gil_scoped_release>(),
      "Load a .glb/.gltf (every mesh its skin deforms, or only `mesh`), or an .obj with <stem>.skeleton.json. "
      "weld_tolerance is a share of the skin's bounding-box diagonal. Raises ValueError on bad input.");
  m.def("character_from_arrays", &characterFromArrays, py::arg("name"), py::arg("vertices"), py::arg("triangles"),
        py::arg("bone_names"), py::arg("bone_parents"), py::arg("bone_heads"), py::arg("bone_tails"),
        py::arg("bone_rest"), py::arg("weight_joints"), py::arg("weight_values"),
        "Build a validated Character from arrays (vertices #V by 3, triangles #F by 3, bone_rest #B by 4 by 4, "
        "weight_joints/weight_values #V by K). Raises ValueError naming the offending item.");
  m.def(
      "weld_mesh",
      [](const Points& vertices, const Triangles& triangles, double tolerance) {
        Mesh mesh{vertices, triangles};
        validateMesh(mesh);
        if (!(tolerance >= 0)) throw InputError("weld_mesh: tolerance must be >= 0");
        std::vector<int> weldMap;
        Mesh welded;
        {
          py::gil_scoped_release release;
          welded = weldByPosition(mesh, tolerance, weldMap);
        }
        IndexVector map(static_cast<Eigen::Index>(weldMap.size()));
        for (size_t i = 0; i < weldMap.size(); ++i) map[static_cast<Eigen::Index>(i)] = weldMap[i];
        return py::make_tuple(welded.vertices, welded.triangles, map);
      },
      py::arg("vertices"), py::arg("triangles"), py::arg("tolerance") = 1e-6,
      "Merge vertices closer than tolerance (UV seams). Returns (vertices #W by 3, triangles #F' by 3, "
      "weld_map #V: welded index of each input vertex); collapsed triangles are dropped.");
  m.def(
      "analyze_topology",
      [](const Points& vertices, const Triangles& triangles) {
        Mesh mesh{vertices, triangles};
        validateMesh(mesh);
        return topologyToDict(analyzeTopology(mesh));
      },
      py::arg("vertices"), py::arg("triangles"), "Boundary/non-manifold/inconsistent edges and components.");
  m.def(
      "write_obj",
      [](const std::string& path, const Points& v, const Triangles& f) { writeObj(path, v, f); },
      py::arg("path"), py::arg("vertices"), py::arg("triangles"));
}

}  // namespace myoskin::python
