// Muscle shapes that read as muscles (issue 14 item 4): every extracted muscle's rest surface is watertight, free of
// self-intersections, untwisted and unspiked, and inside the skin, on the shared characters (skipped when
// ../shared is absent) and on held-out generated bodies. Prints one line per character: the worst muscle's figures.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/muscle_shape.h"
#include "myoskin/synthetic_character.h"
#include "test_support.h"

using namespace myoskin;

namespace {

const int kRing = SurfaceOptions{}.ringVertices;

// Tolerances (relative: degrees, ring radii). Measured with the lofts of main before this change (same characters):
// 2-8 self-intersecting muscles per shared character, spikes up to 1.31 ring radii, folds (dihedral up to 180
// degrees), 310 vertices outside the skin on makehuman_muscular_male (up to 0.49 limb radii; horse 0.60); now none,
// spikes at most 0.52, dihedral at most 91 degrees.
constexpr double kMaxTwist = 30.0;      // degrees between neighbouring elongated rings
constexpr double kMaxSpike = 0.6;       // normal offset from the neighbours' mean, in ring radii (main: up to 1.31)
constexpr double kMaxDihedral = 120.0;  // degrees between neighbouring triangles: no fold (main: up to 180)

struct Worst {
  int muscles = 0, leaky = 0, intersecting = 0, outsideMuscles = 0, outsideVertices = 0;
  double twist = 0, spike = 0, dihedral = 0, outside = 0;
  std::string twistName, spikeName, outsideName;
};

// Measures and asserts every muscle of an extraction on `c`; prints the worst figures under `label`.
Worst checkShapes(const std::string& label, const Character& c, const ExtractionResult& r) {
  Worst w;
  EXPECT_FALSE(r.muscles.empty()) << label << ": no muscle extracted";
  const SkinWinding skin(c.mesh.vertices, c.mesh.triangles);
  const double limb = r.report.limbRadius;
  EXPECT_GT(limb, 0.0) << label;
  for (const Muscle& m : r.muscles) {
    const MuscleShape s = measureMuscleShape(m.surface, kRing, &skin, limb);
    ++w.muscles;
    w.leaky += !s.watertight;
    w.intersecting += s.selfIntersections > 0;
    if (s.maxTwist > w.twist) w.twist = s.maxTwist, w.twistName = m.name;
    if (s.maxSpike > w.spike) w.spike = s.maxSpike, w.spikeName = m.name;
    w.dihedral = std::max(w.dihedral, s.maxDihedral);
    w.outsideMuscles += s.outside > 0;
    w.outsideVertices += s.outside;
    if (s.maxOutside > w.outside) w.outside = s.maxOutside, w.outsideName = m.name;
    EXPECT_TRUE(s.watertight) << label << " " << m.name << ": volume " << s.volume;
    EXPECT_EQ(s.selfIntersections, 0) << label << " " << m.name;
    EXPECT_LE(s.maxTwist, kMaxTwist) << label << " " << m.name;
    EXPECT_LE(s.maxSpike, kMaxSpike) << label << " " << m.name;
    EXPECT_LE(s.maxDihedral, kMaxDihedral) << label << " " << m.name;
    EXPECT_EQ(s.outside, 0) << label << " " << m.name << ": up to " << s.maxOutside << " limb radii outside";
  }
  std::printf("%-28s %2d muscles: leaky %d, self-intersecting %d, twist %5.1f deg (%s), spike %.2f (%s), dihedral %5.1f, "
              "outside %d muscles / %d vertices, up to %.3f r (%s)\n",
              label.c_str(), w.muscles, w.leaky, w.intersecting, w.twist, w.twistName.c_str(), w.spike,
              w.spikeName.c_str(), w.dihedral, w.outsideMuscles, w.outsideVertices, w.outside, w.outsideName.c_str());
  return w;
}

void checkShared(const std::string& relative, const std::string& label) {
  const std::string path = test::sharedPath(relative);
  MYOSKIN_REQUIRE_SHARED(path);
  const Character c = loadCharacter(path);
  checkShapes(label, c, extractMuscles(c));
}

}  // namespace

// ============================================================================
// The winding number and the containment on simple shapes
// ============================================================================

// A closed outward box: winding 1 inside, 0 outside, distance to the nearest face.
TEST(MuscleShapes, WindingNumberOfABox) {
  Mesh box;
  box.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i) box.vertices.row(i) << (i & 1) * 2.0, ((i >> 1) & 1) * 1.0, ((i >> 2) & 1) * 1.0;
  box.triangles.resize(12, 3);
  box.triangles << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3,
      7, 5;
  ASSERT_GT(enclosedVolume(box.vertices, box.triangles), 0);
  const SkinWinding w(box.vertices, box.triangles);
  EXPECT_NEAR(w.windingNumber(Vec3(1.0, 0.5, 0.5)), 1.0, 1e-9);
  EXPECT_NEAR(w.windingNumber(Vec3(0.1, 0.9, 0.2)), 1.0, 1e-9);
  EXPECT_NEAR(w.windingNumber(Vec3(3.0, 0.5, 0.5)), 0.0, 1e-9);
  EXPECT_NEAR(w.windingNumber(Vec3(-5.0, 7.0, 2.0)), 0.0, 1e-2);
  EXPECT_NEAR(w.distance(Vec3(1.0, 0.5, 0.5)), 0.5, 1e-12);
  EXPECT_NEAR(w.distance(Vec3(3.0, 0.5, 0.5)), 1.0, 1e-12);
  EXPECT_NEAR(w.distance(Vec3(3.0, 2.0, 0.5)), std::sqrt(2.0), 1e-12);
  // An open box (its top removed) still tells inside from outside in the middle.
  Mesh open = box;
  open.triangles.resize(10, 3);
  open.triangles << 0, 2, 1, 1, 2, 3, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
  const SkinWinding wo(open.vertices, open.triangles);
  EXPECT_TRUE(wo.inside(Vec3(1.0, 0.5, 0.3)));
  EXPECT_FALSE(wo.inside(Vec3(1.0, 0.5, -0.3)));
  EXPECT_FALSE(wo.inside(Vec3(4.0, 0.5, 0.5)));
  EXPECT_NE(test::inputErrorOf([] { SkinWinding(Points(0, 3), Triangles(0, 3)); }), "");
}

// A muscle lofted through a thin skin tube comes out partly outside; containment brings every vertex inside with
// its margin and keeps the surface watertight and smooth.
TEST(MuscleShapes, ContainmentPullsALoftInsideTheSkin) {
  // Skin: a closed cylinder of radius 1 along x from -3 to 3 (48 around, 30 along) with fan caps.
  Mesh skin;
  const int A = 48, L = 30;
  skin.vertices.resize(A * (L + 1) + 2, 3);
  for (int i = 0; i <= L; ++i)
    for (int k = 0; k < A; ++k) {
      const double t = 2 * 3.14159265358979323846 * k / A;
      skin.vertices.row(i * A + k) << -3.0 + 6.0 * i / L, std::cos(t), std::sin(t);
    }
  const int c0 = A * (L + 1), c1 = c0 + 1;
  skin.vertices.row(c0) << -3, 0, 0;
  skin.vertices.row(c1) << 3, 0, 0;
  std::vector<Eigen::Vector3i> tris;
  for (int i = 0; i < L; ++i)
    for (int k = 0; k < A; ++k) {
      const int a = i * A + k, b = i * A + (k + 1) % A, c = (i + 1) * A + (k + 1) % A, d = (i + 1) * A + k;
      tris.emplace_back(a, b, c), tris.emplace_back(a, c, d);
    }
  for (int k = 0; k < A; ++k) tris.emplace_back(c0, (k + 1) % A, k), tris.emplace_back(c1, L * A + k, L * A + (k + 1) % A);
  skin.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) skin.triangles.row(static_cast<Eigen::Index>(f)) = tris[f].transpose();
  if (enclosedVolume(skin.vertices, skin.triangles) < 0)
    for (int f = 0; f < skin.numTriangles(); ++f) std::swap(skin.triangles(f, 1), skin.triangles(f, 2));
  // Muscle: sections of semi-axes 0.8 and 0.4 centred 0.5 off the axis (it pokes out by up to 0.3).
  Muscle m;
  m.name = "test";
  m.origin.position = Vec3(-2.5, 0.3, 0);
  m.insertion.position = Vec3(2.5, 0.3, 0);
  for (int i = 0; i < 7; ++i) {
    MuscleSection s;
    s.center = Vec3(-1.5 + 0.5 * i, 0.5, 0.0);
    s.u = -0.6 + 0.2 * i;
    s.axisA = Vec3::UnitY();
    s.a = 0.8, s.b = 0.4;
    s.normal = Vec3::UnitX();
    m.sections.push_back(s);
  }
  m.rootCurve = {m.origin.position};
  for (const MuscleSection& s : m.sections) m.rootCurve.push_back(s.center);
  m.rootCurve.push_back(m.insertion.position);
  Mesh surface = loftMuscleSurface(m);
  const SkinWinding w(skin.vertices, skin.triangles);
  const MuscleShape before = measureMuscleShape(surface, kRing, &w, 1.0);
  EXPECT_GT(before.outside, 20);
  EXPECT_GT(before.maxOutside, 0.2);
  const int moved = containMuscleSurface(surface, kRing, w, 0.1);
  EXPECT_GE(moved, before.outside);
  const MuscleShape after = measureMuscleShape(surface, kRing, &w, 1.0);
  EXPECT_EQ(after.outside, 0);
  EXPECT_TRUE(after.watertight);
  EXPECT_EQ(after.selfIntersections, 0);
  EXPECT_LE(after.maxSpike, kMaxSpike);
  // Every ring vertex stays at least ~margin of its radius inside: radius from the axis <= 1 - 0.1 * 0.3 or so.
  double farthest = 0.0;
  for (int v = 0; v < surface.numVertices(); ++v)
    farthest = std::max(farthest, surface.vertices.row(v).tail<2>().norm());
  EXPECT_LT(farthest, 0.99);
  EXPECT_GT(farthest, 0.9);  // pulled in, not collapsed
  EXPECT_NE(test::inputErrorOf([&] { measureMuscleShape(skin, kRing); }), "");
}

// An elongated ellipse turning 20 degrees per section, written each time in one of its equivalent forms (axis a
// reversed, or turned 90 degrees with the semi-axes swapped): the loft unwraps the angle, so neighbouring rings turn
// by about 20 degrees, not by the 70-110 the written axes jump.
TEST(MuscleShapes, UnwrappedEllipseAnglesTurnSmoothly) {
  Muscle m;
  m.name = "turning";
  const double kPi = 3.14159265358979323846;
  for (int i = 0; i < 8; ++i) {
    MuscleSection s;
    s.center = Vec3(0.03 * i, 0.0, 0.0);
    s.u = -0.8 + 0.2 * i;
    s.normal = Vec3::UnitX();
    const double t = (20.0 * i) * kPi / 180.0;
    const Vec3 a(0, std::cos(t), std::sin(t)), b(0, -std::sin(t), std::cos(t));
    if (i % 3 == 0) s.axisA = a, s.a = 0.03, s.b = 0.012;
    if (i % 3 == 1) s.axisA = -a, s.a = 0.03, s.b = 0.012;
    if (i % 3 == 2) s.axisA = b, s.a = 0.012, s.b = 0.03;
    m.sections.push_back(s);
  }
  m.origin.position = Vec3(-0.05, 0, 0);
  m.insertion.position = Vec3(0.26, 0, 0);
  m.rootCurve = {m.origin.position};
  for (const MuscleSection& s : m.sections) m.rootCurve.push_back(s.center);
  m.rootCurve.push_back(m.insertion.position);
  const Mesh surface = loftMuscleSurface(m);
  const MuscleShape shape = measureMuscleShape(surface, kRing);
  EXPECT_TRUE(shape.watertight);
  EXPECT_EQ(shape.selfIntersections, 0);
  EXPECT_GT(shape.maxTwist, 10.0);  // it does turn
  EXPECT_LE(shape.maxTwist, 21.0);
  EXPECT_LE(shape.maxSpike, kMaxSpike);
  EXPECT_EQ(shape.outside, 0);  // no skin given: nothing counted
}

// ============================================================================
// Extracted muscles on real and generated characters
// ============================================================================

TEST(MuscleShapes, MakeHumanMuscularMale) {
  checkShared("characters/makehuman_muscular_male/makehuman_muscular_male.glb", "makehuman_muscular_male");
}

TEST(MuscleShapes, MakeHumanNeutral) {
  checkShared("characters/makehuman_neutral/makehuman_neutral.glb", "makehuman_neutral");
}

TEST(MuscleShapes, GodotMaleLowPoly) {
  checkShared("characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb", "godot_male_base_mesh_lowpoly");
}

TEST(MuscleShapes, QuaterniusHorse) { checkShared("characters/quaternius_horse/horse.glb", "quaternius_horse (x100)"); }

TEST(MuscleShapes, QuaterniusWomanSoldier) {
  checkShared("characters/quaternius_woman_soldier/woman_soldier.glb", "quaternius_woman_soldier");
}

// The held-out seeds 20-27 (test_varied_characters), bipeds on even seeds and quadrupeds on odd ones (a few seconds
// each: 90k-140k vertices).
TEST(MuscleShapes, HeldOutGeneratedBodies) {
  for (unsigned seed = 20; seed <= 27; ++seed) {
    SyntheticBodyOptions o;
    o.seed = seed;
    o.kind = seed % 2 ? BodyKind::Quadruped : BodyKind::Biped;
    const SyntheticCharacter b = makeSyntheticBody(o);
    checkShapes(std::string("generated ") + bodyKindName(o.kind) + " " + std::to_string(seed), b.character,
                extractMuscles(b.character));
  }
}
