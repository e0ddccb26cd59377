// Anchoring a skin vertex to the nearest point of one component (Schneider & Wilhelms 1998, section 4.1).
#include <algorithm>
#include <cmath>

#include "anchored/anchored_internal.h"

namespace myoskin::anchored {

// ============================================================================
// Nearest points per kind
// ============================================================================

Vec3 restPoseCentre(const AnchoredComponent& c) {
  return c.kind == ComponentKind::MuscleCylinder ? c.origin : c.center;
}

namespace {

// A unit vector along p, or X when p is (nearly) zero.
Vec3 directionOr(const Vec3& p, double tiny) {
  const double n = p.norm();
  return n > tiny ? Vec3(p / n) : Vec3(Vec3::UnitX());
}

// The deformable cylinder's point in the vertex's direction from the section interpolated at its height
// (Wilhelms' parametric anchor): the radial point on that section's ellipse.
AnchorCandidate onCylinder(const AnchoredComponent& c, const Vec3& p) {
  const std::vector<CylinderSection>& s = c.sections;
  const double z = std::clamp(p.y(), s.front().z, s.back().z);
  size_t k = 0;
  while (k + 2 < s.size() && s[k + 1].z < z) ++k;
  CylinderSection q = s[k];
  if (k + 1 < s.size()) {
    const CylinderSection& n = s[k + 1];
    const double t = (z - q.z) / (n.z - q.z);
    q.offset = (1 - t) * q.offset + t * n.offset;
    double da = n.angle - q.angle;  // the shorter way round (a half turn swaps nothing on an ellipse)
    while (da > M_PI / 2) da -= M_PI;
    while (da < -M_PI / 2) da += M_PI;
    q.angle += t * da;
    q.a = (1 - t) * q.a + t * n.a;
    q.b = (1 - t) * q.b + t * n.b;
  }
  const double ca = std::cos(q.angle), sa = std::sin(q.angle);
  const Vec2 w(p.x() - q.offset.x(), p.z() - q.offset.y());
  Vec2 e(ca * w.x() + sa * w.y(), -sa * w.x() + ca * w.y());  // in the section's (a, b) axes
  if (e.norm() <= 1e-12 * q.a) e = Vec2(1.0, 0.0);
  const double k2 = 1.0 / std::sqrt((e.x() / q.a) * (e.x() / q.a) + (e.y() / q.b) * (e.y() / q.b));
  const Vec2 onE = k2 * e;
  const Vec2 back(ca * onE.x() - sa * onE.y(), sa * onE.x() + ca * onE.y());
  AnchorCandidate a;
  a.q = Vec3(q.offset.x() + back.x(), z, q.offset.y() + back.y());
  a.distance = (p - a.q).norm();
  a.alongside = p.y() >= s.front().z && p.y() <= s.back().z;
  return a;
}

}  // namespace

AnchorCandidate anchorOn(const AnchoredComponent& c, const Vec3& v, const AnchoredSkinOptions& options) {
  const Vec3 p = c.axes.transpose() * (v - restPoseCentre(c));
  const double tiny = 1e-12 * c.radii.maxCoeff();
  AnchorCandidate a;
  switch (c.kind) {
    case ComponentKind::MuscleEllipsoid:
    case ComponentKind::Stuffing: {
      const EllipsoidClosest e = closestPointOnEllipsoid(c.radii, p, options.solver);
      a.q = e.point;
      a.distance = e.distance;
      a.iterations = e.iterations;
      a.alongside = c.kind == ComponentKind::Stuffing || std::abs(p.y()) <= options.bellyReach * c.radii.y();
      break;
    }
    case ComponentKind::MuscleCylinder:
      a = onCylinder(c, p);
      break;
    case ComponentKind::BoneCapsule: {
      const Vec3 axis(0.0, std::clamp(p.y(), -c.halfLength, c.halfLength), 0.0);
      a.q = axis + c.radii.x() * directionOr(p - axis, tiny);
      a.distance = (p - a.q).norm();
      break;
    }
    case ComponentKind::JointSphere:
      a.q = c.radii.x() * directionOr(p, tiny);
      a.distance = (p - a.q).norm();
      break;
  }
  return a;
}

// ============================================================================
// Candidate bones
// ============================================================================

std::vector<std::vector<int>> componentBones(const AnchoredComponents& components, const Skeleton& skeleton) {
  std::vector<std::vector<int>> out;
  out.reserve(components.components.size());
  for (const AnchoredComponent& c : components.components) {
    std::vector<int> bones{c.bone};
    if (c.kind == ComponentKind::JointSphere) bones.push_back(c.insertionBone);
    if (c.kind == ComponentKind::MuscleEllipsoid || c.kind == ComponentKind::MuscleCylinder) {
      // The tree path origin bone -> common ancestor <- insertion bone.
      std::vector<int> up;
      for (int b = c.bone; b >= 0; b = skeleton.bones[b].parent) up.push_back(b);
      std::vector<int> down;
      int meet = -1;
      for (int b = c.insertionBone; b >= 0; b = skeleton.bones[b].parent) {
        if (std::find(up.begin(), up.end(), b) != up.end()) {
          meet = b;
          break;
        }
        down.push_back(b);
      }
      bones.clear();
      for (int b : up) {
        bones.push_back(b);
        if (b == meet) break;
      }
      if (meet < 0) bones = {c.bone};  // different trees: the two ends only
      bones.insert(bones.end(), down.begin(), down.end());
      if (meet < 0) bones.push_back(c.insertionBone);
    }
    std::sort(bones.begin(), bones.end());
    bones.erase(std::unique(bones.begin(), bones.end()), bones.end());
    out.push_back(bones);
  }
  return out;
}

}  // namespace myoskin::anchored
