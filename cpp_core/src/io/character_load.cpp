// Character loading: dispatch by file extension and the finishing steps shared by all loaders.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "io/character_common.h"
#include "myoskin/errors.h"
#include "myoskin/io.h"

namespace myoskin {

namespace fs = std::filesystem;

namespace io_detail {

// ============================================================================
// Files
// ============================================================================

// Fails with a one-line reason when the path is missing or not a regular file.
void requireFile(const std::string& path) {
  std::error_code ec;
  if (path.empty()) throw InputError("no file name given");
  if (!fs::exists(path, ec)) throw InputError(path + ": file not found");
  if (!fs::is_regular_file(path, ec)) throw InputError(path + ": not a regular file");
}

// The file name without folder and extension.
std::string fileStem(const std::string& path) {
  return fs::path(path).stem().string();
}

// ============================================================================
// Ordering
// ============================================================================

// Depth-first emission of each item after its parent chain, in the original order otherwise.
std::vector<int> parentFirstOrder(const std::vector<int>& parents, const std::string& path) {
  const int n = static_cast<int>(parents.size());
  std::vector<int> state(n, 0);  // 0 = new, 1 = on the current chain, 2 = emitted
  std::vector<int> order;
  order.reserve(n);
  for (int start = 0; start < n; ++start) {
    std::vector<int> chain;  // start and its unemitted ancestors, child first
    for (int i = start; i >= 0 && state[i] != 2; i = parents[i]) {
      if (state[i] == 1) throw InputError(path + ": the bone hierarchy has a cycle");
      state[i] = 1;
      chain.push_back(i);
    }
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      state[*it] = 2;
      order.push_back(*it);
    }
  }
  return order;
}

// ============================================================================
// Weights
// ============================================================================

// Canonical K-slot form of per-vertex influence lists.
SkinWeights packInfluences(const std::vector<Influences>& perVertex, int minSlots, const std::string& path) {
  const int n = static_cast<int>(perVertex.size());
  std::vector<Influences> merged(n);
  int slots = minSlots;
  for (int v = 0; v < n; ++v) {
    Influences& m = merged[v];
    for (const auto& [bone, w] : perVertex[v]) {
      if (!std::isfinite(w) || w < 0.0)
        throw InputError(path + ": vertex " + std::to_string(v) + " has an invalid skin weight " + std::to_string(w));
      if (w == 0.0 || bone < 0) continue;
      auto it = std::find_if(m.begin(), m.end(), [b = bone](const auto& p) { return p.first == b; });
      if (it == m.end())
        m.emplace_back(bone, w);
      else
        it->second += w;
    }
    std::sort(m.begin(), m.end(), [](const auto& a, const auto& b) {
      return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    slots = std::max(slots, static_cast<int>(m.size()));
  }
  SkinWeights out;
  out.joints = IndexMatrix::Constant(n, slots, -1);
  out.weights = WeightMatrix::Zero(n, slots);
  for (int v = 0; v < n; ++v) {
    double sum = 0.0;
    for (const auto& p : merged[v]) sum += p.second;
    // Blender leaves a vertex with sum <= 1e-4 at rest, so only larger sums are normalised.
    const double scale = sum > 1e-4 ? 1.0 / sum : 1.0;
    for (size_t k = 0; k < merged[v].size(); ++k) {
      out.joints(v, static_cast<Eigen::Index>(k)) = merged[v][k].first;
      out.weights(v, static_cast<Eigen::Index>(k)) = merged[v][k].second * scale;
    }
  }
  return out;
}

// ============================================================================
// Finishing
// ============================================================================

// Weld, carry weights over, check options and validate, naming the file in every error.
Character finishCharacter(const std::string& path, const Mesh& source, Skeleton skeleton,
                          const SkinWeights& sourceWeights, const LoadOptions& options) {
  if (!(options.weldTolerance >= 0.0) || !std::isfinite(options.weldTolerance))
    throw InputError(path + ": weld tolerance must be a finite number >= 0");
  validateMesh(source, path);  // NaN/inf positions and indices, before welding hashes them
  const bool hasWeights = sourceWeights.numVertices() > 0;
  if (options.requireWeights && !hasWeights) throw InputError(path + ": the mesh has no skin weights");
  if (hasWeights && sourceWeights.numVertices() != source.numVertices())
    throw InputError(path + ": " + std::to_string(sourceWeights.numVertices()) + " weight rows for " +
                     std::to_string(source.numVertices()) + " vertices");

  Character c;
  c.name = fileStem(path);
  Vec3 lo, hi;
  boundingBox(source.vertices, lo, hi);
  c.mesh = weldByPosition(source, options.weldTolerance * (hi - lo).norm(), c.sourceToWelded);
  c.sourceVertexCount = source.numVertices();
  c.skeleton = std::move(skeleton);
  if (hasWeights) {
    const int k = sourceWeights.influences();
    c.weights.joints = IndexMatrix::Constant(c.mesh.numVertices(), k, -1);
    c.weights.weights = WeightMatrix::Zero(c.mesh.numVertices(), k);
    std::vector<char> filled(c.mesh.numVertices(), 0);
    for (int i = 0; i < source.numVertices(); ++i) {
      const int w = c.sourceToWelded[i];
      if (filled[w]) continue;
      filled[w] = 1;
      c.weights.joints.row(w) = sourceWeights.joints.row(i);
      c.weights.weights.row(w) = sourceWeights.weights.row(i);
    }
  }
  try {
    validateCharacter(c);
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
  return c;
}

}  // namespace io_detail

// ============================================================================
// Dispatch
// ============================================================================

// Chooses the loader from the lower-cased extension.
Character loadCharacter(const std::string& path, const LoadOptions& options, const std::string& skeletonPath) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return std::tolower(ch); });
  if (ext == ".glb" || ext == ".gltf") return loadGltf(path, options);
  if (ext == ".obj") {
    if (!skeletonPath.empty()) return loadObjWithSkeleton(path, skeletonPath, options);
    const fs::path sibling = fs::path(path).parent_path() / (fs::path(path).stem().string() + ".skeleton.json");
    io_detail::requireFile(path);
    if (!fs::exists(sibling))
      throw InputError(path + ": no skeleton given and " + sibling.string() + " does not exist");
    return loadObjWithSkeleton(path, sibling.string(), options);
  }
  throw InputError(path + ": unknown character file type '" + ext + "' (expected .glb, .gltf or .obj)");
}

}  // namespace myoskin
