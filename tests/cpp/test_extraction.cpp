// Extraction stages 5-9: linking, Hermite ends, lofting, and the measured pipeline (synthetic arm,
// shared MakeHuman characters).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>

#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "test_support.h"

using namespace myoskin;

namespace {


// A family of planes perpendicular to +X at x = spacing * i, bone axis along X through the origin.
SectionBumps plane(int i, double spacing = 0.02) {
  SectionBumps s;
  s.plane.bone = 0;
  s.plane.family = "limb";
  s.plane.order = i;
  s.plane.origin = Vec3(spacing * i, 0, 0);
  s.plane.normal = Vec3::UnitX();
  s.plane.xAxis = Vec3::UnitY();
  s.plane.yAxis = Vec3::UnitZ();
  return s;
}

void addBump(SectionBumps& s, double angleDeg, double radius = 0.04, double a = 0.02, double b = 0.01,
             double significance = 2.0) {
  Ellipse2 e;
  const double t = angleDeg * kPi / 180;
  e.center = Vec2(radius * std::cos(t), radius * std::sin(t));
  e.angle = t + kPi / 2;
  e.a = a;
  e.b = b;
  s.ellipses.push_back(e);
  s.significance.push_back(significance);
}

Skeleton threeBones() {
  Skeleton sk;
  auto add = [&](const std::string& name, int parent, Vec3 h, Vec3 t) {
    Bone b;
    b.name = name;
    b.parent = parent;
    b.head = h;
    b.tail = t;
    b.rest = boneMatrix(h, t, Vec3::UnitZ());
    sk.bones.push_back(b);
  };
  add("upper", -1, Vec3(-0.3, 0, 0), Vec3(0, 0, 0));
  add("mid", 0, Vec3(0, 0, 0), Vec3(0.3, 0, 0));
  add("lower", 1, Vec3(0.3, 0, 0), Vec3(0.5, 0, 0));
  return sk;
}

double distanceToBones(const Vec3& p, const Skeleton& sk) {
  double best = INFINITY;
  for (const Bone& b : sk.bones) {
    const Vec3 d = b.tail - b.head;
    const double t = std::clamp((p - b.head).dot(d) / d.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (b.head + t * d)).norm());
  }
  return best;
}

double angleBetween(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
}

}  // namespace

// ============================================================================
// Linking
// ============================================================================

TEST(Linking, ChainsWithGapAndShortChainDropped) {
  std::vector<SectionBumps> s;
  for (int i = 0; i < 10; ++i) {
    SectionBumps p = plane(i);
    if (i != 4) addBump(p, 90);           // A: all but section 4 (a gap of one)
    if (i <= 6) addBump(p, -90);          // B: sections 0..6
    if (i == 2 || i == 3) addBump(p, 0);  // C: too short
    s.push_back(p);
  }
  int branches = -1;
  const auto chains = linkBumps(s, LinkOptions{}, &branches);
  EXPECT_EQ(branches, 0);
  int longChains = 0;
  std::vector<int> lengths;
  for (const MuscleChain& c : chains) {
    lengths.push_back(c.realSections);
    if (c.realSections >= 4) ++longChains;
    EXPECT_GE(c.confidence, 0.0);
    EXPECT_LE(c.confidence, 1.0);
  }
  EXPECT_EQ(longChains, 2);
  ASSERT_EQ(chains.size(), 3u);
  std::sort(lengths.begin(), lengths.end());
  EXPECT_EQ(lengths, (std::vector<int>{2, 7, 9}));
  // Every chain keeps one angle: links do not jump between muscles.
  for (const MuscleChain& c : chains)
    for (const ChainLink& l : c.links)  // hygiene: the three chains have 2, 7 and 9 sections (above)
      EXPECT_NEAR(std::atan2(l.ellipse.center.y(), l.ellipse.center.x()),
                  std::atan2(c.links[0].ellipse.center.y(), c.links[0].ellipse.center.x()), 1e-12);
}

TEST(Linking, GapLongerThanMaxGapBreaksChain) {
  std::vector<SectionBumps> s;
  for (int i = 0; i < 12; ++i) {
    SectionBumps p = plane(i);
    if (i < 4 || i > 6) addBump(p, 90);  // a gap of three sections
    s.push_back(p);
  }
  EXPECT_EQ(linkBumps(s).size(), 2u);  // default maxGap 2
  LinkOptions wide;
  wide.maxGap = 3;
  EXPECT_EQ(linkBumps(s, wide).size(), 1u);
}

TEST(Linking, SplitGetsTransitionSection) {
  std::vector<SectionBumps> s;
  for (int i = 0; i < 10; ++i) {
    SectionBumps p = plane(i);
    if (i < 5) {
      addBump(p, 90);
    } else {
      addBump(p, 70);
      addBump(p, 110);
    }
    s.push_back(p);
  }
  int branches = 0;
  LinkOptions branchesOnly;
  branchesOnly.mergeFactor = 0.0;  // keep the branches apart (fragment merging is tested below)
  const auto chains = linkBumps(s, branchesOnly, &branches);
  ASSERT_EQ(chains.size(), 2u);
  EXPECT_EQ(branches, 1);
  int transitions = 0;
  for (const MuscleChain& c : chains)
    for (const ChainLink& l : c.links)
      if (l.bump < 0) {
        ++transitions;
        EXPECT_EQ(s[l.section].plane.order, 4);                       // in the parent's last plane
        const double ang = std::atan2(l.ellipse.center.y(), l.ellipse.center.x()) * 180 / kPi;
        EXPECT_TRUE(std::abs(ang - 80) < 1 || std::abs(ang - 100) < 1) << ang;  // average of 90 and 70/110
      }
  EXPECT_EQ(transitions, 1);
}

TEST(Linking, MergeGetsTransitionSection) {
  std::vector<SectionBumps> s;
  for (int i = 0; i < 10; ++i) {
    SectionBumps p = plane(i);
    if (i >= 5) {
      addBump(p, 90);
    } else {
      addBump(p, 70);
      addBump(p, 110);
    }
    s.push_back(p);
  }
  int branches = 0;
  LinkOptions branchesOnly;
  branchesOnly.mergeFactor = 0.0;  // keep the branches apart (fragment merging is tested below)
  const auto chains = linkBumps(s, branchesOnly, &branches);
  ASSERT_EQ(chains.size(), 2u);
  EXPECT_EQ(branches, 1);
  int transitions = 0;
  for (const MuscleChain& c : chains)
    for (const ChainLink& l : c.links)
      if (l.bump < 0) {
        ++transitions;
        EXPECT_EQ(s[l.section].plane.order, 5);
        EXPECT_EQ(&l, &c.links.back());
      }
  EXPECT_EQ(transitions, 1);
}

TEST(Linking, FragmentsOfOneBellyMerge) {
  // A belly the bump stage split in two for a few sections (bumps 4 degrees apart) is one muscle.
  std::vector<SectionBumps> s;
  for (int i = 0; i < 10; ++i) {
    SectionBumps p = plane(i);
    addBump(p, 90);
    if (i >= 3 && i < 6) addBump(p, 94);
    s.push_back(p);
  }
  LinkOptions separate;
  separate.mergeFactor = 0.0;
  EXPECT_GE(linkBumps(s, separate).size(), 2u);
  const auto merged = linkBumps(s);
  ASSERT_EQ(merged.size(), 1u);
  EXPECT_EQ(merged[0].realSections, 10);
}

TEST(Linking, AlternatingFragmentsOfOneBellyMerge) {
  // A belly whose apex alternates between two heads (70/85 and 100 degrees): the turn limit (one maxAngle per two
  // links) splits it into planes 0, 1, 3, 5 and 2, 4; the two share no plane, alternate and link (85 -> 100), so
  // they are one muscle.
  std::vector<SectionBumps> s;
  const double angles[] = {70, 85, 100, 70, 100, 85};
  for (int i = 0; i < 6; ++i) {
    SectionBumps p = plane(i);
    addBump(p, angles[i]);
    s.push_back(p);
  }
  LinkOptions separate;
  separate.mergeAlternating = false;
  const auto apart = linkBumps(s, separate);
  ASSERT_EQ(apart.size(), 2u);
  EXPECT_EQ(apart[0].realSections + apart[1].realSections, 6);
  const auto merged = linkBumps(s);
  ASSERT_EQ(merged.size(), 1u);
  EXPECT_EQ(merged[0].realSections, 6);
  int previous = -1;
  ASSERT_EQ(merged[0].links.size(), 6u);
  for (const ChainLink& l : merged[0].links) {  // one link per plane, in plane order
    EXPECT_GT(s[l.section].plane.order, previous);
    previous = s[l.section].plane.order;
  }
  // A second bump at 100 degrees in plane 3 makes them two bellies side by side there: no merge.
  addBump(s[3], 100);
  EXPECT_EQ(linkBumps(s).size(), 2u);
}

TEST(Linking, FaintLinksStayOnlyNearTheChainsPeak) {
  // Two muscles with the same faint tails (significance 0.7 in the first and last two sections): a faint one
  // (peak 1.5) keeps them, a strong one (peak 3) does not; transition-free, no gaps.
  std::vector<SectionBumps> s;
  for (int i = 0; i < 10; ++i) {
    SectionBumps p = plane(i);
    const bool tail = i < 2 || i >= 8;
    addBump(p, 90, 0.04, 0.02, 0.01, tail ? 0.7 : 3.0);
    addBump(p, -90, 0.04, 0.02, 0.01, tail ? 0.7 : 1.5);
    s.push_back(p);
  }
  LinkOptions o;
  EXPECT_EQ(linkBumps(s, o).size(), 2u);
  for (const MuscleChain& c : linkBumps(s, o)) EXPECT_EQ(c.realSections, 10);
  o.faintBelow = 0.8;
  o.faintRelative = 0.36;
  const auto chains = linkBumps(s, o);
  ASSERT_EQ(chains.size(), 2u);
  for (const MuscleChain& c : chains) {
    const bool strong = c.links.front().ellipse.center.y() > 0;
    EXPECT_EQ(c.realSections, strong ? 6 : 10);
    EXPECT_EQ(c.strongSections, 6);
    EXPECT_EQ(s[c.links.front().section].plane.order, strong ? 2 : 0);
    EXPECT_EQ(s[c.links.back().section].plane.order, strong ? 7 : 9);
  }
  // Forced bumps always stay.
  for (SectionBumps& p : s) p.forced.assign(p.ellipses.size(), 1);
  EXPECT_EQ(linkBumps(s, o).size(), 2u);
  for (const MuscleChain& c : linkBumps(s, o)) EXPECT_EQ(c.realSections, 10);
}

TEST(Linking, ConfidenceGrowsWithSectionsAndSignificance) {
  auto chainOf = [](int n, double sig) {
    std::vector<SectionBumps> s;
    for (int i = 0; i < n; ++i) {
      SectionBumps p = plane(i);
      addBump(p, 90, 0.04, 0.02, 0.01, sig);
      s.push_back(p);
    }
    return linkBumps(s).at(0).confidence;
  };
  EXPECT_LT(chainOf(4, 2.0), chainOf(10, 2.0));
  EXPECT_LT(chainOf(10, 1.0), chainOf(10, 5.0));
}

// ============================================================================
// Hermite ends
// ============================================================================

TEST(Ends, HermiteInterpolatesEndsAndTangents) {
  const Vec3 p0(0, 0, 0), m0(1, 2, 0), p1(1, 1, 1), m1(0, 0, 3);
  EXPECT_LT((hermite(p0, m0, p1, m1, 0) - p0).norm(), 1e-12);
  EXPECT_LT((hermite(p0, m0, p1, m1, 1) - p1).norm(), 1e-12);
  const double h = 1e-6;
  EXPECT_LT(((hermite(p0, m0, p1, m1, h) - p0) / h - m0).norm(), 1e-4);
  EXPECT_LT(((p1 - hermite(p0, m0, p1, m1, 1 - h)) / h - m1).norm(), 1e-4);
}

TEST(Ends, OriginInsertionOnBonesAndTangentContinuous) {
  const Skeleton sk = threeBones();
  std::vector<MuscleSection> secs;
  for (int i = 0; i < 9; ++i) {
    const double x = 0.05 + 0.025 * i;
    MuscleSection s;
    s.center = Vec3(x, 0, 0.02 + 0.02 * std::sin(kPi * (x - 0.05) / 0.2));
    s.axisA = Vec3::UnitY();
    s.a = 0.02;
    s.b = 0.012;
    s.normal = (i % 2 ? -1.0 : 1.0) * Vec3::UnitX();  // either way: must come out oriented
    secs.push_back(s);
  }
  for (int samples : {6, 60}) {
    EndOptions eo;
    eo.samplesPerEnd = samples;
    const Muscle m = buildMuscleEnds(secs, 1, sk, eo);
    EXPECT_LT(distanceToBones(m.origin.position, sk), 1e-9);
    EXPECT_LT(distanceToBones(m.insertion.position, sk), 1e-9);
    EXPECT_FALSE(m.origin.bone.empty());
    EXPECT_FALSE(m.insertion.bone.empty());
    EXPECT_LT(m.origin.position.x(), secs.front().center.x());
    EXPECT_GT(m.insertion.position.x(), secs.back().center.x());
    EXPECT_LT((m.rootCurve.front() - m.origin.position).norm(), 1e-12);
    EXPECT_LT((m.rootCurve.back() - m.insertion.position).norm(), 1e-12);
    // Tangent continuity where the Hermite extensions meet the section centres.
    size_t i0 = 0;
    while ((m.rootCurve[i0] - secs.front().center).norm() > 1e-12) ++i0;
    const size_t i1 = i0 + secs.size() - 1;
    const double limit = samples > 10 ? 0.03 : 0.2;
    EXPECT_LT(angleBetween(m.rootCurve[i0] - m.rootCurve[i0 - 1], m.rootCurve[i0 + 1] - m.rootCurve[i0]), limit);
    EXPECT_LT(angleBetween(m.rootCurve[i1] - m.rootCurve[i1 - 1], m.rootCurve[i1 + 1] - m.rootCurve[i1]), limit);
    // u by arc length, increasing inside [-1, 1]; normals oriented origin -> insertion.
    EXPECT_EQ(m.sections.size(), secs.size());
    for (size_t i = 0; i < m.sections.size(); ++i) {
      EXPECT_GT(m.sections[i].u, -1.0);
      EXPECT_LT(m.sections[i].u, 1.0);
      if (i) EXPECT_GT(m.sections[i].u, m.sections[i - 1].u);
      EXPECT_GT(m.sections[i].normal.x(), 0.99);
    }
    Muscle named = m;
    named.name = "m";
    EXPECT_NO_THROW(validateMuscles({named}));
  }
}

TEST(Ends, ParallelMuscleGetsTendonOnNeighbourBone) {
  const Skeleton sk = threeBones();
  std::vector<MuscleSection> secs;
  for (int i = 0; i < 8; ++i) {
    MuscleSection s;
    s.center = Vec3(0.05 + 0.03 * i, 0, 0.03);
    s.axisA = Vec3::UnitY();
    s.a = 0.02;
    s.b = 0.01;
    s.normal = Vec3::UnitX();
    secs.push_back(s);
  }
  const Muscle m = buildMuscleEnds(secs, 1, sk);
  EXPECT_LT(distanceToBones(m.origin.position, sk), 1e-9);
  EXPECT_LT(m.origin.position.x(), 0.05 - 0.01);
  EXPECT_GT(m.insertion.position.x(), 0.26 + 0.01);
}

// ============================================================================
// Lofting
// ============================================================================

TEST(Loft, ClosedOrientedWithAnalyticVolume) {
  const std::vector<double> radii{0.03, 0.04, 0.05, 0.045, 0.03};
  Muscle m;
  m.name = "test";
  for (size_t i = 0; i < radii.size(); ++i) {
    MuscleSection s;
    s.center = Vec3(0.05 * i, 0, 0);
    s.axisA = Vec3::UnitY();
    s.a = s.b = radii[i];
    s.normal = Vec3::UnitX();
    m.sections.push_back(s);
  }
  const double lo = 0.06, li = 0.08;
  m.origin.position = Vec3(-lo, 0, 0);
  m.insertion.position = Vec3(0.2 + li, 0, 0);
  // Analytic: frustums between the circles + caps pi r^2 L int_0^1 (1 - 3t^2 + 2t^3)^2 dt = pi r^2 L 13/35 (the
  // sections as cut: no smoothing).
  double v = 0;
  for (size_t i = 0; i + 1 < radii.size(); ++i)
    v += kPi * 0.05 / 3 * (radii[i] * radii[i] + radii[i] * radii[i + 1] + radii[i + 1] * radii[i + 1]);
  v += kPi * radii.front() * radii.front() * lo * 13 / 35 + kPi * radii.back() * radii.back() * li * 13 / 35;
  SurfaceOptions raw;
  raw.smoothingPasses = 0;
  const Mesh mesh = loftMuscleSurface(m, raw);
  const TopologyReport t = analyzeTopology(mesh);
  EXPECT_TRUE(t.closed());
  EXPECT_TRUE(t.manifold());
  EXPECT_TRUE(t.oriented());
  EXPECT_EQ(t.components, 1);
  const double vol = enclosedVolume(mesh.vertices, mesh.triangles);
  std::printf("loft volume %.6g analytic %.6g (%.2f %%)\n", vol, v, 100 * (vol / v - 1));
  EXPECT_NEAR(vol / v, 1.0, 0.02);
}

TEST(Loft, TwistingEllipsesAndBentEndsStayClosed) {
  Muscle m;
  for (int i = 0; i < 6; ++i) {
    MuscleSection s;
    const double t = i * kPi / 10;
    s.center = Vec3(0.04 * i, 0.01 * std::sin(t), 0.0);
    s.normal = -Vec3::UnitX();  // reversed: the loft must still come out outward
    s.axisA = Vec3(0, std::cos(t), std::sin(t));
    s.a = 0.03;
    s.b = 0.015;
    m.sections.push_back(s);
  }
  m.origin.position = Vec3(-0.05, 0, -0.03);
  m.insertion.position = Vec3(0.25, 0.02, -0.03);
  const Mesh mesh = loftMuscleSurface(m);
  const TopologyReport t = analyzeTopology(mesh);
  EXPECT_TRUE(t.closed() && t.manifold() && t.oriented());
  EXPECT_GT(enclosedVolume(mesh.vertices, mesh.triangles), 0);
}

// ============================================================================
// Accuracy measurement
// ============================================================================

TEST(Accuracy, MatchRule) {
  TrueMuscle tm;
  tm.name = "t";
  for (int i = 0; i <= 10; ++i) {
    tm.centerLine.push_back(Vec3(0.03 * i, 0, 0.04));
    tm.radius.push_back(0.02);
  }
  tm.peakRadius = 0.02;
  Muscle near, partial, far;
  for (int i = 0; i <= 10; ++i) near.rootCurve.push_back(Vec3(0.03 * i, 0.005, 0.04));
  for (int i = 0; i <= 5; ++i) partial.rootCurve.push_back(Vec3(0.03 * i, 0, 0.04));  // 50 %
  for (int i = 0; i <= 10; ++i) far.rootCurve.push_back(Vec3(0.03 * i, 0.02, 0.04));
  MuscleSection s;
  s.center = Vec3(0.15, 0.005, 0.04);
  near.sections.push_back(s);
  const auto acc = measureExtraction({partial, near, far}, {tm});
  EXPECT_EQ(acc.matched, 1);
  EXPECT_EQ(acc.matchOfTrue[0], 1);
  EXPECT_DOUBLE_EQ(acc.recall, 1.0);
  EXPECT_NEAR(acc.precision, 1.0 / 3, 1e-12);
  EXPECT_NEAR(acc.meanCenterError, 0.25, 1e-9);
}

// ============================================================================
// Measured: the synthetic arm (ground truth) and the shared MakeHuman characters
// ============================================================================

namespace {

void printMuscles(const std::vector<Muscle>& muscles) {
  for (const Muscle& m : muscles)
    std::printf("  %-28s region %-22s sections %2zu confidence %.2f origin %s insertion %s\n", m.name.c_str(),
                m.region.c_str(), m.sections.size(), m.confidence, m.origin.bone.c_str(), m.insertion.bone.c_str());
}

Vec3 meanCenter(const Muscle& m) {
  Vec3 c = Vec3::Zero();
  for (const MuscleSection& s : m.sections) c += s.center;
  return c / std::max<size_t>(1, m.sections.size());
}

}  // namespace

TEST(Measured, SyntheticArmRecallPrecision) {
  double recallSum = 0, precisionSum = 0;
  for (unsigned seed : {0u, 1u, 2u, 3u}) {
    SyntheticArmOptions o;
    o.seed = seed;
    const SyntheticCharacter arm = makeSyntheticArm(o);
    const ExtractionResult r = extractMuscles(arm.character);
    const ExtractionAccuracy acc = measureExtraction(r.muscles, arm.muscles);
    std::printf("seed %u: %d true, %d found, %d matched: recall %.3f precision %.3f centre error %.3f radius "
                "(planes %d, sections %d, skipped %zu, bumps %d, chains %d, branches %d)\n",
                seed, acc.trueMuscles, acc.foundMuscles, acc.matched, acc.recall, acc.precision, acc.meanCenterError,
                r.report.planes, r.report.sections, r.report.skipped.size(), r.report.bumps, r.report.chains,
                r.report.branches);
    if (seed == 0) printMuscles(r.muscles);
    for (size_t t = 0; t < arm.muscles.size(); ++t)
      if (acc.matchOfTrue[t] < 0) std::printf("  missed true muscle %s (%s)\n", arm.muscles[t].name.c_str(), arm.muscles[t].bone.c_str());
    // Issue 3's target: recall and precision >= 0.9 on every seed. Measured: all 6 matched and nothing else on
    // every seed. Seed 2's brachialis (mostly buried between biceps and elbow) stands out in only 5 sections;
    // its faint tails (ExtractionOptions::faintRelative) extend it to 7, 61 % of its length (without them it
    // covers 46 %: recall and precision 0.83).
    std::printf("  (issue target: recall >= 0.9, precision >= 0.9)\n");
    EXPECT_GE(acc.recall, 0.9) << "seed " << seed;
    EXPECT_GE(acc.precision, 0.9) << "seed " << seed;
    EXPECT_EQ(acc.matched, 6) << "seed " << seed;
    EXPECT_EQ(acc.foundMuscles, 6) << "seed " << seed;
    EXPECT_LT(acc.meanCenterError, 0.35) << "seed " << seed;
    recallSum += acc.recall;
    precisionSum += acc.precision;
    for (const Muscle& m : r.muscles) {
      const TopologyReport t = analyzeTopology(m.surface);
      EXPECT_TRUE(t.closed() && t.manifold() && t.oriented()) << m.name;
      EXPECT_GT(enclosedVolume(m.surface.vertices, m.surface.triangles), 0) << m.name;
    }
    EXPECT_NO_THROW(validateMuscles(r.muscles));
  }
  std::printf("mean over seeds 0-3: recall %.3f precision %.3f (target 0.9 / 0.9; measured 1.0 / 1.0)\n",
              recallSum / 4, precisionSum / 4);
  EXPECT_GE(recallSum / 4, 0.9);
  EXPECT_GE(precisionSum / 4, 0.9);
}

TEST(Measured, SmoothArmHasNoMuscles) {
  SyntheticArmOptions o;
  o.muscleScale = 0.0;
  const SyntheticCharacter arm = makeSyntheticArm(o);
  const ExtractionResult r = extractMuscles(arm.character);
  std::printf("smooth arm: %zu muscles (%d bumps over %d sections)\n", r.muscles.size(), r.report.bumps,
              r.report.sections);
  printMuscles(r.muscles);
  EXPECT_EQ(r.muscles.size(), 0u);
}

TEST(Measured, DeterministicAndUserControl) {
  const SyntheticCharacter arm = makeSyntheticArm();
  const ExtractionResult a = extractMuscles(arm.character);
  const ExtractionResult b = extractMuscles(arm.character);
  EXPECT_EQ(musclesToJson(a.muscles), musclesToJson(b.muscles));
  // Minimum confidence and the per-region limit only remove muscles.
  ExtractionOptions o;
  o.maxPerRegion = 1;
  const ExtractionResult limited = extractMuscles(arm.character, o);
  std::map<std::string, int> perRegion;
  EXPECT_FALSE(limited.muscles.empty());  // as the Python tier: some kept, some dropped
  EXPECT_LT(limited.muscles.size(), a.muscles.size());
  EXPECT_GT(limited.report.droppedRegionLimit, 0);
  for (const Muscle& m : limited.muscles) EXPECT_LE(++perRegion[m.region], 1) << m.region;
  o = {};
  o.filters.minConfidence = 1.0;
  EXPECT_EQ(extractMuscles(arm.character, o).muscles.size(), 0u);
  o.filters.minConfidence = 1.01;  // out of range
  EXPECT_THROW(extractMuscles(arm.character, o), InputError);
  o.filters.minConfidence = 0.5;
  o.profiles.sampleSpacing = 0.0;  // refused before any work, as cutSections would
  EXPECT_THROW(extractMuscles(arm.character, o), InputError);
  o.profiles.sampleSpacing = ProfileOptions{}.sampleSpacing;
  // A peak-magnitude floor only removes muscles: no belly stands out half its section's radius, and every
  // significant bump stands out at least minProtrusion (3.5 mm), over 5 % of these sections' radius. (The spindle
  // rule keeps closed spindles below the floor: off here; 5 of the arm's 6 muscles are such spindles. A continuous
  // chain is held to one bump's floor instead, bumps.minRelativeProtrusion: that rule is off here too.)
  o = {};
  o.filters.spindleEnds = 0.0;
  o.filters.continuousEvidence = 1e9;
  o.filters.minRelative = 0.5;
  const ExtractionResult flat = extractMuscles(arm.character, o);
  EXPECT_EQ(flat.muscles.size(), 0u);
  EXPECT_GE(flat.report.droppedFlat, static_cast<int>(a.muscles.size()));  // chains, before family dominance
  o.filters.minRelative = 0.05;
  EXPECT_EQ(extractMuscles(arm.character, o).muscles.size(), a.muscles.size());
  // A vertex mask restricted to the forearm's side of the elbow finds no upper-arm muscle.
  const int forearm = arm.character.skeleton.find("forearm");
  ASSERT_GE(forearm, 0);
  const double elbowX = arm.character.skeleton.bones[forearm].head.x();
  o = {};
  o.vertexMask.assign(arm.character.mesh.numVertices(), 0);
  for (int v = 0; v < arm.character.mesh.numVertices(); ++v) o.vertexMask[v] = arm.character.mesh.vertices(v, 0) > elbowX;
  const ExtractionResult masked = extractMuscles(arm.character, o);
  EXPECT_FALSE(masked.muscles.empty());  // the forearm's own muscles are still found (as the Python tier)
  EXPECT_LT(masked.muscles.size(), a.muscles.size());
  for (const Muscle& m : masked.muscles) EXPECT_GT(meanCenter(m).x(), elbowX - 0.01) << m.name;
  // A forced region yields exactly one muscle there when a bump stands out at all: on an arm whose muscles are a
  // tenth of the default (measured: nothing extracted without forcing; one muscle, on the forearm, with it), and
  // none on the smooth arm (no bump above forcedMinProtrusion). At a fifth of the default the closed-spindle cue
  // (track_evidence.h) finds 2-3 of the faint bellies on its own (seeds 0-3, every one a true muscle).
  for (double scale : {0.1, 0.0}) {
    SyntheticArmOptions so;
    so.muscleScale = scale;
    const SyntheticCharacter faint = makeSyntheticArm(so);
    EXPECT_TRUE(extractMuscles(faint.character).muscles.empty()) << scale;
    o = {};
    o.forcedRegions.emplace_back(faint.character.mesh.numVertices(), 0);
    for (int v = 0; v < faint.character.mesh.numVertices(); ++v)
      o.forcedRegions[0][v] = faint.character.mesh.vertices(v, 2) > 0 && faint.character.mesh.vertices(v, 0) > elbowX;
    const ExtractionResult forced = extractMuscles(faint.character, o);
    std::printf("forced region on the arm with muscle scale %.1f: %zu muscles\n", scale, forced.muscles.size());
    ASSERT_EQ(forced.muscles.size(), scale > 0 ? 1u : 0u) << scale;
    EXPECT_EQ(forced.report.forced, static_cast<int>(forced.muscles.size()));
    for (const Muscle& m : forced.muscles) EXPECT_GT(meanCenter(m).x(), elbowX - 0.01) << m.name;
  }
}

// Left/right symmetry of muscles extracted from a mirror-symmetric body (x -> -x): each muscle is paired with
// the nearest unused muscle to its mirror image, compared by mean section centre, origin and insertion.
struct MirrorReport {
  int muscles = 0, paired = 0;  // muscles paired within the tolerance (a centre muscle may pair with itself)
  double worst = 0.0;           // metres: largest distance of a muscle's mirror image to its partner's
  int left = 0, right = 0;      // muscles at +x, -x (mean centre beyond 1 cm)
};

MirrorReport mirrorReport(const std::vector<Muscle>& muscles, double tolerance) {
  MirrorReport r;
  r.muscles = static_cast<int>(muscles.size());
  const Vec3 flip(-1, 1, 1);
  auto distance = [&](const Muscle& a, const Muscle& b) {
    return std::max({(meanCenter(a).cwiseProduct(flip) - meanCenter(b)).norm(),
                     (a.origin.position.cwiseProduct(flip) - b.origin.position).norm(),
                     (a.insertion.position.cwiseProduct(flip) - b.insertion.position).norm()});
  };
  std::vector<char> used(muscles.size(), 0);
  for (size_t i = 0; i < muscles.size(); ++i) {
    const double x = meanCenter(muscles[i]).x();
    r.left += x > 0.01;
    r.right += x < -0.01;
    if (used[i]) continue;
    int best = -1;
    for (size_t j = 0; j < muscles.size(); ++j)
      if (!used[j] && (best < 0 || distance(muscles[i], muscles[j]) < distance(muscles[i], muscles[best])))
        best = static_cast<int>(j);
    const double d = distance(muscles[i], muscles[best]);
    r.worst = std::max(r.worst, d);
    if (d > tolerance) continue;
    used[i] = used[best] = 1;
    r.paired += best == static_cast<int>(i) ? 1 : 2;
  }
  return r;
}

TEST(Measured, MakeHumanMuscularVersusNeutral) {
  const std::string muscular = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  const std::string neutral = test::sharedPath("characters/makehuman_neutral/makehuman_neutral.glb");
  MYOSKIN_REQUIRE_SHARED(muscular);
  MYOSKIN_REQUIRE_SHARED(neutral);
  const Character cm = loadCharacter(muscular);
  const ExtractionResult rm = extractMuscles(cm);
  printMuscles(rm.muscles);
  for (const StageTiming& t : rm.report.timings) std::printf("  %s %.3f s\n", t.stage.c_str(), t.seconds);
  std::map<std::string, int> reasons;
  for (const SkippedSection& s : rm.report.skipped) ++reasons[s.reason];
  for (const auto& [reason, n] : reasons) std::printf("  skipped %d: %s\n", n, reason.c_str());

  // Body parts by bone name, sides by the sign of x.
  auto part = [](const Muscle& m) -> std::string {
    std::string b = m.region;
    for (char& c : b) c = static_cast<char>(std::tolower(c));
    if (b.find("torso.") == 0 || b.find("spine") != std::string::npos || b.find("pelvis") != std::string::npos ||
        b.find("clavicle") != std::string::npos || b.find("neck") != std::string::npos ||
        b.find("breast") != std::string::npos || b.find("shoulder") != std::string::npos)
      return "torso";
    if (b.find("arm") != std::string::npos) return "arm";
    if (b.find("leg") != std::string::npos || b.find("thigh") != std::string::npos || b.find("shin") != std::string::npos ||
        b.find("calf") != std::string::npos)
      return "leg";
    return "other";
  };
  std::map<std::string, int> left, right;
  for (const Muscle& m : rm.muscles) {
    const Vec3 c = meanCenter(m);
    if (c.x() > 0.01) ++left[part(m)];
    if (c.x() < -0.01) ++right[part(m)];
  }
  // Issue 3's target: muscles on both arms, legs and the torso, all mirrored within 1 cm. Measured: arms 4 + 4,
  // legs 4 + 4 (quadriceps, calf and two more), torso 3 + 3 (abdomen: external oblique into serratus, the upper
  // chest to the neck; shoulder planes: pectorals); all 22 mirrored (worst 1.3 mm over centres, origins and
  // insertions). Before the abdomen's sections were split along their mirror axis: 6 of 8 pairs, worst 2.6 cm.
  for (const char* p : {"arm", "leg", "torso"}) std::printf("  %s: %d at +x, %d at -x (issue target: both)\n", p, left[p], right[p]);
  for (const char* p : {"arm", "leg", "torso"}) {
    EXPECT_GE(left[p], 1) << p;
    EXPECT_GE(right[p], 1) << p;
  }
  // The trunk's sections (abdomen, neck): split along the mirror axis, and on this body exactly symmetric.
  int trunkPlanes = 0;
  for (const CuttingPlane& p : makeCuttingPlanes(cm, classifyBones(cm.skeleton)))
    if (p.family == "abdomen" || p.family == "neck") ++trunkPlanes;
  std::printf("  trunk: %d planes, %d sections split along the mirror axis, %d made exactly symmetric\n", trunkPlanes,
              rm.report.split, rm.report.mirrored);
  EXPECT_GT(rm.report.split, 10);
  EXPECT_EQ(rm.report.mirrored, rm.report.split);
  const MirrorReport mr = mirrorReport(rm.muscles, 0.01);
  std::printf("  symmetry: %d at +x, %d at -x, %d of %d muscles mirrored within 1 cm (worst %.4f m; issue target: all)\n",
              mr.left, mr.right, mr.paired, mr.muscles, mr.worst);
  EXPECT_EQ(mr.paired, mr.muscles);
  EXPECT_EQ(mr.left, mr.right);

  const Character cn = loadCharacter(neutral);
  const ExtractionResult rn = extractMuscles(cn);
  std::printf("muscular male: %zu muscles, neutral: %zu muscles (issue target: neutral at most half; measured 22 vs 6)\n",
              rm.muscles.size(), rn.muscles.size());
  printMuscles(rn.muscles);
  EXPECT_GE(rm.muscles.size(), 12u);
  // Issue 3's target: the smooth skin gives at most half as many. The neutral body's front thighs, inner upper
  // arms and forearms stand out as muscles do; against the trunk's Fourier base its belly and flanks give no chain.
  EXPECT_LE(2 * rn.muscles.size(), rm.muscles.size());
}

TEST(Measured, MakeHumanChestIsSectionedAndHasPectorals) {
  // The trunk planes through the shoulders used to run into the arms and were skipped (7 of 23 abdomen planes);
  // their runs over the arms are now chords, so every trunk plane gives a section. Against the trunk's Fourier
  // base the pectorals stand out on the front of the chest: a muscle on each side there (measured: centre
  // (+-0.117, 0.477, 0.076), 7 sections of the shoulder planes, origin shoulder01, insertion upperarm01; with
  // other floors the abdomen's planes give it instead), and the flanks are no longer whole-side "muscles".
  const std::string muscular = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  MYOSKIN_REQUIRE_SHARED(muscular);
  const Character c = loadCharacter(muscular);
  const ExtractionResult r = extractMuscles(c);
  int trunkSkipped = 0;
  for (const SkippedSection& s : r.report.skipped) trunkSkipped += s.family == "abdomen" || s.family == "neck";
  std::printf("trunk sections skipped: %d\n", trunkSkipped);
  EXPECT_EQ(trunkSkipped, 0);
  int left = 0, right = 0;
  for (const Muscle& m : r.muscles) {
    const Vec3 p = meanCenter(m);  // MakeHuman: +y up, +z front, +x the character's left
    const bool chest = p.y() > 0.40 && p.y() < 0.56 && p.z() > 0.03 && std::abs(p.x()) > 0.03 && std::abs(p.x()) < 0.22;
    if (!chest) continue;
    std::printf("  chest muscle %s: centre (%.3f, %.3f, %.3f), %zu sections, %s -> %s\n", m.name.c_str(), p.x(), p.y(),
                p.z(), m.sections.size(), m.origin.bone.c_str(), m.insertion.bone.c_str());
    left += p.x() > 0, right += p.x() < 0;
  }
  EXPECT_GE(left, 1);
  EXPECT_GE(right, 1);
}

TEST(Measured, MakeHumanAnatomicalGroups) {
  // The list (biceps/triceps, deltoids, pectorals, quadriceps, calves), each found muscle labelled by
  // where its centre line lies: the nearest bone segment to its mean centre and the side of that bone it is on
  // (MakeHuman: +y up, +z front; "outer" is the bone's upper side, world up made perpendicular to the bone).
  // The deltoid caps the shoulder joint and the upper third of the humerus from the front over the top to the back:
  // a muscle on the shoulder bones or the upper arm's first third, on the bone's upper side (up > 0.3; in the A pose
  // that is the arm's lateral surface), not straight behind it (front > -0.8, within ~53 degrees of the upper side
  // behind the bone: the posterior deltoid; the triceps lie under the bone, up < 0).
  const std::string muscular = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  MYOSKIN_REQUIRE_SHARED(muscular);
  const Character c = loadCharacter(muscular);
  const Skeleton& sk = c.skeleton;
  const ExtractionResult r = extractMuscles(c);
  std::map<std::string, int> left, right;
  std::vector<Vec3> deltoids[2];  // mean centres at +x, -x
  for (const Muscle& m : r.muscles) {
    const Vec3 p = meanCenter(m);
    int bone = -1;
    double best = INFINITY, t = 0;
    for (int b = 0; b < sk.numBones(); ++b) {
      const Vec3 d = sk.bones[b].tail - sk.bones[b].head;
      if (d.norm() < 1e-6) continue;
      const double tb = std::clamp((p - sk.bones[b].head).dot(d) / d.squaredNorm(), 0.0, 1.0);
      const double dist = (p - (sk.bones[b].head + tb * d)).norm();
      if (dist < best) best = dist, bone = b, t = tb;
    }
    const Vec3 d = (sk.bones[bone].tail - sk.bones[bone].head).normalized();
    const Vec3 v = (p - (sk.bones[bone].head + t * (sk.bones[bone].tail - sk.bones[bone].head))).normalized();
    Vec3 outer = Vec3::UnitY() - Vec3::UnitY().dot(d) * d;
    outer = outer.norm() > 1e-6 ? Vec3(outer.normalized()) : Vec3::Zero();
    const double front = v.z(), up = v.dot(outer);
    const std::string& name = sk.bones[bone].name;
    auto on = [&](const char* prefix) { return name.rfind(prefix, 0) == 0; };
    std::string group;
    if (p.y() > 0.40 && p.y() < 0.56 && p.z() > 0.03 && std::abs(p.x()) > 0.03 && std::abs(p.x()) < 0.22) group = "pectoral";
    else if ((on("upperarm01") || on("shoulder01") || (on("upperarm02") && t < 0.35)) && up > 0.3 && front > -0.8) group = "deltoid";
    else if (on("upperarm") && front > 0.5) group = "biceps";
    else if (on("upperarm") && front < -0.3) group = "triceps";
    else if (on("upperleg") && front > 0.3) group = "quadriceps";
    else if (on("lowerleg") && front < -0.3) group = "calf";
    else group = "other (" + name + ")";
    std::printf("  %-26s nearest %-13s t %.2f front %+.2f up %+.2f -> %s\n", m.name.c_str(), name.c_str(), t, front, up,
                group.c_str());
    (p.x() > 0 ? left : right)[group]++;
    if (group == "deltoid") deltoids[p.x() > 0 ? 0 : 1].push_back(p);
  }
  for (const char* g : {"biceps", "triceps", "deltoid", "pectoral", "quadriceps", "calf"})
    std::printf("  %-10s %d at +x, %d at -x\n", g, left[g], right[g]);
  // Found on both sides (measured at the default spacing): biceps 1 + 1, triceps 1 + 1, deltoids 1 + 1 (the back-lateral
  // cap of the upper arm's first third: upperarm02 planes 0-3, t 0.22, front -0.68, up +0.72; over spacings x 0.9-1.1
  // at t 0.14-0.22, front -0.66 to -0.68, up +0.72 to +0.75, found at every spacing except x 1.1; the triceps chains
  // there lie at up -0.74 to -0.94, the neutral body's at up -0.71 to -0.76), pectorals 1 + 1, quadriceps
  // 1 + 1 (planes 3-9 of the thigh, 0.056-0.085 of its radius, mean 0.067: under minRelative 0.09, kept as a
  // continuous chain, held to one bump's floor 0.05: ChainFilterOptions::continuousEvidence) and calves 1 + 1 (the
  // gastrocnemius below the knee, planes 17-22, its apex alternating between the two heads: two fragments of evidence
  // 5.1 and 2.3 merged, LinkOptions::mergeAlternating). Over spacings x 0.9-1.1 the quadriceps are found at every one, the calves at
  // x 0.9-1.025 except x 0.925. Not found: the deltoid's top over the joint (the clipped shoulder01 profiles' cap
  // bump encloses the bone; the upperarm01 planes' loops run into the trunk and are skipped).
  for (const char* g : {"biceps", "triceps", "deltoid", "pectoral", "quadriceps", "calf"}) {
    EXPECT_GE(left[g], 1) << g;
    EXPECT_GE(right[g], 1) << g;
  }
  // The deltoids mirror each other about x = 0 (MakeHuman's mirror plane) within 1 cm (measured: exactly).
  ASSERT_FALSE(deltoids[0].empty());
  ASSERT_FALSE(deltoids[1].empty());
  for (const Vec3& p : deltoids[0]) {
    double nearest = INFINITY;
    for (const Vec3& q : deltoids[1]) nearest = std::min(nearest, (p - Vec3(-q.x(), q.y(), q.z())).norm());
    EXPECT_LT(nearest, 0.01);
  }
}

TEST(Measured, MakeHumanRobustToPlaneSpacing) {
  const std::string muscular = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  const std::string neutral = test::sharedPath("characters/makehuman_neutral/makehuman_neutral.glb");
  MYOSKIN_REQUIRE_SHARED(muscular);
  MYOSKIN_REQUIRE_SHARED(neutral);
  const Character cm = loadCharacter(muscular), cn = loadCharacter(neutral);
  auto spaced = [](const Character& c, double f) {  // f times the default spacing (1/80 of the largest extent)
    const Vec3 lo = c.mesh.vertices.colwise().minCoeff().transpose(), hi = c.mesh.vertices.colwise().maxCoeff().transpose();
    ExtractionOptions o;
    o.planes.spacing = f * (hi - lo).maxCoeff() / 80.0;
    o.buildSurfaces = false;
    return o;
  };
  // Measured (muscular vs neutral), spacing x 0.9 ... 1.1 in steps of 0.025 (no surfaces): 24/4, 18/8, 20/8, 22/8,
  // 22/6, 20/4, 24/6, 16/6, 16/4 (with the track evidence, track_evidence.h: at x 1.075 a muscular lower-leg pair more,
  // 12 of 16 mirrored; before it 14/6; spindle ends 0.85 and steepness 0.04; with 0.75 and 0.05: 20/4, 18/8, 20/6, 22/6,
  // 22/6, 18/4, 24/6, 14/6, 16/4; x 1.075: 14/4 without the spindle rule, which keeps the neutral forearms there);
  // earlier 20/4, 20/8, 20/6, 24/6, 20/6, 18/4, 22/6, 14/4, 18/4 (before the continuous floor and the alternating fragments: 18/4, 18/6, 18/6, 20/6, 16/6, 16/4,
  // 20/6, 12/4, 15/4). The "at most half" holds at every one (ExtractionOptions::minEvidence; with the
  // earlier rule of 4 significant sections it failed at x 0.925, 0.975, 1.025, 1.075 and 1.1). Every muscular
  // muscle is mirrored within 1 cm (worst 1.3 mm) except at x 1.075, where a calf fragment's ends differ by 4 cm
  // (12 of 14); at x 1.1 the knee-side thigh chain (mean height 0.091 vs 0.090 of the section radius, once kept on
  // one side only) is now kept on both as a continuous chain.
  for (int step = 0; step <= 8; ++step) {
    const double f = 0.9 + 0.025 * step;
    const ExtractionResult rm = extractMuscles(cm, spaced(cm, f)), rn = extractMuscles(cn, spaced(cn, f));
    const MirrorReport mr = mirrorReport(rm.muscles, 0.01);
    std::printf("spacing x %.3f: muscular %zu, neutral %zu; %d of %d muscular mirrored within 1 cm (worst %.4f m)\n",
                f, rm.muscles.size(), rn.muscles.size(), mr.paired, mr.muscles, mr.worst);
    EXPECT_GE(rm.muscles.size(), 10u) << f;
    EXPECT_LE(2 * rn.muscles.size(), rm.muscles.size()) << f;
    if (f < 1.06) EXPECT_EQ(mr.paired, mr.muscles) << f;
  }
}

TEST(Measured, FaintHysteresisWithMirroredLimbs) {
  // Opt-in: hysteresis down to half the threshold for every chain, mirrored limb profiles averaged. Measured:
  // every seed's six muscles and nothing else; MakeHuman muscular 20 / 20 / 22 at spacing x 0.95 / 1 / 1.05
  // against neutral 10 / 6 / 8 (the height floor averages the links down to weakFraction), every muscular one exactly
  // mirrored. Not the default: the synthetic arm's biceps then reaches further towards the
  // elbow and the hybrid skinning's elbow region at 35 degrees grows more than LBS loses (test_hybrid_skinning).
  ExtractionOptions o;
  o.sectionBumps.weakFraction = 0.5;
  o.profiles.mirrorLimbs = true;
  for (unsigned seed : {0u, 1u, 2u, 3u}) {
    SyntheticArmOptions so;
    so.seed = seed;
    const SyntheticCharacter arm = makeSyntheticArm(so);
    const ExtractionAccuracy acc = measureExtraction(extractMuscles(arm.character, o).muscles, arm.muscles);
    std::printf("faint hysteresis, seed %u: recall %.3f precision %.3f centre error %.3f radius\n", seed, acc.recall,
                acc.precision, acc.meanCenterError);
    EXPECT_GE(acc.recall, 0.9) << seed;
    EXPECT_GE(acc.precision, 0.9) << seed;
  }
  SyntheticArmOptions smooth;
  smooth.muscleScale = 0.0;
  EXPECT_EQ(extractMuscles(makeSyntheticArm(smooth).character, o).muscles.size(), 0u);

  const std::string muscular = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
  const std::string neutral = test::sharedPath("characters/makehuman_neutral/makehuman_neutral.glb");
  MYOSKIN_REQUIRE_SHARED(muscular);
  MYOSKIN_REQUIRE_SHARED(neutral);
  const Character cm = loadCharacter(muscular), cn = loadCharacter(neutral);
  for (double f : {0.95, 1.0, 1.05}) {
    auto spaced = [&](const Character& c) {
      const Vec3 lo = c.mesh.vertices.colwise().minCoeff().transpose(), hi = c.mesh.vertices.colwise().maxCoeff().transpose();
      ExtractionOptions q = o;
      q.planes.spacing = f * (hi - lo).maxCoeff() / 80.0;
      return q;
    };
    const ExtractionResult rm = extractMuscles(cm, spaced(cm)), rn = extractMuscles(cn, spaced(cn));
    const MirrorReport mr = mirrorReport(rm.muscles, 0.01);
    std::printf("faint hysteresis, spacing x %.2f: muscular %zu, neutral %zu; %d of %d mirrored (worst %.5f m), %d "
                "sections made exactly symmetric\n", f, rm.muscles.size(), rn.muscles.size(), mr.paired, mr.muscles,
                mr.worst, rm.report.mirrored);
    EXPECT_GE(rm.muscles.size(), 10u) << f;
    EXPECT_LE(2 * rn.muscles.size(), rm.muscles.size()) << f;
    EXPECT_EQ(mr.paired, mr.muscles) << f;
    EXPECT_LT(mr.worst, 0.001) << f;
    EXPECT_GT(rm.report.mirrored, rm.report.split) << f;  // limb twins too
  }
}

// ============================================================================
// Bad input: holes, a skeleton outside the skin, zero-length bones, NaNs
// ============================================================================

TEST(ExtractionInput, OpenMeshSkipsSectionsThroughTheHoleWithAReason) {
  SyntheticCharacter arm = makeSyntheticArm();
  Mesh& m = arm.character.mesh;
  // Cut a hole: drop the triangles with a vertex in a band of the forearm's upper side.
  std::vector<int> keep;
  for (int f = 0; f < m.numTriangles(); ++f) {
    bool inBand = false;
    for (int k = 0; k < 3; ++k)
      inBand |= std::abs(m.vertices(m.triangles(f, k), 0) - 0.58) < 0.01 && m.vertices(m.triangles(f, k), 2) > 0;
    if (!inBand) keep.push_back(f);
  }
  Triangles kept(static_cast<Eigen::Index>(keep.size()), 3);
  for (size_t i = 0; i < keep.size(); ++i) kept.row(i) = m.triangles.row(keep[i]);
  m.triangles = kept;
  ASSERT_FALSE(analyzeTopology(m).closed());
  const ExtractionResult r = extractMuscles(arm.character);
  int open = 0;
  for (const SkippedSection& s : r.report.skipped) open += s.reason.find("open") != std::string::npos;
  EXPECT_GE(open, 1);
  EXPECT_NO_THROW(validateMuscles(r.muscles));
}

TEST(ExtractionInput, SkeletonOutsideTheSkinFindsNothingAndSaysWhy) {
  SyntheticCharacter arm = makeSyntheticArm();
  for (Bone& b : arm.character.skeleton.bones) {
    b.head.y() += 1.0;
    b.tail.y() += 1.0;
    b.rest(1, 3) += 1.0;
  }
  const ExtractionResult r = extractMuscles(arm.character);
  EXPECT_TRUE(r.muscles.empty());
  ASSERT_GT(r.report.planes, 0);
  ASSERT_EQ(static_cast<int>(r.report.skipped.size()), r.report.planes);
  for (const SkippedSection& s : r.report.skipped) EXPECT_NE(s.reason.find("no skin loop"), std::string::npos) << s.reason;
}

TEST(ExtractionInput, ZeroLengthBonesAndNaNsAreClearErrors) {
  SyntheticCharacter arm = makeSyntheticArm();
  Character c = arm.character;
  c.skeleton.bones[2].tail = c.skeleton.bones[2].head;
  try {
    extractMuscles(c);
    ADD_FAILURE() << "a zero-length bone must be rejected";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("forearm"), std::string::npos) << e.what();
  }
  c = arm.character;
  c.mesh.vertices(10, 1) = std::nan("");
  EXPECT_THROW(extractMuscles(c), InputError);
  ExtractionOptions o;
  o.vertexMask.assign(5, 1);
  EXPECT_THROW(extractMuscles(arm.character, o), InputError);
}
