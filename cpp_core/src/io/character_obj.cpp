// Wavefront OBJ meshes plus the skeleton JSON beside them: reading and writing.
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "io/character_common.h"
#include "myoskin/errors.h"
#include "myoskin/io.h"

namespace myoskin {

using nlohmann::json;

namespace {

// ============================================================================
// OBJ parsing
// ============================================================================

// Splits a line into whitespace-separated tokens.
std::vector<std::string_view> tokens(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

// Locale-independent number parsing of a whole token (accepts a leading '+', "nan", "inf").
template <typename T>
bool parseNumber(std::string_view s, T& value) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), value);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// Reads `v` and `f` lines; faces are fan-triangulated, indices resolved to 0-based and range-checked.
Mesh readObj(const std::string& path) {
  io_detail::requireFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open");
  std::vector<Vec3> vertices;
  std::vector<Eigen::Vector3i> triangles;
  struct FaceRef {
    long long index;
    int line;
  };
  std::vector<FaceRef> refs;  // positive references, range-checked once all vertices are known
  std::string line;
  int lineNo = 0;
  const auto where = [&](int n) { return path + ": line " + std::to_string(n) + ": "; };
  while (std::getline(in, line)) {
    ++lineNo;
    const auto t = tokens(line);
    if (t.empty()) continue;
    if (t[0] == "v") {
      Vec3 p;
      if (t.size() < 4 || !parseNumber(t[1], p.x()) || !parseNumber(t[2], p.y()) || !parseNumber(t[3], p.z()))
        throw InputError(where(lineNo) + "a vertex needs three numbers");
      if (!p.allFinite()) throw InputError(where(lineNo) + "vertex has a NaN or infinite coordinate");
      vertices.push_back(p);
    } else if (t[0] == "f") {
      if (t.size() < 4) throw InputError(where(lineNo) + "a face needs at least three vertices");
      std::vector<int> face;
      for (size_t k = 1; k < t.size(); ++k) {
        long long idx = 0;
        if (!parseNumber(t[k].substr(0, t[k].find('/')), idx) || idx == 0)
          throw InputError(where(lineNo) + "bad face vertex '" + std::string(t[k]) + "'");
        const long long count = static_cast<long long>(vertices.size());
        if (idx < 0) {
          if (idx < -count)  // (not -idx > count: -LLONG_MIN overflows)
            throw InputError(where(lineNo) + "face index " + std::to_string(idx) + " is out of range (" +
                             std::to_string(count) + " vertices so far)");
          idx = count + idx;
        } else {
          idx -= 1;
          refs.push_back({idx, lineNo});
        }
        if (idx > INT32_MAX) throw InputError(where(lineNo) + "face index is too large");
        face.push_back(static_cast<int>(idx));
      }
      for (size_t k = 1; k + 1 < face.size(); ++k) triangles.emplace_back(face[0], face[k], face[k + 1]);
    }
  }
  if (in.bad()) throw InputError(path + ": read error");
  for (const FaceRef& r : refs)
    if (r.index >= static_cast<long long>(vertices.size()))
      throw InputError(where(r.line) + "face index " + std::to_string(r.index + 1) + " is out of range (" +
                       std::to_string(vertices.size()) + " vertices)");
  if (vertices.empty()) throw InputError(path + ": no vertices (not an OBJ mesh?)");
  if (triangles.empty()) throw InputError(path + ": no faces");
  Mesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (size_t i = 0; i < vertices.size(); ++i)
    mesh.vertices.row(static_cast<Eigen::Index>(i)) = vertices[i].transpose();
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (size_t f = 0; f < triangles.size(); ++f)
    mesh.triangles.row(static_cast<Eigen::Index>(f)) = triangles[f].transpose();
  return mesh;
}

// ============================================================================
// Skeleton JSON parsing
// ============================================================================

// A 3-vector from a JSON array of three finite numbers.
Vec3 readVec3(const json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3) throw InputError(what + " must be an array of three numbers");
  Vec3 v;
  for (int k = 0; k < 3; ++k) {
    if (!j[k].is_number()) throw InputError(what + " must be an array of three numbers");
    v[k] = j[k].get<double>();
  }
  if (!v.allFinite()) throw InputError(what + " has a NaN or infinite value");
  return v;
}

// Parses the file into a skeleton (parent-before-child) and per-vertex influences (empty when absent).
void readSkeletonJson(const std::string& path, int numVertices, Skeleton& skeleton,
                      std::vector<io_detail::Influences>& influences) {
  io_detail::requireFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open");
  json doc;
  try {
    doc = json::parse(in);
  } catch (const json::exception& e) {
    throw InputError(path + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!doc.is_object() || !doc.contains("bones") || !doc["bones"].is_array() || doc["bones"].empty())
    throw InputError(path + ": expected an object with a non-empty \"bones\" array");

  // Bones in file order, then parents by name, then reordered parent-before-child.
  const json& jb = doc["bones"];
  const int n = static_cast<int>(jb.size());
  std::vector<Bone> bones(n);
  std::vector<std::string> parentNames(n);
  std::unordered_map<std::string, int> byName;
  for (int i = 0; i < n; ++i) {
    const json& b = jb[i];
    const std::string label = path + ": bone " + std::to_string(i);
    if (!b.is_object() || !b.contains("name") || !b["name"].is_string() || b["name"].get<std::string>().empty())
      throw InputError(label + " needs a non-empty \"name\"");
    Bone& bone = bones[i];
    bone.name = b["name"].get<std::string>();
    const std::string named = path + ": bone '" + bone.name + "'";
    if (!byName.emplace(bone.name, i).second) throw InputError(named + " appears twice");
    if (!b.contains("head") || !b.contains("tail")) throw InputError(named + " needs \"head\" and \"tail\"");
    bone.head = readVec3(b["head"], named + " head");
    bone.tail = readVec3(b["tail"], named + " tail");
    if (bone.length() < 1e-9) throw InputError(named + " has zero length (head equals tail)");
    const Vec3 xHint =
        b.contains("x_axis") && !b["x_axis"].is_null() ? readVec3(b["x_axis"], named + " x_axis") : Vec3::Zero();
    bone.rest = boneMatrix(bone.head, bone.tail, xHint);
    if (b.contains("parent") && !b["parent"].is_null()) {
      if (!b["parent"].is_string()) throw InputError(named + " parent must be a bone name or null");
      parentNames[i] = b["parent"].get<std::string>();
    }
  }
  std::vector<int> parents(n, -1);
  for (int i = 0; i < n; ++i) {
    if (parentNames[i].empty()) continue;
    const auto it = byName.find(parentNames[i]);
    if (it == byName.end())
      throw InputError(path + ": bone '" + bones[i].name + "' has unknown parent '" + parentNames[i] + "'");
    parents[i] = it->second;
  }
  const std::vector<int> order = io_detail::parentFirstOrder(parents, path);
  std::vector<int> newIndex(n);
  for (int k = 0; k < n; ++k) newIndex[order[k]] = k;
  skeleton.bones.clear();
  for (int k = 0; k < n; ++k) {
    Bone b = bones[order[k]];
    b.parent = parents[order[k]] < 0 ? -1 : newIndex[parents[order[k]]];
    skeleton.bones.push_back(std::move(b));
  }

  // Weights: {"bone": [[vertex, weight], ...]}.
  influences.clear();
  if (!doc.contains("weights") || doc["weights"].is_null()) return;
  const json& jw = doc["weights"];
  if (!jw.is_object()) throw InputError(path + ": \"weights\" must be an object of bone -> [[vertex, weight], ...]");
  influences.assign(numVertices, {});
  for (const auto& [name, list] : jw.items()) {
    const auto it = byName.find(name);
    if (it == byName.end()) throw InputError(path + ": weights for unknown bone '" + name + "'");
    if (!list.is_array()) throw InputError(path + ": weights of bone '" + name + "' must be an array");
    const int bone = newIndex[it->second];
    for (const json& pair : list) {
      if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_integer() || !pair[1].is_number())
        throw InputError(path + ": weights of bone '" + name + "' must be [vertex, weight] pairs");
      const long long v = pair[0].get<long long>();
      if (v < 0 || v >= numVertices)
        throw InputError(path + ": weight of bone '" + name + "' on vertex " + std::to_string(v) + ", outside 0.." +
                         std::to_string(numVertices - 1));
      influences[static_cast<size_t>(v)].emplace_back(bone, pair[1].get<double>());
    }
  }
}

// ============================================================================
// Writing helpers
// ============================================================================

// Shortest decimal text that reads back to exactly the same double.
void appendNumber(std::string& out, double value) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), value);
  out.append(buf, r.ptr);
}

// Opens a file for writing or throws naming it.
std::ofstream openForWriting(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path + ": cannot open for writing");
  return out;
}

// A 3-vector as a JSON array.
json vecJson(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

}  // namespace

// ============================================================================
// Public API
// ============================================================================

// OBJ mesh + skeleton JSON -> welded, validated character.
Mesh readObjMesh(const std::string& path) { return readObj(path); }

Character loadObjWithSkeleton(const std::string& objPath, const std::string& skeletonJsonPath,
                              const LoadOptions& options) {
  const Mesh source = readObj(objPath);
  if (skeletonJsonPath.empty()) throw InputError(objPath + ": no skeleton JSON given");
  Skeleton skeleton;
  std::vector<io_detail::Influences> influences;
  readSkeletonJson(skeletonJsonPath, source.numVertices(), skeleton, influences);
  SkinWeights weights;
  if (!influences.empty()) weights = io_detail::packInfluences(influences, 4, skeletonJsonPath);
  return io_detail::finishCharacter(objPath, source, std::move(skeleton), weights, options);
}

// `v x y z` and 1-based `f a b c` lines, round-trip precision.
void writeObj(const std::string& path, const Points& vertices, const Triangles& triangles) {
  std::string text = "# myoskin\n";
  text.reserve(static_cast<size_t>(vertices.rows()) * 64 + static_cast<size_t>(triangles.rows()) * 24);
  for (Eigen::Index i = 0; i < vertices.rows(); ++i) {
    text += 'v';
    for (int k = 0; k < 3; ++k) {
      text += ' ';
      appendNumber(text, vertices(i, k));
    }
    text += '\n';
  }
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    text += 'f';
    for (int k = 0; k < 3; ++k) text += ' ' + std::to_string(static_cast<long long>(triangles(f, k)) + 1);
    text += '\n';
  }
  std::ofstream out = openForWriting(path);
  out << text;
  if (!out) throw InputError(path + ": write failed");
}

// Bones (name, parent name, head, tail, x_axis = rest X column) and per-bone weight lists of the welded mesh.
void writeSkeletonJson(const std::string& path, const Character& character) {
  const Skeleton& s = character.skeleton;
  json doc;
  doc["format"] = "myoskin.skeleton";
  doc["version"] = 1;
  doc["bones"] = json::array();
  for (const Bone& b : s.bones) {
    const bool hasParent = b.parent >= 0 && b.parent < s.numBones();
    doc["bones"].push_back({{"name", b.name},
                            {"parent", hasParent ? json(s.bones[b.parent].name) : json(nullptr)},
                            {"head", vecJson(b.head)},
                            {"tail", vecJson(b.tail)},
                            {"x_axis", vecJson(b.rest.block<3, 1>(0, 0))}});
  }
  if (character.hasWeights()) {
    std::vector<json> lists(s.bones.size(), json::array());
    const SkinWeights& w = character.weights;
    for (int v = 0; v < w.numVertices(); ++v)
      for (int k = 0; k < w.influences(); ++k) {
        const int j = w.joints(v, k);
        if (j < 0 || j >= s.numBones() || w.weights(v, k) == 0.0) continue;
        lists[j].push_back(json::array({v, w.weights(v, k)}));
      }
    json weights = json::object();
    for (int j = 0; j < s.numBones(); ++j)
      if (!lists[j].empty()) weights[s.bones[j].name] = std::move(lists[j]);
    doc["weights"] = std::move(weights);
  }
  std::ofstream out = openForWriting(path);
  out << doc.dump(1) << '\n';
  if (!out) throw InputError(path + ": write failed");
}

}  // namespace myoskin
