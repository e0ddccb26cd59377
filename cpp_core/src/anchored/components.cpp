// Anchored-skin components: validation, authored ellipsoid muscles and the components derived from a character.
#include <algorithm>
#include <cmath>
#include <string>

#include "anchored/anchored_internal.h"
#include "myoskin/anchored_skin.h"
#include "myoskin/errors.h"

namespace myoskin {

// ============================================================================
// Names and frames
// ============================================================================

// The kind's name as the Python module and reports spell it.
const char* componentKindName(ComponentKind kind) {
  switch (kind) {
    case ComponentKind::MuscleEllipsoid: return "muscle_ellipsoid";
    case ComponentKind::MuscleCylinder: return "muscle_cylinder";
    case ComponentKind::Stuffing: return "stuffing";
    case ComponentKind::BoneCapsule: return "bone_capsule";
    case ComponentKind::JointSphere: return "joint_sphere";
  }
  return "unknown";
}

namespace anchored {

// Columns X, Y, Z with Y along `along` (unit) and X the part of xHint across it (any perpendicular if parallel).
Mat3 frameAlong(const Vec3& along, const Vec3& xHint) {
  Vec3 x = xHint - xHint.dot(along) * along;
  if (x.norm() < 1e-9 * std::max(1.0, xHint.norm())) {
    const Vec3 trial = std::abs(along.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitZ();
    x = trial - trial.dot(along) * along;
  }
  x.normalize();
  Mat3 a;
  a.col(0) = x;
  a.col(1) = along;
  a.col(2) = x.cross(along);
  return a;
}

}  // namespace anchored

// ============================================================================
// Validation
// ============================================================================

void validateComponents(const AnchoredComponents& components, const Skeleton& skeleton, double scale) {
  const int nb = skeleton.numBones();
  for (size_t k = 0; k < components.components.size(); ++k) {
    const AnchoredComponent& c = components.components[k];
    const std::string who = "component " + std::to_string(k) + " ('" + c.name + "', " + componentKindName(c.kind) + ")";
    if (c.bone < 0 || c.bone >= nb) throw InputError(who + ": bone index " + std::to_string(c.bone) + " is not a bone");
    const bool twoBones = c.kind == ComponentKind::MuscleEllipsoid || c.kind == ComponentKind::MuscleCylinder ||
                          c.kind == ComponentKind::JointSphere;
    if (twoBones && (c.insertionBone < 0 || c.insertionBone >= nb))
      throw InputError(who + ": insertion/child bone index " + std::to_string(c.insertionBone) + " is not a bone");
    if (!c.center.allFinite() || !c.axes.allFinite() || !c.radii.allFinite() || !c.origin.allFinite() ||
        !c.insertion.allFinite() || !std::isfinite(c.halfLength))
      throw InputError(who + ": a value is not finite");
    const bool oneRadius = c.kind == ComponentKind::BoneCapsule || c.kind == ComponentKind::JointSphere;
    for (int i = 0; i < (oneRadius ? 1 : 3); ++i)
      if (!(c.radii[i] > 1e-9 * scale))
        throw InputError(who + ": radius " + std::to_string(i) + " is " + std::to_string(c.radii[i]) +
                         " (must be positive)");
    if ((c.axes.transpose() * c.axes - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-6 || c.axes.determinant() < 0.0)
      throw InputError(who + ": axes are not a rotation (orthonormal, right-handed columns)");
    if (c.kind == ComponentKind::BoneCapsule && c.halfLength < 0.0) throw InputError(who + ": negative half length");
    if (c.kind == ComponentKind::MuscleEllipsoid || c.kind == ComponentKind::MuscleCylinder) {
      if ((c.insertion - c.origin).norm() <= 1e-9 * scale)
        throw InputError(who + ": origin and insertion are the same point");
      if (!(c.bulge >= 0.0 && c.bulge <= 1.0)) throw InputError(who + ": bulge ratio must be in [0, 1]");
      if (!(c.startRatio < c.endRatio)) throw InputError(who + ": startRatio must be below endRatio");
    }
    if (c.kind == ComponentKind::MuscleCylinder) {
      if (c.sections.empty()) throw InputError(who + ": a deformable cylinder needs sections");
      for (size_t s = 0; s < c.sections.size(); ++s) {
        const CylinderSection& q = c.sections[s];
        if (!(q.a > 1e-9 * scale) || !(q.b > 1e-9 * scale) || !std::isfinite(q.z) || !q.offset.allFinite() ||
            !std::isfinite(q.angle))
          throw InputError(who + ": section " + std::to_string(s) + " has a non-positive or non-finite value");
        if (s > 0 && !(q.z > c.sections[s - 1].z)) throw InputError(who + ": sections must increase in z");
      }
    }
  }
}

// ============================================================================
// Authored ellipsoid muscle
// ============================================================================

AnchoredComponent makeEllipsoidMuscle(const std::string& name, int originBone, const Vec3& origin, int insertionBone,
                                      const Vec3& insertion, double startRatio, double endRatio, double radiusX,
                                      double radiusZ, const Vec3& xHint, double bulge) {
  const double length = (insertion - origin).norm();
  if (!origin.allFinite() || !insertion.allFinite() || !(length > 1e-12))
    throw InputError("muscle '" + name + "': origin and insertion must be two different finite points");
  if (!(startRatio < endRatio) || !std::isfinite(startRatio) || !std::isfinite(endRatio))
    throw InputError("muscle '" + name + "': startRatio must be below endRatio");
  if (!(radiusX > 0.0) || !(radiusZ > 0.0) || !std::isfinite(radiusX) || !std::isfinite(radiusZ))
    throw InputError("muscle '" + name + "': cross radii must be positive");
  AnchoredComponent c;
  c.kind = ComponentKind::MuscleEllipsoid;
  c.name = name;
  c.bone = originBone;
  c.insertionBone = insertionBone;
  c.origin = origin;
  c.insertion = insertion;
  c.startRatio = startRatio;
  c.endRatio = endRatio;
  c.bulge = bulge;
  const Vec3 along = (insertion - origin) / length;
  c.axes = anchored::frameAlong(along, xHint);
  c.center = origin + 0.5 * (startRatio + endRatio) * (insertion - origin);
  c.radii = Vec3(radiusX, 0.5 * (endRatio - startRatio) * length, radiusZ);
  return c;
}

// ============================================================================
// Derived components
// ============================================================================

namespace {

// One ellipsoid (or cylinder) fitted to a muscle's sections: the frame along origin -> insertion, cross radii of
// the belly (the section of largest area), long radius R by least squares from how the sections narrow away
// from the belly (a_k b_k / (a b) = 1 - dz_k^2 / R^2), kept within [0.75, 1.5] of the sections' half span.
AnchoredComponent fitMuscle(const Muscle& m, int ob, int ib, double scale, const ComponentOptions& options) {
  const Vec3 o = m.origin.position, in = m.insertion.position;
  const double length = (in - o).norm();
  if (!o.allFinite() || !in.allFinite() || length <= 1e-9 * scale)
    throw InputError("muscle '" + m.name + "': origin and insertion are the same point (no axis to anchor along)");
  int belly = -1;
  for (size_t s = 0; s < m.sections.size(); ++s) {
    const MuscleSection& q = m.sections[s];
    if (!(q.a > 0.0 && q.b > 0.0) || !q.center.allFinite()) continue;
    if (belly < 0 || q.a * q.b > m.sections[belly].a * m.sections[belly].b) belly = static_cast<int>(s);
  }
  if (belly < 0) throw InputError("muscle '" + m.name + "': no section with positive radii to fit a component to");
  const Vec3 along = (in - o) / length;
  const MuscleSection& big = m.sections[belly];
  AnchoredComponent c;
  c.name = m.name;
  c.bone = ob;
  c.insertionBone = ib;
  c.origin = o;
  c.insertion = in;
  c.bulge = options.muscleBulge;
  c.axes = anchored::frameAlong(along, big.axisA);
  const double zc = (big.center - o).dot(along);
  if (options.muscleCylinders) {
    c.kind = ComponentKind::MuscleCylinder;
    c.center = o;
    for (const MuscleSection& q : m.sections) {
      if (!(q.a > 0.0 && q.b > 0.0) || !q.center.allFinite()) continue;
      const Vec3 local = c.axes.transpose() * (q.center - o);
      const Vec3 ax = c.axes.transpose() * q.axisA;
      CylinderSection cs;
      cs.z = local.y();
      cs.offset = Vec2(local.x(), local.z());
      cs.angle = std::atan2(ax.z(), ax.x());
      cs.a = q.a;
      cs.b = q.b;
      if (c.sections.empty() || cs.z > c.sections.back().z + 1e-9 * scale) c.sections.push_back(cs);
    }
    c.radii = Vec3(big.a, 0.5 * length, big.b);
    c.startRatio = c.sections.front().z / length;
    c.endRatio = std::max(c.sections.back().z / length, c.startRatio + 1e-6);
    return c;
  }
  c.kind = ComponentKind::MuscleEllipsoid;
  double num = 0.0, den = 0.0, halfSpan = 0.0;
  for (const MuscleSection& q : m.sections) {
    if (!(q.a > 0.0 && q.b > 0.0) || !q.center.allFinite()) continue;
    const double dz = (q.center - o).dot(along) - zc;
    const double rho2 = (q.a * q.b) / (big.a * big.b);
    num += dz * dz * (1.0 - rho2);
    den += dz * dz * dz * dz;
    halfSpan = std::max(halfSpan, std::abs(dz));
  }
  if (halfSpan <= 1e-9 * scale) halfSpan = std::max(big.a, big.b);
  double radius = (num > 0.0 && den > 0.0) ? 1.0 / std::sqrt(num / den) : 1.5 * halfSpan;
  radius = std::clamp(radius, 0.75 * halfSpan, 1.5 * halfSpan);
  const Vec3 offset = c.axes.transpose() * (big.center - o);
  c.center = o + c.axes * Vec3(offset.x(), zc, offset.z());
  c.radii = Vec3(big.a, radius, big.b);
  c.startRatio = (zc - radius) / length;
  c.endRatio = (zc + radius) / length;
  return c;
}

}  // namespace

AnchoredComponents deriveComponents(const Skeleton& skeleton, const std::vector<Muscle>& muscles, const Mesh& skin,
                                    const SkinWeights& skinWeights, const ComponentOptions& options) {
  validateMesh(skin, "skin");
  validateSkeleton(skeleton);
  validateSkinWeights(skinWeights, skin.numVertices(), skeleton.numBones());
  if (!(options.capsuleRadius > 0.0) || !(options.jointSphereRadius > 0.0) || !(options.muscleBulge >= 0.0) ||
      !(options.muscleBulge <= 1.0))
    throw InputError("component options: capsuleRadius and jointSphereRadius must be > 0, muscleBulge in [0, 1]");
  const double scale = principalExtent(skin.vertices);
  AnchoredComponents out;
  // Muscles.
  if (options.muscleEllipsoids || options.muscleCylinders) {
    for (const Muscle& m : muscles) {
      const int ob = skeleton.find(m.origin.bone), ib = skeleton.find(m.insertion.bone);
      if (ob < 0 || ib < 0)
        throw InputError("muscle '" + m.name + "': bone '" + (ob < 0 ? m.origin.bone : m.insertion.bone) +
                         "' is not in the skeleton");
      out.components.push_back(fitMuscle(m, ob, ib, scale, options));
    }
  }
  // Bone capsules: radius from the skin each bone dominates.
  const int nb = skeleton.numBones();
  std::vector<double> capsule(nb, 0.0);
  if (options.boneCapsules) {
    std::vector<std::vector<double>> distances(nb);
    for (int v = 0; v < skin.numVertices(); ++v) {
      int best = -1;
      double w = 0.0;
      for (int k = 0; k < skinWeights.influences(); ++k)
        if (skinWeights.joints(v, k) >= 0 && skinWeights.weights(v, k) > w) {
          w = skinWeights.weights(v, k);
          best = skinWeights.joints(v, k);
        }
      if (best < 0) continue;
      const Bone& b = skeleton.bones[best];
      const Vec3 p = skin.vertices.row(v).transpose();
      const Vec3 d = b.tail - b.head;
      const double t = std::clamp((p - b.head).dot(d) / d.squaredNorm(), 0.0, 1.0);
      distances[best].push_back((p - (b.head + t * d)).norm());
    }
    for (int i = 0; i < nb; ++i) {
      std::vector<double>& d = distances[i];
      if (d.size() < 3 || !skeleton.bones[i].deform) continue;
      std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
      const double radius = options.capsuleRadius * d[d.size() / 2];
      if (!(radius > 1e-6 * scale)) continue;
      const Bone& b = skeleton.bones[i];
      AnchoredComponent c;
      c.kind = ComponentKind::BoneCapsule;
      c.name = b.name;
      c.bone = i;
      c.center = 0.5 * (b.head + b.tail);
      c.axes = anchored::frameAlong((b.tail - b.head).normalized(), b.rest.block<3, 1>(0, 0));
      c.radii = Vec3::Constant(radius);
      c.halfLength = 0.5 * b.length();
      capsule[i] = radius;
      out.components.push_back(c);
    }
  }
  // Joint spheres where a bone with a capsule meets its parent with one.
  if (options.jointSpheres && options.boneCapsules) {
    for (int i = 0; i < nb; ++i) {
      const int p = skeleton.bones[i].parent;
      if (p < 0 || capsule[i] <= 0.0 || capsule[p] <= 0.0) continue;
      const Bone& b = skeleton.bones[i];
      AnchoredComponent c;
      c.kind = ComponentKind::JointSphere;
      c.name = skeleton.bones[p].name + "|" + b.name;
      c.bone = p;
      c.insertionBone = i;
      c.center = b.head;
      c.axes = anchored::frameAlong((b.tail - b.head).normalized(), b.rest.block<3, 1>(0, 0));
      c.radii = Vec3::Constant(options.jointSphereRadius * std::max(capsule[i], capsule[p]));
      out.components.push_back(c);
    }
  }
  for (const AnchoredComponent& c : options.stuffing) out.components.push_back(c);
  validateComponents(out, skeleton, scale);
  return out;
}

}  // namespace myoskin
