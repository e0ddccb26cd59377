// Shared helpers of the anchored-skin sources (not public API).
#pragma once
#include "myoskin/types.h"

namespace myoskin::anchored {

// Columns X, Y, Z with Y = along (unit) and X the part of xHint across it (any perpendicular if parallel).
Mat3 frameAlong(const Vec3& along, const Vec3& xHint);

}  // namespace myoskin::anchored

#include <vector>

#include "myoskin/anchored_skin.h"
#include "myoskin/mesh.h"

namespace myoskin::anchored {

// ============================================================================
// Anchoring (anchoring.cpp)
// ============================================================================

// Where a vertex anchors on one component, in the component's rest frame: the anchor point `q` relative to the
// component's pose centre (the ellipsoid/capsule/sphere centre, a cylinder's origin attachment) and the distance.
struct AnchorCandidate {
  Vec3 q = Vec3::Zero();
  double distance = 0.0;
  bool alongside = true;  // muscles: the vertex lies alongside the belly (within bellyReach of the long radius)
  int iterations = 0;
};

// The nearest point of component c to the mesh-space point v.
AnchorCandidate anchorOn(const AnchoredComponent& c, const Vec3& v, const AnchoredSkinOptions& options);

// The component's pose centre at rest (what q is relative to).
Vec3 restPoseCentre(const AnchoredComponent& c);

// Bones each component may take a vertex from (#C lists of skeleton indices): its carrying bone; a muscle's
// bones on the tree path from origin bone to insertion bone; a joint sphere's two bones.
std::vector<std::vector<int>> componentBones(const AnchoredComponents& components, const Skeleton& skeleton);

// ============================================================================
// Relaxation (relaxation.cpp)
// ============================================================================

// Edge-length relaxation over the vertices near seams, built once (adjacency from OpenMesh), run per frame.
class Relaxer {
 public:
  Relaxer() = default;
  // movable[v] != 0 for the vertices the relaxation may move; edges from meshEdges(rest).
  void build(const Mesh& rest, const std::vector<char>& movable, const std::vector<std::pair<int, int>>& edges);
  int numMovable() const { return static_cast<int>(movable_.size()); }
  // Jacobi iterations toward the rest lengths on x (#V by 3) over the strained seam vertices and their
  // neighbours, energy checked per iteration (a step that raises it is undone and halved); trace receives the
  // energies (none when nothing is strained, e.g. at rest). No allocation.
  // normals: #V by 3 unit directions (the anchors' posed surface vectors) along which, with
  // options.relaxTangential, the vertices do not move.
  void run(Eigen::Map<Points> x, const Points& normals, const AnchoredSkinOptions& options,
           RelaxationTrace* trace) const;
  // Edges of the mesh as pairs (a < b), from OpenMesh plus any faces it refused (non-manifold).
  static std::vector<std::pair<int, int>> meshEdges(const Mesh& mesh);

 private:
  double energy(const Eigen::Map<Points>& x, int activeCount) const;
  std::vector<int> movable_;                // vertex ids
  std::vector<int> offsets_;                // CSR over movable_: neighbours
  std::vector<int> neighbours_;
  std::vector<double> restLength_;          // per CSR entry
  std::vector<int> neighbourSlot_;          // per CSR entry: the neighbour's index in movable_, or -1
  std::vector<int> edgeA_, edgeB_;          // edges with at least one end movable
  std::vector<double> edgeRest_;
  mutable std::vector<char> strained_, active_;  // #movable, per frame
  mutable std::vector<int> activeList_;          // #movable capacity; the first `count` are this frame's
  mutable Points next_;                     // #movable by 3 scratch
  mutable Points backup_;
};

}  // namespace myoskin::anchored
