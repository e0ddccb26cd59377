// Bone roles for extraction: name heuristics for Rigify, MakeHuman and Mixamo rigs, chain topology for the
// rest, caller overrides first.
#include <algorithm>
#include <cctype>
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

std::vector<BoneRole> classifyBones(const Skeleton& skeleton, const std::map<std::string, BoneRole>& overrides) {
  for (const auto& [name, role] : overrides)
    if (skeleton.find(name) < 0) throw InputError("bone role override names no bone: '" + name + "'");
  const int n = skeleton.numBones();
  std::vector<BoneRole> roles(n, BoneRole::Ignore);
  std::vector<char> known(n, 0);
  for (int i = 0; i < n; ++i) {
    bool k = false;
    roles[i] = roleFromName(skeleton.bones[i].name, k);
    known[i] = k;
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

}  // namespace myoskin
