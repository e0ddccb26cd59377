// Bone roles for extraction: the shape of the bone tree (limb pairs, girdles, trunk, neck), name heuristics for
// Rigify, MakeHuman and Mixamo rigs where names say something, caller overrides first.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/sections.h"

namespace myoskin {

namespace {

// ============================================================================
// Names
// ============================================================================

// Lower case without the usual rig prefixes (mixamorig:, DEF-, ORG-).
std::string normalisedName(const std::string& name) {
  std::string s = name;
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* prefix : {"mixamorig:", "mixamorig_", "def-", "org-", "def_"})
    if (s.rfind(prefix, 0) == 0) s = s.substr(std::string(prefix).size());
  return s;
}

bool containsAny(const std::string& s, std::initializer_list<const char*> words) {
  for (const char* w : words)
    if (s.find(w) != std::string::npos) return true;
  return false;
}

// Role from the name alone; `known` is false when the name says nothing.
BoneRole roleFromName(const std::string& raw, bool& known) {
  const std::string s = normalisedName(raw);
  known = true;
  if (containsAny(s, {"finger", "thumb", "index", "middle", "ring", "pinky", "f_", "toe", "metacarpal", "hand", "foot",
                      "wrist", "heel", "head", "eye", "jaw", "tongue", "oris", "levator", "special", "orbicularis",
                      "oculi", "temporalis", "risorius", "breast", "twist", "root", "pole", "target"}))
    return BoneRole::Ignore;
  if (containsAny(s, {"clavicle", "shoulder", "collar"})) return BoneRole::Shoulder;
  if (containsAny(s, {"upperarm", "upper_arm", "forearm", "lowerarm", "lower_arm", "arm", "thigh", "upperleg",
                      "upper_leg", "upleg", "shin", "calf", "lowerleg", "lower_leg", "leg", "knee", "elbow"}))
    return BoneRole::Limb;
  if (containsAny(s, {"neck"})) return BoneRole::Neck;
  if (containsAny(s, {"pelvis", "hips", "hip"})) return BoneRole::Pelvis;
  if (containsAny(s, {"spine", "chest", "torso", "abdomen", "belly", "back"})) return BoneRole::Spine;
  known = false;
  return BoneRole::Ignore;
}

// ============================================================================
// The bone tree
// ============================================================================

// What the shape of the bone tree says, for bones whose names say nothing: left/right limb pairs (sibling subtrees
// that mirror each other, long against the body's other pairs), each limb's girdle, long segments and extremity,
// the trunk between the limbs' attachments, the neck beyond the top one. Ignore for everything else.
class TreeRoles {
 public:
  // twist: per bone, 1 when its joint with its parent is a twist split (twistSplits); null = judged by collinearity.
  TreeRoles(const Skeleton& sk, const std::vector<char>* twist)
      : sk_(sk), twist_(twist), n_(sk.numBones()), kids_(n_), subtree_(n_, 0.0), count_(n_, 1) {
    for (int i = 0; i < n_; ++i)
      if (sk.bones[i].parent >= 0) kids_[sk.bones[i].parent].push_back(i);
    for (int i = n_ - 1; i >= 0; --i) {  // parents come before children
      subtree_[i] += sk.bones[i].length();
      const int p = sk.bones[i].parent;
      if (p >= 0) subtree_[p] += subtree_[i], count_[p] += count_[i];
    }
  }

  std::vector<BoneRole> classify() const {
    std::vector<BoneRole> roles(n_, BoneRole::Ignore);
    const std::vector<std::pair<int, int>> pairs = limbPairs();
    std::vector<int> attachments;
    for (const auto& [a, b] : pairs) {
      const std::vector<int> ca = mainChain(a), cb = mainChain(b);
      classifyLimb(a, roles, &cb);  // each side judged with its mirror: the same roles on both
      classifyLimb(b, roles, &ca);
      if (sk_.bones[a].parent >= 0) attachments.push_back(sk_.bones[a].parent);
    }
    if (pairs.empty()) {  // one limb on its own (an arm, a leg): the longest chain from the largest root
      int root = -1;
      for (int i = 0; i < n_; ++i)
        if (sk_.bones[i].parent < 0 && (root < 0 || subtree_[i] > subtree_[root])) root = i;
      if (root >= 0) classifyLimb(root, roles);
      return roles;
    }
    // The trunk: every bone on the paths between the attachments; the root-most attachment is the pelvis end.
    std::sort(attachments.begin(), attachments.end());
    attachments.erase(std::unique(attachments.begin(), attachments.end()), attachments.end());
    std::vector<char> trunk(n_, 0);
    for (int a : attachments)
      for (int b : attachments) markPath(a, b, trunk);
    int bottom = attachments[0], top = attachments[0];
    for (int a : attachments) {
      if (depth(a) < depth(bottom)) bottom = a;
      if (depth(a) > depth(top)) top = a;
    }
    for (int i = 0; i < n_; ++i)
      if (trunk[i] && roles[i] == BoneRole::Ignore) roles[i] = BoneRole::Spine;
    if (attachments.size() > 1) roles[bottom] = BoneRole::Pelvis;
    // The neck: beyond the top attachment, its largest branch that is neither limb nor trunk, up to the head (the
    // first bone that branches or ends).
    int neck = -1;
    for (int c : kids_[top])
      if (!trunk[c] && roles[c] == BoneRole::Ignore && (neck < 0 || subtree_[c] > subtree_[neck])) neck = c;
    for (int b = neck; b >= 0 && kids_[b].size() == 1 && attachments.size() > 1; b = kids_[b][0])
      roles[b] = BoneRole::Neck;
    return roles;
  }

 private:
  const Skeleton& sk_;
  const std::vector<char>* twist_;
  int n_;
  std::vector<std::vector<int>> kids_;
  std::vector<double> subtree_;  // total bone length of each subtree
  std::vector<int> count_;       // bones in each subtree

  int depth(int b) const {
    int d = 0;
    for (; sk_.bones[b].parent >= 0; b = sk_.bones[b].parent) ++d;
    return d;
  }

  void markPath(int a, int b, std::vector<char>& mark) const {
    std::vector<char> up(n_, 0);
    for (int x = a; x >= 0; x = sk_.bones[x].parent) up[x] = 1;
    int lca = b;
    while (lca >= 0 && !up[lca]) lca = sk_.bones[lca].parent;
    if (lca < 0) return;
    for (int x = a; x != lca; x = sk_.bones[x].parent) mark[x] = 1;
    for (int x = b; x != lca; x = sk_.bones[x].parent) mark[x] = 1;
    mark[lca] = 1;
  }

  // From `b` down through the child with the largest subtree, to a leaf.
  std::vector<int> mainChain(int b) const {
    std::vector<int> chain{b};
    while (!kids_[chain.back()].empty()) {
      int next = kids_[chain.back()][0];
      for (int c : kids_[chain.back()])
        if (subtree_[c] > subtree_[next]) next = c;
      chain.push_back(next);
    }
    return chain;
  }

  double chainLength(const std::vector<int>& chain) const {
    double s = 0.0;
    for (int b : chain) s += sk_.bones[b].length();
    return s;
  }

  // Sibling subtrees that mirror each other: as many bones, main chains of equal length, and each joint of one main
  // chain reflected through the bisector plane of the two first heads lands on the other's (within 15 % of its length).
  bool mirrored(int a, int b) const {
    if (!sk_.bones[a].deform || !sk_.bones[b].deform) return false;
    if (std::abs(count_[a] - count_[b]) > std::max(1, count_[a] / 10)) return false;
    const std::vector<int> ca = mainChain(a), cb = mainChain(b);
    const double la = chainLength(ca), lb = chainLength(cb);
    if (!(la > 0) || !(lb > 0) || std::min(la, lb) < 0.85 * std::max(la, lb)) return false;
    // The mirror plane bisects the first pair of chain joints that are apart (hip bones often share their head).
    Vec3 ha = sk_.bones[a].head, hb = sk_.bones[b].head;
    if ((hb - ha).norm() < 1e-3 * la) ha = sk_.bones[a].tail, hb = sk_.bones[b].tail;
    if ((hb - ha).norm() < 1e-3 * la) return false;
    const Vec3 normal = (hb - ha).normalized(), mid = 0.5 * (ha + hb);
    auto reflect = [&](const Vec3& p) { return Vec3(p - 2.0 * (p - mid).dot(normal) * normal); };
    const size_t m = std::min(ca.size(), cb.size());
    for (size_t k = 0; k < m; ++k)
      if ((reflect(sk_.bones[ca[k]].tail) - sk_.bones[cb[k]].tail).norm() > 0.15 * la) return false;
    return true;
  }

  // Limb pairs, outermost first: mirrored siblings whose main chains are at least 0.4 of the longest pair's (ears,
  // eyes, breasts and fingers are shorter), none inside another pair's subtree.
  std::vector<std::pair<int, int>> limbPairs() const {
    std::vector<std::pair<int, int>> pairs;
    std::vector<double> lengths;
    std::vector<char> taken(n_, 0);
    std::vector<std::vector<int>> groups(kids_);
    std::vector<int> roots;
    for (int i = 0; i < n_; ++i)
      if (sk_.bones[i].parent < 0) roots.push_back(i);
    groups.push_back(roots);
    for (const std::vector<int>& siblings : groups)
      for (size_t x = 0; x < siblings.size(); ++x)
        for (size_t y = x + 1; y < siblings.size(); ++y) {
          const int a = siblings[x], b = siblings[y];
          if (taken[a] || taken[b] || !mirrored(a, b)) continue;
          taken[a] = taken[b] = 1;
          pairs.emplace_back(a, b);
          lengths.push_back(chainLength(mainChain(a)));
        }
    double longest = 0.0;
    for (double l : lengths) longest = std::max(longest, l);
    std::vector<std::pair<int, int>> limbs;
    std::vector<char> inLimb(n_, 0);
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (lengths[k] < 0.4 * longest) continue;
      bool nested = false;
      for (int x = sk_.bones[pairs[k].first].parent; x >= 0 && !nested; x = sk_.bones[x].parent) nested = inLimb[x];
      if (nested) continue;
      limbs.push_back(pairs[k]);
      for (int side : {pairs[k].first, pairs[k].second}) {
        std::vector<int> stack{side};
        while (!stack.empty()) {
          const int b = stack.back();
          stack.pop_back();
          inLimb[b] = 1;
          for (int c : kids_[b]) stack.push_back(c);
        }
      }
    }
    std::sort(limbs.begin(), limbs.end());
    return limbs;
  }

  // One limb along its main chain: segments of nearly collinear bones (twist splits join); a first segment shorter
  // than 0.6 of the longest is its girdle (Shoulder: clavicle, hip bone), then Limb up to the longest segment and on while
  // segments reach 0.4 of it; the first shorter one after it, or a bone with three or more children (hand, foot), and
  // everything after is Ignore. With the mirrored limb's main chain (`mate`), a joint counts as a twist split only
  // when the mirrored joint is one too (twist splits come from each side's own skin weights, which a mesh that is not
  // exactly symmetric makes differ), so mirrored limbs get the same roles.
  void classifyLimb(int root, std::vector<BoneRole>& roles, const std::vector<int>* mate = nullptr) const {
    const std::vector<int> chain = mainChain(root);
    std::vector<int> segmentOf(chain.size(), 0);
    std::vector<double> segments{sk_.bones[chain[0]].length()};
    for (size_t k = 1; k < chain.size(); ++k) {
      const Bone &a = sk_.bones[chain[k - 1]], &b = sk_.bones[chain[k]];
      const double cosine = (a.tail - a.head).normalized().dot((b.tail - b.head).normalized());
      const bool mirrorTwist = !twist_ || !mate || k >= mate->size() || (*twist_)[(*mate)[k]] != 0;
      const bool joined = twist_ ? (*twist_)[chain[k]] != 0 && mirrorTwist
                                 : (b.head - a.tail).norm() < 0.1 * a.length() && cosine > std::cos(0.26);
      if (!joined) segments.push_back(0.0);
      segments.back() += b.length();
      segmentOf[k] = static_cast<int>(segments.size()) - 1;
    }
    const int longest = static_cast<int>(std::max_element(segments.begin(), segments.end()) - segments.begin());
    for (size_t k = 0; k < chain.size(); ++k) {
      const int b = chain[k], segment = segmentOf[k];
      if (kids_[b].size() >= 3 && k > 0) break;  // a hand or foot
      if (segment > longest && segments[segment] < 0.4 * segments[longest]) break;
      roles[b] = segment == 0 && longest > 0 && segments[0] < 0.6 * segments[longest] ? BoneRole::Shoulder : BoneRole::Limb;
    }
  }
};

}  // namespace

// ============================================================================
// Public
// ============================================================================

const char* boneRoleName(BoneRole role) {
  switch (role) {
    case BoneRole::Ignore: return "ignore";
    case BoneRole::Limb: return "limb";
    case BoneRole::Shoulder: return "shoulder";
    case BoneRole::Neck: return "neck";
    case BoneRole::Spine: return "spine";
    case BoneRole::Pelvis: return "pelvis";
  }
  return "ignore";
}

BoneRole boneRoleFromName(const std::string& name) {
  for (BoneRole r : {BoneRole::Ignore, BoneRole::Limb, BoneRole::Shoulder, BoneRole::Neck, BoneRole::Spine, BoneRole::Pelvis})
    if (name == boneRoleName(r)) return r;
  throw InputError("unknown bone role '" + name + "' (ignore, limb, shoulder, neck, spine or pelvis)");
}

std::vector<BoneRole> classifyBones(const Skeleton& skeleton, const std::map<std::string, BoneRole>& overrides,
                                    const std::vector<char>* twist) {
  if (twist && static_cast<int>(twist->size()) != skeleton.numBones())
    throw InputError("bone roles: " + std::to_string(twist->size()) + " twist flags for " +
                     std::to_string(skeleton.numBones()) + " bones");
  for (const auto& [name, role] : overrides)
    if (skeleton.find(name) < 0) throw InputError("bone role override names no bone: '" + name + "'");
  const int n = skeleton.numBones();
  // Names are hints: where a name says nothing, the shape of the bone tree decides.
  const std::vector<BoneRole> fromTree = TreeRoles(skeleton, twist).classify();
  std::vector<BoneRole> roles(n, BoneRole::Ignore);
  std::vector<char> known(n, 0);
  for (int i = 0; i < n; ++i) {
    bool k = false;
    roles[i] = roleFromName(skeleton.bones[i].name, k);
    if (!k) roles[i] = fromTree[i];
    known[i] = k || fromTree[i] != BoneRole::Ignore;
  }
  // Topology for unknown names: a bone in the middle of a chain (parent and child both limb-like, long
  // enough) continues the limb; everything else stays ignored.
  double longest = 0.0;
  for (const Bone& b : skeleton.bones) longest = std::max(longest, b.length());
  for (int i = 0; i < n; ++i) {
    if (known[i]) continue;
    const Bone& b = skeleton.bones[i];
    const bool limbParent = b.parent >= 0 && roles[b.parent] == BoneRole::Limb;
    bool limbChild = false;
    for (int c : skeleton.children(i)) limbChild |= roles[c] == BoneRole::Limb;
    if (limbParent && limbChild && b.length() > 0.1 * longest) roles[i] = BoneRole::Limb;
  }
  // Spine bones above the arms' branch point with no limb below them are the neck (Rigify spine.004...),
  // and a spine leaf is the head.
  for (int i = 0; i < n; ++i) {
    if (roles[i] != BoneRole::Spine || overrides.count(skeleton.bones[i].name)) continue;
    std::vector<int> stack = skeleton.children(i);
    bool anyLimbOrShoulderBelow = false, anySpineChild = false;
    for (int c : skeleton.children(i)) anySpineChild |= roles[c] == BoneRole::Spine || roles[c] == BoneRole::Neck;
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      anyLimbOrShoulderBelow |= roles[c] == BoneRole::Limb || roles[c] == BoneRole::Shoulder;
      for (int g : skeleton.children(c)) stack.push_back(g);
    }
    int a = skeleton.bones[i].parent;
    bool shoulderSibling = false;
    for (; a >= 0 && !shoulderSibling; a = skeleton.bones[a].parent)
      for (int c : skeleton.children(a)) shoulderSibling |= roles[c] == BoneRole::Shoulder;
    if (!anyLimbOrShoulderBelow && shoulderSibling) roles[i] = anySpineChild ? BoneRole::Neck : BoneRole::Ignore;
  }
  for (int i = 0; i < n; ++i) {
    if (!skeleton.bones[i].deform || skeleton.bones[i].length() < 1e-6) roles[i] = BoneRole::Ignore;
    auto it = overrides.find(skeleton.bones[i].name);
    if (it != overrides.end()) roles[i] = it->second;
  }
  return roles;
}

std::vector<char> twistSplits(const Character& character) { return twistSplits(character.skeleton, character.weights); }

std::vector<char> twistSplits(const Skeleton& sk, const SkinWeights& w) {
  const int nb = sk.numBones();
  std::vector<char> twist(nb, 0);
  if (w.numVertices() == 0) return twist;
  std::vector<int> pairSkin(nb, 0), blended(nb, 0);  // per child: skin mostly on it + its parent, and how much blends
  for (int v = 0; v < w.numVertices(); ++v) {
    double total = 0.0;
    for (int k = 0; k < w.influences(); ++k)
      if (w.joints(v, k) >= 0) total += w.weights(v, k);
    if (!(total > 0)) continue;
    for (int k = 0; k < w.influences(); ++k) {
      const int c = w.joints(v, k);
      if (c < 0 || c >= nb || sk.bones[c].parent < 0) continue;
      double wc = 0.0, wp = 0.0;
      for (int q = 0; q < w.influences(); ++q) {
        if (w.joints(v, q) == c) wc += w.weights(v, q);
        if (w.joints(v, q) == sk.bones[c].parent) wp += w.weights(v, q);
      }
      if (wc + wp < 0.5 * total) continue;
      ++pairSkin[c];
      const double share = wc / (wc + wp);
      blended[c] += share > 0.1 && share < 0.9;
    }
    // (a vertex counts for each of its bones that has a parent among its influences)
  }
  for (int c = 0; c < nb; ++c) {
    const int p = sk.bones[c].parent;
    if (p < 0 || pairSkin[c] < 16) continue;
    const Bone &a = sk.bones[p], &b = sk.bones[c];
    const bool continues = (b.head - a.tail).norm() < 0.1 * a.length() &&
                           (a.tail - a.head).normalized().dot((b.tail - b.head).normalized()) > std::cos(30.0 * M_PI / 180.0);
    twist[c] = continues && blended[c] >= 0.45 * pairSkin[c];
  }
  return twist;
}

std::vector<BoneRole> characterBoneRoles(const Character& character, const std::map<std::string, BoneRole>& overrides) {
  const std::vector<char> twist = twistSplits(character);
  return classifyBones(weightedSkeleton(character), overrides, character.hasWeights() ? &twist : nullptr);
}

namespace {

// Bone tails from the joints, so that extraction does not depend on how an importer guessed them (Blender's glTF
// importer: along the joint's Y axis in 4.x/5.x, along the joint axis nearest the children in 3.4, as long as the
// nearest child or 0.004 armature units; the CLI's loader: at the child along Y). A bone ends at its continuing
// child's head: the child best aligned with its given direction, within 30 degrees, or its only child elsewhere; a
// bone whose children spread one way (a hand or foot) points at their mean, as far as the farthest along it. Any
// other bone (a leaf, or a hub with children all round) keeps its direction, and when it is shorter than a tenth of
// its parent it takes the parent's length.
// The rest matrix follows with the given roll (the given X axis, made perpendicular). A given tail within round-off of
// its continuing child's head (1e-6 of the skeleton's size) is set to that head exactly: an end at the joint is then
// equally near both bones bit for bit, as on a file whose tails are the joints, whatever an importer's float32 left.
void tailsFromJoints(Skeleton& sk) {
  const int n = sk.numBones();
  if (n == 0) return;
  Vec3 lo = sk.bones[0].head, hi = lo;
  for (const Bone& b : sk.bones) lo = lo.cwiseMin(b.head), hi = hi.cwiseMax(b.head);
  const double same = 1e-6 * std::max((hi - lo).norm(), 1e-300);  // "at the same place"
  const double cosLimit = std::cos(30.0 * M_PI / 180.0);
  for (int i = 0; i < n; ++i) {  // parents first: a parent's new length is known
    Bone& b = sk.bones[i];
    const Vec3 given = b.tail - b.head;
    const bool hasDirection = given.norm() > same;
    int pick = -1, elsewhere = 0, only = -1;
    double best = cosLimit;
    for (int c : sk.children(i)) {
      const Vec3 d = sk.bones[c].head - b.head;
      if (d.norm() <= same) continue;
      ++elsewhere, only = c;
      const double cosine = hasDirection ? d.normalized().dot(given.normalized()) : -1.0;
      if (cosine >= best) pick = c, best = cosine;
    }
    if (pick < 0 && elsewhere == 1) pick = only;
    Vec3 tail = b.tail, mean = Vec3::Zero();
    double reach = 0.0, spread = 0.0;
    for (int c : sk.children(i))
      if ((sk.bones[c].head - b.head).norm() > same) mean += (sk.bones[c].head - b.head) / elsewhere;
    for (int c : sk.children(i))
      if ((sk.bones[c].head - b.head).norm() > same) spread += (sk.bones[c].head - b.head).norm() / elsewhere;
    if (pick >= 0) {
      tail = sk.bones[pick].head;
    } else if (elsewhere > 1 && mean.norm() >= 0.5 * spread) {  // a hand or foot: towards its fingers or toes
      for (int c : sk.children(i)) reach = std::max(reach, (sk.bones[c].head - b.head).dot(mean.normalized()));
      tail = b.head + reach * mean.normalized();
    } else if (hasDirection && b.parent >= 0 && given.norm() < 0.1 * sk.bones[b.parent].length()) {
      tail = b.head + given.normalized() * sk.bones[b.parent].length();
    }
    if ((tail - b.head).norm() <= same || tail == b.tail) continue;
    if ((tail - b.tail).norm() <= same) {  // a given tail that is the joint but for round-off is set to it exactly
      if (pick >= 0) b.tail = tail;       // (its rest matrix kept): the bones on either side share one point
      continue;
    }
    b.tail = tail;
    b.rest = boneMatrix(b.head, b.tail, b.rest.block<3, 1>(0, 0));
  }
}

}  // namespace

Skeleton weightedSkeleton(const Character& character) {
  Skeleton sk = character.skeleton;
  tailsFromJoints(sk);
  if (!character.hasWeights()) return sk;
  const std::vector<double> totals = boneWeightTotals(character.weights, sk.numBones());
  for (int i = 0; i < sk.numBones(); ++i)
    if (!(totals[i] > 0)) sk.bones[i].deform = false;
  return sk;
}

}  // namespace myoskin
