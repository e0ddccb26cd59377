// The synthetic muscular arm: determinism, a clean closed skin, visible bumps over the true muscles,
// smooth skin without muscles, skin weights, and the ground-truth JSON.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "myoskin/errors.h"
#include "myoskin/mesh.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

// ============================================================================
// Helpers
// ============================================================================

SyntheticCharacter arm(unsigned seed, double muscleScale = 1.0) {
  SyntheticArmOptions o;
  o.seed = seed;
  o.muscleScale = muscleScale;
  return makeSyntheticArm(o);
}

// Farthest hit of the ray from the arm axis at x, in direction (0, cos t, sin t), through the point p's
// angle: the skin radius over p. Brute force over triangles spanning x.
double skinRadiusOver(const Mesh& mesh, const Vec3& p) {
  const Vec3 origin(p.x(), 0.0, 0.0);
  const Vec3 dir = Vec3(0.0, p.y(), p.z()).normalized();
  double best = -1.0;
  for (int f = 0; f < mesh.numTriangles(); ++f) {
    const Vec3 a = mesh.vertices.row(mesh.triangles(f, 0)).transpose();
    const Vec3 b = mesh.vertices.row(mesh.triangles(f, 1)).transpose();
    const Vec3 c = mesh.vertices.row(mesh.triangles(f, 2)).transpose();
    if (std::min({a.x(), b.x(), c.x()}) > p.x() || std::max({a.x(), b.x(), c.x()}) < p.x()) continue;
    const Vec3 e1 = b - a, e2 = c - a, h = dir.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < 1e-15) continue;
    const Vec3 s = origin - a;
    const double u = s.dot(h) / det;
    if (u < -1e-9 || u > 1 + 1e-9) continue;
    const Vec3 q = s.cross(e1);
    const double v = dir.dot(q) / det;
    if (v < -1e-9 || u + v > 1 + 1e-9) continue;
    best = std::max(best, e2.dot(q) / det);
  }
  return best;
}

// Distance of p from the X axis.
double axisDistance(const Vec3& p) { return std::hypot(p.y(), p.z()); }

// The rings of vertices around the axis (tube and caps), in the generator's order: pole, rings, pole.
std::vector<std::vector<int>> rings(const Mesh& mesh, int around) {
  std::vector<std::vector<int>> rings;
  for (int start = 1; start + around <= mesh.numVertices() - 1; start += around) {
    std::vector<int> ring(around);
    for (int j = 0; j < around; ++j) ring[j] = start + j;
    rings.push_back(ring);
  }
  return rings;
}

// True if the ring polygon (projected on YZ) turns the same way at every vertex.
bool ringIsConvex(const Mesh& mesh, const std::vector<int>& ring) {
  const int n = static_cast<int>(ring.size());
  for (int j = 0; j < n; ++j) {
    const Eigen::Vector2d p0 = mesh.vertices.row(ring[(j + n - 1) % n]).tail<2>().transpose();
    const Eigen::Vector2d p1 = mesh.vertices.row(ring[j]).tail<2>().transpose();
    const Eigen::Vector2d p2 = mesh.vertices.row(ring[(j + 1) % n]).tail<2>().transpose();
    const Eigen::Vector2d d1 = p1 - p0, d2 = p2 - p1;
    if (d1.x() * d2.y() - d1.y() * d2.x() < -1e-12) return false;
  }
  return true;
}

}  // namespace

// ============================================================================
// Determinism and options
// ============================================================================

TEST(SyntheticArm, IsDeterministic) {
  for (unsigned seed : {0u, 1u, 7u}) {
    const SyntheticCharacter a = arm(seed), b = arm(seed);
    EXPECT_EQ(a.character.mesh.vertices, b.character.mesh.vertices);
    EXPECT_EQ(a.character.mesh.triangles, b.character.mesh.triangles);
    EXPECT_EQ(a.character.weights.joints, b.character.weights.joints);
    EXPECT_EQ(a.character.weights.weights, b.character.weights.weights);
    ASSERT_EQ(a.muscles.size(), b.muscles.size());
    ASSERT_EQ(a.muscles.size(), 6u);
    for (size_t m = 0; m < a.muscles.size(); ++m) {
      EXPECT_EQ(a.muscles[m].centerLine, b.muscles[m].centerLine);
      EXPECT_EQ(a.muscles[m].radius, b.muscles[m].radius);
    }
  }
}

TEST(SyntheticArm, DifferentSeedsDiffer) {
  const SyntheticCharacter a = arm(0), b = arm(1), c = arm(2);
  // Seeds change bone lengths and so the ring count: Eigen's != needs equal sizes (it asserted under the sanitizer
  // build, and read past the smaller matrix in Release).
  const auto differ = [](const Points& p, const Points& q) { return p.rows() != q.rows() || p != q; };
  EXPECT_TRUE(differ(a.character.mesh.vertices, b.character.mesh.vertices));
  EXPECT_TRUE(differ(b.character.mesh.vertices, c.character.mesh.vertices));
  EXPECT_NE(b.muscles[1].centerLine, c.muscles[1].centerLine);
  EXPECT_NE(b.character.skeleton.bones[1].tail, c.character.skeleton.bones[1].tail);
}

TEST(SyntheticArm, RejectsBadOptions) {
  SyntheticArmOptions o;
  o.ringsPerMetre = 5;
  EXPECT_THROW(makeSyntheticArm(o), InputError);
  o = {};
  o.segmentsAround = 4;
  EXPECT_THROW(makeSyntheticArm(o), InputError);
  o = {};
  o.muscleScale = -1.0;
  EXPECT_THROW(makeSyntheticArm(o), InputError);
  o.muscleScale = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(makeSyntheticArm(o), InputError);
}

// ============================================================================
// Skin and skeleton
// ============================================================================

TEST(SyntheticArm, SkinIsClosedManifoldOrientedOnePiece) {
  for (unsigned seed : {0u, 1u, 2u, 3u})
    for (double scale : {0.0, 0.5, 1.0, 1.5}) {
      SCOPED_TRACE("seed " + std::to_string(seed) + " scale " + std::to_string(scale));
      const SyntheticCharacter s = arm(seed, scale);
      const Mesh& mesh = s.character.mesh;
      const TopologyReport t = analyzeTopology(mesh);
      EXPECT_TRUE(t.closed());
      EXPECT_TRUE(t.manifold());
      EXPECT_TRUE(t.oriented());
      EXPECT_EQ(t.components, 1);
      EXPECT_EQ(t.degenerateTriangles, 0);
      EXPECT_GT(enclosedVolume(mesh.vertices, mesh.triangles), 0.0);
      double minArea = std::numeric_limits<double>::infinity();
      for (int f = 0; f < mesh.numTriangles(); ++f) {
        const Vec3 a = mesh.vertices.row(mesh.triangles(f, 0)).transpose();
        const Vec3 b = mesh.vertices.row(mesh.triangles(f, 1)).transpose();
        const Vec3 c = mesh.vertices.row(mesh.triangles(f, 2)).transpose();
        minArea = std::min(minArea, 0.5 * (b - a).cross(c - a).norm());
      }
      EXPECT_GT(minArea, 1e-9);  // 1 mm^2 / 1000
    }
}

TEST(SyntheticArm, DefaultSizeAndShape) {
  const SyntheticCharacter s = arm(0);
  const Mesh& mesh = s.character.mesh;
  std::printf("synthetic arm (seed 0): %d vertices, %d triangles, volume %.3f l\n", mesh.numVertices(),
              mesh.numTriangles(), 1000.0 * enclosedVolume(mesh.vertices, mesh.triangles));
  EXPECT_GE(mesh.numVertices(), 20000);
  EXPECT_LE(mesh.numVertices(), 40000);
  Vec3 lo, hi;
  boundingBox(mesh.vertices, lo, hi);
  EXPECT_LT(lo.x(), 0.0);
  EXPECT_GT(hi.x(), 0.83);
  EXPECT_LT(hi.y(), 0.08);
  EXPECT_LT(hi.z(), 0.08);
  EXPECT_EQ(s.character.name, "synthetic_arm");
  EXPECT_EQ(s.character.sourceVertexCount, mesh.numVertices());
  ASSERT_EQ(static_cast<int>(s.character.sourceToWelded.size()), mesh.numVertices());
  for (int i = 0; i < mesh.numVertices(); ++i) ASSERT_EQ(s.character.sourceToWelded[i], i);
  EXPECT_NO_THROW(validateCharacter(s.character));
}

TEST(SyntheticArm, SkeletonIsAChainAlongX) {
  const Skeleton& sk = arm(1).character.skeleton;
  ASSERT_EQ(sk.numBones(), 4);
  const char* names[] = {"clavicle", "upper_arm", "forearm", "hand"};
  for (int i = 0; i < 4; ++i) {
    const Bone& b = sk.bones[i];
    EXPECT_EQ(b.name, names[i]);
    EXPECT_EQ(b.parent, i - 1);
    EXPECT_NEAR((b.tail - b.head).normalized().x(), 1.0, 1e-12);
    EXPECT_TRUE(b.rest.isApprox(boneMatrix(b.head, b.tail, -Vec3::UnitY())));
    EXPECT_NEAR(b.rest(2, 2), 1.0, 1e-12);  // bone Z = world Z (Blender roll 0)
    if (i > 0) EXPECT_EQ(b.head, sk.bones[i - 1].tail);
  }
  EXPECT_EQ(sk.bones[0].head, Vec3::Zero());
  EXPECT_NEAR(sk.bones[0].length(), 0.18, 0.18 * 0.07);
  EXPECT_NEAR(sk.bones[1].length(), 0.30, 0.30 * 0.07);
  EXPECT_NEAR(sk.bones[2].length(), 0.26, 0.26 * 0.07);
  EXPECT_NEAR(sk.bones[3].length(), 0.09, 0.09 * 0.07);
}

TEST(SyntheticArm, SkinIsSmoothAroundEachRing) {
  // No cliffs: between neighbouring vertices of a ring the radius changes by less than the arc step.
  for (unsigned seed : {0u, 1u, 2u, 3u, 4u, 5u})
    for (double scale : {0.3, 0.6, 1.0, 1.5}) {
    const SyntheticCharacter s = arm(seed, scale);
    const Mesh& mesh = s.character.mesh;
    double worst = 0.0;
    for (const auto& ring : rings(mesh, 96))
      for (int j = 0; j < 96; ++j) {
        const Vec3 p = mesh.vertices.row(ring[j]).transpose(), q = mesh.vertices.row(ring[(j + 1) % 96]).transpose();
        const double r0 = axisDistance(p), r1 = axisDistance(q);
        worst = std::max(worst, std::abs(r1 - r0) / (0.5 * (r0 + r1) * 2.0 * M_PI / 96));
      }
    std::printf("seed %u scale %.1f: steepest ring slope %.2f\n", seed, scale, worst);
    EXPECT_LT(worst, 2.0) << "seed " << seed;  // a cliff (a belly's silhouette above the limb) gives > 3
  }
}

// ============================================================================
// Muscles and bumps
// ============================================================================

TEST(SyntheticArm, NoMusclesGivesASmoothArm) {
  const SyntheticCharacter smooth = arm(0, 0.0), muscular = arm(0, 1.0);
  EXPECT_TRUE(smooth.muscles.empty());
  int concaveSmooth = 0, concaveMuscular = 0;
  for (const auto& ring : rings(smooth.character.mesh, 96))
    concaveSmooth += ringIsConvex(smooth.character.mesh, ring) ? 0 : 1;
  for (const auto& ring : rings(muscular.character.mesh, 96))
    concaveMuscular += ringIsConvex(muscular.character.mesh, ring) ? 0 : 1;
  EXPECT_EQ(concaveSmooth, 0);  // every section is an ellipse (convex): no bumps, no valleys
  EXPECT_GT(concaveMuscular, 100);  // valleys between bellies
}

TEST(SyntheticArm, HasTheSixMusclesWithSaneTruth) {
  const SyntheticCharacter s = arm(0);
  const char* names[] = {"deltoid", "biceps", "triceps", "brachialis", "forearm_flexors", "forearm_extensors"};
  ASSERT_EQ(s.muscles.size(), 6u);
  for (size_t m = 0; m < 6; ++m) {
    const TrueMuscle& t = s.muscles[m];
    EXPECT_EQ(t.name, names[m]);
    EXPECT_GE(s.character.skeleton.find(t.bone), 0);
    EXPECT_GE(t.centerLine.size(), 20u);
    EXPECT_LE(t.centerLine.size(), 40u);
    ASSERT_EQ(t.radius.size(), t.centerLine.size());
    double peak = 0.0;
    for (size_t k = 0; k < t.radius.size(); ++k) {
      EXPECT_GT(t.radius[k], 0.09 * t.peakRadius);
      peak = std::max(peak, t.radius[k]);
      if (k > 0) EXPECT_GT(t.centerLine[k].x(), t.centerLine[k - 1].x());
    }
    EXPECT_LE(peak, t.peakRadius + 1e-12);
    EXPECT_GT(peak, 0.95 * t.peakRadius);
  }
  // Biceps on top (+Z), triceps underneath.
  EXPECT_GT(s.muscles[1].centerLine[16].z(), 0.02);
  EXPECT_LT(s.muscles[2].centerLine[16].z(), -0.02);
}

TEST(SyntheticArm, CentreLinesLieUnderTheSkinAndBumpsProtrude) {
  for (unsigned seed : {0u, 1u, 2u}) {
    const SyntheticCharacter s = arm(seed), smooth = arm(seed, 0.0);
    ASSERT_EQ(s.muscles.size(), 6u);
    for (const TrueMuscle& t : s.muscles) {
      double protrusion = 0.0;
      for (size_t k = 0; k < t.centerLine.size(); ++k) {
        const Vec3& p = t.centerLine[k];
        const double skin = skinRadiusOver(s.character.mesh, p);
        ASSERT_GT(skin, 0.0);
        // Inside, and at least half the muscle's radius below the skin.
        EXPECT_LT(axisDistance(p) + 0.5 * t.radius[k], skin) << t.name << " point " << k;
        protrusion = std::max(protrusion, skin - skinRadiusOver(smooth.character.mesh, p));
      }
      if (seed == 0)
        std::printf("  %-18s peak radius %5.1f mm, length %5.1f mm, peak protrusion %5.1f mm\n", t.name.c_str(),
                    1000 * t.peakRadius, 1000 * (t.centerLine.back() - t.centerLine.front()).norm(),
                    1000 * protrusion);
      EXPECT_GE(protrusion, 0.005) << t.name << " seed " << seed;
    }
  }
}

TEST(SyntheticArm, MuscleScaleScalesTheBumps) {
  const SyntheticCharacter half = arm(0, 0.5), full = arm(0, 1.0), smooth = arm(0, 0.0);
  ASSERT_EQ(half.muscles.size(), full.muscles.size());
  ASSERT_EQ(full.muscles.size(), 6u);
  for (size_t m = 0; m < full.muscles.size(); ++m) {
    EXPECT_NEAR(half.muscles[m].peakRadius, 0.5 * full.muscles[m].peakRadius, 1e-12);
    const Vec3& p = full.muscles[m].centerLine[16];
    const double base = skinRadiusOver(smooth.character.mesh, p);
    EXPECT_LT(skinRadiusOver(half.character.mesh, p) - base, skinRadiusOver(full.character.mesh, p) - base);
  }
}

// ============================================================================
// Skin weights
// ============================================================================

TEST(SyntheticArm, WeightsArePartitionsOfUnityBlendedAtJoints) {
  const SyntheticCharacter s = arm(1);
  const Character& c = s.character;
  ASSERT_EQ(c.weights.numVertices(), c.mesh.numVertices());
  ASSERT_EQ(c.weights.influences(), 4);
  const double shoulder = c.skeleton.bones[1].head.x(), elbow = c.skeleton.bones[2].head.x();
  int blended = 0;
  for (int i = 0; i < c.mesh.numVertices(); ++i) {
    double sum = 0.0, clavicle = 0.0;
    int used = 0;
    for (int k = 0; k < 4; ++k) {
      const int j = c.weights.joints(i, k);
      const double w = c.weights.weights(i, k);
      EXPECT_GE(w, 0.0);
      if (j < 0) {
        EXPECT_EQ(w, 0.0);
        continue;
      }
      ++used;
      sum += w;
      if (j == 0) clavicle += w;
    }
    ASSERT_NEAR(sum, 1.0, 1e-12) << "vertex " << i;
    const double x = c.mesh.vertices(i, 0);
    if (x > shoulder + 0.021) EXPECT_EQ(clavicle, 0.0) << "vertex " << i;
    if (std::abs(x - elbow) < 0.01) blended += used == 2 ? 1 : 0;
  }
  EXPECT_GT(blended, 0);
}

// ============================================================================
// Ground-truth JSON
// ============================================================================

TEST(SyntheticArm, TruthJsonRoundTrips) {
  const SyntheticCharacter s = arm(3);
  const std::vector<TrueMuscle> back = trueMusclesFromJson(trueMusclesToJson(s.muscles));
  ASSERT_EQ(back.size(), s.muscles.size());
  ASSERT_EQ(back.size(), 6u);
  for (size_t m = 0; m < back.size(); ++m) {
    EXPECT_EQ(back[m].name, s.muscles[m].name);
    EXPECT_EQ(back[m].bone, s.muscles[m].bone);
    EXPECT_DOUBLE_EQ(back[m].peakRadius, s.muscles[m].peakRadius);
    ASSERT_EQ(back[m].centerLine.size(), s.muscles[m].centerLine.size());
    for (size_t k = 0; k < back[m].centerLine.size(); ++k) {
      EXPECT_TRUE(back[m].centerLine[k].isApprox(s.muscles[m].centerLine[k], 1e-12));
      EXPECT_DOUBLE_EQ(back[m].radius[k], s.muscles[m].radius[k]);
    }
    ASSERT_EQ(back[m].relief.size(), s.muscles[m].relief.size());
    ASSERT_EQ(back[m].relief.size(), back[m].centerLine.size());
    for (size_t k = 0; k < back[m].relief.size(); ++k) EXPECT_DOUBLE_EQ(back[m].relief[k], s.muscles[m].relief[k]);
  }
  EXPECT_TRUE(trueMusclesFromJson(trueMusclesToJson({})).empty());
}

TEST(SyntheticArm, TruthReliefAndItsJson) {
  // Relief: how far each muscle raises the skin over the arm without it; the tendon ends lie under the skin.
  const SyntheticCharacter s = arm(1);
  ASSERT_EQ(s.muscles.size(), 6u);
  for (const TrueMuscle& m : s.muscles) {
    ASSERT_EQ(m.relief.size(), m.centerLine.size()) << m.name;
    const double peak = *std::max_element(m.relief.begin(), m.relief.end());
    EXPECT_GT(peak, 0.1 * m.peakRadius) << m.name;
    EXPECT_LT(std::min(m.relief.front(), m.relief.back()), 0.5 * peak) << m.name;
    EXPECT_GE(*std::min_element(m.relief.begin(), m.relief.end()), 0.0) << m.name;
  }
  // JSON: relief optional (absent or empty = unknown), one value per point, never negative.
  std::string json = trueMusclesToJson({s.muscles[0]});
  const size_t at = json.find("\"relief\"");
  ASSERT_NE(at, std::string::npos);
  std::vector<TrueMuscle> none = s.muscles;
  none.resize(1);
  none[0].relief.clear();
  EXPECT_TRUE(trueMusclesFromJson(trueMusclesToJson(none))[0].relief.empty());
  TrueMuscle shortRelief = s.muscles[0];
  shortRelief.relief.pop_back();
  EXPECT_THROW(trueMusclesFromJson(trueMusclesToJson({shortRelief})), InputError);
  TrueMuscle negative = s.muscles[0];
  negative.relief[3] = -1e-3;
  EXPECT_THROW(trueMusclesFromJson(trueMusclesToJson({negative})), InputError);
}

TEST(SyntheticArm, TruthJsonRejectsBadInput) {
  EXPECT_THROW(trueMusclesFromJson("not json"), InputError);
  EXPECT_THROW(trueMusclesFromJson(R"({"format":"other","version":1,"muscles":[]})"), InputError);
  EXPECT_THROW(trueMusclesFromJson(R"({"format":"myoskin.true_muscles","version":2,"muscles":[]})"), InputError);
  const std::string head = R"({"format":"myoskin.true_muscles","version":1,"muscles":[)";
  EXPECT_THROW(trueMusclesFromJson(head + R"({"name":"m","bone":"b","center_line":[[0,0,0],[1,0,0]],"radius":[1],"peak_radius":1}]})"),
               InputError);
  EXPECT_THROW(trueMusclesFromJson(head + R"({"name":"m","bone":"b","center_line":[[0,0,0],[1,0]],"radius":[1,1],"peak_radius":1}]})"),
               InputError);
  EXPECT_THROW(trueMusclesFromJson(head + R"({"name":"m","bone":"b","center_line":[[0,0,0],[1,0,0]],"radius":[1,-1],"peak_radius":1}]})"),
               InputError);
  EXPECT_THROW(trueMusclesFromJson(head + R"({"bone":"b","center_line":[[0,0,0],[1,0,0]],"radius":[1,1],"peak_radius":1}]})"),
               InputError);
  EXPECT_NO_THROW(trueMusclesFromJson(head + R"({"name":"m","bone":"b","center_line":[[0,0,0],[1,0,0]],"radius":[1,1],"peak_radius":1}]})"));
}
