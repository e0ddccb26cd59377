// Anatomical muscle names: the body's axes from its legs, feet and neck, then each muscle's limb segment and its
// side of the bone (front / back along the body's forward axis).
#include "muscles/muscle_names.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "muscles/muscle_util.h"

namespace myoskin::detail {

namespace {

// v with its component along unit axis a removed.
Vec3 across(const Vec3& v, const Vec3& a) { return v - v.dot(a) * a; }

// The side suffix of the muscle's middle (".L", ".R"; "" within half its radius of the mirror plane, or unsided).
std::string sideOf(const Muscle& muscle, const BodyFrame& frame) {
  const Vec3 p = muscle.sections[muscle.sections.size() / 2].center;
  double radius = 0.0;
  for (const MuscleSection& s : muscle.sections) radius += std::sqrt(std::max(s.a * s.b, 0.0));
  radius /= static_cast<double>(muscle.sections.size());
  const double lateral = (p - frame.centre).dot(frame.left);
  return !frame.sided || std::abs(lateral) < 0.5 * radius ? "" : lateral > 0 ? ".L" : ".R";
}

// Which way `out` (across `axis`) points: of the body's forward, up and left axes taken across the bone, the one it
// lies along most: front / back, top / bottom, or outer / inner (away from / towards the mirror plane, `lateral` the
// muscle's side of it).
std::string facingName(const Vec3& out, const Vec3& axis, const BodyFrame& frame, double lateral) {
  const Vec3 o = out.normalized();
  double best = -1.0;
  std::string name = "outer";
  const Vec3 axes[3] = {frame.forward, frame.up, frame.left};
  const char* names[3][2] = {{"front", "back"}, {"top", "bottom"}, {"outer", "inner"}};
  for (int k = 0; k < 3; ++k) {
    const Vec3 a = across(axes[k], axis);
    if (a.norm() < 0.5) continue;  // the bone runs along it
    double c = o.dot(a.normalized());
    if (k == 2 && lateral < 0.0) c = -c;  // outer: away from the mirror plane on either side
    if (std::abs(c) > best) best = std::abs(c), name = names[k][c >= 0.0 ? 0 : 1];
  }
  return name;
}

}  // namespace

BodyFrame bodyFrame(const Skeleton& sk, const std::vector<BoneRole>& roles, const std::vector<char>& twist) {
  const int n = sk.numBones();
  BodyFrame f;
  f.limb.assign(n, 0);
  f.segment.assign(n, -1);
  if (static_cast<int>(roles.size()) != n || static_cast<int>(twist.size()) != n) return f;
  auto isLimb = [&](int b) { return b >= 0 && roles[b] == BoneRole::Limb; };
  // Each limb's root, and how deep in the tree the trunk bone it hangs from lies: the legs hang from the trunk's
  // root end (the pelvis), the arms (front legs) further along it; with one depth only, a shoulder girdle says arm.
  auto depth = [&](int b) {
    int d = 0;
    for (; b >= 0; b = sk.bones[b].parent) ++d;
    return d;
  };
  std::vector<int> roots, rootOf(n, -1), attachDepth(n, 0);
  for (int b = 0; b < n; ++b) {
    if (!isLimb(b)) continue;
    int root = b, segment = 0;
    for (; isLimb(sk.bones[root].parent); root = sk.bones[root].parent) segment += !twist[root];
    rootOf[b] = root;
    f.segment[b] = segment;
    if (root != b) continue;
    roots.push_back(b);
    int attach = sk.bones[b].parent;  // the first trunk bone above it, else the skeleton's root (-1: none)
    while (attach >= 0 && roles[attach] != BoneRole::Spine && roles[attach] != BoneRole::Pelvis &&
           roles[attach] != BoneRole::Neck && sk.bones[attach].parent >= 0)
      attach = sk.bones[attach].parent;
    attachDepth[b] = depth(attach);
  }
  // Limbs that hang from no trunk bone (IK or helper chains beside the body) are not the body's limbs.
  std::vector<int> body;
  for (int r : roots)
    if (attachDepth[r] > 0) body.push_back(r);
  if (!body.empty()) roots.swap(body);
  if (roots.empty()) return f;
  int shallow = attachDepth[roots[0]], deep = shallow;
  for (int r : roots) shallow = std::min(shallow, attachDepth[r]), deep = std::max(deep, attachDepth[r]);
  for (int b = 0; b < n; ++b) {
    if (rootOf[b] < 0 || std::find(roots.begin(), roots.end(), rootOf[b]) == roots.end()) continue;
    const int r = rootOf[b], girdle = sk.bones[r].parent;
    f.limb[b] = deep > shallow ? (attachDepth[r] == shallow ? 2 : 1)
                               : (girdle >= 0 && roles[girdle] == BoneRole::Shoulder ? 1 : 2);
  }
  Vec3 up = Vec3::Zero(), feet = Vec3::Zero(), centre = Vec3::Zero();
  double footLength = 0.0;
  for (int r : roots) centre += sk.bones[r].head;
  f.centre = centre / static_cast<double>(roots.size());
  for (int r : roots) {
    if (f.limb[r] != 2) continue;
    int last = r;  // down the chain through its longest limb continuation
    for (bool more = true; more;) {
      more = false;
      for (int c : sk.children(last))
        if (isLimb(c)) {
          last = c, more = true;
          break;
        }
    }
    up += sk.bones[r].head - sk.bones[last].tail;
    for (int c : sk.children(last)) {
      feet += sk.bones[c].tail - sk.bones[c].head;
      footLength += sk.bones[c].length();
    }
  }
  if (!(up.norm() > 0)) return f;
  f.up = up.normalized();
  Vec3 forward = across(feet, f.up);
  if (!(footLength > 0) || forward.norm() < 0.3 * footLength) {  // hooves point down: the neck leans forward
    Vec3 neck = Vec3::Zero();
    double neckLength = 0.0;
    for (int b = 0; b < n; ++b)
      if (roles[b] == BoneRole::Neck) neck += sk.bones[b].tail - sk.bones[b].head, neckLength += sk.bones[b].length();
    forward = across(neck, f.up);
    if (!(neckLength > 0) || forward.norm() < 0.3 * neckLength) return f;
  }
  f.forward = forward.normalized();
  f.left = f.up.cross(f.forward);
  f.sided = roots.size() >= 2;
  // Left-right from the limbs, which mirror each other where the feet or the neck may turn (the horse's neck leans
  // 1 degree sideways): each limb root's offset from the centre, counted towards its side, sums to the mirror normal.
  Vec3 side = Vec3::Zero();
  for (int r : roots) {
    const Vec3 d = sk.bones[r].head - f.centre;
    side += d.dot(f.left) >= 0.0 ? d : Vec3(-d);
  }
  side -= side.dot(f.up) * f.up;
  if (f.sided && side.norm() > 0.0 && side.normalized().dot(f.left) > 0.9) {
    f.left = side.normalized();
    f.up = (f.up - f.up.dot(f.left) * f.left).normalized();
    f.forward = f.left.cross(f.up);
  }
  f.valid = true;
  return f;
}

std::string anatomicalName(const Muscle& muscle, int bone, const std::string& family, const Skeleton& sk,
                           const BodyFrame& frame) {
  if (!frame.valid || muscle.sections.empty() || bone < 0 || bone >= sk.numBones()) return "";
  const Vec3 p = muscle.sections[muscle.sections.size() / 2].center;
  const double lateral = (p - frame.centre).dot(frame.left);
  const std::string side = sideOf(muscle, frame);
  const Bone& b = sk.bones[bone];
  if (family == "shoulder") {
    // Round the shoulder: in front of the girdle bone and medial of its middle, the pectoral's clavicular part;
    // else the deltoid capping the joint.
    const Vec3 out = p - closestOnSegment(p, b.head, b.tail);
    const double medial = std::abs((0.5 * (b.head + b.tail) - frame.centre).dot(frame.left)) - std::abs(lateral);
    const bool chest = out.dot(frame.forward) > 0.0 && medial > 0.0;
    return (chest ? "pectoral" : "deltoid") + side;
  }
  if (family == "limb") {
    const Vec3 axis = (b.tail - b.head).normalized();
    const Vec3 out = across(p - closestOnSegment(p, b.head, b.tail), axis), ahead = across(frame.forward, axis);
    if (out.norm() < 1e-12 || ahead.norm() < 0.5) return "";  // the bone points forward: no front or back
    const double c = out.normalized().dot(ahead.normalized());
    const int front = c > 0.5 ? 1 : c < -0.5 ? -1 : 0;
    const int limb = frame.limb[bone], segment = frame.segment[bone];
    if (front == 0 || segment > 1) return "";
    if (limb == 1 && segment == 0) return (front > 0 ? "biceps" : "triceps") + side;
    if (limb == 2 && segment == 0) return (front > 0 ? "quadriceps" : "hamstrings") + side;
    if (limb == 2 && segment == 1) return (front > 0 ? "tibialis_anterior" : "calf") + side;
    return "";  // forearms: which side is the flexors' depends on the hand's turn
  }
  if (family == "abdomen") {
    // The trunk between the legs' and the arms' roots: in front, pectorals in its upper 40 %, abdominals below;
    // behind, the back.
    Vec3 arms = Vec3::Zero(), legs = Vec3::Zero();
    int na = 0, nl = 0;
    for (int x = 0; x < sk.numBones(); ++x) {
      if (frame.limb[x] == 0 || frame.segment[x] != 0 ||
          (sk.bones[x].parent >= 0 && frame.segment[sk.bones[x].parent] == 0))
        continue;
      (frame.limb[x] == 1 ? arms : legs) += sk.bones[x].head;
      (frame.limb[x] == 1 ? na : nl) += 1;
    }
    const Vec3 out = across(p - frame.centre, frame.up);
    if (na == 0 || nl == 0 || out.norm() < 1e-12) return "";
    const Vec3 rise = arms / na - legs / nl;  // from the hips to the shoulders
    // Only an upright trunk (a quadruped's runs along its forward axis: its front is its underside).
    if (!(rise.dot(frame.up) > std::abs(rise.dot(frame.forward)))) return "";
    const double c = out.normalized().dot(frame.forward);
    const double height = (p - legs / nl).dot(frame.up) / rise.dot(frame.up);
    if (height < 0.0 || height > 1.0) return "";  // below the hips or above the shoulders
    if (c < -0.5) return "back" + side;
    if (c > 0.5) return (height > 0.6 ? "pectoral" : "abdominal") + side;
    return "";
  }
  return "";
}


std::string regionName(const Muscle& muscle, int bone, const std::string& family, const Skeleton& sk,
                       const BodyFrame& frame) {
  if (!frame.valid || muscle.sections.empty() || bone < 0 || bone >= sk.numBones()) return "";
  const Vec3 p = muscle.sections[muscle.sections.size() / 2].center;
  if (!p.allFinite()) return "";
  const std::string side = sideOf(muscle, frame);
  const double lateral = (p - frame.centre).dot(frame.left);
  const Bone& b = sk.bones[bone];
  const Vec3 axis = (b.tail - b.head).normalized();
  const Vec3 out = across(p - closestOnSegment(p, b.head, b.tail), axis);
  if (!axis.allFinite() || !out.allFinite() || out.norm() < 1e-12) return "";
  std::string region;
  if (family == "limb" || family == "shoulder") {
    static const char* arm[] = {"upper_arm", "forearm", "hand"};
    static const char* leg[] = {"thigh", "shin", "foot"};
    const int limb = frame.limb[bone], segment = std::min(frame.segment[bone], 2);
    if (family == "shoulder")
      region = "shoulder";
    else if (limb == 0 || segment < 0)
      return "";
    else
      region = (limb == 1 ? arm : leg)[segment];
  } else if (family == "neck") {
    region = "neck";
  } else if (family == "abdomen") {
    // The trunk: its side faces are the flanks; front and back of an upright trunk are the chest and the back, a
    // horizontal one's top and bottom its back and belly.
    const std::string facing = facingName(out, axis, frame, lateral);
    if (facing == "outer" || facing == "inner") return "flank" + side;
    if (facing == "front" || facing == "bottom") return (facing == "front" ? "chest" : "belly") + side;
    return "back" + side;
  } else {
    return "";
  }
  return region + "_" + facingName(out, axis, frame, lateral) + side;
}

Vec3 mirrored(const Vec3& p, const BodyFrame& frame) {
  return p - 2.0 * (p - frame.centre).dot(frame.left) * frame.left;
}

std::vector<int> mirrorTwins(const std::vector<const Muscle*>& muscles, const std::vector<std::string>& family,
                             const BodyFrame& frame) {
  const int n = static_cast<int>(muscles.size());
  std::vector<int> twin(n, -1);
  if (!frame.valid || !frame.sided || static_cast<int>(family.size()) != n) return twin;
  std::vector<Vec3> centre(n, Vec3::Zero());
  std::vector<double> reach(n, 0.0);
  for (int i = 0; i < n; ++i) {
    const std::vector<MuscleSection>& s = muscles[i]->sections;
    for (const MuscleSection& x : s) centre[i] += x.center, reach[i] += x.a;
    if (!s.empty()) centre[i] /= static_cast<double>(s.size()), reach[i] /= static_cast<double>(s.size());
  }
  auto lateral = [&](int i) { return (centre[i] - frame.centre).dot(frame.left); };
  auto nearest = [&](int i) {
    int best = -1;
    double bestDistance = std::numeric_limits<double>::infinity();
    if (muscles[i]->sections.empty()) return best;
    for (int j = 0; j < n; ++j) {
      if (j == i || muscles[j]->sections.empty() || family[j] != family[i] || !(lateral(i) * lateral(j) < 0.0)) continue;
      const double d = (mirrored(centre[j], frame) - centre[i]).norm();
      if (d < std::max(reach[i], reach[j]) && d < bestDistance) bestDistance = d, best = j;
    }
    return best;
  };
  std::vector<int> near(n);
  for (int i = 0; i < n; ++i) near[i] = nearest(i);
  for (int i = 0; i < n; ++i)
    if (near[i] >= 0 && near[near[i]] == i) twin[i] = near[i];
  return twin;
}

Muscle symmetrisedForNaming(const Muscle& muscle, const Muscle& twin, const BodyFrame& frame) {
  Muscle m;
  m.sections = muscle.sections;
  if (m.sections.empty() || twin.sections.empty()) return m;
  Vec3& p = m.sections[m.sections.size() / 2].center;
  p = 0.5 * (p + mirrored(twin.sections[twin.sections.size() / 2].center, frame));
  return m;
}

}  // namespace myoskin::detail
