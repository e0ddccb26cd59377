// Cutting-plane families from the skeleton (sections.h): limbs, shoulders, neck, abdomen.
#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/sections.h"

namespace myoskin {

namespace {

// ============================================================================
// Chains
// ============================================================================

// Maximal chains of bones with role `role`: each starts at a bone whose parent has another role and
// continues through the single child with the same role.
std::vector<std::vector<int>> chainsOf(const Skeleton& sk, const std::vector<BoneRole>& roles, BoneRole role) {
  std::vector<std::vector<int>> chains;
  for (int i = 0; i < sk.numBones(); ++i) {
    if (roles[i] != role) continue;
    const int p = sk.bones[i].parent;
    if (p >= 0 && roles[p] == role) {
      int same = 0;
      for (int c : sk.children(p)) same += roles[c] == role;
      if (same == 1) continue;  // continues its parent's chain
    }
    std::vector<int> chain{i};
    for (;;) {
      std::vector<int> next;
      for (int c : sk.children(chain.back()))
        if (roles[c] == role) next.push_back(c);
      if (next.size() != 1) break;
      chain.push_back(next[0]);
    }
    chains.push_back(chain);
  }
  return chains;
}

void addSubtree(const Skeleton& sk, int root, std::set<int>& out) {
  std::vector<int> stack{root};
  while (!stack.empty()) {
    const int b = stack.back();
    stack.pop_back();
    out.insert(b);
    for (int c : sk.children(b)) stack.push_back(c);
  }
}

// In-plane X axis: `previous` projected onto the plane (parallel transport), or `hint` when degenerate.
Vec3 transportAxis(const Vec3& previous, const Vec3& normal, const Vec3& hint) {
  Vec3 x = previous - previous.dot(normal) * normal;
  if (x.norm() < 1e-6) x = hint - hint.dot(normal) * normal;
  if (x.norm() < 1e-6) x = normal.unitOrthogonal();
  return x.normalized();
}

// Perpendicular planes along a chain, `spacing` apart from `startAt` (metres along the chain) to its end,
// with end margins at the chain's ends and around joints bending more than bendAngle.
// Planes on the bones in `clipBones` get clipRadius (their profiles are clipped near the origin).
void chainPlanes(const Skeleton& sk, const std::vector<int>& chain, const std::string& family, int familyIndex,
                 double spacing, double startAt, const PlaneOptions& o, const std::vector<int>& region,
                 const std::set<int>& clipBones, double clipRadius, std::vector<CuttingPlane>& out) {
  std::vector<double> start(chain.size() + 1, 0.0);
  for (size_t k = 0; k < chain.size(); ++k) start[k + 1] = start[k] + sk.bones[chain[k]].length();
  const double total = start.back();
  if (total <= 1e-9) return;
  // Forbidden intervals along the chain (margins).
  std::vector<std::pair<double, double>> forbidden;
  forbidden.emplace_back(-1.0, std::max(startAt, o.endMargin * sk.bones[chain.front()].length()));
  forbidden.emplace_back(total - o.endMargin * sk.bones[chain.back()].length(), total + 1.0);
  for (size_t k = 0; k + 1 < chain.size(); ++k) {
    const Bone &a = sk.bones[chain[k]], &b = sk.bones[chain[k + 1]];
    const double angle = std::acos(std::clamp((a.tail - a.head).normalized().dot((b.tail - b.head).normalized()), -1.0, 1.0));
    if (angle > o.bendAngle)
      forbidden.emplace_back(start[k + 1] - o.endMargin * a.length(), start[k + 1] + o.endMargin * b.length());
  }
  Vec3 xAxis = sk.bones[chain.front()].rest.block<3, 1>(0, 0);
  int order = 0;
  const int count = static_cast<int>(std::floor(total / spacing));
  const double offset = 0.5 * (total - count * spacing);  // the grid is centred on the chain
  for (int i = 0; i <= count; ++i) {
    const double s = offset + i * spacing;
    bool skip = s < 0 || s > total;
    for (const auto& [lo, hi] : forbidden) skip |= s >= lo && s <= hi;
    if (skip) continue;
    size_t k = 0;
    while (k + 1 < chain.size() && s > start[k + 1]) ++k;
    const Bone& bone = sk.bones[chain[k]];
    if (bone.length() < 1e-9) continue;
    CuttingPlane p;
    p.bone = chain[k];
    p.family = family;
    p.familyIndex = familyIndex;
    p.order = order++;
    p.t = (s - start[k]) / bone.length();
    p.normal = (bone.tail - bone.head).normalized();
    p.origin = bone.head + p.t * (bone.tail - bone.head);
    xAxis = transportAxis(xAxis, p.normal, bone.rest.block<3, 1>(0, 0));
    p.xAxis = xAxis;
    p.yAxis = p.normal.cross(p.xAxis).normalized();
    p.region = region;
    if (clipBones.count(chain[k])) p.clipRadius = clipRadius;
    out.push_back(std::move(p));
  }
}


// ============================================================================
// Mirror frames
// ============================================================================

// Mirror image of point p about the plane through c with unit normal n.
Vec3 mirrored(const Vec3& p, const Vec3& c, const Vec3& n) { return p - 2.0 * (p - c).dot(n) * n; }

// Orients the frames for the skeleton's mirror plane (skeletonMirrorPlane): every mirror-axis plane gets its X axis
// across the mirror plane (its y axis in it), whichever of its in-plane axes the spine's rest frame made sideways, and
// of two limb planes that mirror each other (same order, origins within a quarter of `spacing`) the one on the
// normal's negative side is turned half a turn where needed, so mirrored limbs' X axes are mirrored and negated (their +Y axes mirrored), as
// the profiles' resampling from +Y and the mirrored twins assume (sections.h, ProfileOptions::mirrorLimbs).
void orientMirrorFrames(std::vector<CuttingPlane>& planes, double spacing) {
  Vec3 c, n;
  if (!skeletonMirrorPlane(planes, c, n)) return;
  for (CuttingPlane& p : planes) {
    if (!p.mirrorAxis || std::abs(p.xAxis.dot(n)) >= std::abs(p.yAxis.dot(n))) continue;
    const Vec3 x = p.yAxis.dot(n) >= 0 ? p.yAxis : Vec3(-p.yAxis);  // a quarter turn about the normal
    p.xAxis = x;
    p.yAxis = p.normal.cross(x).normalized();
  }
  for (size_t i = 0; i < planes.size(); ++i) {
    const CuttingPlane& a = planes[i];
    if (a.family != "limb") continue;
    const Vec3 m = mirrored(a.origin, c, n);
    int best = -1;
    double nearest = 0.25 * spacing;
    for (size_t j = 0; j < planes.size(); ++j) {
      const CuttingPlane& b = planes[j];
      if (b.family != "limb" || b.familyIndex <= a.familyIndex || b.order != a.order) continue;
      const double d = (b.origin - m).norm();
      if (d < nearest) nearest = d, best = static_cast<int>(j);
    }
    if (best < 0) continue;
    const Vec3 mn = a.normal - 2.0 * a.normal.dot(n) * n, mx = a.xAxis - 2.0 * a.xAxis.dot(n) * n;
    if (mn.dot(planes[best].normal) < 0.9 || mx.dot(planes[best].xAxis) <= 0) continue;
    // The plane on the mirror normal's negative side turns (by place, not by bone order, which names can change).
    CuttingPlane& b = (a.origin - c).dot(n) < 0 ? planes[i] : planes[best];
    b.xAxis = -b.xAxis, b.yAxis = -b.yAxis;  // half a turn about the normal
  }
}

}  // namespace

// ============================================================================
// Public
// ============================================================================

bool skeletonMirrorPlane(const std::vector<CuttingPlane>& planes, Vec3& c, Vec3& n) {
  const auto axis = std::find_if(planes.begin(), planes.end(), [](const CuttingPlane& p) { return p.mirrorAxis; });
  if (axis == planes.end()) return false;
  std::vector<const CuttingPlane*> limb;
  for (const CuttingPlane& p : planes)
    if (p.family == "limb") limb.push_back(&p);
  if (limb.size() < 2) return false;
  double best = INFINITY;
  c = axis->origin;
  for (const Vec3& candidate : {axis->xAxis, axis->yAxis}) {
    const Vec3 u = candidate.normalized();
    double sum = 0.0;
    for (const CuttingPlane* p : limb) {
      const Vec3 m = mirrored(p->origin, c, u);
      double nearest = INFINITY;
      for (const CuttingPlane* q : limb)
        if (q->familyIndex != p->familyIndex) nearest = std::min(nearest, (m - q->origin).squaredNorm());
      sum += std::isfinite(nearest) ? nearest : 0.0;
    }
    if (sum < best) best = sum, n = u;
  }
  return true;
}

double automaticPlaneSpacing(const Points& vertices) { return principalExtent(vertices) / 80.0; }

std::vector<CuttingPlane> makeCuttingPlanes(const Character& character, const std::vector<BoneRole>& roles,
                                            const PlaneOptions& options) {
  const Skeleton& sk = character.skeleton;
  if (static_cast<int>(roles.size()) != sk.numBones())
    throw InputError("bone roles: " + std::to_string(roles.size()) + " roles for " + std::to_string(sk.numBones()) + " bones");
  if (!(options.spacing >= 0) || !std::isfinite(options.spacing)) throw InputError("plane spacing must be >= 0");
  if (character.mesh.numVertices() == 0) throw InputError("cutting planes: the skin is empty");
  const double spacing = options.spacing > 0 ? options.spacing : automaticPlaneSpacing(character.mesh.vertices);
  if (!(spacing > 1e-5)) throw InputError("cutting planes: the skin has no extent");

  const auto limbChains = chainsOf(sk, roles, BoneRole::Limb);
  std::set<int> limbBones;  // limbs and everything below them
  for (const auto& c : limbChains) addSubtree(sk, c.front(), limbBones);
  std::vector<int> torsoRegion;
  for (int b = 0; b < sk.numBones(); ++b)
    if (!limbBones.count(b)) torsoRegion.push_back(b);

  std::vector<CuttingPlane> planes;
  int index = 0;
  for (const auto& limb : limbChains) {
    // An arm continues up through its shoulder bones (clavicle, shoulder): the deltoid spans the joint.
    std::vector<int> chain = limb;
    double shoulderLength = 0.0;
    std::set<int> shoulderBones;
    for (int p = sk.bones[chain.front()].parent; p >= 0 && roles[p] == BoneRole::Shoulder; p = sk.bones[p].parent) {
      chain.insert(chain.begin(), p);
      shoulderBones.insert(p);
      shoulderLength += sk.bones[p].length();
    }
    std::set<int> region;
    addSubtree(sk, chain.front(), region);
    if (sk.bones[chain.front()].parent >= 0) region.insert(sk.bones[chain.front()].parent);
    chainPlanes(sk, chain, "limb", index++, spacing, options.shoulderStart * shoulderLength, options,
                std::vector<int>(region.begin(), region.end()), shoulderBones,
                options.shoulderClip * shoulderLength, planes);
  }
  index = 0;
  for (const auto& chain : chainsOf(sk, roles, BoneRole::Shoulder)) {
    std::set<int> region(torsoRegion.begin(), torsoRegion.end());
    for (int c : sk.children(chain.back())) region.insert(c);  // the arm's first bone
    double length = 0;
    for (int b : chain) length += sk.bones[b].length();
    chainPlanes(sk, chain, "shoulder", index++, spacing * options.shoulderSpacing, options.shoulderStart * length, options,
                std::vector<int>(region.begin(), region.end()), std::set<int>(chain.begin(), chain.end()),
                options.shoulderClip * length, planes);
  }
  index = 0;
  for (const auto& chain : chainsOf(sk, roles, BoneRole::Neck)) {
    // A neck plane keeps to the neck's and head's skin: where it cuts into the trunk (the neck's base, a
    // quadruped's sloping neck) the trunk's runs become chords, so its lobes are no bumps of the neck.
    std::set<int> region;
    addSubtree(sk, chain.front(), region);
    const size_t first = planes.size();
    chainPlanes(sk, chain, "neck", index++, spacing, 0.0, options, std::vector<int>(region.begin(), region.end()), {},
                0.0, planes);
    for (size_t i = first; i < planes.size(); ++i) planes[i].mirrorAxis = true;
  }

  // Abdomen: the spine chain (pelvis bones below it do not count for the axis).
  const auto spines = chainsOf(sk, roles, BoneRole::Spine);
  if (!spines.empty()) {
    const auto& spine = *std::max_element(spines.begin(), spines.end(),
                                          [](const auto& a, const auto& b) { return a.size() < b.size(); });
    std::vector<Vec3> line{sk.bones[spine.front()].head};
    for (int b : spine) line.push_back(sk.bones[b].tail);
    const Vec3 up = (line.back() - line.front()).normalized();
    double bottom = line.front().dot(up), top = line.back().dot(up);
    for (const auto& c : limbChains) {  // legs: the hip joints are below the spine's start
      const double h = sk.bones[c.front()].head.dot(up);
      if (h < line.front().dot(up)) bottom = std::max(bottom, h + 2.0 * spacing);
    }
    int order = 0;
    Vec3 xAxis = sk.bones[spine.front()].rest.block<3, 1>(0, 0);
    for (double h = bottom + 0.5 * spacing; h < top - 0.5 * spacing; h += spacing) {
      size_t k = 0;
      while (k + 2 < line.size() && line[k + 1].dot(up) < h) ++k;
      const double h0 = line[k].dot(up), h1 = line[k + 1].dot(up);
      const double t = h1 - h0 > 1e-9 ? std::clamp((h - h0) / (h1 - h0), 0.0, 1.0) : 0.0;
      CuttingPlane p;
      p.bone = spine[k];
      p.family = "abdomen";
      p.familyIndex = 0;
      p.order = order++;
      p.t = t;
      p.origin = line[k] + t * (line[k + 1] - line[k]);
      p.origin += (h - p.origin.dot(up)) * up;
      p.normal = up;
      xAxis = transportAxis(xAxis, up, sk.bones[spine[k]].rest.block<3, 1>(0, 0));
      p.xAxis = xAxis;
      p.yAxis = up.cross(xAxis).normalized();
      p.region = torsoRegion;
      p.mirrorAxis = true;
      planes.push_back(std::move(p));
    }
  }
  orientMirrorFrames(planes, spacing);
  return planes;
}

}  // namespace myoskin
