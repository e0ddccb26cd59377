// Volume blend shares (volume_blend.h): per joint the dual-quaternion share that keeps the band's volume at a
// reference bend, spread over the skin the joint's skeleton weights blend.
#include "myoskin/volume_blend.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "myoskin/character.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/sections.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace {

constexpr int kShareSteps = 100;  // shares tried: 0, 1/100, ..., 1
constexpr double kRounding = 1e-9;  // band changes this small are rounding (a band no bend changes keeps share 1)

// ============================================================================
// Checks
// ============================================================================

// InputError on mismatched sizes, bad indices or weights, non-finite vertices or options out of range.
void validate(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin, const VolumeBlendOptions& o) {
  if (!(o.bendDegrees > 0.0 && o.bendDegrees <= 180.0))
    throw InputError("volume blend: bendDegrees must be in (0, 180], got " + std::to_string(o.bendDegrees));
  if (!(o.bandRadius > 0.0 && std::isfinite(o.bandRadius)))
    throw InputError("volume blend: bandRadius must be > 0, got " + std::to_string(o.bandRadius));
  if (!(o.keepTolerance >= 0.0 && o.keepTolerance <= 1.0))
    throw InputError("volume blend: keepTolerance must be in [0, 1], got " + std::to_string(o.keepTolerance));
  if (!(o.minBlend > 0.0 && o.minBlend <= 1.0))
    throw InputError("volume blend: minBlend must be in (0, 1], got " + std::to_string(o.minBlend));
  if (!(o.unblendedShare >= 0.0 && o.unblendedShare <= 1.0))
    throw InputError("volume blend: unblendedShare must be in [0, 1], got " + std::to_string(o.unblendedShare));
  validateSkeleton(skeleton);
  if (skin.numVertices() == 0) throw InputError("volume blend: the skin has no vertices");
  if (!skin.vertices.allFinite()) throw InputError("volume blend: the skin has a NaN or infinite vertex");
  validateSkinWeights(w, skin.numVertices(), skeleton.numBones());
  for (Eigen::Index i = 0; i < skin.triangles.size(); ++i)
    if (skin.triangles.data()[i] < 0 || skin.triangles.data()[i] >= skin.numVertices())
      throw InputError("volume blend: triangle " + std::to_string(i / 3) + " uses vertex " +
                       std::to_string(skin.triangles.data()[i]) + ", outside the skin");
}

// ============================================================================
// One joint
// ============================================================================

// Signed cone volume of triangles (indices into p) from apex.
double coneVolume(const Points& p, const Triangles& tris, const Vec3& apex) {
  double v = 0.0;
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const Vec3 a = p.row(tris(f, 0)).transpose() - apex, b = p.row(tris(f, 1)).transpose() - apex,
               c = p.row(tris(f, 2)).transpose() - apex;
    v += a.dot(b.cross(c));
  }
  return v / 6.0;
}

// #V by 3: each row of `rest` moved by its vertex's affine map (#V by 12, row-major 3 by 4).
Points applyMaps(const VertexTransforms& maps, const Points& rest) {
  Points out(rest.rows(), 3);
  for (Eigen::Index v = 0; v < rest.rows(); ++v)
    for (int r = 0; r < 3; ++r)
      out(v, r) = maps(v, 4 * r) * rest(v, 0) + maps(v, 4 * r + 1) * rest(v, 1) + maps(v, 4 * r + 2) * rest(v, 2) +
                  maps(v, 4 * r + 3);
  return out;
}

// The joint at bone c's head: its band (bandRadius body limb radii) and share at the reference flexion about
// flexionAxis (fills `out`; false when it blends no skin or has no band).
bool measureJoint(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin, const VolumeBlendOptions& o,
                  int c, double limbRadius, const Vec3& flexionAxis, const std::vector<char>& inSubtree,
                  const Eigen::VectorXd& blend, JointVolumeBlend& out) {
  const int nv = skin.numVertices();
  const Vec3 joint = skeleton.bones[c].head;
  int blended = 0;
  for (int v = 0; v < nv; ++v) blended += blend[v] >= o.minBlend;
  out.bone = c;
  out.blendedVertices = blended;
  out.radius = limbRadius;
  if (blended == 0) return false;
  // The band: local copies of its vertices, weights and triangles.
  const double reach = o.bandRadius * limbRadius;
  std::vector<int> local(nv, -1);
  std::vector<int> ids;
  for (int v = 0; v < nv; ++v)
    if ((skin.vertices.row(v).transpose() - joint).norm() <= reach) {
      local[v] = static_cast<int>(ids.size());
      ids.push_back(v);
    }
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index f = 0; f < skin.triangles.rows(); ++f) {
    const int a = local[skin.triangles(f, 0)], b = local[skin.triangles(f, 1)], d = local[skin.triangles(f, 2)];
    if (a >= 0 && b >= 0 && d >= 0) faces.emplace_back(a, b, d);
  }
  out.bandTriangles = static_cast<int>(faces.size());
  if (faces.empty()) return false;
  const int n = static_cast<int>(ids.size());
  Points rest(n, 3);
  SkinWeights sub;
  sub.joints.resize(n, w.influences());
  sub.weights.resize(n, w.influences());
  for (int i = 0; i < n; ++i) {
    rest.row(i) = skin.vertices.row(ids[i]);
    sub.joints.row(i) = w.joints.row(ids[i]);
    sub.weights.row(i) = w.weights.row(ids[i]);
  }
  Triangles tris(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) tris.row(static_cast<Eigen::Index>(f)) = faces[f].transpose();
  const int nb = skeleton.numBones();
  SkinnerOptions linearOptions;
  linearOptions.threads = 1;
  SkinnerOptions dqOptions = linearOptions;
  dqOptions.preserveVolume = true;
  for (const Bone& b : skeleton.bones) dqOptions.jointRest.push_back(b.rest);
  Skinner skinner(rest, sub, nb, linearOptions);
  const double v0 = coneVolume(rest, tris, joint);
  if (!(std::abs(v0) > 0.0)) return false;
  // Band volume change for each tried share at the reference flexion.
  Mat4 turn = Mat4::Identity();
  turn.block<3, 3>(0, 0) = Eigen::AngleAxisd(o.bendDegrees * kPi / 180.0, flexionAxis).toRotationMatrix();
  turn.block<3, 1>(0, 3) = joint - turn.block<3, 3>(0, 0) * joint;
  std::vector<Mat4> transforms(nb, Mat4::Identity());
  for (int b = 0; b < nb; ++b)
    if (inSubtree[b]) transforms[b] = turn;
  // In float64 (the skinner's per-vertex affine maps on the float64 rest positions): the shares then depend on the
  // body, not on how its coordinates round (a character turned in space gets the same shares to 1e-9).
  VertexTransforms maps;
  skinner.vertexTransforms(transforms, maps);
  const Points lin = applyMaps(maps, rest);
  skinner.setOptions(dqOptions);
  skinner.vertexTransforms(transforms, maps);
  const Points dq = applyMaps(maps, rest);
  std::vector<double> change(kShareSteps + 1);
  for (int k = 0; k <= kShareSteps; ++k) {
    const double s = static_cast<double>(k) / kShareSteps;
    const Points p = (1.0 - s) * lin + s * dq;
    change[k] = (coneVolume(p, tris, joint) - v0) / std::abs(v0);
  }
  // The largest share whose |change| is at most the smallest |change| of any share or keepTolerance x |linear's
  // change| or kRounding (dual quaternions where they keep the volume well enough or lose it anyway).
  double smallest = std::abs(change[0]);
  for (double x : change) smallest = std::min(smallest, std::abs(x));
  const double allowed = std::max({smallest, o.keepTolerance * std::abs(change[0]), kRounding});
  int best = kShareSteps;
  while (best > 0 && std::abs(change[best]) > allowed) --best;
  out.share = static_cast<double>(best) / kShareSteps;
  out.axis = flexionAxis;
  out.linearChange = change[0];
  out.dualQuatChange = change[kShareSteps];
  out.blendChange = change[best];
  return true;
}

// ============================================================================
// Body frame
// ============================================================================

struct BodyFrame {
  Vec3 up, left, facing;  // unit, orthogonal; facing = left x up
};

// The body's up, left-right and facing axes from its skeleton and skin, whichever way it was modelled or imported:
// left-right = the normal of the skeleton's mirror plane (skeletonMirrorPlane; X, the mirror plane X = 0 of glTF and
// Blender, without one); up = `givenUp` if non-zero, else against the limbs (the sum of the limb bones across the
// left-right axis: legs down, arms sideways or down), else the taller of +Y and +Z; facing = left x up, its sign
// where the feet point (bones hanging from a downward limb bone and lying along the ground), else where the neck
// leans (a horse's neck reaches forward), else the left-right axis's largest coordinate positive (glTF and Blender:
// the left side at +X).
BodyFrame bodyFrame(const Character& body, const Skeleton& joined, const std::vector<BoneRole>& roles,
                    const Vec3& givenUp) {
  const Skeleton& skeleton = body.skeleton;
  const int nb = skeleton.numBones();
  Vec3 across = Vec3::UnitX(), c;
  try {
    Vec3 n;
    if (skeletonMirrorPlane(makeCuttingPlanes(body, roles), c, n) && n.allFinite() && n.norm() > 0.5)
      across = n.normalized();
  } catch (const InputError&) {
    // no planes (a skin too small for the plane spacing's floor): the conventions' X
  }
  // The conventions' sign (its largest coordinate positive: +X on a body modelled with X across, and never a sign
  // taken from round-off when a turned body's normal has no X), turned below by the feet or the neck.
  Eigen::Index largest = 0;
  across.cwiseAbs().maxCoeff(&largest);
  if (across[largest] < 0.0) across = -across;
  Vec3 limbs = Vec3::Zero();
  for (int b = 0; b < nb; ++b)
    if (roles[b] == BoneRole::Limb) limbs += joined.bones[b].tail - joined.bones[b].head;
  limbs -= limbs.dot(across) * across;
  const Vec3 extent = body.mesh.vertices.colwise().maxCoeff() - body.mesh.vertices.colwise().minCoeff();
  BodyFrame f;
  f.up = extent.y() >= extent.z() ? Vec3::UnitY() : Vec3::UnitZ();
  if (givenUp.squaredNorm() > 0.0)
    f.up = givenUp.normalized();
  else if (limbs.norm() > 1e-9)
    f.up = -limbs.normalized();
  f.left = across - across.dot(f.up) * f.up;
  if (f.left.norm() < 1e-6) f.left = f.up.unitOrthogonal();  // an up given along the mirror normal
  f.left.normalize();
  auto unit = [&](int b) {
    const Vec3 d = joined.bones[b].tail - joined.bones[b].head;
    return d.norm() > 0.0 ? Vec3(d.normalized()) : Vec3(Vec3::Zero());
  };
  // Votes along left x up: each foot (a bone hanging from a downward limb bone, lying along the ground) by its
  // direction; without feet, the neck bones by theirs. A sum of unit directions under 0.5 along the axis is no vote.
  const Vec3 ahead = f.left.cross(f.up);
  double feet = 0.0, neck = 0.0;
  for (int b = 0; b < nb; ++b) {
    if (roles[b] == BoneRole::Neck) neck += unit(b).dot(ahead);
    const int p = skeleton.bones[b].parent;
    if (p < 0 || roles[p] != BoneRole::Limb) continue;
    const Vec3 db = unit(b), dp = unit(p);
    if (dp.dot(f.up) < -0.5 && db.squaredNorm() > 0.0 && std::abs(db.dot(f.up)) < 0.7) feet += db.dot(ahead);
  }
  const double vote = std::abs(feet) >= 0.5 ? feet : std::abs(neck) >= 0.5 ? neck : 0.0;
  if (vote < 0.0) f.left = -f.left;
  f.facing = f.left.cross(f.up);
  return f;
}

}  // namespace

// ============================================================================
// Shares over the skin
// ============================================================================

Eigen::VectorXd computeDqsShare(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin,
                                const VolumeBlendOptions& options, std::vector<JointVolumeBlend>* joints) {
  validate(skeleton, w, skin, options);
  const int nv = skin.numVertices(), nb = skeleton.numBones();
  if (joints) joints->clear();
  Eigen::VectorXd shareSum = Eigen::VectorXd::Zero(nv), blendSum = Eigen::VectorXd::Zero(nv);
  Eigen::VectorXd total = Eigen::VectorXd::Zero(nv);
  for (int v = 0; v < nv; ++v)
    for (int k = 0; k < w.influences(); ++k)
      if (w.joints(v, k) >= 0) total[v] += w.weights(v, k);
  Character body;
  body.mesh = skin;
  body.skeleton = skeleton;
  body.weights = w;
  const Skeleton joined = weightedSkeleton(body);  // tails at the continuing child's head (importers guess them)
  const std::vector<BoneRole> roles = characterBoneRoles(body);
  const std::vector<char> twist = twistSplits(joined, w);  // on the joined tails, as importers differ
  const double limbRadius = bodyLimbRadius(body, roles);
  const BodyFrame frame = bodyFrame(body, joined, roles, options.up);
  const Vec3 up = frame.up, left = frame.left, facing = frame.facing;
  auto direction = [&](int b) { return Vec3((joined.bones[b].tail - joined.bones[b].head).normalized()); };
  std::vector<char> inSubtree(nb);
  Eigen::VectorXd blend(nv);
  std::vector<char> crossed(nv, 0);    // blended across any joint or twist split (b >= minBlend)
  std::vector<char> nearJoint(nv, 0);  // in a real joint's band (bandRadius limb radii of its head)
  const double reach = options.bandRadius * limbRadius;
  for (int c = 0; c < nb; ++c) {
    if (skeleton.bones[c].parent < 0) continue;
    for (int b = 0; b < nb; ++b) inSubtree[b] = b == c || (skeleton.bones[b].parent >= 0 && inSubtree[skeleton.bones[b].parent]);
    // b = 2 min(inside, outside) per vertex (weights normalised; rest vertices 0).
    bool anyBlend = false;
    for (int v = 0; v < nv; ++v) {
      double inside = 0.0;
      for (int k = 0; k < w.influences(); ++k)
        if (w.joints(v, k) >= 0 && inSubtree[w.joints(v, k)]) inside += w.weights(v, k);
      blend[v] = total[v] > kRestWeightThreshold ? 2.0 * std::min(inside, total[v] - inside) / total[v] : 0.0;
      anyBlend = anyBlend || blend[v] >= options.minBlend;
      if (blend[v] >= options.minBlend) crossed[v] = 1;  // a twist split, or a joint even where not measured
      if (!twist[c] && (skin.vertices.row(v).transpose() - skeleton.bones[c].head).norm() <= reach) nearJoint[v] = 1;
    }
    if (!anyBlend || twist[c]) continue;
    // Flexion: the child swings forward (about d x facing); down a leg (downward bones, across twist splits) the
    // joints alternate from the leg's root: hip forward, knee backward, a horse's hock forward again; a child along
    // the facing (a foot) turns its tail down.
    const Vec3 d = direction(c);
    auto realParent = [&](int b) {
      int a = skeleton.bones[b].parent;
      while (a >= 0 && twist[a] && skeleton.bones[a].parent >= 0) a = skeleton.bones[a].parent;
      return a;
    };
    int downAbove = 0;  // downward bones above the joint, down to the leg's root
    for (int a = realParent(c); a >= 0 && direction(a).dot(up) < -0.5; a = realParent(a)) ++downAbove;
    Vec3 axis = d.cross(facing);
    if (axis.norm() < 0.5) {
      axis = left - left.dot(d) * d;
      if (axis.norm() < 1e-6) continue;
      axis.normalize();
      if (axis.cross(d).dot(up) > 0.0) axis = -axis;
    } else {
      axis.normalize();
      if (d.dot(up) < -0.5 && downAbove % 2 == 1) axis = -axis;
    }
    JointVolumeBlend report;
    if (!measureJoint(skeleton, w, skin, options, c, limbRadius, axis, inSubtree, blend, report)) continue;
    if (joints) joints->push_back(report);
    for (int v = 0; v < nv; ++v)
      if (blend[v] >= options.minBlend) {
        shareSum[v] += blend[v] * report.share;
        blendSum[v] += blend[v];
      }
  }
  Eigen::VectorXd share(nv);
  for (int v = 0; v < nv; ++v)
    share[v] = blendSum[v] > 0.0 ? std::clamp(shareSum[v] / blendSum[v], 0.0, 1.0)
                                 : (crossed[v] || nearJoint[v] ? 1.0 : options.unblendedShare);
  return share;
}

}  // namespace myoskin
