// Varied procedural characters (bipeds and quadrupeds) with known muscles: the limb machinery of the synthetic arm
// (limb_model.h) on straight limb axes, joined with a trunk, neck, head and tail by a smooth union of implicit
// surfaces, meshed by marching tetrahedra (one closed, manifold, outward-oriented skin).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "generate/limb_model.h"
#include "myoskin/errors.h"
#include "myoskin/mesh.h"
#include "myoskin/skeleton.h"
#include "myoskin/synthetic_character.h"

namespace myoskin {

namespace {

using namespace limb;

constexpr double kUnionSoftness = 0.03;  // smooth-minimum width where parts meet (armpit, crotch, neck)
constexpr double kDefaultCell = 0.009;   // marching grid spacing (metres): about 90k skin vertices for a biped
constexpr double kWeightPower = 8.0;     // skin weights ~ (distance to the bone segment + kWeightOffset)^-power
constexpr double kWeightOffset = 0.01;
constexpr double kMinBellyWidth = 0.7;   // limb::makeMuscles: narrow a belly to at most this share, then lower it

// ============================================================================
// A straight part: a star-shaped generalized cylinder around an axis, rounded ends
// ============================================================================

// Joints and muscle-free cross-sections along the axis (x from the part's root), in the shape limb_model.h expects.
struct PartLayout {
  std::vector<double> canonical, joints;  // canonical and actual joint positions along the axis (same count)
  double tubeStart = 0.0, tubeEnd = 0.0;  // x range of the cylinder part; rounded ends beyond
  MonotoneCurve halfWidth, halfHeight;    // semi-axes of the muscle-free section along the frame's y and z

  double mapX(double c) const {
    size_t i = 0;
    while (i + 2 < canonical.size() && c > canonical[i + 1]) ++i;
    const double t = (c - canonical[i]) / (canonical[i + 1] - canonical[i]);
    return joints[i] + t * (joints[i + 1] - joints[i]);
  }
  double baseRadius(double x, double theta) const {
    const double w = halfWidth(x), h = halfHeight(x);
    const double c = std::cos(theta) / w, s = std::sin(theta) / h;
    return 1.0 / std::sqrt(c * c + s * s);
  }
};

struct Part {
  std::string name;
  PartLayout layout;
  std::vector<MuscleModel> muscles;
  Vec3 root = Vec3::Zero(), ex = Vec3::UnitX(), ey = Vec3::UnitY(), ez = Vec3::UnitZ();  // right-handed frame
  bool mirrored = false;   // evaluated at the point reflected through x = 0 (the right side of a left part)
  double capStart = 1.0, capEnd = 1.0;  // rounded ends: the radius over this factor along the axis (1 = round)
  Vec3 lo, hi;             // bounding box (world, inflated)

  // Signed, roughly distance-like: < 0 inside.
  double field(Vec3 p) const {
    if (mirrored) p.x() = -p.x();
    const Vec3 d = p - root;
    const double x = d.dot(ex), y = d.dot(ey), z = d.dot(ez);
    const double r = std::sqrt(y * y + z * z);
    const double theta = std::atan2(z, y);
    const double xc = std::clamp(x, layout.tubeStart, layout.tubeEnd);
    const double R = skinRadius(layout, muscles, xc, theta);
    const double over = (x - xc) * (x < xc ? capStart : capEnd);
    return std::sqrt(r * r + over * over) - R;
  }
  Vec3 toWorld(const Vec3& local) const {
    Vec3 p = root + local.x() * ex + local.y() * ey + local.z() * ez;
    if (mirrored) p.x() = -p.x();
    return p;
  }
};

// Stations: canonical x, half-width (frame y), half-height (frame z) of the muscle-free section.
struct Station {
  double x, w, h;
};

// A part along `dir` from `root`: joints given as canonical positions and actual positions (metres along the axis);
// stations in canonical x, radii multiplied by `thickness` (+ the fat layer); rounded ends at the first and last
// station (tube from the first station's x, to the last one's).
// leftHanded: the frame (x, y, z) is a mirror image (a left limb with the right arm's muscle angles).
Part makePart(const std::string& name, const Vec3& root, const Vec3& dir, const Vec3& anterior,
              const std::vector<double>& canonical, const std::vector<double>& joints, const std::vector<Station>& stations,
              double thickness, bool leftHanded = false) {
  Part part;
  part.name = name;
  part.root = root;
  part.ex = dir.normalized();
  part.ez = (anterior - anterior.dot(part.ex) * part.ex).normalized();
  part.ey = leftHanded ? Vec3(-part.ez.cross(part.ex)) : Vec3(part.ez.cross(part.ex));
  part.layout.canonical = canonical;
  part.layout.joints = joints;
  std::vector<double> xs, ws, hs;
  for (const Station& s : stations) {
    xs.push_back(part.layout.mapX(s.x));
    ws.push_back(s.w * thickness + kFat);
    hs.push_back(s.h * thickness + kFat);
  }
  part.layout.tubeStart = xs.front();
  part.layout.tubeEnd = xs.back();
  part.layout.halfWidth = MonotoneCurve(xs, ws);
  part.layout.halfHeight = MonotoneCurve(xs, hs);
  return part;
}

// The part's bounding box: its axis segment inflated by its largest radius plus muscles and margins.
void boundPart(Part& part) {
  double rmax = 0.0;
  for (int k = 0; k <= 64; ++k) {
    const double x = part.layout.tubeStart + (part.layout.tubeEnd - part.layout.tubeStart) * k / 64.0;
    for (int j = 0; j < 16; ++j) rmax = std::max(rmax, skinRadius(part.layout, part.muscles, x, 2.0 * kPi * j / 16.0));
  }
  const double pad = rmax * 1.05 + 2.0 * kUnionSoftness;
  const Vec3 a = part.toWorld(Vec3(part.layout.tubeStart, 0, 0)), b = part.toWorld(Vec3(part.layout.tubeEnd, 0, 0));
  part.lo = a.cwiseMin(b) - Vec3::Constant(pad);
  part.hi = a.cwiseMax(b) + Vec3::Constant(pad);
}

// Polynomial smooth minimum: min(a, b) when |a - b| >= k.
double smoothMin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}

// ============================================================================
// The body plan
// ============================================================================

struct BoneDef {
  std::string key;   // rig name
  int parent = -1;
  Vec3 head, tail;
  std::string german, japanese;
};

struct Body {
  std::vector<Part> parts;
  std::vector<BoneDef> bones;
  std::vector<int> limbParts;          // parts carrying muscles (left and right)
  std::vector<std::string> groupOf;    // per bone: mesh piece name when split
};

int addBone(Body& body, const std::string& key, int parent, const Vec3& head, const Vec3& tail, const std::string& german,
            const std::string& japanese, const std::string& group) {
  body.bones.push_back({key, parent, head, tail, german, japanese});
  body.groupOf.push_back(group);
  return static_cast<int>(body.bones.size()) - 1;
}

Vec3 mirrorX(const Vec3& p) { return Vec3(-p.x(), p.y(), p.z()); }

// Adds a left limb chain and its mirror: bone keys/names per joint interval along the part's axis.
void addLimbBones(Body& body, const Part& part, int parent, const std::vector<std::string>& keys,
                  const std::vector<std::string>& german, const std::vector<std::string>& japanese, const std::string& group) {
  for (int side = 0; side < 2; ++side) {
    const char* suffix = side == 0 ? ".L" : ".R";
    int p = parent;
    for (size_t i = 0; i < keys.size(); ++i) {
      Vec3 h = part.toWorld(Vec3(part.layout.joints[i], 0, 0)), t = part.toWorld(Vec3(part.layout.joints[i + 1], 0, 0));
      if (side == 1) h = mirrorX(h), t = mirrorX(t);
      p = addBone(body, keys[i] + suffix, p, h, t, german[i] + suffix, japanese[i] + suffix, group);
    }
  }
}

// Muscles of a limb part: the specs' sizes and heights grow with the limb's thickness (a thin limb has thin muscles).
void addMuscles(Part& part, std::vector<MuscleSpec> specs, double thickness, double muscleScale, Jitter& jitter) {
  for (MuscleSpec& m : specs) m.a *= thickness, m.b *= thickness, m.protrusion *= thickness;
  part.muscles = limb::makeMuscles(part.layout, muscleScale, jitter, specs, kMinBellyWidth);
}

std::vector<double> cumulative(const std::vector<double>& lengths) {
  std::vector<double> out{0.0};
  for (double l : lengths) out.push_back(out.back() + l);
  return out;
}

// Arm muscles: the synthetic arm's but for its deltoid, whose belly would lie half inside the trunk where the arm meets
// it (the ground truth would hold a muscle no skin shows). Across each joint, bellies in line lie >= 60 degrees apart
// around the limb (as the arm's), so that the truth's separate muscles are separate on the skin.
const std::vector<MuscleSpec>& armSpecs() {
  static const std::vector<MuscleSpec> specs = {
      {"biceps", "upper_arm", 0.25, 0.47, 90, 90, 0.030, 0.020, 0.0110, 0.55},
      {"triceps", "upper_arm", 0.21, 0.46, 270, 270, 0.034, 0.017, 0.0090, 0.42},
      {"brachialis", "upper_arm", 0.34, 0.50, 148, 148, 0.018, 0.013, 0.0070, 0.60},
      {"forearm_flexors", "forearm", 0.49, 0.66, 25, 25, 0.025, 0.015, 0.0080, 0.35},
      {"forearm_extensors", "forearm", 0.49, 0.67, 205, 205, 0.023, 0.014, 0.0075, 0.35},
  };
  return specs;
}

// Leg muscles in canonical leg x (hip 0, knee 0.44, ankle 0.86); theta 90 = anterior, 270 = posterior, 0 = lateral.
const std::vector<MuscleSpec>& legSpecs() {
  static const std::vector<MuscleSpec> specs = {
      {"quadriceps", "thigh", 0.13, 0.41, 100, 100, 0.045, 0.030, 0.0150, 0.55},
      {"hamstrings", "thigh", 0.15, 0.41, 260, 260, 0.040, 0.026, 0.0130, 0.45},
      {"gastrocnemius", "shin", 0.47, 0.68, 320, 320, 0.034, 0.022, 0.0120, 0.35},
      {"tibialis_anterior", "shin", 0.48, 0.72, 40, 40, 0.020, 0.014, 0.0080, 0.35},
  };
  return specs;
}

// Quadruped front leg (scapula top 0, shoulder 0.12, elbow 0.44, carpus 0.78, hoof tip 0.88; the trunk's underside
// at about 0.2).
const std::vector<MuscleSpec>& frontLegSpecs() {
  static const std::vector<MuscleSpec> specs = {
      {"triceps", "front_thigh", 0.23, 0.44, 270, 270, 0.034, 0.021, 0.0120, 0.40},
      {"biceps", "front_thigh", 0.25, 0.44, 90, 90, 0.026, 0.017, 0.0090, 0.55},
      {"forearm_extensors", "front_shin", 0.47, 0.68, 30, 30, 0.024, 0.015, 0.0085, 0.35},
      {"forearm_flexors", "front_shin", 0.47, 0.68, 210, 210, 0.024, 0.015, 0.0080, 0.35},
  };
  return specs;
}

// Quadruped hind leg (hip 0, stifle 0.34, hock 0.70, hoof tip 0.80; the trunk's underside at about 0.13).
const std::vector<MuscleSpec>& hindLegSpecs() {
  static const std::vector<MuscleSpec> specs = {
      {"quadriceps", "thigh", 0.13, 0.33, 100, 100, 0.040, 0.027, 0.0140, 0.55},
      {"hamstrings", "thigh", 0.13, 0.33, 260, 260, 0.040, 0.027, 0.0140, 0.45},
      {"gastrocnemius", "shin", 0.37, 0.56, 320, 320, 0.030, 0.019, 0.0110, 0.35},
      {"tibialis_anterior", "shin", 0.37, 0.58, 40, 40, 0.020, 0.013, 0.0075, 0.35},
  };
  return specs;
}

Body makeBiped(Jitter& j, double muscleScale) {
  Body body;
  const double size = j.factor(0.10);
  const double trunkW = j.factor(0.10), trunkD = j.factor(0.10);
  const double hipZ = 0.95 * size * j.factor(0.06), chestLen = 0.45 * size * j.factor(0.08);
  const double shoulderZ = hipZ + chestLen;
  // The legs stand apart: a 6 cm gap between the thighs (twice the union's softness), so they meet only at the crotch.
  const double legThick = size * j.factor(0.15);
  const double hipX = 0.085 * legThick + kFat + 0.03 * size;
  const double hipW = std::max(0.165 * trunkW, (hipX + 0.06 * size) / size);  // the hips are as wide as the legs
  // Trunk: vertical axis, from below the hips to the shoulders.
  {
    const double z0 = hipZ - 0.07 * size, z1 = shoulderZ + 0.04 * size;
    const std::vector<double> c = {0.0, 1.0}, jj = {0.0, z1 - z0};
    const std::vector<Station> st = {{0.00, hipW - 0.015, 0.095 * trunkD}, {0.12, hipW, 0.105 * trunkD},
                                     {0.35, 0.135 * trunkW, 0.090 * trunkD}, {0.60, 0.150 * trunkW, 0.100 * trunkD},
                                     {0.85, 0.165 * trunkW, 0.105 * trunkD}, {1.00, 0.150 * trunkW, 0.085 * trunkD}};
    Part trunk = makePart("trunk", Vec3(0, 0, z0), Vec3::UnitZ(), Vec3(0, 1, 0), c, jj, st, size);
    trunk.capStart = 2.5;  // a flat seat between the legs, rounded shoulders
    trunk.capEnd = 1.6;
    body.parts.push_back(trunk);
  }
  // Neck and head.
  const double neckLen = 0.14 * size * j.factor(0.10), headLen = 0.22 * size * j.factor(0.06);
  {
    const double z0 = shoulderZ - 0.04 * size, n1 = neckLen + 0.04 * size, h1 = n1 + headLen;
    const std::vector<double> c = {0.0, 1.0, 2.0}, jj = {0.0, n1, h1};
    const double neckR = 0.052 * j.factor(0.10), headR = 0.085 * j.factor(0.06);
    const std::vector<Station> st = {{0.0, neckR, neckR}, {0.8, neckR, neckR}, {1.3, headR, 1.1 * headR},
                                     {1.75, headR, 1.1 * headR}, {2.0, 0.6 * headR, 0.6 * headR}};
    body.parts.push_back(makePart("head", Vec3(0, 0, z0), Vec3::UnitZ(), Vec3(0, -1, 0), c, jj, st, size));
  }
  // Left arm in an A-pose: clavicle from near the trunk's middle to the shoulder joint, then down and out.
  const double angle = (40.0 + j.offset(10.0)) * kDeg;
  const double armLen = size * j.factor(0.12), armThick = size * j.factor(0.15);
  const double clav = 0.16 * size * trunkW * j.factor(0.06);
  const std::vector<double> armCanonical = {0.0, 0.18, 0.48, 0.74, 0.83};
  const std::vector<double> armJoints =
      cumulative({clav, 0.30 * armLen * j.factor(0.08), 0.26 * armLen * j.factor(0.08), 0.09 * armLen * j.factor(0.08)});
  const Vec3 armRoot(0.02 * size, 0.0, shoulderZ - 0.02 * size);
  const Vec3 armDir(std::cos(angle), 0.0, -std::sin(angle));
  {
    // The clavicle runs to the shoulder joint horizontally; the arm's axis is one straight line, so the clavicle
    // part of the tube (inside the trunk) tilts with the arm.
    const std::vector<Station> st = {{0.00, 0.056, 0.054}, {0.10, 0.055, 0.054}, {0.18, 0.052, 0.053},
                                     {0.26, 0.046, 0.046}, {0.33, 0.043, 0.043}, {0.42, 0.041, 0.040},
                                     {0.48, 0.038, 0.036}, {0.54, 0.040, 0.038}, {0.64, 0.035, 0.031},
                                     {0.74, 0.029, 0.020}, {0.78, 0.038, 0.016}, {0.83, 0.040, 0.014}};
    // The synthetic arm is a right arm (+Y medial, -Y lateral): the left arm's frame is its mirror image.
    Part arm = makePart("arm", armRoot, armDir, Vec3(0, -1, 0), armCanonical, armJoints, st, armThick, true);
    addMuscles(arm, armSpecs(), armThick, muscleScale, j);
    body.parts.push_back(arm);
  }
  // Left leg: straight down from the hip joint, slightly outwards; the foot forward from the ankle.
  const double legLen = hipZ - 0.07 * size;  // hip joint to ankle
  const double kneeAt = 0.44 * j.factor(0.05) / 0.86;  // share of the leg length above the knee
  const std::vector<double> legCanonical = {0.0, 0.44, 0.86};
  const std::vector<double> legJoints = {0.0, kneeAt * legLen, legLen};
  const Vec3 legRoot(hipX, 0.0, hipZ);
  const Vec3 legDir = Vec3(0.03, 0.0, -1.0).normalized();
  {
    const std::vector<Station> st = {{0.00, 0.085, 0.085}, {0.10, 0.082, 0.082}, {0.25, 0.072, 0.070},
                                     {0.38, 0.056, 0.055}, {0.44, 0.050, 0.050}, {0.52, 0.050, 0.052},
                                     {0.62, 0.046, 0.048}, {0.76, 0.036, 0.036}, {0.86, 0.032, 0.032}};
    Part leg = makePart("leg", legRoot, legDir, Vec3(0, -1, 0), legCanonical, legJoints, st, legThick);
    addMuscles(leg, legSpecs(), legThick, muscleScale, j);
    body.parts.push_back(leg);
  }
  const Vec3 ankle = legRoot + legLen * legDir;
  const double footLen = 0.14 * size * j.factor(0.08);
  const Vec3 toe = Vec3(ankle.x() + 0.01 * size, -footLen, 0.03 * size);
  {
    const std::vector<double> c = {0.0, 1.0}, jj = {-0.03 * size, (toe - ankle).norm()};
    const std::vector<Station> st = {{0.0, 0.036, 0.034}, {0.5, 0.040, 0.026}, {1.0, 0.038, 0.016}};
    body.parts.push_back(makePart("foot", ankle, toe - ankle, Vec3(0, 0, 1), c, jj, st, legThick));
  }
  // Bones.
  const int hips = addBone(body, "hips", -1, Vec3(0, 0, hipZ - 0.05 * size), Vec3(0, 0, hipZ + 0.08 * size),
                           "H\xC3\xBC" "fte", "\xE8\x85\xB0", "Body");  // Hüfte, 腰
  const double spineTop = hipZ + 0.45 * chestLen;
  const int spine = addBone(body, "spine", hips, Vec3(0, 0, hipZ + 0.08 * size), Vec3(0, 0, spineTop),
                            "Wirbels\xC3\xA4ule", "\xE8\x83\x8C\xE9\xAA\xA8", "Body");  // Wirbelsäule, 背骨
  const int chest = addBone(body, "chest", spine, Vec3(0, 0, spineTop), Vec3(0, 0, shoulderZ),
                            "Brustkorb", "\xE8\x83\xB8", "Body");  // 胸
  const int neck = addBone(body, "neck", chest, Vec3(0, 0, shoulderZ), Vec3(0, 0, shoulderZ + neckLen), "Hals",
                           "\xE9\xA6\x96", "Body");  // 首
  addBone(body, "head", neck, Vec3(0, 0, shoulderZ + neckLen), Vec3(0, 0, shoulderZ + neckLen + headLen), "Kopf",
          "\xE9\xA0\xAD", "Body");  // 頭
  addLimbBones(body, body.parts[2], chest, {"shoulder", "upper_arm", "forearm", "hand"},
               {"Schl\xC3\xBC" "sselbein", "Oberarm", "Unterarm", "Hand"},
               {"\xE9\x8E\x96\xE9\xAA\xA8", "\xE4\xB8\x8A\xE8\x85\x95", "\xE5\x89\x8D\xE8\x85\x95", "\xE6\x89\x8B"},
               "Arms");  // Schlüsselbein; 鎖骨 上腕 前腕 手
  // Legs: thigh and shin along the leg part, the foot along the foot part.
  for (int side = 0; side < 2; ++side) {
    const char* suffix = side == 0 ? ".L" : ".R";
    auto m = [&](const Vec3& p) { return side == 0 ? p : mirrorX(p); };
    const Part& leg = body.parts[3];
    const int thigh = addBone(body, std::string("thigh") + suffix, hips, m(leg.toWorld(Vec3(0, 0, 0))),
                              m(leg.toWorld(Vec3(legJoints[1], 0, 0))), std::string("Oberschenkel") + suffix,
                              std::string("\xE5\xA4\xAA\xE3\x82\x82\xE3\x82\x82") + suffix, "Legs");  // 太もも
    const int shin = addBone(body, std::string("shin") + suffix, thigh, m(leg.toWorld(Vec3(legJoints[1], 0, 0))),
                             m(leg.toWorld(Vec3(legJoints[2], 0, 0))), std::string("Unterschenkel") + suffix,
                             std::string("\xE3\x81\x99\xE3\x81\xAD") + suffix, "Legs");  // すね
    addBone(body, std::string("foot") + suffix, shin, m(ankle), m(toe), std::string("Fu\xC3\x9F") + suffix,
            std::string("\xE8\xB6\xB3") + suffix, "Legs");  // Fuß, 足
  }
  body.limbParts = {2, 3};
  return body;
}

Body makeQuadruped(Jitter& j, double muscleScale) {
  Body body;
  const double size = j.factor(0.10);
  const double trunkW = j.factor(0.10), trunkH = j.factor(0.10);
  const double legLen = 0.80 * size * j.factor(0.10);  // ground to the trunk's axis
  const double trunkLen = 0.85 * size * j.factor(0.10);
  const double z = legLen;
  const double yHip = 0.5 * trunkLen, yChest = -0.5 * trunkLen;
  {
    const std::vector<double> c = {0.0, 1.0}, jj = {0.0, trunkLen + 0.16 * size};
    const std::vector<Station> st = {{0.00, 0.110 * trunkW, 0.115 * trunkH}, {0.15, 0.120 * trunkW, 0.125 * trunkH},
                                     {0.50, 0.115 * trunkW, 0.130 * trunkH}, {0.80, 0.120 * trunkW, 0.135 * trunkH},
                                     {1.00, 0.105 * trunkW, 0.120 * trunkH}};
    Part trunk = makePart("trunk", Vec3(0, yHip + 0.08 * size, z), -Vec3::UnitY(), Vec3(0, 0, 1), c, jj, st, size);
    trunk.capStart = trunk.capEnd = 1.5;
    body.parts.push_back(trunk);
  }
  // Neck and head: up and forward from the chest, the head forward and down.
  const double neckLen = 0.32 * size * j.factor(0.10), headLen = 0.30 * size * j.factor(0.08);
  const Vec3 neckBase(0, yChest + 0.12 * size, z + 0.06 * size);
  const Vec3 neckDir = Vec3(0, -0.75, 1.0).normalized();
  const Vec3 poll = neckBase + neckLen * neckDir;
  const Vec3 headDir = Vec3(0, -1.0, -0.35).normalized();
  const Vec3 muzzle = poll + headLen * headDir;
  {
    const std::vector<double> c = {0.0, 1.0}, jj = {0.0, neckLen + 0.03 * size};
    const double r = 0.070 * j.factor(0.10);
    const std::vector<Station> st = {{0.0, 1.1 * r, 1.3 * r}, {0.6, r, 1.1 * r}, {1.0, 0.85 * r, 0.95 * r}};
    body.parts.push_back(makePart("neck", neckBase, neckDir, Vec3(0, -1, 0), c, jj, st, size));
    const std::vector<double> hc = {0.0, 1.0}, hj = {0.0, headLen};
    const std::vector<Station> hs = {{0.0, 0.075, 0.085}, {0.4, 0.070, 0.075}, {1.0, 0.045, 0.045}};
    body.parts.push_back(makePart("head", poll, headDir, Vec3(0, 0, 1), hc, hj, hs, size));
  }
  // Tail: back and down from the rump.
  const double tailLen = 0.45 * size * j.factor(0.15);
  const Vec3 tailBase(0, yHip + 0.06 * size, z + 0.05 * size);
  const Vec3 tailDir = Vec3(0, 1.0, -0.6).normalized();
  {
    const std::vector<double> c = {0.0, 1.0}, jj = {0.0, tailLen};
    const std::vector<Station> st = {{0.0, 0.040, 0.040}, {0.3, 0.030, 0.030}, {1.0, 0.014, 0.014}};
    body.parts.push_back(makePart("tail", tailBase, tailDir, Vec3(0, 0, 1), c, jj, st, size));
  }
  // Front leg (left): straight down from the scapula's top beside the withers.
  const double frontThick = size * j.factor(0.15), hindThick = size * j.factor(0.15);
  const double legX = 0.075 * size * trunkW;
  const Vec3 frontRoot(legX, yChest + 0.08 * size, z + 0.06 * size);
  const double frontTotal = frontRoot.z() - 0.02 * size;
  const std::vector<double> frontCanonical = {0.0, 0.12, 0.44, 0.78, 0.88};
  std::vector<double> frontJoints;
  {
    const double l[4] = {0.12 * j.factor(0.05), 0.32 * j.factor(0.08), 0.34 * j.factor(0.08), 0.10 * j.factor(0.05)};
    const double sum = l[0] + l[1] + l[2] + l[3];
    frontJoints = cumulative({l[0] / sum * frontTotal, l[1] / sum * frontTotal, l[2] / sum * frontTotal,
                              l[3] / sum * frontTotal});
    const std::vector<Station> st = {{0.00, 0.060, 0.070}, {0.12, 0.062, 0.072}, {0.28, 0.058, 0.066},
                                     {0.44, 0.046, 0.050}, {0.54, 0.044, 0.046}, {0.70, 0.034, 0.034},
                                     {0.78, 0.030, 0.030}, {0.88, 0.034, 0.036}};
    Part leg = makePart("front_leg", frontRoot, Vec3(0.02, 0.0, -1.0), Vec3(0, -1, 0), frontCanonical, frontJoints, st,
                        frontThick);
    addMuscles(leg, frontLegSpecs(), frontThick, muscleScale, j);
    body.parts.push_back(leg);
  }
  const Vec3 hindRoot(legX + 0.01 * size, yHip - 0.02 * size, z);
  const double hindTotal = hindRoot.z() - 0.02 * size;
  const std::vector<double> hindCanonical = {0.0, 0.34, 0.70, 0.80};
  std::vector<double> hindJoints;
  {
    const double l[3] = {0.34 * j.factor(0.08), 0.36 * j.factor(0.08), 0.10 * j.factor(0.05)};
    const double sum = l[0] + l[1] + l[2];
    hindJoints = cumulative({l[0] / sum * hindTotal, l[1] / sum * hindTotal, l[2] / sum * hindTotal});
    const std::vector<Station> st = {{0.00, 0.085, 0.090}, {0.12, 0.080, 0.088}, {0.28, 0.062, 0.066},
                                     {0.34, 0.052, 0.054}, {0.46, 0.044, 0.048}, {0.62, 0.032, 0.034},
                                     {0.70, 0.030, 0.030}, {0.80, 0.034, 0.036}};
    Part leg = makePart("hind_leg", hindRoot, Vec3(0.02, 0.0, -1.0), Vec3(0, -1, 0), hindCanonical, hindJoints, st,
                        hindThick);
    addMuscles(leg, hindLegSpecs(), hindThick, muscleScale, j);
    body.parts.push_back(leg);
  }
  // Bones.
  const int hips = addBone(body, "hips", -1, Vec3(0, yHip, z), Vec3(0, yHip - 0.25 * trunkLen, z), "Becken",
                           "\xE8\x85\xB0", "Body");
  const int spine = addBone(body, "spine", hips, Vec3(0, yHip - 0.25 * trunkLen, z), Vec3(0, yChest + 0.35 * trunkLen, z),
                            "Wirbels\xC3\xA4ule", "\xE8\x83\x8C\xE9\xAA\xA8", "Body");
  const int chest = addBone(body, "chest", spine, Vec3(0, yChest + 0.35 * trunkLen, z), Vec3(0, yChest, z), "Brustkorb",
                            "\xE8\x83\xB8", "Body");
  const int neck = addBone(body, "neck", chest, neckBase, poll, "Hals", "\xE9\xA6\x96", "Body");
  addBone(body, "head", neck, poll, muzzle, "Kopf", "\xE9\xA0\xAD", "Body");
  int tail = hips;
  const char* tailKeys[3] = {"tail", "tail.001", "tail.002"};
  const char* tailGerman[3] = {"Schwanz", "Schwanz.001", "Schwanz.002"};
  const char* tailJapanese[3] = {"\xE5\xB0\xBB\xE5\xB0\xBE", "\xE5\xB0\xBB\xE5\xB0\xBE.001", "\xE5\xB0\xBB\xE5\xB0\xBE.002"};
  for (int k = 0; k < 3; ++k)
    tail = addBone(body, tailKeys[k], tail, tailBase + tailLen * k / 3.0 * tailDir, tailBase + tailLen * (k + 1) / 3.0 * tailDir,
                   tailGerman[k], tailJapanese[k], "Body");  // 尻尾
  addLimbBones(body, body.parts[4], chest, {"shoulder", "front_thigh", "front_shin", "front_foot"},
               {"Schulterblatt", "Oberarm", "Unterarm", "Vorderfu\xC3\x9F"},
               {"\xE8\x82\xA9\xE7\x94\xB2\xE9\xAA\xA8", "\xE4\xB8\x8A\xE8\x85\x95", "\xE5\x89\x8D\xE8\x85\x95",
                "\xE5\x89\x8D\xE8\xB6\xB3"},
               "FrontLegs");  // 肩甲骨 上腕 前腕 前足
  addLimbBones(body, body.parts[5], hips, {"thigh", "shin", "foot"}, {"Oberschenkel", "Unterschenkel", "Hinterfu\xC3\x9F"},
               {"\xE5\xA4\xAA\xE3\x82\x82\xE3\x82\x82", "\xE3\x81\x99\xE3\x81\xAD", "\xE5\xBE\x8C\xE8\xB6\xB3"},
               "HindLegs");  // 太もも すね 後足
  body.limbParts = {4, 5};
  return body;
}

// ============================================================================
// Marching tetrahedra
// ============================================================================

struct Grid {
  Vec3 origin;
  double h = 0.0;
  int nx = 0, ny = 0, nz = 0;
  int64_t index(int i, int j, int k) const { return i + static_cast<int64_t>(nx) * (j + static_cast<int64_t>(ny) * k); }
  Vec3 point(int i, int j, int k) const { return origin + h * Vec3(i, j, k); }
};

class BodyField {
 public:
  explicit BodyField(const std::vector<Part>& parts) : parts_(parts) {}
  double operator()(const Vec3& p) const {
    double f = std::numeric_limits<double>::infinity();
    for (const Part& part : parts_) {
      // A left part and its mirror: the box test on the point reflected for the mirror.
      for (int side = 0; side < 2; ++side) {
        if (side == 1 && !mirroredToo(part)) break;
        const Vec3 q = side == 0 ? p : mirrorX(p);
        if ((q.array() < part.lo.array()).any() || (q.array() > part.hi.array()).any()) continue;
        Part const* use = &part;
        const double g = side == 0 ? use->field(p) : use->field(q);
        f = std::isfinite(f) ? smoothMin(f, g, kUnionSoftness) : g;
      }
    }
    return std::isfinite(f) ? f : 2.0 * kUnionSoftness + 0.05;
  }

 private:
  static bool mirroredToo(const Part& part) { return part.root.x() > 1e-9; }  // left limbs (x > 0) have a right twin
  const std::vector<Part>& parts_;
};

// Distance of the skin from a part's axis at (x, theta) of its frame (left side): the first point where the body field
// turns outside going out along the ray, 0.5 mm steps then bisection; `reach` (metres) when the ray stays inside.
double skinAlongRay(const BodyField& field, const Part& part, double x, double theta, double reach = 0.6) {
  const double c = std::cos(theta), s = std::sin(theta);
  auto at = [&](double r) { return field(part.toWorld(Vec3(x, r * c, r * s))); };
  constexpr double kStep = 0.0005;
  if (at(0.0) >= 0.0) return 0.0;
  for (double r = 0.0; r < reach; r += kStep) {
    if (at(r + kStep) < 0.0) continue;
    double lo = r, hi = r + kStep;
    for (int it = 0; it < 30; ++it) (at(0.5 * (lo + hi)) < 0.0 ? lo : hi) = 0.5 * (lo + hi);
    return 0.5 * (lo + hi);
  }
  return reach;
}

// Closed, outward-oriented triangle mesh of {field < 0}.
Mesh marchTetrahedra(const BodyField& field, const Vec3& lo, const Vec3& hi, double h) {
  Grid g;
  g.h = h;
  g.origin = lo - Vec3::Constant(2 * h);
  g.nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / h)) + 5;
  g.ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / h)) + 5;
  g.nz = static_cast<int>(std::ceil((hi.z() - lo.z()) / h)) + 5;
  const int64_t total = static_cast<int64_t>(g.nx) * g.ny * g.nz;
  std::vector<float> value(static_cast<size_t>(total), std::numeric_limits<float>::quiet_NaN());
  auto valueAt = [&](int i, int j, int k) {
    float& v = value[static_cast<size_t>(g.index(i, j, k))];
    if (std::isnan(v)) {
      double f = field(g.point(i, j, k));
      if (f == 0.0) f = 1e-12;  // zero counts as outside
      v = static_cast<float>(f);
      if (v == 0.0f) v = 1e-30f;
    }
    return v;
  };
  // Blocks of B cells: skipped when the field at the centre says the surface is far (its gradient stays below 2.5,
  // the flattest cap's factor).
  constexpr int B = 4;
  const double reach = 2.6 * (0.5 * B * h * std::sqrt(3.0)) + h;
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::unordered_map<uint64_t, int> edgeVertex;
  auto vertexOn = [&](int64_t a, int64_t b, int code, const Vec3& pa, const Vec3& pb, float fa, float fb) {
    const int64_t low = std::min(a, b);
    const uint64_t key = static_cast<uint64_t>(low) * 8u + static_cast<uint64_t>(code);
    auto it = edgeVertex.find(key);
    if (it != edgeVertex.end()) return it->second;
    double t = static_cast<double>(fa) / (static_cast<double>(fa) - static_cast<double>(fb));
    t = std::clamp(t, 0.02, 0.98);
    vertices.push_back(pa + t * (pb - pa));
    const int id = static_cast<int>(vertices.size()) - 1;
    edgeVertex.emplace(key, id);
    return id;
  };
  // Kuhn decomposition: the six tetrahedra 0 -> e_a -> e_a + e_b -> 7 over the permutations (a, b, c).
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int bk = 0; bk + 1 < g.nz; bk += B)
    for (int bj = 0; bj + 1 < g.ny; bj += B)
      for (int bi = 0; bi + 1 < g.nx; bi += B) {
        const Vec3 centre = g.point(bi, bj, bk) + 0.5 * B * h * Vec3::Ones();
        if (std::abs(field(centre)) > reach) continue;
        for (int k = bk; k < std::min(bk + B, g.nz - 1); ++k)
          for (int jj = bj; jj < std::min(bj + B, g.ny - 1); ++jj)
            for (int i = bi; i < std::min(bi + B, g.nx - 1); ++i) {
              float f[8];
              bool anyIn = false, anyOut = false;
              for (int c = 0; c < 8; ++c) {
                f[c] = valueAt(i + (c & 1), jj + ((c >> 1) & 1), k + ((c >> 2) & 1));
                (f[c] < 0 ? anyIn : anyOut) = true;
              }
              if (!anyIn || !anyOut) continue;
              for (const auto& perm : perms) {
                int corner[4] = {0, 0, 0, 0};
                for (int s = 1; s < 4; ++s) corner[s] = corner[s - 1] | (1 << perm[s - 1]);
                int inside[4], outside[4], ni = 0, no = 0;
                for (int s = 0; s < 4; ++s) (f[corner[s]] < 0 ? inside[ni++] : outside[no++]) = corner[s];
                if (ni == 0 || no == 0) continue;
                auto pos = [&](int c) { return g.point(i + (c & 1), jj + ((c >> 1) & 1), k + ((c >> 2) & 1)); };
                auto idx = [&](int c) { return g.index(i + (c & 1), jj + ((c >> 1) & 1), k + ((c >> 2) & 1)); };
                auto cut = [&](int a, int b) {
                  const int lowC = std::min(a, b), highC = std::max(a, b);
                  return vertexOn(idx(lowC), idx(highC), highC ^ lowC, pos(lowC), pos(highC), f[lowC], f[highC]);
                };
                Vec3 inMean = Vec3::Zero(), outMean = Vec3::Zero();
                for (int s = 0; s < ni; ++s) inMean += pos(inside[s]) / ni;
                for (int s = 0; s < no; ++s) outMean += pos(outside[s]) / no;
                const Vec3 outward = outMean - inMean;
                auto emit = [&](int a, int b, int c) {
                  const Vec3 n = (vertices[b] - vertices[a]).cross(vertices[c] - vertices[a]);
                  if (n.dot(outward) < 0) std::swap(b, c);
                  triangles.push_back({a, b, c});
                };
                if (ni == 1 || no == 1) {
                  const int lone = ni == 1 ? inside[0] : outside[0];
                  const int* others = ni == 1 ? outside : inside;
                  emit(cut(lone, others[0]), cut(lone, others[1]), cut(lone, others[2]));
                } else {
                  const int a = cut(inside[0], outside[0]), b = cut(inside[0], outside[1]),
                            c = cut(inside[1], outside[1]), d = cut(inside[1], outside[0]);
                  emit(a, b, c);
                  emit(a, c, d);
                }
              }
            }
      }
  Mesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (size_t v = 0; v < vertices.size(); ++v) mesh.vertices.row(static_cast<Eigen::Index>(v)) = vertices[v].transpose();
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (size_t t = 0; t < triangles.size(); ++t)
    mesh.triangles.row(static_cast<Eigen::Index>(t)) << triangles[t][0], triangles[t][1], triangles[t][2];
  return mesh;
}

// ============================================================================
// Skeleton, weights, names
// ============================================================================

double segmentDistance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

SkinWeights buildWeights(const Points& vertices, const Skeleton& sk) {
  const int n = static_cast<int>(vertices.rows()), nb = sk.numBones();
  SkinWeights w;
  w.joints = IndexMatrix::Constant(n, 4, -1);
  w.weights = WeightMatrix::Zero(n, 4);
  std::vector<std::pair<double, int>> raw(nb);
  for (int v = 0; v < n; ++v) {
    const Vec3 p = vertices.row(v).transpose();
    for (int b = 0; b < nb; ++b)
      raw[b] = {std::pow(segmentDistance(p, sk.bones[b].head, sk.bones[b].tail) + kWeightOffset, -kWeightPower), b};
    std::partial_sort(raw.begin(), raw.begin() + std::min(4, nb), raw.end(),
                      [](const auto& x, const auto& y) { return x.first > y.first || (x.first == y.first && x.second < y.second); });
    double sum = 0.0;
    for (int s = 0; s < std::min(4, nb); ++s) sum += raw[s].first;
    for (int s = 0; s < std::min(4, nb); ++s) {
      w.joints(v, s) = raw[s].second;
      w.weights(v, s) = raw[s].first / sum;
    }
  }
  return w;
}

std::string boneName(const BoneDef& def, int index, BoneNaming naming) {
  switch (naming) {
    case BoneNaming::Rig: return def.key;
    case BoneNaming::BlenderDefault: {
      if (index == 0) return "Bone";
      std::string digits = std::to_string(index);
      while (digits.size() < 3) digits = "0" + digits;
      return "Bone." + digits;
    }
    case BoneNaming::German: return def.german;
    case BoneNaming::Japanese: return def.japanese;
    case BoneNaming::Unnamed: return "joint_" + std::to_string(index);
  }
  return def.key;
}

// Rest frame hint: the body's front (-Y), or up for bones along Y.
Vec3 rollHint(const Vec3& head, const Vec3& tail) {
  const Vec3 d = (tail - head).normalized();
  return std::abs(d.y()) > 0.8 ? Vec3(0, 0, 1) : Vec3(0, -1, 0);
}

}  // namespace

// ============================================================================
// Public entry
// ============================================================================

const char* bodyKindName(BodyKind kind) { return kind == BodyKind::Biped ? "biped" : "quadruped"; }

const char* boneNamingName(BoneNaming naming) {
  switch (naming) {
    case BoneNaming::Rig: return "rig";
    case BoneNaming::BlenderDefault: return "blender";
    case BoneNaming::German: return "german";
    case BoneNaming::Japanese: return "japanese";
    case BoneNaming::Unnamed: return "unnamed";
  }
  return "rig";
}

SyntheticCharacter makeSyntheticBody(const SyntheticBodyOptions& options) {
  if (!std::isfinite(options.muscleScale) || options.muscleScale < 0.0)
    throw InputError("synthetic body: muscleScale must be finite and >= 0");
  if (!std::isfinite(options.scale) || !(options.scale > 0.0))
    throw InputError("synthetic body: scale must be finite and > 0");
  if (!std::isfinite(options.cellSize) || options.cellSize < 0.0 || options.cellSize > 0.02)
    throw InputError("synthetic body: cellSize must be 0 (default) or in (0, 0.02] metres");
  Jitter jitter(options.seed * 7919u + (options.kind == BodyKind::Biped ? 0u : 1u));
  if (options.seed == 0) jitter = Jitter(0);
  Body body = options.kind == BodyKind::Biped ? makeBiped(jitter, options.muscleScale)
                                              : makeQuadruped(jitter, options.muscleScale);
  // Bounds of every part and of the right twins of the left limbs.
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (Part& part : body.parts) {
    boundPart(part);
    lo = lo.cwiseMin(part.lo), hi = hi.cwiseMax(part.hi);
    if (part.root.x() > 1e-9) lo = lo.cwiseMin(mirrorX(part.hi)), hi = hi.cwiseMax(mirrorX(part.lo));
  }
  const BodyField field(body.parts);
  const double h = options.cellSize > 0 ? options.cellSize : kDefaultCell;
  Mesh skin = marchTetrahedra(field, lo, hi, h);

  SyntheticCharacter out;
  Character& c = out.character;
  c.name = std::string("synthetic_") + bodyKindName(options.kind);
  for (size_t b = 0; b < body.bones.size(); ++b) {
    const BoneDef& def = body.bones[b];
    Bone bone;
    bone.name = boneName(def, static_cast<int>(b), options.naming);
    bone.parent = def.parent;
    bone.head = def.head * options.scale;
    bone.tail = def.tail * options.scale;
    bone.rest = boneMatrix(bone.head, bone.tail, rollHint(def.head, def.tail));
    c.skeleton.bones.push_back(bone);
  }
  skin.vertices *= options.scale;
  // Weights in metres (the offset is a length), from the unscaled positions.
  const SkinWeights weights = buildWeights(skin.vertices / options.scale, [&] {
    Skeleton metres = c.skeleton;
    for (Bone& b : metres.bones) b.head /= options.scale, b.tail /= options.scale;
    return metres;
  }());
  if (!options.split) {
    c.mesh = std::move(skin);
    c.weights = weights;
    c.sourceVertexCount = c.mesh.numVertices();
    c.sourceToWelded.resize(c.sourceVertexCount);
    for (int i = 0; i < c.sourceVertexCount; ++i) c.sourceToWelded[i] = i;
  } else {
    // Each triangle goes to the piece (bone group) that most of its three vertices' dominant bones belong to.
    std::vector<std::string> groups;
    std::map<std::string, int> groupIndex;
    for (const std::string& gname : body.groupOf)
      if (!groupIndex.count(gname)) groupIndex[gname] = static_cast<int>(groups.size()), groups.push_back(gname);
    const Eigen::Index nf = skin.triangles.rows();
    std::vector<int> pieceOf(static_cast<size_t>(nf));
    for (Eigen::Index f = 0; f < nf; ++f) {
      int votes[8] = {0};
      for (int k = 0; k < 3; ++k) ++votes[groupIndex[body.groupOf[weights.joints(skin.triangles(f, k), 0)]]];
      pieceOf[f] = static_cast<int>(std::max_element(votes, votes + groups.size()) - votes);
    }
    Mesh source;
    std::vector<int> sourceOriginal;
    std::vector<Eigen::RowVector3i> tris;
    for (size_t p = 0; p < groups.size(); ++p) {
      std::vector<int> local(static_cast<size_t>(skin.numVertices()), -1);
      const int first = static_cast<int>(sourceOriginal.size());
      for (Eigen::Index f = 0; f < nf; ++f) {
        if (pieceOf[f] != static_cast<int>(p)) continue;
        Eigen::RowVector3i t;
        for (int k = 0; k < 3; ++k) {
          const int v = skin.triangles(f, k);
          if (local[v] < 0) local[v] = static_cast<int>(sourceOriginal.size()), sourceOriginal.push_back(v);
          t[k] = local[v];
        }
        tris.push_back(t);
      }
      c.pieces.push_back({groups[p], first, static_cast<int>(sourceOriginal.size()) - first});
    }
    source.vertices.resize(static_cast<Eigen::Index>(sourceOriginal.size()), 3);
    for (size_t s = 0; s < sourceOriginal.size(); ++s)
      source.vertices.row(static_cast<Eigen::Index>(s)) = skin.vertices.row(sourceOriginal[s]);
    source.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
    for (size_t t = 0; t < tris.size(); ++t) source.triangles.row(static_cast<Eigen::Index>(t)) = tris[t];
    // As the loader does: weld by position (1e-6 of the bounding-box diagonal), weights of the first source vertex.
    Vec3 bmin, bmax;
    boundingBox(source.vertices, bmin, bmax);
    c.mesh = weldByPosition(source, 1e-6 * (bmax - bmin).norm(), c.sourceToWelded);
    c.sourceVertexCount = static_cast<int>(sourceOriginal.size());
    c.weights.joints = IndexMatrix::Constant(c.mesh.numVertices(), 4, -1);
    c.weights.weights = WeightMatrix::Zero(c.mesh.numVertices(), 4);
    std::vector<char> done(static_cast<size_t>(c.mesh.numVertices()), 0);
    for (int s = 0; s < c.sourceVertexCount; ++s) {
      const int w = c.sourceToWelded[s];
      if (done[w]) continue;
      done[w] = 1;
      c.weights.joints.row(w) = weights.joints.row(sourceOriginal[s]);
      c.weights.weights.row(w) = weights.weights.row(sourceOriginal[s]);
    }
  }
  // Ground truth: each limb part's muscles, left and right.
  std::map<std::string, int> boneByKey;
  for (size_t b = 0; b < body.bones.size(); ++b) boneByKey[body.bones[b].key] = static_cast<int>(b);
  // Relief (TrueMuscle::relief) from the whole body's skin, with and without the muscle (the same on both sides).
  std::map<std::pair<int, size_t>, std::vector<double>> reliefOf;
  for (int p : body.limbParts) {
    const Part& part = body.parts[p];
    for (size_t i = 0; i < part.muscles.size(); ++i) {
      std::vector<Part> without = body.parts;
      without[p].muscles.erase(without[p].muscles.begin() + static_cast<std::ptrdiff_t>(i));
      const BodyField fieldWithout(without);
      reliefOf[{p, i}] = muscleRelief(part.muscles[i], part.layout, [&](double x, double theta, bool with) {
        return skinAlongRay(with ? field : fieldWithout, part, x, theta);
      });
    }
  }
  for (int p : body.limbParts) {
    Part part = body.parts[p];
    for (int side = 0; side < 2; ++side) {
      part.mirrored = side == 1;
      const char* suffix = side == 0 ? ".L" : ".R";
      for (size_t i = 0; i < part.muscles.size(); ++i) {
        const MuscleModel& m = part.muscles[i];
        TrueMuscle t = trueMuscle(m, part.layout);
        t.relief = reliefOf.at({p, i});
        for (double& r : t.relief) r *= options.scale;
        for (Vec3& q : t.centerLine) q = part.toWorld(q) * options.scale;
        for (double& r : t.radius) r *= options.scale;
        t.peakRadius *= options.scale;
        t.name = m.name + suffix;
        t.bone = c.skeleton.bones[boneByKey.at(m.bone + suffix)].name;
        out.muscles.push_back(std::move(t));
      }
    }
  }
  validateCharacter(c);
  return out;
}

}  // namespace myoskin
