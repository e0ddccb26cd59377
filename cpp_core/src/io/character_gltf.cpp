// glTF 2.0 characters (.glb/.gltf) through tinygltf: skin mesh at rest in scene space, skin joints as bones.
#include <tiny_gltf.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <unordered_map>

#include "io/character_common.h"
#include "myoskin/errors.h"
#include "myoskin/io.h"

namespace myoskin {

namespace tg = tinygltf;

namespace {

constexpr double kMinBoneLength = 1e-6;  // child joints closer than this to a joint do not give it a tail
constexpr double kAlongYDegrees = 15.0;  // a child "continues along Y" within this angle of the joint's Y axis
constexpr double kFallbackLength = 0.1;  // metres, for a root bone without a usable child
constexpr size_t kMaxViewlessElements = size_t(1) << 24;  // an accessor without a buffer view (all zeros)

// ============================================================================
// File
// ============================================================================

// Image callback that keeps nothing: characters need no textures, and tinygltf fails without a loader.
bool ignoreImage(tg::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

// tinygltf's multi-line messages on one line.
std::string oneLine(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  for (char& ch : s)
    if (ch == '\n' || ch == '\r') ch = ';';
  return s;
}

// Parses the file; binary or text is decided by the "glTF" magic, not the extension.
tg::Model readModel(const std::string& path) {
  io_detail::requireFile(path);
  char magic[4] = {0, 0, 0, 0};
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot open");
    in.read(magic, 4);
  }
  const bool binary = magic[0] == 'g' && magic[1] == 'l' && magic[2] == 'T' && magic[3] == 'F';
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (ext == ".glb" && !binary) throw InputError(path + ": not a binary glTF file (it does not start with 'glTF')");
  tg::TinyGLTF loader;
  loader.SetImageLoader(&ignoreImage, nullptr);
  tg::Model model;
  std::string err, warn;
  const bool ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path)
                         : loader.LoadASCIIFromFile(&model, &err, &warn, path);
  if (!ok) {
    const std::string reason = oneLine(err.empty() ? warn : err);
    throw InputError(path + ": not a valid glTF file" + (reason.empty() ? "" : " (" + reason + ")"));
  }
  return model;
}

// ============================================================================
// Accessors
// ============================================================================

// Bytes of one component, or 0 for an unknown type.
size_t componentSize(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

// One component as a double; normalised integers map to [0, 1] (unsigned) or [-1, 1] (signed).
double readComponent(const unsigned char* p, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
      uint8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? v / 255.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return normalized ? v / 4294967295.0 : v;
    }
    default: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

// Pointer to `count` elements of `elementSize` bytes at `stride` in a buffer view, bounds-checked.
const unsigned char* viewData(const tg::Model& model, int viewIndex, size_t offset, size_t stride, size_t count,
                              size_t elementSize, const std::string& what) {
  if (viewIndex < 0 || viewIndex >= static_cast<int>(model.bufferViews.size()))
    throw InputError(what + " refers to a missing buffer view");
  const tg::BufferView& view = model.bufferViews[viewIndex];
  if (view.buffer < 0 || view.buffer >= static_cast<int>(model.buffers.size()))
    throw InputError(what + " refers to a missing buffer");
  const std::vector<unsigned char>& data = model.buffers[view.buffer].data;
  // In this order no sum or product can wrap around (the sizes come from the file: up to 2^64 - 1 each).
  const bool fits = view.byteOffset <= data.size() && view.byteLength <= data.size() - view.byteOffset &&
                    (count == 0 || (offset <= view.byteLength && elementSize <= view.byteLength - offset &&
                                    count - 1 <= (view.byteLength - offset - elementSize) / stride));
  if (!fits)
    throw InputError(what + " reads past the end of its buffer");
  return data.data() + view.byteOffset + offset;
}

// Accessor `index` as count * components doubles (sparse substitution applied).
std::vector<double> readAccessor(const tg::Model& model, int index, int expectedType, const std::string& what,
                                 const tg::Accessor** info = nullptr) {
  if (index < 0 || index >= static_cast<int>(model.accessors.size()))
    throw InputError(what + " refers to a missing accessor");
  const tg::Accessor& a = model.accessors[index];
  if (info) *info = &a;
  if (a.type != expectedType) throw InputError(what + " has the wrong accessor type");
  const size_t cs = componentSize(a.componentType);
  const int nc = tg::GetNumComponentsInType(static_cast<uint32_t>(a.type));
  if (cs == 0 || nc <= 0) throw InputError(what + " has an unknown component type");
  const size_t elementSize = cs * static_cast<size_t>(nc);
  // The count is checked against the data before anything is allocated for it: a buffer view must hold it; an
  // accessor without one (zeros, maybe with sparse values) may not claim more than kMaxViewlessElements.
  const unsigned char* base = nullptr;
  size_t stride = elementSize;
  if (a.bufferView >= 0) {
    if (a.bufferView >= static_cast<int>(model.bufferViews.size()))
      throw InputError(what + " refers to a missing buffer view");
    const tg::BufferView& view = model.bufferViews[a.bufferView];
    stride = view.byteStride ? view.byteStride : elementSize;
    if (stride < elementSize) throw InputError(what + " has a byte stride smaller than its element");
    base = viewData(model, a.bufferView, a.byteOffset, stride, a.count, elementSize, what);
  } else if (a.count > kMaxViewlessElements) {
    throw InputError(what + " has " + std::to_string(a.count) + " elements and no buffer view (at most " +
                     std::to_string(kMaxViewlessElements) + ")");
  }
  std::vector<double> out(a.count * static_cast<size_t>(nc), 0.0);
  if (base) {
    for (size_t i = 0; i < a.count; ++i)
      for (int c = 0; c < nc; ++c)
        out[i * nc + c] = readComponent(base + i * stride + c * cs, a.componentType, a.normalized);
  }
  if (a.sparse.isSparse && a.sparse.count > 0) {
    const size_t n = static_cast<size_t>(a.sparse.count);
    const size_t ics = componentSize(a.sparse.indices.componentType);
    if (ics == 0) throw InputError(what + " has sparse indices of an unknown type");
    const unsigned char* idx = viewData(model, a.sparse.indices.bufferView, a.sparse.indices.byteOffset, ics, n, ics,
                                        what + " (sparse indices)");
    const unsigned char* val = viewData(model, a.sparse.values.bufferView, a.sparse.values.byteOffset, elementSize, n,
                                        elementSize, what + " (sparse values)");
    for (size_t s = 0; s < n; ++s) {
      const double target = readComponent(idx + s * ics, a.sparse.indices.componentType, false);
      if (target < 0 || target >= static_cast<double>(a.count))
        throw InputError(what + " has a sparse index out of range");
      for (int c = 0; c < nc; ++c)
        out[static_cast<size_t>(target) * nc + c] =
            readComponent(val + s * elementSize + c * cs, a.componentType, a.normalized);
    }
  }
  return out;
}

// ============================================================================
// Scene graph
// ============================================================================

// The node's local matrix: `matrix` if given, else translation * rotation * scale.
Mat4 localMatrix(const tg::Node& node) {
  Mat4 m = Mat4::Identity();
  if (node.matrix.size() == 16) {
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m(r, c) = node.matrix[c * 4 + r];  // column-major
    return m;
  }
  if (node.rotation.size() == 4) {
    Eigen::Quaterniond q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    if (q.norm() > 0) m.block<3, 3>(0, 0) = q.normalized().toRotationMatrix();
  }
  if (node.scale.size() == 3)
    for (int c = 0; c < 3; ++c) m.block<3, 1>(0, c) *= node.scale[c];
  if (node.translation.size() == 3)
    m.block<3, 1>(0, 3) = Vec3(node.translation[0], node.translation[1], node.translation[2]);
  return m;
}

// World matrix of every node and each node's parent (-1 for roots); throws on bad children or cycles.
std::vector<Mat4> worldMatrices(const tg::Model& model, const std::string& path, std::vector<int>& parentOf) {
  const int n = static_cast<int>(model.nodes.size());
  parentOf.assign(n, -1);
  for (int i = 0; i < n; ++i)
    for (int c : model.nodes[i].children) {
      if (c < 0 || c >= n) throw InputError(path + ": node " + std::to_string(i) + " has a missing child");
      if (parentOf[c] >= 0 || c == i) throw InputError(path + ": node " + std::to_string(c) + " has two parents");
      parentOf[c] = i;
    }
  std::vector<Mat4> world(n);
  std::vector<char> done(n, 0);
  for (int i = 0; i < n; ++i) {
    std::vector<int> chain;
    for (int k = i; k >= 0 && !done[k]; k = parentOf[k]) {
      chain.push_back(k);
      if (static_cast<int>(chain.size()) > n) throw InputError(path + ": the node hierarchy has a cycle");
    }
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const int p = parentOf[*it];
      world[*it] = (p >= 0 ? world[p] : Mat4::Identity()) * localMatrix(model.nodes[*it]);
      done[*it] = 1;
    }
  }
  return world;
}

// ============================================================================
// Skeleton
// ============================================================================

// Bones from a skin's joints: parent = nearest joint ancestor, parent-before-child order, heads at the joints,
// tails from the child joints or along the joint's Y axis. boneOfJoint[j] = bone index of skin joint j.
Skeleton buildSkeleton(const tg::Model& model, const tg::Skin& skin, const std::vector<Mat4>& world,
                       const std::vector<int>& parentOf, const std::string& path, std::vector<int>& boneOfJoint) {
  const int nj = static_cast<int>(skin.joints.size());
  if (nj == 0) throw InputError(path + ": the skin has no joints");
  std::unordered_map<int, int> jointOfNode;
  for (int j = 0; j < nj; ++j) {
    const int node = skin.joints[j];
    if (node < 0 || node >= static_cast<int>(model.nodes.size()))
      throw InputError(path + ": skin joint " + std::to_string(j) + " is a missing node");
    if (!jointOfNode.emplace(node, j).second)
      throw InputError(path + ": node " + std::to_string(node) + " is listed twice among the skin joints");
  }
  std::vector<int> parents(nj, -1);
  for (int j = 0; j < nj; ++j)
    for (int p = parentOf[skin.joints[j]]; p >= 0; p = parentOf[p]) {
      const auto it = jointOfNode.find(p);
      if (it != jointOfNode.end()) {
        parents[j] = it->second;
        break;
      }
    }
  const std::vector<int> order = io_detail::parentFirstOrder(parents, path);
  boneOfJoint.assign(nj, -1);
  for (int k = 0; k < nj; ++k) boneOfJoint[order[k]] = k;

  Skeleton skeleton;
  skeleton.bones.resize(nj);
  for (int k = 0; k < nj; ++k) {
    const int node = skin.joints[order[k]];
    Bone& b = skeleton.bones[k];
    b.name = model.nodes[node].name.empty() ? "joint_" + std::to_string(node) : model.nodes[node].name;
    b.parent = parents[order[k]] < 0 ? -1 : boneOfJoint[parents[order[k]]];
    b.head = world[node].block<3, 1>(0, 3);
  }
  const double cosAlong = std::cos(kAlongYDegrees * M_PI / 180.0);
  for (int k = 0; k < nj; ++k) {
    Bone& b = skeleton.bones[k];
    const Mat4& w = world[skin.joints[order[k]]];
    Vec3 y = w.block<3, 1>(0, 1);
    if (!(y.norm() > 1e-12)) throw InputError(path + ": joint '" + b.name + "' has a zero-length Y axis (zero scale)");
    y.normalize();
    std::vector<int> kids;  // child bones whose heads are not on this head
    for (int c = k + 1; c < nj; ++c)
      if (skeleton.bones[c].parent == k && (skeleton.bones[c].head - b.head).norm() > kMinBoneLength) kids.push_back(c);
    int pick = kids.size() == 1 ? kids[0] : -1;
    double bestCos = cosAlong;
    if (kids.size() > 1)
      for (int c : kids) {
        const double cosine = (skeleton.bones[c].head - b.head).normalized().dot(y);
        if (cosine >= bestCos) bestCos = cosine, pick = c;
      }
    if (pick >= 0) {
      b.tail = skeleton.bones[pick].head;
    } else {
      double length = b.parent >= 0 ? skeleton.bones[b.parent].length() : kFallbackLength;
      if (!(length > kMinBoneLength)) length = kFallbackLength;
      b.tail = b.head + y * length;
    }
    if (!(b.length() > 1e-9)) throw InputError(path + ": bone '" + b.name + "' has zero length");
    b.rest = boneMatrix(b.head, b.tail, w.block<3, 1>(0, 0));
  }
  return skeleton;
}

// ============================================================================
// Mesh
// ============================================================================

// Source geometry: vertices at rest in the scene and per-vertex influences in skin-joint indices.
struct Geometry {
  std::vector<Vec3> vertices;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<io_detail::Influences> influences;
  bool hasWeights = false;
};

// Appends one TRIANGLES primitive (or reuses the vertices of an earlier primitive with the same attributes).
void addPrimitive(const tg::Model& model, const tg::Primitive& prim, bool skinned, int numJoints,
                  const std::vector<Mat4>& jointMatrices, const Mat4& meshWorld, const std::string& what,
                  std::map<std::vector<int>, int>& reuse, Geometry& g) {
  const auto pos = prim.attributes.find("POSITION");
  if (pos == prim.attributes.end()) throw InputError(what + " has no POSITION");
  std::vector<int> key = {pos->second};
  std::vector<std::pair<int, int>> sets;  // (JOINTS_s, WEIGHTS_s) accessor pairs
  for (int s = 0;; ++s) {
    const auto js = prim.attributes.find("JOINTS_" + std::to_string(s));
    const auto ws = prim.attributes.find("WEIGHTS_" + std::to_string(s));
    if (js == prim.attributes.end() || ws == prim.attributes.end()) break;
    sets.emplace_back(js->second, ws->second);
    key.push_back(js->second);
    key.push_back(ws->second);
  }
  const auto known = reuse.find(key);
  const int offset = known != reuse.end() ? known->second : static_cast<int>(g.vertices.size());
  const tg::Accessor* posInfo = nullptr;
  const std::vector<double> p = readAccessor(model, pos->second, TINYGLTF_TYPE_VEC3, what + " POSITION", &posInfo);
  const size_t count = posInfo->count;

  if (known == reuse.end()) {
    reuse.emplace(key, offset);
    std::vector<io_detail::Influences> inf(count);
    for (size_t s = 0; s < sets.size() && skinned; ++s) {
      const std::string sw = what + " WEIGHTS_" + std::to_string(s), sj = what + " JOINTS_" + std::to_string(s);
      const tg::Accessor *ja = nullptr, *wa = nullptr;
      const std::vector<double> jv = readAccessor(model, sets[s].first, TINYGLTF_TYPE_VEC4, sj, &ja);
      const std::vector<double> wv = readAccessor(model, sets[s].second, TINYGLTF_TYPE_VEC4, sw, &wa);
      if (ja->count != count || wa->count != count) throw InputError(sj + " / WEIGHTS count differs from POSITION");
      if (ja->componentType == TINYGLTF_COMPONENT_TYPE_FLOAT || ja->normalized)
        throw InputError(sj + " must be unsigned integers");
      if (wa->componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !wa->normalized)
        throw InputError(sw + " must be float or normalised integers");
      for (size_t v = 0; v < count; ++v)
        for (int c = 0; c < 4; ++c) {
          const double w = wv[v * 4 + c];
          if (w == 0.0) continue;
          const double j = jv[v * 4 + c];
          if (j < 0 || j >= numJoints)
            throw InputError(sj + ": vertex " + std::to_string(v) + " uses joint " + std::to_string(int64_t(j)) +
                             ", the skin has " + std::to_string(numJoints));
          inf[v].emplace_back(static_cast<int>(j), w);
        }
    }
    for (size_t v = 0; v < count; ++v) {
      // Rest skinning: sum_j w_j (World(joint_j) * IBM_j) v, or the mesh node's world matrix when unweighted.
      double sum = 0.0;
      for (const auto& [j, w] : inf[v]) sum += w;
      Mat4 m = Mat4::Zero();
      if (skinned && sum > 1e-4) {
        for (const auto& [j, w] : inf[v]) m += (w / sum) * jointMatrices[j];
      } else {
        m = meshWorld;
      }
      const Vec3 local(p[v * 3], p[v * 3 + 1], p[v * 3 + 2]);
      g.vertices.push_back(m.block<3, 3>(0, 0) * local + m.block<3, 1>(0, 3));
      if (!inf[v].empty()) g.hasWeights = true;
      g.influences.push_back(std::move(inf[v]));
    }
  }

  std::vector<int64_t> idx;
  if (prim.indices >= 0) {
    const tg::Accessor* ia = nullptr;
    const std::vector<double> iv = readAccessor(model, prim.indices, TINYGLTF_TYPE_SCALAR, what + " indices", &ia);
    if (ia->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        ia->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        ia->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      throw InputError(what + " indices must be unsigned integers");
    idx.assign(iv.begin(), iv.end());
  } else {
    idx.resize(count);
    for (size_t i = 0; i < count; ++i) idx[i] = static_cast<int64_t>(i);
  }
  if (idx.size() % 3 != 0) throw InputError(what + " has an index count that is not a multiple of 3");
  for (size_t t = 0; t < idx.size(); t += 3) {
    Eigen::Vector3i tri;
    for (int c = 0; c < 3; ++c) {
      if (idx[t + c] >= static_cast<int64_t>(count))
        throw InputError(what + ": index " + std::to_string(idx[t + c]) + " is out of range (" + std::to_string(count) +
                         " vertices)");
      tri[c] = offset + static_cast<int>(idx[t + c]);
    }
    g.triangles.push_back(tri);
  }
}

}  // namespace

// ============================================================================
// Public API
// ============================================================================

// Every mesh node skinned by the first skin used (or the one named by options.meshName, else the first mesh
// node), placed at rest in the scene, with that skin as skeleton; one piece per node.
Character loadGltf(const std::string& path, const LoadOptions& options) {
  const tg::Model model = readModel(path);
  const int numNodes = static_cast<int>(model.nodes.size());
  auto nodeName = [&](int i) {
    const tg::Node& n = model.nodes[i];
    if (!n.name.empty()) return n.name;
    if (n.mesh >= 0 && n.mesh < static_cast<int>(model.meshes.size()) && !model.meshes[n.mesh].name.empty())
      return model.meshes[n.mesh].name;
    return "mesh_node_" + std::to_string(i);
  };
  std::vector<int> meshNodes;
  if (!options.meshName.empty()) {
    std::string names;
    for (int i = 0; i < numNodes; ++i) {
      if (model.nodes[i].mesh < 0) continue;
      const bool meshMatches = model.nodes[i].mesh < static_cast<int>(model.meshes.size()) &&
                               model.meshes[model.nodes[i].mesh].name == options.meshName;
      if (model.nodes[i].name == options.meshName || meshMatches) {
        meshNodes.push_back(i);
        break;
      }
      names += (names.empty() ? "" : ", ") + nodeName(i);
    }
    if (meshNodes.empty())
      throw InputError(path + ": no mesh called '" + options.meshName + "' (meshes: " + (names.empty() ? "none" : names) + ")");
  } else {
    // The first skin a mesh uses; other skins over the same joints (one per mesh, as exporters write them) count too.
    int skinIndex = -1;
    for (int i = 0; i < numNodes && skinIndex < 0; ++i)
      if (model.nodes[i].mesh >= 0 && model.nodes[i].skin >= 0 && model.nodes[i].skin < static_cast<int>(model.skins.size()))
        skinIndex = model.nodes[i].skin;
    auto sameJoints = [&](int s) {
      if (s < 0 || s >= static_cast<int>(model.skins.size())) return false;
      std::vector<int> a = model.skins[s].joints, b = model.skins[skinIndex].joints;
      std::sort(a.begin(), a.end()), std::sort(b.begin(), b.end());
      return a == b;
    };
    for (int i = 0; i < numNodes; ++i)
      if (model.nodes[i].mesh >= 0 && (skinIndex < 0 ? meshNodes.empty() : sameJoints(model.nodes[i].skin)))
        meshNodes.push_back(i);
  }
  if (meshNodes.empty()) throw InputError(path + ": contains no mesh");
  const int meshNode = meshNodes[0];
  for (int i : meshNodes) {
    if (model.nodes[i].mesh >= static_cast<int>(model.meshes.size()))
      throw InputError(path + ": a node refers to a missing mesh");
    if (model.nodes[i].skin >= static_cast<int>(model.skins.size()))
      throw InputError(path + ": a node refers to a missing skin");
  }
  const tg::Node& node = model.nodes[meshNode];
  const bool skinned = node.skin >= 0;
  if (!skinned && options.requireWeights) throw InputError(path + ": the mesh has no skin (no skin weights)");

  std::vector<int> parentOf;
  const std::vector<Mat4> world = worldMatrices(model, path, parentOf);

  // The skeleton: the mesh's skin, or for an unskinned mesh the file's first skin.
  if (!skinned && model.skins.empty()) throw InputError(path + ": has no skeleton (no glTF skin)");
  const tg::Skin& skin = model.skins[skinned ? node.skin : 0];
  std::vector<int> boneOfJoint;
  Skeleton skeleton = buildSkeleton(model, skin, world, parentOf, path, boneOfJoint);
  const int nj = static_cast<int>(skin.joints.size());

  // Joint matrices at rest of one skin, in its own joint order: World(joint_j) * inverseBindMatrix_j.
  std::unordered_map<int, int> jointOfNode;
  for (int j = 0; j < nj; ++j) jointOfNode[skin.joints[j]] = j;
  auto restJointMatrices = [&](const tg::Skin& s) {
    std::vector<Mat4> matrices(s.joints.size(), Mat4::Identity());
    std::vector<double> ibm;
    if (s.inverseBindMatrices >= 0) {
      const tg::Accessor* info = nullptr;
      ibm = readAccessor(model, s.inverseBindMatrices, TINYGLTF_TYPE_MAT4, path + ": inverse bind matrices", &info);
      if (info->count < s.joints.size()) throw InputError(path + ": fewer inverse bind matrices than joints");
    }
    for (size_t j = 0; j < s.joints.size(); ++j) {
      Mat4 inv = Mat4::Identity();
      if (!ibm.empty())
        for (int c = 0; c < 4; ++c)
          for (int r = 0; r < 4; ++r) inv(r, c) = ibm[j * 16 + c * 4 + r];
      matrices[j] = world[s.joints[j]] * inv;
    }
    return matrices;
  };

  // Geometry: all TRIANGLES primitives of every piece.
  Geometry g;
  std::vector<MeshPiece> pieces;
  for (int n : meshNodes) {
    const tg::Mesh& mesh = model.meshes[model.nodes[n].mesh];
    const int first = static_cast<int>(g.vertices.size());
    std::map<std::vector<int>, int> reuse;
    const int nodeSkin = model.nodes[n].skin;
    const bool pieceSkinned = skinned && nodeSkin >= 0;
    const std::vector<Mat4> jointMatrices =
        pieceSkinned ? restJointMatrices(model.skins[nodeSkin]) : std::vector<Mat4>(nj, Mat4::Identity());
    // Influences are read in this skin's joint order and renumbered into the skeleton skin's.
    const size_t before = g.influences.size();
    for (size_t k = 0; k < mesh.primitives.size(); ++k) {
      const tg::Primitive& prim = mesh.primitives[k];
      if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) continue;  // -1: mode absent = TRIANGLES
      addPrimitive(model, prim, pieceSkinned, static_cast<int>(jointMatrices.size()), jointMatrices, world[n],
                   path + ": mesh '" + mesh.name + "' primitive " + std::to_string(k), reuse, g);
    }
    if (pieceSkinned)
      for (size_t v = before; v < g.influences.size(); ++v)
        for (auto& entry : g.influences[v]) entry.first = jointOfNode.at(model.skins[nodeSkin].joints[entry.first]);
    pieces.push_back({nodeName(n), first, static_cast<int>(g.vertices.size()) - first});
  }
  if (g.triangles.empty()) throw InputError(path + ": the mesh has no triangles");
  if (skinned && options.requireWeights && !g.hasWeights)
    throw InputError(path + ": the mesh has no skin weights (JOINTS_0/WEIGHTS_0)");

  Mesh source;
  source.vertices.resize(static_cast<Eigen::Index>(g.vertices.size()), 3);
  for (size_t i = 0; i < g.vertices.size(); ++i)
    source.vertices.row(static_cast<Eigen::Index>(i)) = g.vertices[i].transpose();
  source.triangles.resize(static_cast<Eigen::Index>(g.triangles.size()), 3);
  for (size_t f = 0; f < g.triangles.size(); ++f)
    source.triangles.row(static_cast<Eigen::Index>(f)) = g.triangles[f].transpose();

  SkinWeights weights;
  if (g.hasWeights) {
    for (auto& inf : g.influences)
      for (auto& entry : inf) entry.first = boneOfJoint[entry.first];
    weights = io_detail::packInfluences(g.influences, 4, path);
  }
  Character c = io_detail::finishCharacter(path, source, std::move(skeleton), weights, options);
  c.pieces = std::move(pieces);
  return c;
}

}  // namespace myoskin
