// Volume blend shares (volume_blend.h): per joint the dual-quaternion share that keeps the band's volume at a
// reference bend, spread over the skin the joint's skeleton weights blend.
#include "myoskin/volume_blend.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <string>

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "myoskin/character.h"
#include "myoskin/deformation.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/sections.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace {

constexpr int kShareSteps = 100;  // shares tried: 0, 1/100, ..., 1
constexpr double kLeanFloor = 1e-12;  // volumeKeyWeight: a lean this small is the rest pose (Blender's driver too)
constexpr double kRounding = 1e-9;  // band changes this small are rounding (a band no bend changes keeps share 1)
constexpr double kVisibleOffset = 0.01;  // volume keys: the smallest offset kept, in limb radii
constexpr double kContactFade = 0.5;     // volume keys: the profile's fade around skin held at a contact, limb radii
constexpr int kContactRounds = 8;        // volume keys: contact rounds per sample flexion
constexpr double kLossTie = 1e-12;      // volume keys: fits whose summed |band change| differ less are tied
constexpr double kGroundShare = 0.2;  // a limb whose skin reaches this share of the body height above its lowest: a leg

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

// ============================================================================
// Real joints
// ============================================================================

// One real joint (a bone with a parent, not a twist split, whose skin the skeleton blends across it).
struct RealJoint {
  int bone = -1;
  Vec3 axis = Vec3::Zero();          // its reference flexion's rotation axis (unit)
  bool limb = false;                 // a limb's joint: the segment below or above it is a limb's (Limb role)
  bool limbRoot = false;             // a limb's root (shoulder, hip): its bone is a limb's, the bone above is not
  bool keyOnly = false;              // a twist split where a limb begins by its role: volume keys, no share
  std::vector<char> inSubtree;       // #B: the bones that turn with it
  std::vector<int> blended;          // vertices with b >= minBlend
  std::vector<double> blend;         // their b
};

// What both computeDqsShare and computeVolumeKeys need: the real joints with their flexion axes, the body's limb
// radius, and per vertex whether it is blended across any joint or twist split or lies in a real joint's band.
struct JointScan {
  double limbRadius = 0.0;
  std::vector<RealJoint> joints;
  std::vector<char> crossed, nearJoint;
};

JointScan scanJoints(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin, const VolumeBlendOptions& options) {
  const int nv = skin.numVertices(), nb = skeleton.numBones();
  JointScan scan;
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
  scan.limbRadius = bodyLimbRadius(body, roles);
  const BodyFrame frame = bodyFrame(body, joined, roles, options.up);
  const Vec3 up = frame.up, left = frame.left, facing = frame.facing;
  auto direction = [&](int b) { return Vec3((joined.bones[b].tail - joined.bones[b].head).normalized()); };
  // Legs stand on the ground: a limb whose skin (the vertices weighted most to its bones and the bones below them)
  // reaches within kGroundShare of the body's height of the body's lowest skin (arms stay at 0.41-0.77 of it, legs
  // reach 0.08 at most, a horse's four included, on every character measured). Only a leg's joints alternate their
  // flexion down the limb; an arm's joints bend forward however far it hangs (an A-pose). A lone arm hanging down is
  // its own lowest skin: a leg.
  const Eigen::VectorXd heightOf = skin.vertices * up;
  const double ground = heightOf.minCoeff(), height = heightOf.maxCoeff() - ground;
  std::vector<int> strongest(nv, -1);  // each vertex's most weighted bone
  for (int v = 0; v < nv; ++v) {
    double most = 0.0;
    for (int k = 0; k < w.influences(); ++k)
      if (w.joints(v, k) >= 0 && w.weights(v, k) > most) most = w.weights(v, k), strongest[v] = w.joints(v, k);
  }
  auto standsOnGround = [&](int c) {
    int root = c;  // the limb's first bone: up the limb bones above c
    while (skeleton.bones[root].parent >= 0 && roles[skeleton.bones[root].parent] == BoneRole::Limb)
      root = skeleton.bones[root].parent;
    std::vector<char> below(nb, 0);  // root and the bones under it
    for (int b = 0; b < nb; ++b) {
      int a = b;
      while (a >= 0 && a != root) a = skeleton.bones[a].parent;
      below[b] = a == root;
    }
    double lowest = std::numeric_limits<double>::infinity();
    for (int v = 0; v < nv; ++v)
      if (strongest[v] >= 0 && below[strongest[v]]) lowest = std::min(lowest, heightOf[v]);
    return lowest <= ground + kGroundShare * height;
  };
  std::vector<char> inSubtree(nb);
  Eigen::VectorXd blend(nv);
  scan.crossed.assign(nv, 0);    // blended across any joint or twist split (b >= minBlend)
  scan.nearJoint.assign(nv, 0);  // in a real joint's band (bandRadius limb radii of its head)
  const double reach = options.bandRadius * scan.limbRadius;
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
      if (blend[v] >= options.minBlend) scan.crossed[v] = 1;  // a twist split, or a joint even where not measured
      if (!twist[c] && (skin.vertices.row(v).transpose() - skeleton.bones[c].head).norm() <= reach) scan.nearJoint[v] = 1;
    }
    // A twist split is no joint, except where a limb begins by its role (MakeHuman's shoulder01 -> upperarm01: the
    // twist analysis puts the real joint at shoulder01's head, animators swing upperarm01): volume keys only.
    const int above = skeleton.bones[c].parent;
    const bool limbStart = roles[c] == BoneRole::Limb && roles[above] != BoneRole::Limb;
    if (!anyBlend || (twist[c] && !limbStart)) continue;
    // Flexion: the child swings forward (about d x facing); down a leg (downward bones, across twist splits) the
    // joints alternate from the leg's root: hip forward, knee backward, a horse's hock forward again (an arm's elbow
    // still bends forward); a child along the facing (a foot) turns its tail down.
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
      if (d.dot(up) < -0.5 && downAbove % 2 == 1 && (roles[c] != BoneRole::Limb || standsOnGround(c))) axis = -axis;
    }
    RealJoint joint;
    joint.bone = c;
    joint.axis = axis;
    // The segment below the joint is a limb's when its bone or a bone continuing it across twist splits is (MakeHuman's
    // shoulder01 -> upperarm01); above, when the real joint's bone is.
    std::function<bool(int)> limbBelow = [&](int b) {
      if (roles[b] == BoneRole::Limb) return true;
      for (int x = 0; x < nb; ++x)
        if (skeleton.bones[x].parent == b && twist[x] && limbBelow(x)) return true;
      return false;
    };
    // Above: the bones up to the real joint above (across twist splits), any of them a limb's.
    bool parentLimb = false;
    for (int a = skeleton.bones[c].parent; a >= 0 && !parentLimb; a = twist[a] ? skeleton.bones[a].parent : -1)
      parentLimb = roles[a] == BoneRole::Limb;
    joint.limb = limbBelow(c) || parentLimb;
    joint.limbRoot = limbBelow(c) && !parentLimb;
    joint.keyOnly = twist[c] != 0;
    joint.inSubtree = inSubtree;
    for (int v = 0; v < nv; ++v)
      if (blend[v] >= options.minBlend) {
        joint.blended.push_back(v);
        joint.blend.push_back(blend[v]);
      }
    scan.joints.push_back(std::move(joint));
  }
  return scan;
}

// ============================================================================
// Joint bands
// ============================================================================

// The skin within `reach` of a joint as local arrays: its vertices (ids into the skin), rest positions, skeleton
// weights and the triangles whose three vertices lie in it.
struct Band {
  std::vector<int> ids;
  Points rest;
  SkinWeights weights;
  Triangles triangles;
};

Band jointBand(const SkinWeights& w, const Mesh& skin, const Vec3& joint, double reach) {
  const int nv = skin.numVertices();
  Band band;
  std::vector<int> local(nv, -1);
  for (int v = 0; v < nv; ++v)
    if ((skin.vertices.row(v).transpose() - joint).norm() <= reach) {
      local[v] = static_cast<int>(band.ids.size());
      band.ids.push_back(v);
    }
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index f = 0; f < skin.triangles.rows(); ++f) {
    const int a = local[skin.triangles(f, 0)], b = local[skin.triangles(f, 1)], d = local[skin.triangles(f, 2)];
    if (a >= 0 && b >= 0 && d >= 0) faces.emplace_back(a, b, d);
  }
  const int n = static_cast<int>(band.ids.size());
  band.rest.resize(n, 3);
  band.weights.joints.resize(n, w.influences());
  band.weights.weights.resize(n, w.influences());
  for (int i = 0; i < n; ++i) {
    band.rest.row(i) = skin.vertices.row(band.ids[i]);
    band.weights.joints.row(i) = w.joints.row(band.ids[i]);
    band.weights.weights.row(i) = w.weights.row(band.ids[i]);
  }
  band.triangles.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) band.triangles.row(static_cast<Eigen::Index>(f)) = faces[f].transpose();
  return band;
}

// The skeleton transforms of a joint's child subtree turned about the joint by `degrees` about `axis` (unit).
std::vector<Mat4> turnedSubtree(const Skeleton& skeleton, const RealJoint& joint, double degrees, const Vec3& axis) {
  const Vec3 head = skeleton.bones[joint.bone].head;
  Mat4 turn = Mat4::Identity();
  turn.block<3, 3>(0, 0) = Eigen::AngleAxisd(degrees * kPi / 180.0, axis).toRotationMatrix();
  turn.block<3, 1>(0, 3) = head - turn.block<3, 3>(0, 0) * head;
  std::vector<Mat4> transforms(static_cast<size_t>(skeleton.numBones()), Mat4::Identity());
  for (int b = 0; b < skeleton.numBones(); ++b)
    if (joint.inSubtree[b]) transforms[b] = turn;
  return transforms;
}

// Per band vertex the linear and the dual-quaternion affine maps (#n by 12 each) at a bend.
void bandMaps(const Skeleton& skeleton, const Band& band, const std::vector<Mat4>& transforms, VertexTransforms& linear,
              VertexTransforms& dualQuat) {
  SkinnerOptions linearOptions;
  linearOptions.threads = 1;
  SkinnerOptions dqOptions = linearOptions;
  dqOptions.preserveVolume = true;
  for (const Bone& b : skeleton.bones) dqOptions.jointRest.push_back(b.rest);
  Skinner skinner(band.rest, band.weights, skeleton.numBones(), linearOptions);
  skinner.vertexTransforms(transforms, linear);
  skinner.setOptions(dqOptions);
  skinner.vertexTransforms(transforms, dualQuat);
}

// The joint's band (bandRadius body limb radii of its head) and its share at the reference flexion (fills `out`;
// false when it has no band).
bool measureJoint(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin, const VolumeBlendOptions& o,
                  const RealJoint& joint, double limbRadius, JointVolumeBlend& out) {
  const Vec3 head = skeleton.bones[joint.bone].head;
  out.bone = joint.bone;
  out.blendedVertices = static_cast<int>(joint.blended.size());
  out.radius = limbRadius;
  const Band band = jointBand(w, skin, head, o.bandRadius * limbRadius);
  out.bandTriangles = static_cast<int>(band.triangles.rows());
  if (band.triangles.rows() == 0) return false;
  const double v0 = coneVolume(band.rest, band.triangles, head);
  if (!(std::abs(v0) > 0.0)) return false;
  // In float64 (the skinner's per-vertex affine maps on the float64 rest positions): the shares then depend on the
  // body, not on how its coordinates round (a character turned in space gets the same shares to 1e-9).
  VertexTransforms linearMaps, dqMaps;
  bandMaps(skeleton, band, turnedSubtree(skeleton, joint, o.bendDegrees, joint.axis), linearMaps, dqMaps);
  const Points lin = applyMaps(linearMaps, band.rest), dq = applyMaps(dqMaps, band.rest);
  // Band volume change for each tried share at the reference flexion.
  std::vector<double> change(kShareSteps + 1);
  for (int k = 0; k <= kShareSteps; ++k) {
    const double s = static_cast<double>(k) / kShareSteps;
    const Points p = (1.0 - s) * lin + s * dq;
    change[k] = (coneVolume(p, band.triangles, head) - v0) / std::abs(v0);
  }
  // The largest share whose |change| is at most the smallest |change| of any share or keepTolerance x |linear's
  // change| or kRounding (dual quaternions where they keep the volume well enough or lose it anyway).
  double smallest = std::abs(change[0]);
  for (double x : change) smallest = std::min(smallest, std::abs(x));
  const double allowed = std::max({smallest, o.keepTolerance * std::abs(change[0]), kRounding});
  int best = kShareSteps;
  while (best > 0 && std::abs(change[best]) > allowed) --best;
  out.share = static_cast<double>(best) / kShareSteps;
  out.axis = joint.axis;
  out.linearChange = change[0];
  out.dualQuatChange = change[kShareSteps];
  out.blendChange = change[best];
  return true;
}

}  // namespace

// ============================================================================
// Shares over the skin
// ============================================================================

Eigen::VectorXd computeDqsShare(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin,
                                const VolumeBlendOptions& options, std::vector<JointVolumeBlend>* joints) {
  validate(skeleton, w, skin, options);
  const int nv = skin.numVertices();
  if (joints) joints->clear();
  const JointScan scan = scanJoints(skeleton, w, skin, options);
  Eigen::VectorXd shareSum = Eigen::VectorXd::Zero(nv), blendSum = Eigen::VectorXd::Zero(nv);
  for (const RealJoint& joint : scan.joints) {
    if (joint.keyOnly) continue;
    JointVolumeBlend report;
    if (!measureJoint(skeleton, w, skin, options, joint, scan.limbRadius, report)) continue;
    if (joints) joints->push_back(report);
    for (size_t i = 0; i < joint.blended.size(); ++i) {
      shareSum[joint.blended[i]] += joint.blend[i] * report.share;
      blendSum[joint.blended[i]] += joint.blend[i];
    }
  }
  Eigen::VectorXd share(nv);
  for (int v = 0; v < nv; ++v)
    share[v] = blendSum[v] > 0.0 ? std::clamp(shareSum[v] / blendSum[v], 0.0, 1.0)
                                 : (scan.crossed[v] || scan.nearJoint[v] ? 1.0 : options.unblendedShare);
  return share;
}

// ============================================================================
// Volume keys
// ============================================================================

namespace {

constexpr size_t kTestedPerBend = 4;  // position sets a bend remembers with their self-intersecting pairs

// A band's bends about one swing axis, shared by the fits of its profile sides and contact modes: per flexion the
// vertices' affine maps (the skeleton's blend, or Bind's skin with the muscle joints) and the self-intersecting pairs
// under them alone (found once).
struct BendCache {
  struct Bend {
    VertexTransforms maps;  // per band vertex the skin's affine map at this bend
    bool counted = false;
    std::vector<std::pair<int, int>> folds;  // under the blend alone, the self-intersecting pairs with a movable triangle
    // The band positions last tested at this bend and their pairs, newest first: the fits of one axis test the same
    // positions again (a sample's last contact round, then its fold check; both contact modes' first rounds).
    std::deque<std::pair<Points, std::vector<std::pair<int, int>>>> tested;
  };
  std::map<double, Bend> bends;
  std::unique_ptr<SelfIntersectionTest> crossings;  // the band's self-intersection test, made once
  std::vector<char> movable;  // per band triangle: whether a key can move it (crossings counts pairs with one)
};

// Bind's skin, when the keys are fitted on it: the muscle rig's joints with their hybrid weights (#V rows over the
// skeleton's bones and then the rig's joints) and the combined joints' rest matrices.
struct MuscleSkin {
  const MuscleRig* rig = nullptr;
  const SkinWeights* weights = nullptr;
  std::vector<Mat4> rest;
  DualQuatScale dualQuatScale = DualQuatScale::Pivot;
};

// Per band vertex the blended affine map of Bind's skin at a skeleton bend (transforms: turnedSubtree's).
void muscleBandMaps(const Skeleton& skeleton, const Band& band, const MuscleSkin& muscles, const Eigen::VectorXd& share,
                    const std::vector<Mat4>& transforms, VertexTransforms& out) {
  Pose pose;
  for (int b = 0; b < skeleton.numBones(); ++b) pose.matrices.push_back(transforms[b] * skeleton.bones[b].rest);
  MuscleRigState state = muscles.rig->makeState();
  muscles.rig->evaluate(pose, state);
  std::vector<Mat4> all;
  skinningTransforms(skeleton, pose, *muscles.rig, state, all);
  const int n = static_cast<int>(band.ids.size());
  SkinWeights w;
  w.joints.resize(n, muscles.weights->influences());
  w.weights.resize(n, muscles.weights->influences());
  SkinnerOptions options;
  options.threads = 1;
  options.jointRest = muscles.rest;
  options.dualQuatScale = muscles.dualQuatScale;
  for (int i = 0; i < n; ++i) {
    w.joints.row(i) = muscles.weights->joints.row(band.ids[i]);
    w.weights.row(i) = muscles.weights->weights.row(band.ids[i]);
    options.dqsShare.push_back(share[band.ids[i]]);
  }
  Skinner(band.rest, w, static_cast<int>(all.size()), options).vertexTransforms(all, out);
}

// Which skin of a joint's band a volume key moves, by c = n . side of its rest normal (c = 1 on the skin facing the
// way the limb bends, the crease; -1 on the outer side): Outer swells the outer side and keeps the crease, AllRound
// swells all round (by half), Crease swells the crease's side (a shoulder's deltoid on abduction), OuterAndCreaseIn
// swells the outer side and draws the crease's side in (a flexed elbow's skin folding into its crease).
enum class KeySide { Outer, AllRound, Crease, OuterAndCreaseIn };

// Which way a volume key moves the skin: along its rest normal, or away from the joint (the direction from the joint's
// head; at a crease both facing sides then move out the same way instead of into each other: a raised arm's shoulder).
enum class KeyDirection { Normal, FromJoint };

double sideFactor(KeySide keySide, double c) {
  switch (keySide) {
    case KeySide::Outer: return 0.5 * (1.0 - c);
    case KeySide::AllRound: return 0.5;
    case KeySide::Crease: return 0.5 * (1.0 + c);
    case KeySide::OuterAndCreaseIn: return -c;
  }
  return 0.0;
}

// One joint's key for swings about `axis` (unit; `directional`: the key acts only on swings toward that side): the
// offsets' profile and, per sample flexion, the amplitude that keeps the band's volume; then the weight's fit. False
// when the band keeps its volume at every sample (no key). `holdAll`: every contact under the push is held, else only
// the contacts the push makes (the blend's own folds may be pushed apart). `folds`: the band's self-intersecting
// triangle pairs with the key that have a movable triangle (the fits of one axis share the others), summed over the
// samples; `held`: whether any skin was held.
bool fitVolumeKey(const Skeleton& skeleton, const Band& band, const std::vector<double>& bandBlend,
                  const Points& normals, const Eigen::VectorXd& share, const VolumeBlendOptions& o,
                  const VolumeKeyOptions& ko, const RealJoint& joint, const Vec3& axis, bool directional,
                  double limbRadius, KeySide keySide, KeyDirection keyDirection, bool holdAll,
                  const MuscleSkin& muscles, BendCache& cache,
                  VolumeKey& key, int& folds, bool& held) {
  const Vec3 head = skeleton.bones[joint.bone].head;
  const double reach = o.bandRadius * limbRadius;
  const double v0 = coneVolume(band.rest, band.triangles, head);
  if (!(std::abs(v0) > 0.0)) return false;
  const int n = static_cast<int>(band.ids.size());
  // Profile: the joint's blend b, tapered to 0 at the band's edge, times the side's factor of c = n . side (1 on the
  // skin facing the way the limb bends, the crease), along the rest normal n or the unit direction from the joint's
  // head (keyDirection), in limb radii (sideFactor).
  const Vec3 boneY = skeleton.bones[joint.bone].rest.block<3, 1>(0, 1).normalized();
  const Vec3 side = axis.cross(boneY).normalized();
  Points profile = Points::Zero(n, 3);
  for (int i = 0; i < n; ++i) {
    const Vec3 fromHead = band.rest.row(i).transpose() - head;
    const double d = fromHead.norm() / reach;
    const double taper = std::pow(std::max(0.0, 1.0 - d * d), 2);
    const Vec3 normal = normals.row(band.ids[i]).transpose();
    const Vec3 dir = keyDirection == KeyDirection::Normal ? normal
                     : d > 0.0                            ? Vec3(fromHead / fromHead.norm())
                                                          : Vec3::Zero();
    profile.row(i) = limbRadius * bandBlend[static_cast<size_t>(i)] * taper * sideFactor(keySide, normal.dot(side)) *
                     dir.transpose();
  }
  // The band bent by `degrees` about `axis` under the blend: its positions, and how one unit of the profile moves it
  // (each vertex's blended affine map is linear in its input).
  auto bent = [&](double degrees, Points& base, Points& moved) -> BendCache::Bend& {
    BendCache::Bend& bend = cache.bends[degrees];
    if (bend.maps.rows() == 0) {
      const std::vector<Mat4> turned = turnedSubtree(skeleton, joint, degrees, axis);
      if (muscles.rig) {
        muscleBandMaps(skeleton, band, muscles, share, turned, bend.maps);
      } else {
        VertexTransforms linearMaps, dqMaps;
        bandMaps(skeleton, band, turned, linearMaps, dqMaps);
        bend.maps.resize(n, 12);
        for (int i = 0; i < n; ++i) {
          const double s = share[band.ids[i]];
          for (int c = 0; c < 12; ++c) bend.maps(i, c) = (1.0 - s) * linearMaps(i, c) + s * dqMaps(i, c);
        }
      }
    }
    base.resize(n, 3);
    moved.resize(n, 3);
    for (int i = 0; i < n; ++i) {
      Eigen::Matrix<double, 3, 4> m;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) m(r, c) = bend.maps(i, 4 * r + c);
      base.row(i) = (m.leftCols<3>() * band.rest.row(i).transpose() + m.col(3)).transpose();
      moved.row(i) = (m.leftCols<3>() * profile.row(i).transpose()).transpose();
    }
    return bend;
  };
  if (!cache.crossings) {
    cache.crossings = std::make_unique<SelfIntersectionTest>(band.triangles, band.rest.rows());
    // The triangles a key can move (a vertex with blend and taper, whatever the side and direction): every position
    // set tested at a bend differs from the bend's own only there, so only pairs with one of them are counted.
    cache.movable.assign(static_cast<size_t>(band.triangles.rows()), 0);
    for (Eigen::Index t = 0; t < band.triangles.rows(); ++t)
      for (int c = 0; c < 3; ++c) {
        const int i = band.triangles(t, c);
        if (bandBlend[static_cast<size_t>(i)] > 0.0 && (band.rest.row(i).transpose() - head).norm() < reach)
          cache.movable[static_cast<size_t>(t)] = 1;
      }
  }
  auto pairsOf = [&](const Points& p) { return cache.crossings->pairs(p, cache.movable); };
  auto foldPairs = [&](BendCache::Bend& bend, const Points& base) -> const std::vector<std::pair<int, int>>& {
    if (!bend.counted) bend.folds = pairsOf(base), bend.counted = true;
    return bend.folds;  // under the blend alone, found once
  };
  // The pairs under `with` at a bend: a position set tested there before gives its pairs back (compared exactly).
  auto pairsAt = [&](BendCache::Bend& bend, const Points& with) -> std::vector<std::pair<int, int>> {
    for (const auto& [positions, pairs] : bend.tested)
      if (positions == with) return pairs;
    if (bend.tested.size() == kTestedPerBend) bend.tested.pop_back();
    bend.tested.emplace_front(with, pairsOf(with));
    return bend.tested.front().second;
  };
  auto crosses = [&](BendCache::Bend& bend, const Points& base, const Points& with) {  // more folds than the blend
    return pairsAt(bend, with).size() > foldPairs(bend, base).size();
  };
  // The contacts to hold under a push: all of them, or those the blend alone does not have.
  auto contacts = [&](BendCache::Bend& bend, const Points& base, const Points& with) {
    std::vector<std::pair<int, int>> pairs = pairsAt(bend, with);
    if (holdAll) return pairs;
    const std::vector<std::pair<int, int>>& alone = foldPairs(bend, base);
    std::vector<std::pair<int, int>> made;
    std::set_difference(pairs.begin(), pairs.end(), alone.begin(), alone.end(), std::back_inserter(made));
    return made;
  };
  auto change = [&](const Points& p) { return (coneVolume(p, band.triangles, head) - v0) / std::abs(v0); };
  const double amax = ko.maxOffset;
  std::vector<double> s2, amplitude;
  Points base, moved;
  // Which way the profile points: out where the blend loses volume at the sample it changes most, in where it gains.
  // `deficit` is the change with that sign taken off: negative where the profile gives the volume back.
  double direction = 1.0, mostChange = 0.0;
  for (double degrees : ko.sampleDegrees) {
    bent(degrees, base, moved);
    const double c = change(base);
    if (std::abs(c) > std::abs(mostChange)) mostChange = c;
  }
  if (mostChange > 0.0) direction = -1.0, profile = -profile;
  auto deficit = [&](const Points& p) { return direction * change(p); };
  // A key that moves the skin less than kVisibleOffset limb radii changes nothing one could see (and only flips
  // contacts the bent skin already has).
  double reachOut = 0.0;
  for (int i = 0; i < n; ++i) reachOut = std::max(reachOut, profile.row(i).norm());
  const double smallest = kVisibleOffset * limbRadius / std::max(reachOut, 1e-300);
  // The signed amplitude that keeps the band's volume at a bend (|a| at most amax): along the profile where the
  // bend's change has the dominant sample's sign, against it where it has the other (a knee that gains volume at 45
  // degrees and loses it at 135); 0 when moving the skin either way gives none back.
  auto restoring = [&](const Points& base, const Points& moved) {
    const double before = deficit(base);
    if (before == 0.0) return 0.0;
    const double sign = before < 0.0 ? 1.0 : -1.0;
    auto off = [&](double t) { return sign * deficit(base + (sign * t) * moved); };  // < 0 until restored
    const double most = off(amax);
    if (!(most > sign * before)) return 0.0;
    if (most <= 0.0) return sign * amax;
    double lo = 0.0, hi = amax;
    for (int it = 0; it < 40; ++it) (off(0.5 * (lo + hi)) < 0.0 ? lo : hi) = 0.5 * (lo + hi);
    return sign * hi;
  };
  // Contacts: skin that touches other skin under the push (the back of the knee against the calf, an arm against the
  // torso under the armpit) stays still, and the free skin gives the volume back. At each sample the restoring
  // amplitude is tried; the vertices of every triangle pair that intersects with it are held, the profile faded back
  // to full over kContactFade limb radii around them, until no new vertex is held (at most kContactRounds rounds).
  const Points unheld = profile;
  std::vector<char> isHeld(static_cast<size_t>(n), 0);
  std::vector<int> heldIds;
  held = false;
  for (double degrees : ko.sampleDegrees) {
    for (int round = 0; round < kContactRounds; ++round) {
      BendCache::Bend& bend = bent(degrees, base, moved);
      const double a = restoring(base, moved);
      if (!(std::abs(a) > smallest)) break;
      const size_t before = heldIds.size();
      for (const auto& [f, g] : contacts(bend, base, Points(base + a * moved)))
        for (int t : {f, g})
          for (int c = 0; c < 3; ++c) {
            const int i = band.triangles(t, c);
            if (!isHeld[static_cast<size_t>(i)] && unheld.row(i).squaredNorm() > 0.0)
              isHeld[static_cast<size_t>(i)] = 1, heldIds.push_back(i);
          }
      if (heldIds.size() == before) break;
      held = true;
      const double fade = kContactFade * limbRadius;
      for (int i = 0; i < n; ++i) {
        double d2 = std::numeric_limits<double>::infinity();
        for (int h : heldIds) d2 = std::min(d2, (band.rest.row(i) - band.rest.row(h)).squaredNorm());
        const double u = std::min(1.0, std::sqrt(d2) / fade);
        profile.row(i) = (u * u * (3.0 - 2.0 * u)) * unheld.row(i);
      }
    }
  }
  for (double degrees : ko.sampleDegrees) {
    BendCache::Bend& bend = bent(degrees, base, moved);
    const double before = change(base);
    double a = restoring(base, moved);
    if (a != 0.0) {  // moving the skin does give the volume back
      // No more folding than the blend alone at this flexion: the amplitude halves until it does not; an amplitude
      // under the visible offset (halved there or small from the start) is none.
      while (std::abs(a) > smallest && crosses(bend, base, Points(base + a * moved))) a *= 0.5;
      if (!(std::abs(a) > smallest)) a = 0.0;
    }
    const double half = std::sin(0.5 * degrees * kPi / 180.0);
    s2.push_back(half * half);
    amplitude.push_back(a);
    key.sampleDegrees.push_back(degrees);
    key.changeWithout.push_back(before);
  }
  // amplitude(s) = s (c1 + c2 s), least squares. Amplitudes of one sign keep it: a single s^2 term when the pair
  // would change sign on [0, 1]; with both signs among the samples the weight changes sign with the bend.
  double s2s = 0.0, s3 = 0.0, s4 = 0.0, as = 0.0, as2 = 0.0;
  for (size_t k = 0; k < s2.size(); ++k) {
    const double x = s2[k];
    s2s += x * x;
    s3 += x * x * x;
    s4 += x * x * x * x;
    as += amplitude[k] * x;
    as2 += amplitude[k] * x * x;
  }
  double c1 = 0.0, c2 = 0.0;
  const double det = s2s * s4 - s3 * s3;
  if (s2.size() >= 2 && std::abs(det) > 1e-12 * s2s * s4) {
    c1 = (as * s4 - as2 * s3) / det;
    c2 = (s2s * as2 - s3 * as) / det;
  }
  const double lowest = *std::min_element(amplitude.begin(), amplitude.end());
  const double highest = *std::max_element(amplitude.begin(), amplitude.end());
  const double sign = highest > 0.0 ? 1.0 : -1.0;  // of the amplitudes when they have one sign
  if (!(lowest < 0.0 && highest > 0.0) && !(sign * c1 >= 0.0 && sign * (c1 + c2) >= 0.0)) {
    c1 = 0.0;
    c2 = s4 > 0.0 ? as2 / s4 : 0.0;
  }
  double peak = std::abs(c1 + c2);  // the largest |amplitude| over s in [0, 1]: at s = 1 or at the parabola's top
  if (c2 != 0.0) {
    const double top = -c1 / (2.0 * c2);
    if (top > 0.0 && top < 1.0) peak = std::max(peak, std::abs(top * (c1 + c2 * top)));
  }
  if (!(peak > 1e-6)) return false;
  key.k1 = c1 / peak;
  key.k2 = c2 / peak;
  auto weightAt = [&](double degrees) {
    const double half = std::sin(0.5 * degrees * kPi / 180.0);
    return std::clamp(half * half * (key.k1 + key.k2 * half * half), -1.0, 1.0);
  };
  if (!(peak > smallest)) return false;
  // Never fold the skin more than the blend alone does, at every 30 degrees of flexion and at the largest sample: the
  // key halves until it does not (dropped once it would move the skin less than kVisibleOffset).
  const double largest = *std::max_element(key.sampleDegrees.begin(), key.sampleDegrees.end());
  std::vector<double> checked;
  for (double degrees = 30.0; degrees < largest - 1e-9; degrees += 30.0) checked.push_back(degrees);
  checked.push_back(largest);
  std::reverse(checked.begin(), checked.end());  // the deepest bend folds first: a key dropped there costs least
  for (double degrees : checked) {
    if (!(peak > smallest)) break;
    BendCache::Bend& bend = bent(degrees, base, moved);
    while (peak > smallest && crosses(bend, base, Points(base + weightAt(degrees) * peak * moved))) peak *= 0.5;
  }
  if (!(peak > smallest)) return false;
  key.bone = joint.bone;
  key.axis = axis;
  if (directional) {  // the side the bone's tail swings to, in the bone's rest frame (x, z)
    const Mat3 frame = skeleton.bones[joint.bone].rest.block<3, 3>(0, 0);
    const Vec3 side = frame.transpose() * axis.cross(Vec3(frame.col(1).normalized()));
    key.swing = Eigen::Vector2d(side.x(), side.z());
    if (key.swing.norm() < 1e-9) return false;
    key.swing.normalize();
  }
  std::vector<int> rows;  // band.ids ascend, so the key's vertices do too
  for (int i = 0; i < n; ++i)
    if (profile.row(i).squaredNorm() > 0.0) rows.push_back(i);
  if (rows.empty()) return false;
  key.offsets.resize(static_cast<Eigen::Index>(rows.size()), 3);
  for (size_t i = 0; i < rows.size(); ++i) {
    key.vertices.push_back(band.ids[rows[i]]);
    key.offsets.row(static_cast<Eigen::Index>(i)) = peak * profile.row(rows[i]);
  }
  folds = 0;
  for (double degrees : key.sampleDegrees) {
    BendCache::Bend& bend = bent(degrees, base, moved);
    const Points with = base + weightAt(degrees) * peak * moved;
    key.changeWith.push_back(change(with));
    folds += static_cast<int>(pairsAt(bend, with).size());
  }
  return true;
}

}  // namespace

std::vector<VolumeKey> computeVolumeKeys(const Skeleton& skeleton, const SkinWeights& w, const Mesh& skin,
                                         const Eigen::VectorXd& share, const VolumeBlendOptions& options,
                                         const VolumeKeyOptions& keyOptions, const MuscleRig* rig,
                                         const SkinWeights* hybridWeights) {
  validate(skeleton, w, skin, options);
  MuscleSkin muscles;
  if ((rig == nullptr) != (hybridWeights == nullptr))
    throw InputError("volume keys: the muscle rig and its hybrid weights come together");
  if (rig) {
    if (rig->skeleton().numBones() != skeleton.numBones())
      throw InputError("volume keys: the muscle rig has " + std::to_string(rig->skeleton().numBones()) +
                       " bones, the skeleton " + std::to_string(skeleton.numBones()));
    validateSkinWeights(*hybridWeights, skin.numVertices(), skeleton.numBones() + rig->numJoints());
    muscles = MuscleSkin{rig, hybridWeights, combinedRestMatrices(skeleton, *rig), keyOptions.dualQuatScale};
  }
  if (share.size() != skin.numVertices())
    throw InputError("volume keys: " + std::to_string(share.size()) + " shares for " +
                     std::to_string(skin.numVertices()) + " vertices");
  for (Eigen::Index v = 0; v < share.size(); ++v)
    if (!(share[v] >= 0.0 && share[v] <= 1.0))
      throw InputError("volume keys: share of vertex " + std::to_string(v) + " is not in [0, 1]");
  if (keyOptions.sampleDegrees.empty()) throw InputError("volume keys: no sample flexion");
  for (double d : keyOptions.sampleDegrees)
    if (!(d > 0.0 && d <= 180.0))
      throw InputError("volume keys: sample flexions must be in (0, 180] degrees, got " + std::to_string(d));
  if (!(keyOptions.maxOffset > 0.0 && std::isfinite(keyOptions.maxOffset)))
    throw InputError("volume keys: maxOffset must be > 0, got " + std::to_string(keyOptions.maxOffset));
  const JointScan scan = scanJoints(skeleton, w, skin, options);
  const Points normals = vertexNormals(skin.vertices, skin.triangles);
  // One fit per (joint, swing axis, profile side): bands first, then the fits.
  struct JointBand {
    const RealJoint* joint;
    Band band;
    std::vector<double> blend;  // the joint's blend b per band vertex
  };
  struct Fit {
    size_t band;
    Vec3 axis;
    KeySide side;
    KeyDirection direction;
    bool holdAll;
    bool ok = false;
    int folds = 0;
    bool held = false;
    VolumeKey key;
  };
  constexpr KeySide kSides[] = {KeySide::Outer, KeySide::AllRound, KeySide::Crease, KeySide::OuterAndCreaseIn};
  std::vector<JointBand> bands;
  std::vector<Fit> fits;
  std::vector<int> local(static_cast<size_t>(skin.numVertices()), -1);
  for (const RealJoint& joint : scan.joints) {
    if (!joint.limb) continue;
    JointBand jb{&joint, jointBand(w, skin, skeleton.bones[joint.bone].head, options.bandRadius * scan.limbRadius), {}};
    if (jb.band.triangles.rows() == 0) continue;
    jb.blend.assign(jb.band.ids.size(), 0.0);
    for (size_t i = 0; i < jb.band.ids.size(); ++i) local[static_cast<size_t>(jb.band.ids[i])] = static_cast<int>(i);
    for (size_t i = 0; i < joint.blended.size(); ++i)
      if (local[static_cast<size_t>(joint.blended[i])] >= 0)
        jb.blend[static_cast<size_t>(local[static_cast<size_t>(joint.blended[i])])] = joint.blend[i];
    for (int id : jb.band.ids) local[static_cast<size_t>(id)] = -1;
    // The swings are about axes across the bone's own rest Y (what Blender's driver measures the swing from): the
    // reference flexion axis made perpendicular to it; a limb's root (a ball joint) swings every way: one directional
    // key per quarter (that axis turned about the bone by 0, 90, 180 and 270 degrees); elsewhere one key for any swing.
    const Vec3 boneY = skeleton.bones[joint.bone].rest.block<3, 1>(0, 1).normalized();
    Vec3 flexion = joint.axis - joint.axis.dot(boneY) * boneY;
    if (flexion.norm() < 1e-6) continue;
    flexion.normalize();
    bands.push_back(std::move(jb));
    for (int quarter = 0; quarter < (joint.limbRoot ? 4 : 1); ++quarter)
      for (KeyDirection keyDirection : {KeyDirection::Normal, KeyDirection::FromJoint})
        for (KeySide keySide : kSides)
          for (bool holdAll : {true, false})
            fits.push_back(Fit{bands.size() - 1, Eigen::AngleAxisd(0.5 * kPi * quarter, boneY) * flexion, keySide,
                               keyDirection, holdAll, false, 0, false, {}});
  }
  // In parallel per swing axis; its sides in turn, sharing the band's bends.
  constexpr size_t kFitsPerAxis = 2 * 2 * std::size(kSides);  // directions x sides x contact modes
  const tbb::blocked_range<size_t> axes(0, fits.size() / kFitsPerAxis, 1);
  tbb::parallel_for(axes, [&](const tbb::blocked_range<size_t>& r) {
    for (size_t g = r.begin(); g != r.end(); ++g) {
      BendCache cache;
      for (size_t f = g * kFitsPerAxis; f < (g + 1) * kFitsPerAxis; ++f) {
        // A side whose fit holding every contact held none: holding only new contacts gives the same key.
        if (!fits[f].holdAll && !fits[f - 1].held) continue;
        const JointBand& jb = bands[fits[f].band];
        fits[f].ok = fitVolumeKey(skeleton, jb.band, jb.blend, normals, share, options, keyOptions, *jb.joint,
                                  fits[f].axis, jb.joint->limbRoot, scan.limbRadius, fits[f].side,
                                  fits[f].direction, fits[f].holdAll, muscles, cache, fits[f].key, fits[f].folds,
                                  fits[f].held);
      }
    }
  });
  // Per swing axis, among the fits that lower the band's largest change over the samples (a key that trades a loss
  // at one flexion for a gain past rest at another is none), the one with the least band volume change summed over
  // the samples (each fit's sample amplitudes fold no more than the blend alone), then the fewest self-intersecting
  // pairs (the first in fit order on a tie: along the normals, the outer side's swell, every contact held).
  std::vector<VolumeKey> keys;
  for (size_t first = 0; first < fits.size(); first += kFitsPerAxis) {
    Fit* best = nullptr;
    double bestLoss = std::numeric_limits<double>::infinity();
    for (size_t f = first; f < first + kFitsPerAxis; ++f) {
      if (!fits[f].ok) continue;
      double before = 0.0, after = 0.0, loss = 0.0;
      for (double c : fits[f].key.changeWithout) before = std::max(before, std::abs(c));
      for (double c : fits[f].key.changeWith) after = std::max(after, std::abs(c)), loss += std::abs(c);
      if (!(after < before)) continue;
      if (!best || loss < bestLoss - kLossTie || (loss <= bestLoss + kLossTie && fits[f].folds < best->folds)) {
        bestLoss = loss;
        best = &fits[f];
      }
    }
    if (best) keys.push_back(std::move(best->key));
  }
  return keys;
}

double volumeKeyWeight(const VolumeKey& key, const Eigen::Quaterniond& localRotation) {
  const double n2 = localRotation.squaredNorm();
  if (!(n2 > 0.0)) return 0.0;
  const Eigen::Quaterniond q(localRotation.coeffs() / std::sqrt(n2));
  const double s = q.x() * q.x() + q.z() * q.z();
  const double weight = s * (key.k1 + key.k2 * s);
  if (key.swing.squaredNorm() == 0.0) return std::clamp(weight, -1.0, 1.0);
  // The bone's Y axis leans by (a, c) / 2 in its rest frame's x and z (u(q) in correctives.h).
  const double a = q.x() * q.y() - q.w() * q.z(), c = q.y() * q.z() + q.w() * q.x();
  const double toward = std::max(key.swing.x() * a + key.swing.y() * c, 0.0);
  return std::clamp(weight * toward * toward / std::max(a * a + c * c, kLeanFloor), -1.0, 1.0);
}

void applyVolumeKeys(const std::vector<VolumeKey>& keys, const std::vector<Eigen::Quaterniond>& localRotations,
                     const Points& base, Points& out) {
  out = base;
  for (size_t k = 0; k < keys.size(); ++k) {
    const VolumeKey& key = keys[k];
    if (key.bone < 0 || key.bone >= static_cast<int>(localRotations.size()))
      throw InputError("volume key " + std::to_string(k) + ": bone " + std::to_string(key.bone) + " has no rotation");
    if (key.offsets.rows() != static_cast<Eigen::Index>(key.vertices.size()) || key.offsets.cols() != 3)
      throw InputError("volume key " + std::to_string(k) + ": offsets must be #vertices by 3");
    const double weight = volumeKeyWeight(key, localRotations[static_cast<size_t>(key.bone)]);
    if (weight == 0.0) continue;
    for (size_t i = 0; i < key.vertices.size(); ++i) {
      const int v = key.vertices[i];
      if (v < 0 || v >= base.rows())
        throw InputError("volume key " + std::to_string(k) + ": vertex " + std::to_string(v) + " outside the skin");
      out.row(v) += weight * key.offsets.row(static_cast<Eigen::Index>(i));
    }
  }
}

}  // namespace myoskin
