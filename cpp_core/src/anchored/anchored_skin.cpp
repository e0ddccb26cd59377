// The anchored-skin deformer: anchoring at build, posing the components and the skin per frame.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>

#include "anchored/anchored_internal.h"
#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

using anchored::AnchorCandidate;

// ============================================================================
// State
// ============================================================================

struct AnchoredSkin::Impl {
  int numVertices = 0;
  AnchoredComponents components;
  Skeleton skeleton;
  AnchoredSkinOptions options;
  AnchoringReport report;
  std::vector<Mat4> restInverse;  // #B
  // Per vertex: component, anchor (component frame, relative to its pose centre) and offset (same frame).
  std::vector<int> component;
  Points anchor, offset;
  // Per component at rest: pose centre, muscle length and the centre in the muscle frame relative to its origin.
  std::vector<Vec3> restCentre, centreLocal;
  std::vector<double> restLength;
  anchored::Relaxer relaxer;
  std::unique_ptr<tbb::task_arena> arena;  // when options.threads > 0
  // Per-frame scratch (one evaluate at a time per object).
  mutable std::vector<Mat4> transforms;
  mutable std::vector<Vec3> posedCentre, posedScale;
  mutable std::vector<Mat3> posedAxes;
  mutable Points normals;  // #V by 3: each vertex's posed surface vector, normalised (relaxation's normal)

  void poseComponents(const Pose& pose) const;
};

namespace {

// The rotation of a bone's skinning transform (its 3x3 part, orthonormalised by SVD when the pose scales).
Mat3 rotationOf(const Mat4& t) {
  const Mat3 m = t.block<3, 3>(0, 0);
  if ((m.transpose() * m - Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-9 && m.determinant() > 0.0) return m;
  Eigen::JacobiSVD<Mat3> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0.0) {
    Mat3 u = svd.matrixU();
    u.col(2) = -u.col(2);
    r = u * svd.matrixV().transpose();
  }
  return r;
}

Vec3 apply(const Mat4& t, const Vec3& p) { return t.block<3, 3>(0, 0) * p + t.block<3, 1>(0, 3); }

// Stretch is kept within [kMinStretch, kMaxStretch] (a pose that folds a muscle's ends onto each other or tears
// them apart gives a finite, very flat or thin muscle instead of a division by zero).
constexpr double kMinStretch = 0.05, kMaxStretch = 20.0;

}  // namespace

// Each component's posed centre, axes (columns) and scale along its axes.
void AnchoredSkin::Impl::poseComponents(const Pose& pose) const {
  const int nb = skeleton.numBones();
  for (int b = 0; b < nb; ++b) transforms[b] = pose.matrices[b] * restInverse[b];
  for (size_t k = 0; k < components.components.size(); ++k) {
    const AnchoredComponent& c = components.components[k];
    switch (c.kind) {
      case ComponentKind::Stuffing:
      case ComponentKind::BoneCapsule: {
        posedCentre[k] = apply(transforms[c.bone], restCentre[k]);
        posedAxes[k] = rotationOf(transforms[c.bone]) * c.axes;
        posedScale[k] = Vec3::Ones();
        break;
      }
      case ComponentKind::JointSphere: {
        posedCentre[k] = apply(transforms[c.insertionBone], restCentre[k]);
        const Eigen::Quaterniond a(rotationOf(transforms[c.bone])), b(rotationOf(transforms[c.insertionBone]));
        posedAxes[k] = a.slerp(0.5, b).toRotationMatrix() * c.axes;
        posedScale[k] = Vec3::Ones();
        break;
      }
      case ComponentKind::MuscleEllipsoid:
      case ComponentKind::MuscleCylinder: {
        const Vec3 o = apply(transforms[c.bone], c.origin), in = apply(transforms[c.insertionBone], c.insertion);
        const Mat3 ro = rotationOf(transforms[c.bone]);
        const Vec3 carried = ro * c.axes.col(1);
        const Vec3 d = in - o;
        const double length = d.norm();
        const Vec3 along = length > 1e-12 * restLength[k] ? Vec3(d / length) : carried;
        const Mat3 turn = Eigen::Quaterniond::Identity()
                              .slerp(options.muscleAim, Eigen::Quaterniond::FromTwoVectors(carried, along))
                              .toRotationMatrix();
        const double stretch = std::clamp(length / restLength[k], kMinStretch, kMaxStretch);
        const double effective = std::pow(stretch, c.bulge);
        const double across = 1.0 / std::sqrt(effective);
        posedAxes[k] = turn * ro * c.axes;
        posedScale[k] = Vec3(across, effective, across);
        const Vec3& cl = centreLocal[k];
        posedCentre[k] = o + posedAxes[k] * Vec3(across * cl.x(), stretch * cl.y(), across * cl.z());
        break;
      }
    }
  }
}

// ============================================================================
// Build: anchoring
// ============================================================================

AnchoredSkin::AnchoredSkin(const Mesh& restSkin, const SkinWeights& skinWeights, const AnchoredComponents& components,
                           const Skeleton& skeleton, const AnchoredSkinOptions& options)
    : impl_(std::make_unique<Impl>()) {
  validateMesh(restSkin, "skin");
  validateSkeleton(skeleton);
  validateSkinWeights(skinWeights, restSkin.numVertices(), skeleton.numBones());
  if (components.components.empty()) throw InputError("anchored skin: no components to anchor the skin to");
  if (!(options.weightShare >= 0.0 && options.weightShare <= 1.0) || !(options.bellyReach > 0.0) ||
      !(options.muscleRigidShare >= 0.0 && options.muscleRigidShare <= 1.0) ||
      !(options.muscleAim >= 0.0 && options.muscleAim <= 1.0) ||
      options.relaxRings < 0 || options.relaxIterations < 0 || !(options.relaxTolerance >= 0.0) ||
      !(options.relaxStep > 0.0 && options.relaxStep <= 1.0) || options.grainSize < 1 || options.threads < 0)
    throw InputError("anchored skin options: weightShare, muscleRigidShare and muscleAim in [0, 1], bellyReach > 0, relaxRings/relaxIterations >= 0, "
                     "relaxTolerance >= 0, relaxStep in (0, 1], grainSize >= 1, threads >= 0");
  const int nv = restSkin.numVertices();
  for (int p : options.pinned)
    if (p < 0 || p >= nv) throw InputError("anchored skin: pinned vertex " + std::to_string(p) + " is not a vertex");
  Impl& m = *impl_;
  m.report.scale = principalExtent(restSkin.vertices);
  validateComponents(components, skeleton, m.report.scale);
  m.numVertices = nv;
  m.components = components;
  m.skeleton = skeleton;
  m.options = options;
  const int nb = skeleton.numBones(), nc = static_cast<int>(components.components.size());
  for (const Bone& b : skeleton.bones) m.restInverse.push_back(b.rest.inverse());
  m.restCentre.resize(nc);
  m.centreLocal.resize(nc, Vec3::Zero());
  m.restLength.resize(nc, 0.0);
  for (int k = 0; k < nc; ++k) {
    const AnchoredComponent& c = components.components[k];
    m.restCentre[k] = anchored::restPoseCentre(c);
    if (c.kind == ComponentKind::MuscleEllipsoid || c.kind == ComponentKind::MuscleCylinder) {
      m.restLength[k] = (c.insertion - c.origin).norm();
      m.centreLocal[k] = c.axes.transpose() * (m.restCentre[k] - c.origin);
    }
  }
  // Which bones each component may take a vertex from.
  const std::vector<std::vector<int>> bones = anchored::componentBones(components, skeleton);
  std::vector<char> carries(static_cast<size_t>(nc) * nb, 0);
  for (int k = 0; k < nc; ++k)
    for (int b : bones[k]) carries[static_cast<size_t>(k) * nb + b] = 1;

  m.component.assign(nv, -1);
  m.anchor.resize(nv, 3);
  m.offset.resize(nv, 3);
  std::vector<char> fallback(nv, 0), tie(nv, 0);
  std::vector<int> iterations(nv, 0);
  const double tieTolerance = 1e-9 * m.report.scale;
  const int K = skinWeights.influences();
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 256), [&](const tbb::blocked_range<int>& range) {
    std::vector<int> eligible;
    for (int v = range.begin(); v < range.end(); ++v) {
      const Vec3 p = restSkin.vertices.row(v).transpose();
      double wmax = 0.0, wsum = 0.0;
      for (int j = 0; j < K; ++j)
        if (skinWeights.joints(v, j) >= 0) {
          wmax = std::max(wmax, skinWeights.weights(v, j));
          wsum += skinWeights.weights(v, j);
        }
      const bool rigid = wsum > 0.0 && wmax >= options.muscleRigidShare * wsum;
      eligible.clear();
      for (int j = 0; j < K; ++j)
        if (skinWeights.joints(v, j) >= 0 && skinWeights.weights(v, j) > 0.0 &&
            skinWeights.weights(v, j) >= options.weightShare * wmax)
          eligible.push_back(skinWeights.joints(v, j));
      // Pass 0: candidates by weight, alongside; pass 1: every component alongside; pass 2: every component.
      int best = -1;
      AnchorCandidate bestAnchor;
      for (int pass = 0; pass < 3 && best < 0; ++pass) {
        for (int k = 0; k < nc; ++k) {
          const ComponentKind kind = components.components[k].kind;
          const bool muscle = kind == ComponentKind::MuscleEllipsoid || kind == ComponentKind::MuscleCylinder;
          if (pass == 0 && muscle && !rigid) continue;
          if (pass == 0) {
            bool ok = false;
            for (int b : eligible) ok |= carries[static_cast<size_t>(k) * nb + b] != 0;
            if (!ok) continue;
          }
          const AnchorCandidate a = anchored::anchorOn(components.components[k], p, options);
          iterations[v] = std::max(iterations[v], a.iterations);
          if (pass < 2 && !a.alongside) continue;
          if (best < 0 || a.distance < bestAnchor.distance - tieTolerance) {
            if (best >= 0) tie[v] = 0;
            best = k;
            bestAnchor = a;
          } else if (std::abs(a.distance - bestAnchor.distance) <= tieTolerance) {
            tie[v] = 1;  // the lower index keeps it
          }
        }
        if (best >= 0 && pass > 0) fallback[v] = 1;
      }
      const AnchoredComponent& c = components.components[best];
      m.component[v] = best;
      m.anchor.row(v) = bestAnchor.q.transpose();
      m.offset.row(v) = (c.axes.transpose() * (p - m.restCentre[best]) - bestAnchor.q).transpose();
    }
  });
  AnchoringReport& r = m.report;
  r.vertexComponent = m.component;
  r.verticesPerComponent.assign(nc, 0);
  for (int v = 0; v < nv; ++v) {
    ++r.verticesPerComponent[m.component[v]];
    r.fallbackVertices += fallback[v];
    r.ties += tie[v];
    r.maxSolverIterations = std::max(r.maxSolverIterations, iterations[v]);
  }
  // Seams: edges between vertices anchored to different components, grown by relaxRings rings.
  const std::vector<std::pair<int, int>> edges = anchored::Relaxer::meshEdges(restSkin);
  std::vector<char> movable(nv, 0);
  for (const auto& [a, b] : edges)
    if (m.component[a] != m.component[b]) movable[a] = movable[b] = 1;
  for (int ring = 0; ring < options.relaxRings; ++ring) {
    std::vector<char> grown = movable;
    for (const auto& [a, b] : edges)
      if (movable[a] || movable[b]) grown[a] = grown[b] = 1;
    movable.swap(grown);
  }
  for (int p : options.pinned) movable[p] = 0;
  m.relaxer.build(restSkin, movable, edges);
  r.seamVertices = m.relaxer.numMovable();
  if (options.threads > 0) m.arena = std::make_unique<tbb::task_arena>(options.threads);
  m.normals.resize(nv, 3);
  m.transforms.resize(nb);
  m.posedCentre.resize(nc);
  m.posedScale.resize(nc);
  m.posedAxes.resize(nc);
}

AnchoredSkin::~AnchoredSkin() = default;
AnchoredSkin::AnchoredSkin(AnchoredSkin&&) noexcept = default;
AnchoredSkin& AnchoredSkin::operator=(AnchoredSkin&&) noexcept = default;

int AnchoredSkin::numVertices() const { return impl_->numVertices; }
int AnchoredSkin::numComponents() const { return static_cast<int>(impl_->components.components.size()); }
const AnchoredComponents& AnchoredSkin::components() const { return impl_->components; }
const AnchoringReport& AnchoredSkin::report() const { return impl_->report; }
const AnchoredSkinOptions& AnchoredSkin::options() const { return impl_->options; }

// ============================================================================
// Evaluation
// ============================================================================

namespace {
void checkPose(const Pose& pose, int numBones) {
  if (static_cast<int>(pose.matrices.size()) != numBones)
    throw InputError("anchored skin: the pose has " + std::to_string(pose.matrices.size()) + " bone matrices for " +
                     std::to_string(numBones) + " bones");
  for (int b = 0; b < numBones; ++b)
    if (!pose.matrices[b].allFinite())
      throw InputError("anchored skin: the pose matrix of bone " + std::to_string(b) + " is not finite");
}
}  // namespace

void AnchoredSkin::evaluate(const Pose& pose, Points& out, RelaxationTrace* trace) const {
  if (out.rows() != impl_->numVertices) out.resize(impl_->numVertices, 3);
  evaluate(pose, out.data(), trace);
}

void AnchoredSkin::evaluate(const Pose& pose, double* data, RelaxationTrace* trace) const {
  const Impl& m = *impl_;
  checkPose(pose, m.skeleton.numBones());
  m.poseComponents(pose);
  Eigen::Map<Points> out(data, m.numVertices, 3);
  auto body = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, m.numVertices, m.options.grainSize),
                      [&](const tbb::blocked_range<int>& range) {
                        for (int v = range.begin(); v < range.end(); ++v) {
                          const int k = m.component[v];
                          const Vec3 q = m.anchor.row(v).transpose(), o = m.offset.row(v).transpose();
                          const Vec3 surface = m.posedAxes[k] * o;
                          out.row(v) =
                              (m.posedCentre[k] + m.posedAxes[k] * m.posedScale[k].cwiseProduct(q) + surface).transpose();
                          const double len = surface.norm();
                          m.normals.row(v) = (len > 0.0 ? Vec3(surface / len) : Vec3(Vec3::Zero())).transpose();
                        }
                      });
    m.relaxer.run(out, m.normals, m.options, trace);
  };
  if (m.arena)
    m.arena->execute(body);
  else
    body();
}

void AnchoredSkin::posedComponents(const Pose& pose, std::vector<AnchoredComponent>& out) const {
  const Impl& m = *impl_;
  checkPose(pose, m.skeleton.numBones());
  m.poseComponents(pose);
  out = m.components.components;
  for (size_t k = 0; k < out.size(); ++k) {
    AnchoredComponent& c = out[k];
    c.axes = m.posedAxes[k];
    const Vec3 s = m.posedScale[k];
    if (c.kind == ComponentKind::MuscleCylinder) {
      c.origin = m.posedCentre[k];
      c.center = m.posedCentre[k];
      for (CylinderSection& q : c.sections) {
        q.z *= s.y();
        q.offset *= s.x();
        q.a *= s.x();
        q.b *= s.x();
      }
    } else {
      c.center = m.posedCentre[k];
      if (c.kind != ComponentKind::BoneCapsule && c.kind != ComponentKind::JointSphere) c.radii = c.radii.cwiseProduct(s);
    }
  }
}

// ============================================================================
// Point cache
// ============================================================================

void writeAnchoredPC2(const std::string& path, const AnchoredSkin& skin, const std::vector<Pose>& poses,
                      float startFrame) {
  if (poses.empty()) throw InputError("writeAnchoredPC2: no poses");
  PC2Writer writer(path, skin.numVertices(), startFrame, 1.0f);
  Points frame(skin.numVertices(), 3);
  for (const Pose& pose : poses) {
    skin.evaluate(pose, frame);
    writer.writeFrame(frame);
  }
  writer.close();
}

}  // namespace myoskin
