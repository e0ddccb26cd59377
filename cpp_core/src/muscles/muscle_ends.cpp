// Stage 6: the root curve through the section centres, extended at both ends with cubic Hermite curves
// (tangent continuous) to the default origin and insertion: the nearest bone point to the straight
// extension of the root curve (paper, "Muscle Deformation").
#include <algorithm>
#include <cmath>

#include "muscles/muscle_util.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/muscle_shape.h"

namespace myoskin {

Vec3 hermite(const Vec3& p0, const Vec3& m0, const Vec3& p1, const Vec3& m1, double t) {
  const double t2 = t * t, t3 = t2 * t;
  return (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1;
}

namespace {

struct EndPoint {
  int bone = -1;
  Vec3 position = Vec3::Zero();
};

// Nearest bone point to the extension end + s * dir, s in [0, maxLength]; candidates = bones.
// Near-ties (within tol of the minimum distance) prefer the sample further out.
EndPoint findExtremity(const Vec3& end, const Vec3& dir, double maxLength, const std::vector<int>& bones,
                       const Skeleton& skeleton, double tol) {
  const int samples = 48;
  std::vector<double> dist(samples + 1, INFINITY);
  std::vector<EndPoint> at(samples + 1);
  double dmin = INFINITY;
  for (int k = 0; k <= samples; ++k) {
    const Vec3 q = end + (maxLength * k / samples) * dir;
    for (int b : bones) {
      const Bone& bone = skeleton.bones[b];
      const Vec3 c = detail::closestOnSegment(q, bone.head, bone.tail);
      const double d = (q - c).norm();
      if (d < dist[k]) dist[k] = d, at[k] = EndPoint{b, c};
    }
    dmin = std::min(dmin, dist[k]);
  }
  for (int k = samples; k >= 0; --k)
    if (dist[k] <= dmin + tol) return at[k];
  return at[0];
}

// Root curve: origin, Hermite (tangent at the first centre = the first chord), centres, Hermite, insertion;
// section u by arc length over the full curve. first/last: unit directions at the first/last centre.
void rebuildRootCurve(Muscle& m, const Vec3& origin, const Vec3& insertion, const Vec3& first, const Vec3& last,
                      const EndOptions& options) {
  const int n = static_cast<int>(m.sections.size());
  std::vector<Vec3> centers(n);
  for (int i = 0; i < n; ++i) centers[i] = m.sections[i].center;
  const int k = std::max(1, options.samplesPerEnd);
  std::vector<Vec3> curve;
  std::vector<int> centerIndex(n);
  {
    const double L = (centers[0] - origin).norm();
    const Vec3 m0 = L > 1e-12 ? Vec3((centers[0] - origin)) : Vec3(L * first);
    const Vec3 m1 = L * first;
    curve.push_back(origin);
    for (int j = 1; j < k; ++j) curve.push_back(hermite(origin, m0, centers[0], m1, double(j) / k));
  }
  for (int i = 0; i < n; ++i) {
    centerIndex[i] = static_cast<int>(curve.size());
    curve.push_back(centers[i]);
  }
  {
    const double L = (insertion - centers[n - 1]).norm();
    const Vec3 m0 = L * last;
    const Vec3 m1 = L > 1e-12 ? Vec3(insertion - centers[n - 1]) : Vec3(L * last);
    for (int j = 1; j < k; ++j) curve.push_back(hermite(centers[n - 1], m0, insertion, m1, double(j) / k));
    curve.push_back(insertion);
  }
  std::vector<double> arc(curve.size(), 0.0);
  for (size_t i = 1; i < curve.size(); ++i) arc[i] = arc[i - 1] + (curve[i] - curve[i - 1]).norm();
  const double total = arc.back();
  for (int i = 0; i < n; ++i)
    m.sections[i].u = total > 1e-12 ? std::clamp(-1.0 + 2.0 * arc[centerIndex[i]] / total, -1.0, 1.0) : 0.0;
  // Strictly increasing u (coincident centres would repeat a value).
  for (int i = 1; i < n; ++i)
    if (m.sections[i].u <= m.sections[i - 1].u) m.sections[i].u = std::min(1.0, m.sections[i - 1].u + 1e-9);
  m.rootCurve = std::move(curve);
}

}  // namespace

namespace {

// The joint wrap of a muscle from `o` to `e` when they lie on different bones of one chain: a sphere of radius
// `radius` (at most 0.8 of either end's distance) on the crossed joint farthest from the straight line O-I.
// No wrap (type None) when the bones are the same or unrelated, or the sphere would be under a millimetre.
MuscleWrap defaultJointWrap(const EndPoint& o, const EndPoint& e, double radius, const Skeleton& skeleton) {
  MuscleWrap wrap;
  auto crossed = [&](int ancestor, int descendant) {  // heads of the bones below `ancestor` down to `descendant`
    std::vector<int> joints;
    for (int b = descendant; b >= 0; b = skeleton.bones[b].parent) {
      if (b == ancestor) return joints;
      joints.push_back(b);
    }
    return std::vector<int>{};
  };
  if (o.bone == e.bone) return wrap;
  std::vector<int> joints = crossed(o.bone, e.bone);
  if (joints.empty()) joints = crossed(e.bone, o.bone);
  int best = -1;
  double bestDistance = -1.0;
  for (int j : joints) {
    const Vec3& J = skeleton.bones[j].head;
    const double d = (J - detail::closestOnSegment(J, o.position, e.position)).norm();
    if (d > bestDistance + 1e-9) best = j, bestDistance = d;
  }
  if (best < 0) return wrap;
  const Vec3& J = skeleton.bones[best].head;
  const double r = std::min(radius, 0.8 * std::min((o.position - J).norm(), (e.position - J).norm()));
  if (!(r >= 0.001)) return wrap;
  wrap.type = WrapType::Joint;
  wrap.bone = skeleton.bones[best].name;
  wrap.radius = r;
  return wrap;
}

// A bone, its parent and its children.
std::vector<int> boneAndNeighbours(const Skeleton& skeleton, int bone) {
  std::vector<int> bones{bone};
  if (skeleton.bones[bone].parent >= 0) bones.push_back(skeleton.bones[bone].parent);
  for (int c : skeleton.children(bone)) bones.push_back(c);
  return bones;
}

// The muscle with its ends on the nearest points of the candidate bones (originBones, insertionBones).
Muscle buildEnds(const std::vector<MuscleSection>& input, const std::vector<int>& originBones,
                 const std::vector<int>& insertionBones, const Skeleton& skeleton, const EndOptions& options) {
  if (input.empty()) throw InputError("buildMuscleEnds: a muscle needs at least one section");
  Muscle m;
  m.sections = input;
  const int n = static_cast<int>(m.sections.size());
  std::vector<Vec3> centers(n);
  for (int i = 0; i < n; ++i) centers[i] = m.sections[i].center;

  // Directions along the curve (origin -> insertion); normals oriented the same way.
  Vec3 first = n > 1 ? (centers[1] - centers[0]) : input[0].normal;
  Vec3 last = n > 1 ? (centers[n - 1] - centers[n - 2]) : input[0].normal;
  if (first.norm() < 1e-12) first = input[0].normal;
  if (last.norm() < 1e-12) last = input[n - 1].normal;
  first.normalize();
  last.normalize();
  for (int i = 0; i < n; ++i) {
    MuscleSection& s = m.sections[i];
    Vec3 along = n > 1 ? centers[std::min(i + 1, n - 1)] - centers[std::max(i - 1, 0)] : first;
    if (along.norm() < 1e-12) along = first;
    s.normal.normalize();
    if (s.normal.dot(along) < 0) s.normal = -s.normal;
    s.axisA = detail::perpendicularTo(s.axisA, s.normal);
  }

  double meanB = 0;
  for (const MuscleSection& s : m.sections) meanB += s.b;
  meanB /= n;
  const double visible = detail::polylineLength(centers);
  const double maxLen = std::max(options.maxExtensionFraction * visible, 2.0 * meanB);
  const EndPoint o = findExtremity(centers[0], -first, maxLen, originBones, skeleton, options.tieTolerance);
  const EndPoint e = findExtremity(centers[n - 1], last, maxLen, insertionBones, skeleton, options.tieTolerance);
  m.origin = MuscleAttachment{skeleton.bones[o.bone].name, o.position};
  m.insertion = MuscleAttachment{skeleton.bones[e.bone].name, e.position};
  if (options.jointWrapFraction > 0) m.wrap = defaultJointWrap(o, e, meanB * options.jointWrapFraction, skeleton);

  rebuildRootCurve(m, o.position, e.position, first, last, options);
  return m;
}

}  // namespace

Muscle buildMuscleEnds(const std::vector<MuscleSection>& input, int bone, const Skeleton& skeleton,
                       const EndOptions& options) {
  if (bone < 0 || bone >= skeleton.numBones()) throw InputError("buildMuscleEnds: bad bone index");
  const std::vector<int> bones = boneAndNeighbours(skeleton, bone);  // the muscle's bone, its parent, its children
  return buildEnds(input, bones, bones, skeleton, options);
}

Muscle buildMuscleEnds(const MuscleChain& chain, const std::vector<SectionBumps>& sections, const Skeleton& skeleton,
                       const EndOptions& options) {
  std::vector<MuscleSection> s;
  s.reserve(chain.links.size());
  for (const ChainLink& l : chain.links) {
    const CuttingPlane& p = sections[l.section].plane;
    MuscleSection ms;
    ms.center = planePoint(p, l.ellipse.center);
    ms.axisA = (std::cos(l.ellipse.angle) * p.xAxis + std::sin(l.ellipse.angle) * p.yAxis).normalized();
    ms.a = std::max(l.ellipse.a, l.ellipse.b);
    ms.b = std::min(l.ellipse.a, l.ellipse.b);
    if (l.ellipse.b > l.ellipse.a) ms.axisA = p.normal.normalized().cross(ms.axisA).normalized();
    ms.normal = p.normal.normalized();
    s.push_back(ms);
  }
  if (s.empty()) throw InputError("buildMuscleEnds: a muscle needs at least one section");
  if (chain.bone < 0 || chain.bone >= skeleton.numBones()) throw InputError("buildMuscleEnds: bad bone index");
  if (!detail::trunkFamily(chain.family)) return buildMuscleEnds(s, chain.bone, skeleton, options);
  // A trunk chain climbs past several spine bones: each end attaches near its own end section's bone.
  std::vector<int> originBones = boneAndNeighbours(skeleton, chain.bone),
                   insertionBones = boneAndNeighbours(skeleton, chain.bone);
  for (int b : boneAndNeighbours(skeleton, sections[chain.links.front().section].plane.bone)) originBones.push_back(b);
  for (int b : boneAndNeighbours(skeleton, sections[chain.links.back().section].plane.bone)) insertionBones.push_back(b);
  // No default joint wrap: a trunk muscle's ends span spine joints the trunk bends through smoothly.
  EndOptions trunk = options;
  trunk.jointWrapFraction = 0.0;
  return buildEnds(s, originBones, insertionBones, skeleton, trunk);
}


// ============================================================================
// Re-attachment after the user moved an origin or insertion (locators)
// ============================================================================

// ============================================================================
// Spanning real joints
// ============================================================================

void reattachEnds(Muscle& muscle, const EndOptions& options);

namespace {

// The child across b's tail with the most bone length below it (-1: none).
int continuationBone(const Skeleton& skeleton, int b) {
  int best = -1;
  double bestLength = -1.0;
  for (int c : skeleton.children(b)) {
    if ((skeleton.bones[c].head - skeleton.bones[b].tail).norm() > 0.1 * skeleton.bones[b].length()) continue;
    double length = 0.0;
    std::vector<int> stack{c};
    while (!stack.empty()) {
      const int x = stack.back();
      stack.pop_back();
      length += skeleton.bones[x].length();
      for (int g : skeleton.children(x)) stack.push_back(g);
    }
    if (length > bestLength) best = c, bestLength = length;
  }
  return best;
}

// After an end moved: the default joint wrap for the new ends, then the root curve's ends rebuilt.
void rewrapAndReattach(Muscle& muscle, const Skeleton& skeleton, const EndOptions& options) {
  double meanB = 0;
  for (const MuscleSection& sec : muscle.sections) meanB += sec.b;
  meanB /= static_cast<double>(muscle.sections.size());
  const EndPoint op{skeleton.find(muscle.origin.bone), muscle.origin.position};
  const EndPoint ep{skeleton.find(muscle.insertion.bone), muscle.insertion.position};
  muscle.wrap = options.jointWrapFraction > 0 ? defaultJointWrap(op, ep, meanB * options.jointWrapFraction, skeleton)
                                              : MuscleWrap{};
  reattachEnds(muscle, options);
}

}  // namespace

void spanRealJoint(Muscle& muscle, const Skeleton& skeleton, const std::vector<char>& twist, const EndOptions& options) {
  if (!(options.spanCarry > 0) || muscle.sections.empty()) return;
  const int o = skeleton.find(muscle.origin.bone), e = skeleton.find(muscle.insertion.bone);
  if (o < 0 || e < 0 || static_cast<int>(twist.size()) != skeleton.numBones()) return;
  auto segmentRoot = [&](int b) {
    while (twist[b] && skeleton.bones[b].parent >= 0) b = skeleton.bones[b].parent;
    return b;
  };
  auto continuation = [&](int b) { return continuationBone(skeleton, b); };
  const int root = segmentRoot(o);
  if (segmentRoot(e) != root) {  // already across a real joint: the end beyond it attaches near it
    const int distal = segmentRoot(e), above = skeleton.bones[distal].parent;
    if (above < 0 || segmentRoot(above) != root) return;  // only an insertion one real joint below the origin
    const Vec3 J = skeleton.bones[distal].head;
    const Vec3 belly = muscle.sections[muscle.sections.size() / 2].center;
    const Bone& down = skeleton.bones[distal];
    const Bone& up = skeleton.bones[above];
    const bool bellyBelow = (belly - J).dot((down.tail - down.head).normalized()) > 0;
    bool moved = false;
    if (bellyBelow && up.length() > 0) {  // the origin lies above the joint: at most spanCarry of its bone
      const double carry = options.spanCarry * up.length();
      if ((muscle.origin.position - J).norm() > carry) {
        muscle.origin = MuscleAttachment{up.name, J - carry * (up.tail - up.head).normalized()};
        moved = true;
      }
    } else if (!bellyBelow && down.length() > 0) {  // the insertion lies below it
      const double carry = options.spanCarry * down.length();
      if ((muscle.insertion.position - J).norm() > carry) {
        muscle.insertion = MuscleAttachment{down.name, J + carry * (down.tail - down.head).normalized()};
        moved = true;
      }
    }
    if (moved) rewrapAndReattach(muscle, skeleton, options);
    return;
  }
  int last = root;  // the segment's last bone, through its twist children
  for (int next = continuation(last); next >= 0 && twist[next]; next = continuation(last)) last = next;
  if (last == root) return;  // one bone: the end search already reached across its joints (boneAndNeighbours)
  const Vec3 proximal = skeleton.bones[root].head, distal = skeleton.bones[last].tail;
  const int below = continuation(last), above = skeleton.bones[root].parent;
  const bool toDistal = below >= 0 && (above < 0 || (muscle.insertion.position - distal).norm() <=
                                                          (muscle.origin.position - proximal).norm());
  if (toDistal) {
    const Bone& b = skeleton.bones[below];
    const double carry = options.spanCarry * b.length();
    muscle.insertion = MuscleAttachment{b.name, b.head + carry * (b.tail - b.head).normalized()};
  } else if (above >= 0) {
    const Bone& b = skeleton.bones[above];
    const double carry = std::min(options.spanCarry * (skeleton.bones[root].tail - proximal).norm(), b.length());
    muscle.origin = MuscleAttachment{b.name, b.tail - carry * (b.tail - b.head).normalized()};
  } else {
    return;
  }
  rewrapAndReattach(muscle, skeleton, options);
}

// A limb muscle whose distal end lies on its belly's segment, the limb's last, ending in a foot: that end carried
// over the ankle onto the foot, on the belly's side of the joint (the calf's tendon onto the heel).
void spanDistalJoint(Muscle& muscle, const Skeleton& skeleton, const std::vector<char>& twist,
                     const std::vector<BoneRole>& roles, int bellyBone, const EndOptions& options,
                     const SkinWinding* skin) {
  if (!options.spanDistal || !(options.spanCarry > 0) || muscle.sections.empty()) return;
  const int n = skeleton.numBones();
  const int o = skeleton.find(muscle.origin.bone), e = skeleton.find(muscle.insertion.bone);
  if (o < 0 || e < 0 || bellyBone < 0 || bellyBone >= n || static_cast<int>(twist.size()) != n ||
      static_cast<int>(roles.size()) != n)
    return;
  auto segmentRoot = [&](int b) {
    while (twist[b] && skeleton.bones[b].parent >= 0) b = skeleton.bones[b].parent;
    return b;
  };
  const int root = segmentRoot(bellyBone);
  int last = root;  // the segment's last bone, through its twist children
  for (int next = continuationBone(skeleton, last); next >= 0 && twist[next]; next = continuationBone(skeleton, last))
    last = next;
  const int below = continuationBone(skeleton, last);
  // Only over the limb's last real joint (ankle, wrist): the next bone is its extremity, no limb bone of the role
  // map; a muscle on an inner segment keeps to the joint the end search and spanRealJoint gave it.
  if (below < 0 || roles[below] == BoneRole::Limb) return;
  // A foot, not a hand: the extremity turns across the limb (more than 45 degrees from the segment's axis), a lever
  // whose heel the tendon reaches; a hand continues its forearm (MakeHuman 13 degrees against the foot's 73).
  // Carrying the forearm's muscles onto the hand moved their end taper down the forearm and cost MakeHuman's
  // elbow 1.4 points of band volume and 13 crossing pairs at 120 degrees; the wrist has no measured case yet.
  const Vec3 P = skeleton.bones[root].head, J = skeleton.bones[below].head;
  const Vec3 d = J - P;
  const Bone& extremity = skeleton.bones[below];
  if (!(d.norm() > 0) || !(extremity.length() > 0)) return;
  const Vec3 axis = d.normalized();
  if ((extremity.tail - extremity.head).normalized().dot(axis) > std::cos(M_PI / 4)) return;
  // The end nearer the distal joint must lie on the belly's segment (the other end on it or above it).
  const bool insertionDistal = (muscle.insertion.position - J).norm() <= (muscle.origin.position - J).norm();
  const int distalBone = insertionDistal ? e : o;
  if (segmentRoot(distalBone) != root) return;  // already across the distal joint (or elsewhere)
  // The belly's side: the end section's offset from the segment's axis, kept at the joint (the tendon runs on past
  // the joint along the limb, as the Achilles tendon behind the ankle), spanCarry of the next bone beyond it.
  const MuscleSection& end = insertionDistal ? muscle.sections.back() : muscle.sections.front();
  const Vec3 rel = end.center - P;
  Vec3 offset = rel - rel.dot(axis) * axis;
  const Bone& next = skeleton.bones[below];
  const Vec3 past = options.spanCarry * next.length() * axis;  // from the joint along the segment
  Vec3 step = past + offset;
  if (skin) {  // the joint is thinner than the belly: the end keeps 0.1 of the end section's b inside the skin, the
               // offset shrinking by eighths, spanCarry past the joint, else at the joint's level (a thin heel)
    const double depth = 0.0;
    bool found = false;
    for (int level = 0; level < 2 && !found; ++level)
      for (int k = 8; k >= 0 && !found; --k) {
        const Vec3 candidate = (level == 0 ? past : Vec3::Zero()) + (k / 8.0) * offset;
        const Vec3 p = J + candidate;
        if (skin->inside(p) && skin->distance(p) >= depth) step = candidate, offset *= k / 8.0, found = true;
      }
    if (!found) step = past, offset = Vec3::Zero();
  }
  const MuscleAttachment carried{next.name, J + step};
  (insertionDistal ? muscle.insertion : muscle.origin) = carried;
  // The tendon keeps the belly's offset over the joint (as a retinaculum holds it): a muscle without a wrap gets a
  // joint wrap of that radius there, so bending the joint away from the belly (plantar flexion for the tibialis
  // anterior) carries its line round the joint instead of through it; a wrap the muscle already has (on the joint
  // it spanned before, the calf's knee) stays.
  if (muscle.wrap.type == WrapType::None && options.jointWrapFraction > 0) {  // 0: straight lines, as asked
    const Vec3& other = insertionDistal ? muscle.origin.position : muscle.insertion.position;
    const double r = std::min(offset.norm(), 0.8 * std::min((other - J).norm(), (carried.position - J).norm()));
    if (r > 0.01 * d.norm()) {
      muscle.wrap = MuscleWrap{};
      muscle.wrap.type = WrapType::Joint;
      muscle.wrap.bone = next.name;
      muscle.wrap.radius = r;
    }
  }
  reattachEnds(muscle, options);
}

void reattachMuscle(Muscle& muscle, const EndOptions& options, const SurfaceOptions& surface) {
  reattachEnds(muscle, options);
  muscle.surface = loftMuscleSurface(muscle, surface);
}

// The root curve's Hermite ends rebuilt to the muscle's (moved) origin and insertion; section u by arc length.
void reattachEnds(Muscle& muscle, const EndOptions& options) {
  const int n = static_cast<int>(muscle.sections.size());
  if (n == 0) throw InputError("muscle '" + muscle.name + "': no sections to re-attach");
  if (!muscle.origin.position.allFinite() || !muscle.insertion.position.allFinite())
    throw InputError("muscle '" + muscle.name + "': origin or insertion is not finite");
  Vec3 first = n > 1 ? Vec3(muscle.sections[1].center - muscle.sections[0].center) : muscle.sections[0].normal;
  Vec3 last = n > 1 ? Vec3(muscle.sections[n - 1].center - muscle.sections[n - 2].center)
                    : muscle.sections[n - 1].normal;
  if (first.norm() < 1e-12) first = muscle.sections[0].normal;
  if (last.norm() < 1e-12) last = muscle.sections[n - 1].normal;
  rebuildRootCurve(muscle, muscle.origin.position, muscle.insertion.position, first.normalized(), last.normalized(),
                   options);
}

}  // namespace myoskin
