// Characters as artists export them: any units and placement, several meshes, any bone names, and a reason when
// nothing is found (the "any character" issue).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "test_support.h"

using namespace myoskin;

namespace {

// A similarity transform p -> s R p + t applied to the whole character (skin, bones, rest frames).
struct Similarity {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Vec3 translation = Vec3::Zero();
  Vec3 apply(const Vec3& p) const { return scale * (rotation * p) + translation; }
  Vec3 invert(const Vec3& p) const { return rotation.transpose() * (p - translation) / scale; }
};

Character transformed(const Character& c, const Similarity& x) {
  Character out = c;
  for (Eigen::Index v = 0; v < out.mesh.vertices.rows(); ++v)
    out.mesh.vertices.row(v) = x.apply(c.mesh.vertices.row(v).transpose()).transpose();
  for (Bone& b : out.skeleton.bones) {
    b.head = x.apply(b.head), b.tail = x.apply(b.tail);
    b.rest.block<3, 3>(0, 0) = x.rotation * b.rest.block<3, 3>(0, 0);
    b.rest.block<3, 1>(0, 3) = b.head;
  }
  return out;
}

// Largest distance between the root curves of two muscles of the same name, the second mapped back by `x`.
double rootCurveDistance(const Muscle& a, const Muscle& b, const Similarity& x) {
  double worst = a.rootCurve.size() == b.rootCurve.size() ? 0.0 : INFINITY;
  for (size_t k = 0; k < a.rootCurve.size() && k < b.rootCurve.size(); ++k)
    worst = std::max(worst, (a.rootCurve[k] - x.invert(b.rootCurve[k])).norm());
  return worst;
}

// The character with every bone renamed by `name(index)`, weights and shape unchanged.
Character renamed(const Character& c, const std::function<std::string(int)>& name) {
  Character out = c;
  for (int i = 0; i < out.skeleton.numBones(); ++i) out.skeleton.bones[i].name = name(i);
  return out;
}

std::set<int> bonesWithRole(const std::vector<BoneRole>& roles, BoneRole role) {
  std::set<int> out;
  for (size_t i = 0; i < roles.size(); ++i)
    if (roles[i] == role) out.insert(static_cast<int>(i));
  return out;
}

}  // namespace

// ============================================================================
// Units and placement
// ============================================================================

TEST(AnyCharacter, SameMusclesInAnyUnitsAndPlacement) {
  const std::string path = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  MYOSKIN_REQUIRE_SHARED(path);
  const Character c = loadCharacter(path);
  const ExtractionResult base = extractMuscles(c);
  ASSERT_GE(base.muscles.size(), 10u);
  const double tolerance = 0.01 * base.report.limbRadius;  // 1 % of the limb radius
  std::vector<Similarity> cases(5);
  cases[0].scale = 0.01;                                     // Mixamo's centimetre armature
  cases[1].scale = 100.0;                                    // FBX2glTF's x100
  cases[2].scale = 1000.0;                                   // millimetres, moved far from the origin
  cases[2].translation = Vec3(2500.0, -300.0, 40.0);
  cases[3].rotation = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();  // turned and moved
  cases[3].translation = Vec3(3.0, -1.5, 0.25);
  cases[4].scale = 100.0;                                    // all at once
  cases[4].rotation = Eigen::AngleAxisd(-1.2, Vec3(0.2, 1, -0.4).normalized()).toRotationMatrix();
  cases[4].translation = Vec3(-40.0, 7.0, 120.0);
  for (size_t k = 0; k < cases.size(); ++k) {
    const ExtractionResult r = extractMuscles(transformed(c, cases[k]), ExtractionOptions{});
    ASSERT_EQ(r.muscles.size(), base.muscles.size()) << "case " << k;
    EXPECT_NEAR(r.report.limbRadius, cases[k].scale * base.report.limbRadius, 1e-9 * cases[k].scale);
    // Every section centre and root-curve point agrees to 1 % of the limb radius, every section size to 1 % of itself
    // (measured: within 7e-14 m, the transform's round-off; when a belly fit shrank in 7 % steps a few sections tipped
    // by up to 2.4 mm, and this test allowed 10 %).
    double worstCentre = 0.0, worstCurve = 0.0;
    int sections = 0, tipped = 0;  // sections, and those whose centre moved more than 1 % of the limb radius
    for (size_t m = 0; m < base.muscles.size(); ++m) {
      const Muscle &a = base.muscles[m], &b = r.muscles[m];
      ASSERT_EQ(b.name, a.name) << "case " << k;
      ASSERT_EQ(b.sections.size(), a.sections.size()) << a.name;
      for (size_t q = 0; q < a.sections.size(); ++q) {
        const double d = (a.sections[q].center - cases[k].invert(b.sections[q].center)).norm();
        worstCentre = std::max(worstCentre, d);
        ++sections, tipped += d > tolerance;
        const double size0 = std::sqrt(a.sections[q].a * a.sections[q].b);
        EXPECT_NEAR(std::sqrt(b.sections[q].a * b.sections[q].b) / cases[k].scale, size0, 0.01 * size0) << a.name;
      }
      worstCurve = std::max(worstCurve, rootCurveDistance(a, b, cases[k]));
    }
    std::printf("case %zu (x%g): %zu muscles; section centres within %.2e (%d of %d over 1 %% of the limb radius), root "
                "curves within %.2e (limb radius %.4f)\n", k, cases[k].scale, r.muscles.size(), worstCentre, tipped, sections,
                worstCurve, base.report.limbRadius);
    EXPECT_EQ(tipped, 0) << "case " << k;
    EXPECT_LE(worstCentre, tolerance) << "case " << k;
    EXPECT_LE(worstCurve, tolerance) << "case " << k;
  }
}

// With scale.continuous the character is brought to the reference limb radius exactly, so scales that are no power of
// ten (a character modelled in feet or inches, or 1.7 units tall) give the same muscles too. Measured with the default
// power-of-ten units instead (bench_scale_sweep): makehuman_muscular_male 20 muscles at x1, 2 in feet, 26 at x2.54; the
// woman soldier 26 at x1, 2 at x2.54.
TEST(AnyCharacter, ContinuousScaleGivesTheSameMusclesAtAnyScale) {
  const char* files[] = {"characters/makehuman_muscular_male/makehuman_muscular_male.glb",
                         "characters/quaternius_woman_soldier/woman_soldier.glb",
                         "characters/quaternius_horse/horse.glb",
                         "characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb"};
  ExtractionOptions options;
  options.scale.continuous = true;
  int characters = 0;
  for (const char* file : files) {
    const std::string path = test::sharedPath(file);
    MYOSKIN_REQUIRE_SHARED(path);
    const Character c = loadCharacter(path);
    const ExtractionResult base = extractMuscles(c, options);
    ASSERT_GE(base.muscles.size(), 6u) << file;
    const double tolerance = 0.01 * base.report.limbRadius;
    for (double scale : {0.37, 1.5, 3.2808, 39.37}) {  // a small stylised figure, larger than life, feet, inches
      Similarity x;
      x.scale = scale;
      const ExtractionResult r = extractMuscles(transformed(c, x), options);
      ASSERT_EQ(r.muscles.size(), base.muscles.size()) << file << " x" << scale;
      EXPECT_NEAR(r.report.scale * scale, base.report.scale, 1e-9 * base.report.scale) << file;
      double worst = 0.0;
      for (size_t m = 0; m < base.muscles.size(); ++m) {
        ASSERT_EQ(r.muscles[m].name, base.muscles[m].name) << file << " x" << scale;
        worst = std::max(worst, rootCurveDistance(base.muscles[m], r.muscles[m], x));
      }
      std::printf("%s x%g: %zu muscles, root curves within %.2e of x1 (limb radius %.4f)\n", file, scale,
                  r.muscles.size(), worst, base.report.limbRadius);
      // Measured within 2e-14 m on all four (MakeHuman in feet was once 3.0 mm off, the soldier 1.2 mm, and this test
      // allowed 10 %). The low-poly body lost a muscle pair at x1.5 until a belly fit's cut took points at it within
      // round-off (ellipse_fit.cpp).
      EXPECT_LE(worst, tolerance) << file << " x" << scale;
    }
    ++characters;
  }
  EXPECT_EQ(characters, 4);
}

// With the power-of-ten units a body far from the size the defaults are stated for is analysed at that size: the report
// says so and names scale.continuous; near it (MakeHuman, the soldier at 1.28 times) and in continuous mode it says
// nothing.
TEST(AnyCharacter, SaysWhenTheBodyIsFarFromTheReferenceSize) {
  const std::string path = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  const std::string soldierPath = test::sharedPath("characters/quaternius_woman_soldier/woman_soldier.glb");
  MYOSKIN_REQUIRE_SHARED(path);
  MYOSKIN_REQUIRE_SHARED(soldierPath);
  const Character c = loadCharacter(path);
  ExtractionOptions o;
  o.buildSurfaces = false;
  EXPECT_EQ(extractMuscles(c, o).report.scaleNote, "");
  EXPECT_EQ(extractMuscles(loadCharacter(soldierPath), o).report.scaleNote, "");
  Similarity feet;
  feet.scale = 3.2808;  // analysed as a tenth of that: limb radius 0.018 m
  const std::string note = extractMuscles(transformed(c, feet), o).report.scaleNote;
  std::printf("MakeHuman in feet: %s\n", note.c_str());
  EXPECT_NE(note.find("0.33 times"), std::string::npos) << note;
  EXPECT_NE(note.find("scale.continuous"), std::string::npos) << note;
  Similarity doubled;
  doubled.scale = 2.0;
  EXPECT_NE(extractMuscles(transformed(c, doubled), o).report.scaleNote.find("2.00 times"), std::string::npos);
  o.scale.continuous = true;
  EXPECT_EQ(extractMuscles(transformed(c, feet), o).report.scaleNote, "");
}

// ============================================================================
// Several meshes
// ============================================================================

TEST(AnyCharacter, SeveralSkinnedMeshesAreOneCharacter) {
  const std::string path = test::sharedPath("characters/quaternius_woman_soldier/woman_soldier.glb");
  MYOSKIN_REQUIRE_SHARED(path);
  LoadOptions load;
  load.requireWeights = true;
  const Character c = loadCharacter(path, load);
  ASSERT_EQ(c.pieces.size(), 4u);
  std::set<std::string> names;
  int stored = 0;
  for (const MeshPiece& p : c.pieces) names.insert(p.name), stored += p.vertexCount;
  EXPECT_EQ(names, (std::set<std::string>{"Soldier_Body", "Soldier_Feet", "Soldier_Head", "Soldier_Legs"}));
  EXPECT_EQ(stored, c.sourceVertexCount);
  EXPECT_EQ(c.sourceVertexCount, 15836);  // the README's count: every mesh is in
  // Pieces that meet at open boundaries are welded into one body: the body component holds most of the skin.
  std::vector<ExcludedComponent> excluded;
  const std::vector<char> body = bodySurfaceMask(c, excluded);
  int kept = 0;
  for (char k : body) kept += k;
  EXPECT_GT(kept, c.mesh.numVertices() * 2 / 3);
  ASSERT_FALSE(excluded.empty());  // eyes, hair and helmet parts of the head mesh
  for (const ExcludedComponent& e : excluded) {
    EXPECT_TRUE(e.reason == "small" || e.reason == "rigid") << e.reason;
    EXPECT_EQ(e.bone, "Head");  // all of them sit on the head
  }
  const ExtractionResult r = extractMuscles(c);
  EXPECT_EQ(r.report.excluded.size(), excluded.size());
  std::set<std::string> regions;
  for (const Muscle& m : r.muscles) regions.insert(m.region);
  for (const char* leg : {"UpperLeg.L", "UpperLeg.R"}) EXPECT_TRUE(regions.count(leg)) << leg;
  // One mesh on its own, by name; an unknown name lists the meshes.
  load.meshName = "Soldier_Legs";
  const Character legs = loadCharacter(path, load);
  ASSERT_EQ(legs.pieces.size(), 1u);
  EXPECT_EQ(legs.sourceVertexCount, legs.pieces[0].vertexCount);
  EXPECT_LT(legs.sourceVertexCount, c.sourceVertexCount);
  load.meshName = "Cape";
  const std::string message = test::inputErrorOf([&] { loadCharacter(path, load); });
  EXPECT_NE(message.find("no mesh called 'Cape'"), std::string::npos) << message;
  EXPECT_NE(message.find("Soldier_Head"), std::string::npos) << message;
}

// ============================================================================
// Bone names
// ============================================================================

// Roles come from the bone tree: the same limbs, neck and trunk whatever the bones are called.
TEST(AnyCharacter, RolesFromTheBoneTreeWhateverTheNames) {
  const std::vector<std::string> files = {"characters/makehuman_muscular_male/makehuman_muscular_male.glb",
                                          "characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb",
                                          "characters/quaternius_woman_soldier/woman_soldier.glb",
                                          "characters/quaternius_horse/horse.glb"};
  const std::vector<std::function<std::string(int)>> schemes = {
      [](int i) { return i == 0 ? std::string("Bone") : "Bone." + std::to_string(1000 + i).substr(1); },  // Blender
      [](int i) { return "\xE9\xAA\xA8" + std::to_string(i); },                                              // 骨12
      [](int i) { return "joint_" + std::to_string(i); }};                                                  // unnamed
  for (const std::string& file : files) {
    const std::string path = test::sharedPath(file);
    MYOSKIN_REQUIRE_SHARED(path);
    const Character c = loadCharacter(path);
    const std::vector<BoneRole> named = characterBoneRoles(c);
    std::set<int> limbs = bonesWithRole(named, BoneRole::Limb);
    for (auto it = limbs.begin(); it != limbs.end();)  // the horse's hooves: skinned root bones called "IK...Leg"
      it = c.skeleton.bones[*it].parent < 0 ? limbs.erase(it) : std::next(it);
    ASSERT_GE(limbs.size(), 4u) << file;
    for (const auto& scheme : schemes) {
      const std::vector<BoneRole> roles = characterBoneRoles(renamed(c, scheme));
      const std::set<int> found = bonesWithRole(roles, BoneRole::Limb);
      // Every limb bone the names give is a limb by the tree; at most one extra per limb (a hip or clavicle segment).
      for (int b : limbs) EXPECT_TRUE(found.count(b)) << file << ": " << c.skeleton.bones[b].name;
      EXPECT_LE(found.size(), limbs.size() + 4) << file;
      EXPECT_FALSE(bonesWithRole(roles, BoneRole::Spine).empty()) << file;
    }
  }
}

TEST(AnyCharacter, MusclesOnEveryLimbWithBlenderDefaultNames) {
  const std::string path = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  MYOSKIN_REQUIRE_SHARED(path);
  const Character c = loadCharacter(path);
  const Character plain = renamed(c, [](int i) { return "Bone." + std::to_string(1000 + i).substr(1); });
  const ExtractionResult r = extractMuscles(plain);
  // Which original limb bone each muscle sits on: both arms and both legs have muscles.
  std::set<std::string> limbs;
  ASSERT_FALSE(r.muscles.empty());
  for (const Muscle& m : r.muscles) {
    const int bone = plain.skeleton.find(m.origin.bone);
    ASSERT_GE(bone, 0) << m.origin.bone;
    limbs.insert(c.skeleton.bones[bone].name);
  }
  std::printf("Blender default names: %zu muscles (named rig: %zu) on", r.muscles.size(), extractMuscles(c).muscles.size());
  for (const std::string& l : limbs) std::printf(" %s", l.c_str());
  std::printf("\n");
  auto any = [&](std::initializer_list<const char*> bones) {
    for (const char* b : bones)
      if (limbs.count(b)) return true;
    return false;
  };
  for (const char* side : {".L", ".R"}) {
    const std::string s = side;
    EXPECT_TRUE(any({("upperarm01" + s).c_str(), ("upperarm02" + s).c_str(), ("shoulder01" + s).c_str(),
                     ("clavicle" + s).c_str(), ("lowerarm01" + s).c_str()}))
        << "arm" << s;
    EXPECT_TRUE(any({("upperleg01" + s).c_str(), ("upperleg02" + s).c_str(), ("lowerleg01" + s).c_str(),
                     ("lowerleg02" + s).c_str(), ("pelvis" + s).c_str()}))
        << "leg" << s;
  }
}

// ============================================================================
// Saying why
// ============================================================================

TEST(AnyCharacter, SaysWhyNothingWasFound) {
  const SyntheticCharacter arm = makeSyntheticArm();
  // No bone with a role.
  ExtractionOptions none;
  for (const Bone& b : arm.character.skeleton.bones) none.roleOverrides[b.name] = BoneRole::Ignore;
  const ExtractionResult a = extractMuscles(arm.character, none);
  EXPECT_TRUE(a.muscles.empty());
  EXPECT_FALSE(a.report.analysed);
  EXPECT_NE(a.report.diagnosis.find("no limb chain recognised"), std::string::npos) << a.report.diagnosis;
  // A smooth arm: sections analysed, no relief.
  SyntheticArmOptions smooth;
  smooth.muscleScale = 0.0;
  const ExtractionResult b = extractMuscles(makeSyntheticArm(smooth).character);
  EXPECT_TRUE(b.muscles.empty());
  EXPECT_TRUE(b.report.analysed);
  EXPECT_GT(b.report.sections, 0);
  EXPECT_TRUE(b.report.diagnosis.find("no significant relief") != std::string::npos ||
              b.report.diagnosis.find("none kept") != std::string::npos)
      << b.report.diagnosis;
  // The skeleton beside the skin: every section skipped, and the reason counted.
  Character outside = arm.character;
  for (Bone& bone : outside.skeleton.bones) bone.head.y() += 1.0, bone.tail.y() += 1.0, bone.rest(1, 3) += 1.0;
  const ExtractionResult c = extractMuscles(outside);
  EXPECT_FALSE(c.report.analysed);
  EXPECT_NE(c.report.diagnosis.find("sections was skipped"), std::string::npos) << c.report.diagnosis;
  EXPECT_NE(c.report.diagnosis.find("no skin loop"), std::string::npos) << c.report.diagnosis;
  // A muscular arm says nothing.
  EXPECT_TRUE(extractMuscles(arm.character).report.diagnosis.empty());
}

// ============================================================================
// Held-out generated characters
// ============================================================================

// Seeds 0-3 of the synthetic arm are the ones the options were measured on; 4-11 are held out. Every naming
// scheme and unit must give the same muscles.
TEST(AnyCharacter, HeldOutSyntheticArmsUnderAnyNamesAndUnits) {
  double recall = 0.0, precision = 0.0;
  int seeds = 0;
  for (unsigned seed = 4; seed <= 11; ++seed, ++seeds) {
    SyntheticArmOptions o;
    o.seed = seed;
    const SyntheticCharacter arm = makeSyntheticArm(o);
    const ExtractionResult named = extractMuscles(arm.character);
    const ExtractionAccuracy acc = measureExtraction(named.muscles, arm.muscles);
    recall += acc.recall, precision += acc.precision;
    const Character plain = renamed(arm.character, [](int i) { return i == 0 ? std::string("Bone") : "Bone.00" + std::to_string(i); });
    Similarity centimetres;
    centimetres.scale = 100.0;
    const Character cm = transformed(renamed(arm.character, [](int i) { return "\xE9\xAA\xA8" + std::to_string(i); }), centimetres);
    const ExtractionResult a = extractMuscles(plain), b = extractMuscles(cm);
    ASSERT_EQ(a.muscles.size(), named.muscles.size()) << "seed " << seed << ", Blender default names";
    ASSERT_EQ(b.muscles.size(), named.muscles.size()) << "seed " << seed << ", Japanese names in centimetres";
    // Each muscle has its twin (names differ, so the order may too).
    for (const Muscle& m : named.muscles) {
      double da = INFINITY, db = INFINITY;
      for (const Muscle& x : a.muscles) da = std::min(da, rootCurveDistance(m, x, Similarity{}));
      for (const Muscle& x : b.muscles) db = std::min(db, rootCurveDistance(m, x, centimetres));
      EXPECT_LE(da, 1e-9) << "seed " << seed << " " << m.name;
      EXPECT_LE(db, 0.01 * named.report.limbRadius) << "seed " << seed << " " << m.name;
    }
    std::printf("held-out seed %u: %zu muscles, recall %.2f precision %.2f (the same under Blender default and Japanese "
                "names, in centimetres)\n", seed, named.muscles.size(), acc.recall, acc.precision);
  }
  std::printf("held-out seeds 4-11: mean recall %.3f, precision %.3f\n", recall / seeds, precision / seeds);
  EXPECT_GE(recall / seeds, 0.9);
  EXPECT_GE(precision / seeds, 0.9);
}

// ============================================================================
// Faceting is not relief
// ============================================================================

// A low-poly smooth body's corners stand out of a section like bellies; a bump must contain at least three points
// where its section crosses mesh edges. The finely meshed MakeHuman body keeps every muscle.
TEST(AnyCharacter, LowPolyFacetingIsNotRelief) {
  const std::string lowPoly = test::sharedPath("characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb");
  const std::string muscular = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  MYOSKIN_REQUIRE_SHARED(lowPoly);
  MYOSKIN_REQUIRE_SHARED(muscular);
  ExtractionOptions off;
  off.sectionBumps.minBumpCrossings = 0;
  const Character smooth = loadCharacter(lowPoly), fine = loadCharacter(muscular);
  const size_t facetsToo = extractMuscles(smooth, off).muscles.size(), resolved = extractMuscles(smooth).muscles.size();
  const size_t fineOff = extractMuscles(fine, off).muscles.size(), fineOn = extractMuscles(fine).muscles.size();
  std::printf("low-poly smooth male: %zu muscles, %zu when faceting counts; makehuman_muscular_male: %zu and %zu\n",
              resolved, facetsToo, fineOn, fineOff);
  EXPECT_GE(facetsToo, 12u);  // what the rule is for: 20 measured
  EXPECT_LE(3 * resolved, facetsToo);
  EXPECT_EQ(fineOn, fineOff);
  EXPECT_GE(fineOn, 16u);  // the fine body keeps its limb and chest muscles (measured 22; test_extraction's 12 floor)
}

// ============================================================================
// Odd rigs and skins: a clear outcome, never a crash
// ============================================================================

TEST(AnyCharacter, OddRigsAndSkinsGiveAClearOutcome) {
  const SyntheticCharacter arm = makeSyntheticArm();
  // An armature of one bone carrying the whole skin: it is a limb by the tree; the arm's relief is still found.
  Character one = arm.character;
  one.skeleton.bones.resize(1);
  one.skeleton.bones[0].name = "Bone";
  one.skeleton.bones[0].tail = arm.character.skeleton.bones.back().tail;
  one.skeleton.bones[0].rest = boneMatrix(one.skeleton.bones[0].head, one.skeleton.bones[0].tail,
                                          arm.character.skeleton.bones[0].rest.block<3, 1>(0, 0));
  one.weights.joints.setConstant(-1);
  one.weights.weights.setZero();
  one.weights.joints.col(0).setZero();
  one.weights.weights.col(0).setOnes();
  const ExtractionResult r1 = extractMuscles(one);
  EXPECT_EQ(characterBoneRoles(one)[0], BoneRole::Limb);
  EXPECT_TRUE(r1.report.analysed);
  EXPECT_FALSE(r1.muscles.empty());
  // A skin with no weights (not deformed by the armature): roles from the tree alone, the limb radius from the skin.
  Character unweighted = arm.character;
  unweighted.weights = SkinWeights{};
  const ExtractionResult r2 = extractMuscles(unweighted);
  EXPECT_GT(r2.report.limbRadius, 0.0);
  EXPECT_TRUE(r2.muscles.empty() != r2.report.diagnosis.empty()) << r2.report.diagnosis;
  // Pieces that do not meet: the forearm's skin moved 5 cm off the upper arm's. Both pieces are analysed (neither is
  // small nor rigid); whatever cannot be sectioned is skipped with a reason.
  Character apart = arm.character;
  const int forearm = apart.skeleton.find("forearm");
  ASSERT_GE(forearm, 0);
  const Vec3 elbow = apart.skeleton.bones[forearm].head, along = (apart.skeleton.bones[forearm].tail - elbow).normalized();
  // Triangles past the elbow get their own copies of their vertices (moved), so the skin is two closed-off pieces.
  const Eigen::Index nv = apart.mesh.vertices.rows();
  std::vector<int> copy(nv, -1);
  std::vector<Vec3> extra;
  std::vector<int> extraOf;
  for (Eigen::Index f = 0; f < apart.mesh.triangles.rows(); ++f) {
    Vec3 centroid = Vec3::Zero();
    for (int c = 0; c < 3; ++c) centroid += apart.mesh.vertices.row(apart.mesh.triangles(f, c)).transpose() / 3.0;
    if ((centroid - elbow).dot(along) <= 0) continue;
    for (int c = 0; c < 3; ++c) {
      const int v = apart.mesh.triangles(f, c);
      if (copy[v] < 0) {
        copy[v] = static_cast<int>(nv + extra.size());
        extra.push_back(apart.mesh.vertices.row(v).transpose() + 0.05 * along);
        extraOf.push_back(v);
      }
      apart.mesh.triangles(f, c) = copy[v];
    }
  }
  ASSERT_FALSE(extra.empty());
  apart.mesh.vertices.conservativeResize(nv + static_cast<Eigen::Index>(extra.size()), 3);
  apart.weights.joints.conservativeResize(apart.mesh.vertices.rows(), Eigen::NoChange);
  apart.weights.weights.conservativeResize(apart.mesh.vertices.rows(), Eigen::NoChange);
  for (size_t k = 0; k < extra.size(); ++k) {
    apart.mesh.vertices.row(nv + k) = extra[k].transpose();
    apart.weights.joints.row(nv + k) = apart.weights.joints.row(extraOf[k]);
    apart.weights.weights.row(nv + k) = apart.weights.weights.row(extraOf[k]);
  }
  apart.sourceToWelded.clear();
  EXPECT_EQ(analyzeTopology(apart.mesh).components, 2);
  const ExtractionResult r3 = extractMuscles(apart);
  EXPECT_TRUE(r3.report.analysed);
  EXPECT_TRUE(r3.report.excluded.empty());  // both pieces are body surface
  std::printf("one bone: %zu muscles; unweighted skin: %zu (%s); forearm apart: %zu muscles, %zu of %d sections "
              "skipped\n", r1.muscles.size(), r2.muscles.size(), r2.report.diagnosis.c_str(), r3.muscles.size(),
              r3.report.skipped.size(), r3.report.planes);
  EXPECT_FALSE(r3.report.skipped.empty());  // the gap between the pieces cannot be sectioned
  for (const SkippedSection& s : r3.report.skipped) EXPECT_FALSE(s.reason.empty());
  EXPECT_TRUE(r3.muscles.empty() != r3.report.diagnosis.empty()) << r3.report.diagnosis;
}
