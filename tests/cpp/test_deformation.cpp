// Muscle deformation (issue 4): action paths, carried frames, volume-preserving bulge, muscle joints.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>

#include "joints/bulge.h"
#include "myoskin/deformation.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/synthetic_character.h"
#include "paths/action_path.h"

// Counts heap allocations so a test can prove evaluate() allocates nothing.
static std::atomic<long> gAllocations{0};
void* operator new(std::size_t n) {
  ++gAllocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

using namespace myoskin;

namespace {


const Skeleton& arm() {
  static const Skeleton s = makeSyntheticArm().character.skeleton;
  return s;
}

Vec3 head(const char* bone) { return arm().bones[arm().find(bone)].head; }
Vec3 tail(const char* bone) { return arm().bones[arm().find(bone)].tail; }

// A spindle-shaped muscle from O to I, bowed by `bow` along `side`, peak semi-axis `peak`, lofted.
Muscle spindle(const std::string& name, const Vec3& O, const std::string& ob, const Vec3& I, const std::string& ib,
               const Vec3& side, double bow, double peak) {
  Muscle m;
  m.name = name;
  m.origin = {ob, O};
  m.insertion = {ib, I};
  const Vec3 dir = (I - O).normalized();
  const Vec3 sideN = (side - side.dot(dir) * dir).normalized();
  const int n = 15;
  for (int i = 0; i <= n; ++i) {
    const double t = double(i) / n;
    m.rootCurve.push_back(O + t * (I - O) + bow * std::sin(kPi * t) * sideN);
  }
  for (int i = 2; i <= n - 2; ++i) {
    const double t = double(i) / n;
    MuscleSection s;
    s.u = -1 + 2 * t;
    s.center = m.rootCurve[i];
    s.normal = dir;
    s.axisA = sideN;
    s.a = peak * std::pow(std::sin(kPi * t), 0.8);
    s.b = 0.75 * s.a;
    m.sections.push_back(s);
  }
  m.joints = 6;
  m.bulge = 1.0;
  m.surface = loftMuscleSurface(m);
  return m;
}

// Biceps-like: front (+Z) of the upper arm to the forearm just past the elbow.
Muscle biceps() {
  const Vec3 sh = head("upper_arm"), el = head("forearm");
  return spindle("biceps", sh + 0.15 * (el - sh) + Vec3(0, 0, 0.02), "upper_arm",
                 el + 0.12 * (tail("forearm") - el) + Vec3(0, 0, 0.015), "forearm", Vec3::UnitZ(), 0.02, 0.022);
}

// Triceps-like behind the elbow, wrapping round a sphere at the elbow on flexion.
Muscle tricepsWrap(double radius = 0.03) {
  const Vec3 sh = head("upper_arm"), el = head("forearm");
  Muscle m = spindle("triceps", sh + 0.3 * (el - sh) + Vec3(0, 0, -0.035), "upper_arm",
                     el + Vec3(0.04, 0, -0.034), "forearm", -Vec3::UnitZ(), 0.006, 0.02);
  m.wrap.type = WrapType::Joint;
  m.wrap.bone = "forearm";
  m.wrap.radius = radius;
  return m;
}

// A slim muscle from the upper arm's front round the forearm's cylinder (forearm twist makes it wrap).
Muscle forearmWrap(int side = 1) {
  const Vec3 sh = head("upper_arm"), el = head("forearm"), wr = tail("forearm");
  Muscle m = spindle("supinator", sh + 0.6 * (el - sh) + Vec3(0, 0, 0.035), "upper_arm",
                     el + 0.45 * (wr - el) + Vec3(0, 0, 0.03), "forearm", Vec3::UnitZ(), 0.004, 0.008);
  m.wrap.type = WrapType::Bone;
  m.wrap.bone = "forearm";
  m.wrap.radius = 0.02;
  m.wrap.side = side;
  return m;
}

// Pose with the elbow flexed by `flex` radians (towards +Z) and the forearm twisted by `twist`.
Pose armPose(double flex, double twist = 0.0, double shoulder = 0.0) {
  std::vector<Eigen::Quaterniond> q(arm().numBones(), Eigen::Quaterniond::Identity());
  q[arm().find("forearm")] = Eigen::AngleAxisd(flex, Vec3::UnitX()) * Eigen::AngleAxisd(twist, Vec3::UnitY());
  q[arm().find("upper_arm")] = Eigen::Quaterniond(Eigen::AngleAxisd(shoulder, Vec3::UnitZ()));
  return poseFromLocalRotations(arm(), q);
}

// A pose that moves the forearm (and hand) along the arm so a muscle across the elbow stretches.
Pose stretchPose(double dx) {
  Pose p = restPose(arm());
  for (const char* b : {"forearm", "hand"}) p.matrices[arm().find(b)](0, 3) += dx;
  return p;
}

double relDiff(const Mat4& a, const Mat4& b) { return (a - b).norm() / std::max(1.0, b.norm()); }

// A joint wrap's length and 21 points evenly along it.
std::pair<double, std::vector<Vec3>> jointWrapPoints(const Vec3& O, const Vec3& I, const Vec3& J, double r,
                                                     const Vec3& side) {
  paths::ActionPath p;
  paths::jointWrapPath(O, I, J, r, side, p);
  std::vector<Vec3> out;
  for (int k = 0; k <= 20; ++k) {
    Vec3 x, t;
    paths::pointAt(p, p.length * k / 20.0, x, t);
    out.push_back(x);
  }
  return {p.length, out};
}

}  // namespace

// ============================================================================
// Paths
// ============================================================================

TEST(Paths, StraightWhenLineClearsSphereAndWrapsOtherwise) {
  paths::ActionPath p;
  paths::jointWrapPath(Vec3(-1, 0.5, 0), Vec3(1, 0.5, 0), Vec3::Zero(), 0.3, Vec3::UnitY(), p);
  EXPECT_FALSE(p.wrapped);
  EXPECT_NEAR(p.length, 2.0, 1e-12);
  paths::jointWrapPath(Vec3(-1, 0.1, 0), Vec3(1, 0.1, 0), Vec3::Zero(), 0.3, Vec3::UnitY(), p);
  ASSERT_TRUE(p.wrapped);
  ASSERT_EQ(p.count, 3);
  // Tangent points on the sphere, tangent lines perpendicular to the radius, C1 at both.
  for (int k : {0, 2}) {
    const Vec3 T = k == 0 ? p.pieces[0].b : p.pieces[2].a;
    EXPECT_NEAR(T.norm(), 0.3, 1e-12);
    const Vec3 d = (p.pieces[k].b - p.pieces[k].a).normalized();
    EXPECT_LT(std::abs(d.dot(T.normalized())), 1e-9);
  }
  Vec3 x, t0, t1;
  const double s1 = p.pieces[0].length, s2 = s1 + p.pieces[1].length;
  for (double s : {s1, s2}) {
    paths::pointAt(p, s - 1e-9, x, t0);
    paths::pointAt(p, s + 1e-9, x, t1);
    EXPECT_LT((t0 - t1).norm(), 1e-6) << "tangent jump at " << s;
  }
  // The arc goes over the +Y side, the side asked for.
  paths::pointAt(p, 0.5 * p.length, x, t0);
  EXPECT_NEAR(x.y(), 0.3, 1e-9);
  paths::jointWrapPath(Vec3(-1, 0.1, 0), Vec3(1, 0.1, 0), Vec3::Zero(), 0.3, -Vec3::UnitY(), p);
  paths::pointAt(p, 0.5 * p.length, x, t0);
  EXPECT_NEAR(x.y(), -0.3, 1e-9);
}

TEST(Paths, JointWrapIsShortestAmongPerturbedPaths) {
  // Bent at J by 0.2 rad, more than the sphere's angular radius (0.15 rad seen from I): the geodesic.
  const Vec3 O(-0.8, 0.05, 0.1), I(0.7, -0.02, 0.05), J(0.02, 0.01, 0.0);
  const double r = 0.1;
  paths::ActionPath p;
  paths::jointWrapPath(O, I, J, r, Vec3(0.1, 1, 0.2), p);
  ASSERT_TRUE(p.wrapped);
  const Vec3 T1 = p.pieces[0].b, T2 = p.pieces[2].a;
  std::mt19937 rng(7);
  std::normal_distribution<double> nd(0.0, 1.0);
  int valid = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const double eps = 0.05 * std::pow(10.0, -3.0 * (trial % 4) / 3.0);
    const Vec3 Q1 = J + r * (T1 - J + eps * Vec3(nd(rng), nd(rng), nd(rng))).normalized();
    const Vec3 Q2 = J + r * (T2 - J + eps * Vec3(nd(rng), nd(rng), nd(rng))).normalized();
    // The straight parts must not enter the sphere.
    auto clears = [&](const Vec3& a, const Vec3& b) {
      const Vec3 d = b - a;
      const double t = std::clamp((J - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
      return (a + t * d - J).norm() >= r * (1 - 1e-12);
    };
    if (!clears(O, Q1) || !clears(Q2, I)) continue;
    ++valid;
    const double arc = r * std::acos(std::clamp((Q1 - J).dot(Q2 - J) / (r * r), -1.0, 1.0));
    EXPECT_GE((Q1 - O).norm() + arc + (I - Q2).norm(), p.length - 1e-12);
  }
  EXPECT_GT(valid, 100);
}

TEST(Paths, JointWrapIsContinuousThroughAStraightLimb) {
  // A muscle over a straight joint (O, J and I in line, the rest pose of a straight limb) on its +Y side. Its
  // path must not swing round the joint when I moves by rounding (float32 pose matrices) or by a small bend in
  // any direction: points along it move by at most a few times I's own move.
  const Vec3 O(-0.3, 0.0, 0.0), J(0.0, 0.0, 0.0), side = Vec3::UnitY();
  const double r = 0.01;  // angular radius seen from I: 0.01 / 0.25 = 0.04 rad
  auto pointsOf = [&](const Vec3& I) { return jointWrapPoints(O, I, J, r, side).second; };
  auto moved = [](const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
    double m = 0.0;
    for (size_t k = 0; k < a.size(); ++k) m = std::max(m, (a[k] - b[k]).norm());
    return m;
  };
  const Vec3 I(0.25, 0.0, 0.0);
  const std::vector<Vec3> rest = pointsOf(I);
  Vec3 x, t;
  paths::ActionPath p;
  paths::jointWrapPath(O, I, J, r, side, p);
  ASSERT_TRUE(p.wrapped);
  paths::pointAt(p, p.pieces[0].length + 0.5 * p.pieces[1].length, x, t);
  EXPECT_GT(x.y(), 0.99 * r);  // over the +Y side
  std::mt19937 rng(11);
  std::normal_distribution<double> nd(0.0, 1.0);
  for (double eps : {1e-9, 1e-7, 1e-5}) {
    for (int trial = 0; trial < 50; ++trial) {
      const Vec3 d = eps * Vec3(nd(rng), nd(rng), nd(rng)).normalized();
      EXPECT_LT(moved(pointsOf(I + d), rest), 10.0 * eps + 1e-12) << "I moved by " << eps;
    }
  }
  // Bending towards, away from and across the side, in steps of 1e-4 rad up to 0.02 rad (half the angular
  // radius): no step moves the path by more than 50 times the step's move of I.
  for (const Vec3& across : {Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1), Vec3(0, 0.6, 0.8)}) {
    std::vector<Vec3> last = rest;
    for (int k = 1; k <= 200; ++k) {
      const double a = 1e-4 * k;
      const std::vector<Vec3> now = pointsOf(0.25 * (std::cos(a) * Vec3::UnitX() + std::sin(a) * across));
      EXPECT_LT(moved(now, last), 50.0 * 0.25e-4) << "bend " << a << " across " << across.transpose();
      last = now;
    }
  }
}

TEST(Paths, JointWrapOfAMuscleBesideTheJointDoesNotFlipWithRounding) {
  // A muscle beside a hinge (its side along the hinge's axis, Z), the limb bent by 110 degrees in the XY plane: the
  // side names neither way round, and rounding in the side (float32 bone matrices) must not pick one. Before, a side
  // off the axis by 1e-9 went round the outside or the crease with the sign of that 1e-9 (2 cm apart on the synthetic
  // arm's elbow); the path is the short way for every such side, and the same within 1e-9 of the bend's move.
  const Vec3 O(-0.3, 0.02, 0.0), J(0.0, 0.0, 0.0);
  const double bend = 110.0 * kPi / 180.0, r = 0.04;
  const Vec3 I = 0.25 * Vec3(std::cos(bend), std::sin(bend), 0.0);
  auto pointsOf = [&](const Vec3& side) { return jointWrapPoints(O, I, J, r, side); };
  const auto [length, reference] = pointsOf(Vec3::UnitZ());
  paths::ActionPath shortWay;
  paths::jointWrapPath(O, I, J, r, Vec3::UnitY(), shortWay);  // the side of the crease: the short way
  EXPECT_NEAR(length, shortWay.length, 1e-12);
  paths::ActionPath longWay;
  paths::jointWrapPath(O, I, J, r, -Vec3::UnitY(), longWay);  // over the outside: much longer, so a flip shows
  ASSERT_GT(longWay.length, length + 0.5 * r);
  for (const Vec3& noise : {Vec3(1e-9, 0, 0), Vec3(-1e-9, 0, 0), Vec3(0, 1e-9, 0), Vec3(0, -1e-9, 0),
                            Vec3(3e-7, -2e-7, 0), Vec3(-0.05, 0.05, 0)}) {
    const auto [l, pts] = pointsOf(Vec3::UnitZ() + noise);
    EXPECT_NEAR(l, length, 1e-9) << noise.transpose();
    for (size_t k = 0; k < pts.size(); ++k) EXPECT_LT((pts[k] - reference[k]).norm(), 1e-9) << noise.transpose();
    paths::ActionPath a, b;
    double weight;  // what the rig blends by: the long way must not come in either
    paths::jointWrapWays(O, I, J, r, Vec3::UnitZ() + noise, a, b, weight);
    EXPECT_LT(weight, 1e-6) << noise.transpose();
  }
  // A side leaning towards the outside weighs the long way in by degrees: some at 0.2, all of it pointing outside.
  paths::ActionPath a, b;
  double leaning, outside;
  paths::jointWrapWays(O, I, J, r, Vec3::UnitZ() - 0.2 * Vec3::UnitY(), a, b, leaning);
  paths::jointWrapWays(O, I, J, r, -Vec3::UnitY(), a, b, outside);
  EXPECT_GT(leaning, 0.05);
  EXPECT_LT(leaning, 0.5);
  EXPECT_EQ(outside, 1.0);
}

TEST(Paths, JointWrapWaysWeighTheLongWayByTheSidesCosineWithTheOutside) {
  // Independent answer: past the side band the long way's weight is smoothstep(c / 0.5), c the side's cosine with the
  // outside of the bend, -(o + i) normalised for the unit directions o, i of O and I from J, the side taken across the
  // plane's normal too (its in-plane share). Over bends of 20-170 degrees and sides all round, it holds to 1e-12, is 0
  // for a side in the crease or along the hinge and 1 on the outside, and moves continuously with the bend.
  const Vec3 J(0.01, -0.02, 0.0), O = J + Vec3(-0.3, 0.01, 0.0);
  const double r = 0.03;
  auto smoothstep = [](double x) {
    const double t = std::clamp(x, 0.0, 1.0);
    return t * t * (3 - 2 * t);
  };
  int checked = 0;
  for (double degrees = 20; degrees <= 170; degrees += 2.5) {
    const double a = degrees * kPi / 180;
    const Vec3 I = J + 0.25 * Vec3(-std::cos(kPi - a), std::sin(kPi - a), 0.0);  // bent towards +Y by `degrees`
    const Vec3 o = (O - J).normalized(), i = (I - J).normalized(), n = o.cross(i).normalized();
    const Vec3 outside = -(o + i).normalized();
    for (double turn = 0; turn < 360; turn += 15) {
      const double t = turn * kPi / 180;
      const Vec3 side = std::cos(t) * outside + std::sin(t) * (0.6 * n + 0.8 * o.cross(n));
      paths::ActionPath shortWay, longWay;
      double w;
      paths::jointWrapWays(O, I, J, r, side, shortWay, longWay, w);
      const Vec3 inPlane = side - side.dot(n) * n;
      EXPECT_NEAR(w, smoothstep(inPlane.dot(outside) / side.norm() / 0.5), 1e-12) << degrees << " " << turn;
      EXPECT_LE(shortWay.length, longWay.length + 1e-12);
      ++checked;
    }
    paths::ActionPath s1, l1;
    double inCrease, alongHinge, outer;
    paths::jointWrapWays(O, I, J, r, -outside, s1, l1, inCrease);
    paths::jointWrapWays(O, I, J, r, n, s1, l1, alongHinge);
    paths::jointWrapWays(O, I, J, r, outside, s1, l1, outer);
    EXPECT_EQ(inCrease, 0.0);
    EXPECT_EQ(alongHinge, 0.0);
    EXPECT_EQ(outer, 1.0);
  }
  EXPECT_GT(checked, 1000);
  // Continuity: a side at 50 degrees from the outside, bent in steps of 0.05 degrees from 20 to 170 degrees.
  double last = -1;
  for (double degrees = 20; degrees <= 170; degrees += 0.05) {
    const double a = degrees * kPi / 180;
    const Vec3 I = J + 0.25 * Vec3(-std::cos(kPi - a), std::sin(kPi - a), 0.0);
    const Vec3 side = Vec3(0, -std::cos(50 * kPi / 180), std::sin(50 * kPi / 180));  // the outside of a +Y bend is -Y
    paths::ActionPath shortWay, longWay;
    double w;
    paths::jointWrapWays(O, I, J, r, side, shortWay, longWay, w);
    if (last >= 0) EXPECT_LT(std::abs(w - last), 0.01) << degrees;
    last = w;
  }
}

TEST(Paths, BoneWrapTangentAndShortestAndGeodesic) {
  const Vec3 C(0, 0, 0), e1 = Vec3::UnitZ(), e2 = Vec3::UnitX(), ax = Vec3::UnitY();
  const Vec3 O(0.0, -0.2, 0.06), I(-0.05, 0.25, -0.03);  // O at phi = 0, I round the back
  const double r = 0.03;
  paths::ActionPath p;
  paths::boneWrapPath(O, I, C, e1, e2, ax, r, 1, p);
  ASSERT_TRUE(p.wrapped);
  // Tangent continuity at both tangent points and on the cylinder.
  const double s1 = p.pieces[0].length, s2 = s1 + p.pieces[1].length;
  Vec3 x0, x1, t0, t1;
  for (double s : {s1, s2}) {
    paths::pointAt(p, s - 1e-10, x0, t0);
    paths::pointAt(p, s + 1e-10, x1, t1);
    EXPECT_LT((t0 - t1).norm(), 1e-6);
    const Vec3 d = x1 - C;
    EXPECT_NEAR((d - d.dot(ax) * ax).norm(), r, 1e-8);
  }
  // Shortest among perturbed (phi1, h1, phi2, h2) with a geodesic helix between.
  auto cyl = [&](double phi, double h) { return C + r * (std::cos(phi) * e1 + std::sin(phi) * e2) + h * ax; };
  auto coords = [&](const Vec3& q, double& phi, double& h) {
    const Vec3 d = q - C;
    h = d.dot(ax);
    phi = std::atan2(d.dot(e2), d.dot(e1));
  };
  double phi1, h1, phi2, h2;
  coords(p.pieces[0].b, phi1, h1);
  coords(p.pieces[2].a, phi2, h2);
  double dphi = phi2 - phi1;
  while (dphi < 0) dphi += 2 * kPi;
  auto clears = [&](const Vec3& a, const Vec3& b) {
    for (int k = 0; k <= 200; ++k) {
      const Vec3 q = a + (k / 200.0) * (b - a) - C;
      if ((q - q.dot(ax) * ax).norm() < r * (1 - 1e-9)) return false;
    }
    return true;
  };
  std::mt19937 rng(3);
  std::normal_distribution<double> nd(0.0, 1.0);
  int valid = 0;
  for (int trial = 0; trial < 1500; ++trial) {
    const double eps = 0.05 * std::pow(10.0, -2.0 * (trial % 3) / 2.0);
    const double a1 = phi1 + eps * nd(rng), b1 = h1 + 0.03 * eps * nd(rng);
    const double a2 = a1 + dphi + eps * nd(rng), b2 = h2 + 0.03 * eps * nd(rng);
    if (a2 < a1) continue;
    const Vec3 Q1 = cyl(a1, b1), Q2 = cyl(a2, b2);
    if (!clears(O, Q1) || !clears(Q2, I)) continue;
    ++valid;
    const double helix = std::hypot(r * (a2 - a1), b2 - b1);
    EXPECT_GE((Q1 - O).norm() + helix + (I - Q2).norm(), p.length - 1e-12);
  }
  EXPECT_GT(valid, 100);
  // The other side goes round the other way and is a different (here longer) path.
  paths::ActionPath q;
  paths::boneWrapPath(O, I, C, e1, e2, ax, r, -1, q);
  EXPECT_TRUE(q.wrapped);
  EXPECT_GT(std::abs(q.length - p.length), 1e-4);
  // No wrap needed: straight.
  paths::boneWrapPath(O, Vec3(0.01, 0.25, 0.06), C, e1, e2, ax, r, 1, q);
  EXPECT_FALSE(q.wrapped);
}

TEST(Paths, HelixFrameIsRotationMinimising) {
  // Compare the closed-form frame with a fine discrete parallel transport (double reflection).
  paths::ActionPath p;
  paths::boneWrapPath(Vec3(0, -0.2, 0.06), Vec3(-0.05, 0.25, -0.03), Vec3::Zero(), Vec3::UnitZ(), Vec3::UnitX(),
                      Vec3::UnitY(), 0.03, 1, p);
  Vec3 x, t;
  paths::pointAt(p, 0, x, t);
  Mat3 F0;
  F0.col(1) = t;
  F0.col(0) = t.unitOrthogonal();
  F0.col(2) = F0.col(0).cross(t);
  const int n = 20000;
  Vec3 r = F0.col(0), xPrev = x, tPrev = t;
  for (int k = 1; k <= n; ++k) {
    Vec3 xk, tk;
    paths::pointAt(p, p.length * k / n, xk, tk);
    const Vec3 v1 = xk - xPrev;
    const double c1 = v1.squaredNorm();
    if (c1 > 1e-30) {
      const Vec3 rL = r - (2 / c1) * v1.dot(r) * v1, tL = tPrev - (2 / c1) * v1.dot(tPrev) * v1;
      const Vec3 v2 = tk - tL;
      const double c2 = v2.squaredNorm();
      r = c2 > 1e-30 ? Vec3(rL - (2 / c2) * v2.dot(rL) * v2) : rL;
    }
    xPrev = xk, tPrev = tk;
  }
  const Mat3 F = paths::frameAt(p, F0, p.length);
  EXPECT_LT((F.col(0) - r.normalized()).norm(), 1e-5);
  EXPECT_LT((F.col(1) - tPrev).norm(), 1e-9);
}

// ============================================================================
// The rig
// ============================================================================

TEST(MuscleRig, RestPoseGivesBindMatricesAndRestSurfaces) {
  const std::vector<Muscle> ms{biceps(), tricepsWrap(), forearmWrap()};
  const MuscleRig rig(arm(), ms);
  ASSERT_EQ(rig.numMuscles(), 3);
  ASSERT_EQ(rig.numJoints(), 18);
  EXPECT_EQ(rig.jointNames()[0], "biceps.j0");
  EXPECT_EQ(rig.jointNames()[17], "supinator.j5");
  EXPECT_EQ(rig.jointParentBone()[0], arm().find("upper_arm"));
  MuscleRigState st = rig.makeState();
  rig.evaluate(restPose(arm()), st, true);
  for (int j = 0; j < rig.numJoints(); ++j) {
    EXPECT_LT(relDiff(st.jointMatrices[j], rig.bindMatrices()[j]), 1e-9) << rig.jointNames()[j];
    const Mat3 R = rig.bindMatrices()[j].topLeftCorner<3, 3>();
    EXPECT_LT((R.transpose() * R - Mat3::Identity()).norm(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  }
  for (int m = 0; m < 3; ++m) {
    EXPECT_NEAR(st.stretch[m], 1.0, 1e-12);
    EXPECT_LT((st.surfaces[m] - rig.restSurface(m).vertices).cwiseAbs().maxCoeff(), 1e-12);
  }
  // Joints lie inside the muscle, on its root curve, ordered origin -> insertion.
  const Vec3 O = ms[0].origin.position, I = ms[0].insertion.position;
  double prev = -1;
  for (int k = 0; k < 6; ++k) {
    const Vec3 c = rig.bindMatrices()[k].topRightCorner<3, 1>();
    const double t = (c - O).dot(I - O) / (I - O).squaredNorm();
    EXPECT_GT(t, prev);
    prev = t;
    EXPECT_GT(c.z() - (O.z() + t * (I.z() - O.z())), 0.0);  // bowed to the front like the root curve
  }
}

TEST(MuscleRig, StraightPathFramesFollowAndDoNotSpin) {
  const MuscleRig rig(arm(), {biceps()});
  MuscleRigState st = rig.makeState();
  const Mat4 bind0 = rig.bindMatrices()[0];
  Vec3 prevX = bind0.col(0).head<3>();
  double prevLen = rig.restLengths()[0];
  for (int deg = 0; deg <= 150; ++deg) {
    rig.evaluate(armPose(deg * kPi / 180), st);
    const double lambda = st.stretch[0];
    for (int k = 0; k < 6; ++k) {
      const Mat4& J = st.jointMatrices[k];
      // Scale along Y is the stretch; X and Z share one scale.
      EXPECT_NEAR(J.col(1).head<3>().norm(), lambda, 1e-12);
      EXPECT_NEAR(J.col(0).head<3>().norm(), J.col(2).head<3>().norm(), 1e-12);
    }
    const Vec3 X = st.jointMatrices[0].col(0).head<3>().normalized();
    EXPECT_LT(std::acos(std::clamp(X.dot(prevX), -1.0, 1.0)), 2.0 * kPi / 180) << "frame jumped at " << deg;
    EXPECT_LT(std::abs(st.length[0] - prevLen), 0.01) << "length jumped at " << deg;
    prevX = X;
    prevLen = st.length[0];
  }
  EXPECT_LT(st.stretch[0], 0.8);  // the biceps shortens on flexion
  // Joint axes run along the straight path from origin to insertion.
  rig.evaluate(armPose(1.0), st);
  const Pose pose = armPose(1.0);
  const Muscle& mu = rig.muscles()[0];
  auto posed = [&](const MuscleAttachment& a) {
    const int b = arm().find(a.bone);
    const Mat4 M = pose.matrices[b] * arm().bones[b].rest.inverse();
    return Vec3((M * a.position.homogeneous()).head<3>());
  };
  const Vec3 dir = (posed(mu.insertion) - posed(mu.origin)).normalized();
  EXPECT_LT((st.jointMatrices[3].col(1).head<3>().normalized() - dir).norm(), 1e-9);
  EXPECT_NEAR(st.length[0], (posed(mu.insertion) - posed(mu.origin)).norm(), 1e-12);
  // The frame is anchored to the origin bone: twisting the upper arm about its axis turns it with the bone.
  rig.evaluate(armPose(0.0, 0.0, 0.0), st);
  std::vector<Eigen::Quaterniond> q(arm().numBones(), Eigen::Quaterniond::Identity());
  q[arm().find("upper_arm")] = Eigen::AngleAxisd(0.3, Vec3::UnitY());
  MuscleRigState tw = rig.makeState();
  rig.evaluate(poseFromLocalRotations(arm(), q), tw);
  const Mat3 Rb = Eigen::AngleAxisd(0.3, Vec3::UnitX()).toRotationMatrix();  // bone Y = world +X
  EXPECT_LT((tw.jointMatrices[2].topLeftCorner<3, 3>() - Rb * st.jointMatrices[2].topLeftCorner<3, 3>()).norm(), 1e-9);
}

TEST(MuscleRig, JointWrapBeginsAndEndsContinuously) {
  const MuscleRig rig(arm(), {tricepsWrap()});
  MuscleRigState st = rig.makeState();
  rig.evaluate(armPose(0), st);
  ASSERT_FALSE(st.wrapped[0]) << "the triceps runs straight with the arm extended";
  int transitions = 0;
  bool wasWrapped = false;
  double prevLen = st.length[0];
  std::vector<Mat4> prev = st.jointMatrices;
  const double step = 0.1 * kPi / 180;
  for (int k = 0; k <= 1500; ++k) {
    rig.evaluate(armPose(k * step), st);
    if (bool(st.wrapped[0]) != wasWrapped) ++transitions, wasWrapped = st.wrapped[0];
    // A step of 0.1 degree moves points on a 0.3 m arm by ~0.5 mm; allow 1 mm.
    EXPECT_LT(std::abs(st.length[0] - prevLen), 1e-3) << "at step " << k;
    for (int j = 0; j < rig.numJoints(); ++j) {
      EXPECT_LT((st.jointMatrices[j].col(3) - prev[j].col(3)).norm(), 1e-3) << "joint " << j << " step " << k;
      EXPECT_LT((st.jointMatrices[j].col(1) - prev[j].col(1)).norm(), 0.01) << "joint " << j << " step " << k;
    }
    prevLen = st.length[0];
    prev = st.jointMatrices;
  }
  EXPECT_TRUE(wasWrapped) << "the triceps wraps round the elbow at 150 degrees";
  EXPECT_GE(transitions, 1);
  // Wrapped: every joint stays outside the sphere (less the muscle's own offset) and stretch > 1.
  rig.evaluate(armPose(2.4), st);
  EXPECT_GT(st.stretch[0], 1.0);
}

TEST(MuscleRig, JointWrapOnTheInsideOfTheBendNeverGoesRoundTheBack) {
  // A biceps-like muscle in front of the elbow with a sphere there: flexing moves the line O-I away from
  // the sphere on the muscle's side, so the path stays short and continuous through 90 degrees and beyond.
  Muscle mu = biceps();
  mu.wrap.type = WrapType::Joint;
  mu.wrap.bone = "forearm";
  mu.wrap.radius = 0.012;
  const MuscleRig rig(arm(), {mu});
  MuscleRigState st = rig.makeState();
  double prevLen = rig.restLengths()[0];
  for (int k = 0; k <= 1500; ++k) {
    rig.evaluate(armPose(k * 0.1 * kPi / 180), st);
    EXPECT_LT(std::abs(st.length[0] - prevLen), 1e-3) << "at " << 0.1 * k << " degrees";
    EXPECT_LE(st.length[0], rig.restLengths()[0] + 1e-9) << "at " << 0.1 * k << " degrees";
    prevLen = st.length[0];
  }
}

TEST(MuscleRig, AMuscleBlendingItsTwoWaysRoundIsExactAtRestAndMovesContinuously) {
  // A muscle whose ends lie in front of the elbow at rest (origin and insertion 2 cm in front of the arm's axis, 6 cm
  // either side of the joint: a rest bend of about 37 degrees whose outside is the back, -Z) and whose belly bows 4 cm
  // out along the hinge (+Y) and the back: its side, just behind the joint, names the outside only in part, so at rest
  // the rig blends both ways round. Flexing towards +Z bends it further (no straight limb on the way, where the side
  // band turns the plane) and turns the outside round the side, so the blend's weight changes all along.
  const Vec3 el = head("forearm"), x = Vec3::UnitX(), side = Vec3(0, 0.78, -0.625).normalized();
  Muscle mu = spindle("oblique", el - 0.06 * x + 0.02 * Vec3::UnitZ(), "upper_arm", el + 0.06 * x + 0.02 * Vec3::UnitZ(),
                      "forearm", side, 0.04, 0.008);
  mu.wrap.type = WrapType::Joint;
  mu.wrap.bone = "forearm";
  mu.wrap.radius = 0.012;
  // The side the rig takes (MuscleRig: the root curve's point nearest the joint, across the line O-I) weighs the long
  // way in part at rest.
  const Vec3 O = mu.origin.position, I = mu.insertion.position;
  Vec3 nearest = mu.rootCurve.front();
  for (const Vec3& c : mu.rootCurve)
    if ((c - el).norm() < (nearest - el).norm()) nearest = c;
  const Vec3 along = (I - O).normalized();
  const Vec3 restSide = ((nearest - el) - (nearest - el).dot(along) * along).normalized();
  paths::ActionPath a, b;
  double restWeight;
  paths::jointWrapWays(O, I, el, mu.wrap.radius, restSide, a, b, restWeight);
  ASSERT_GT(restWeight, 0.05);
  ASSERT_LT(restWeight, 0.95);

  const MuscleRig rig(arm(), {mu});
  MuscleRigState st = rig.makeState();
  rig.evaluate(restPose(arm()), st, true);
  for (int j = 0; j < rig.numJoints(); ++j)
    EXPECT_LT(relDiff(st.jointMatrices[j], rig.bindMatrices()[j]), 1e-12) << rig.jointNames()[j];
  EXPECT_NEAR(st.stretch[0], 1.0, 1e-12);
  EXPECT_NEAR(rig.restLengths()[0], (1 - restWeight) * a.length + restWeight * b.length, 1e-12);
  EXPECT_LT((st.surfaces[0] - rig.restSurface(0).vertices).cwiseAbs().maxCoeff(), 1e-12);
  // Flexed towards +Z in steps of 0.1 degree up to 120: joints move at most 1 mm and turn their axes by at most 0.01 a
  // step, the length by at most 1 mm; the weight at 120 degrees is another than at rest.
  std::vector<Mat4> prev = st.jointMatrices;
  double prevLength = st.length[0], shortest = st.length[0], longest = st.length[0];
  for (int k = 1; k <= 1200; ++k) {
    rig.evaluate(armPose(k * 0.1 * kPi / 180), st, true);
    EXPECT_LT(std::abs(st.length[0] - prevLength), 1e-3) << "at " << 0.1 * k << " degrees";
    for (int j = 0; j < rig.numJoints(); ++j) {
      EXPECT_LT((st.jointMatrices[j].col(3) - prev[j].col(3)).norm(), 1e-3) << "joint " << j << " at " << 0.1 * k;
      EXPECT_LT((st.jointMatrices[j].col(1) - prev[j].col(1)).norm(), 0.01) << "joint " << j << " at " << 0.1 * k;
    }
    ASSERT_TRUE(st.surfaces[0].allFinite());
    prev = st.jointMatrices;
    prevLength = st.length[0];
    shortest = std::min(shortest, st.length[0]), longest = std::max(longest, st.length[0]);
  }
  EXPECT_GT(longest - shortest, 0.005);  // the sweep moves the muscle: the steps could have jumped
  const Pose bent = armPose(120 * kPi / 180);
  auto posed = [&](const MuscleAttachment& at) {
    const int bone = arm().find(at.bone);
    return Vec3((bent.matrices[bone] * arm().bones[bone].rest.inverse() * at.position.homogeneous()).head<3>());
  };
  double bentWeight;
  paths::jointWrapWays(posed(mu.origin), posed(mu.insertion), bent.matrices[arm().find("forearm")].topRightCorner<3, 1>(),
                       mu.wrap.radius, restSide, a, b, bentWeight);  // the side is carried by the upper arm, unturned
  EXPECT_GT(std::abs(bentWeight - restWeight), 0.1);
}

TEST(MuscleRig, BoneWrapFollowsTwistBothSides) {
  for (int side : {1, -1}) {
    const MuscleRig rig(arm(), {forearmWrap(side)});
    MuscleRigState st = rig.makeState();
    double prevLen = rig.restLengths()[0];
    std::vector<Mat4> prev = rig.bindMatrices();
    bool wrapped = false;
    int transitions = 0;
    for (int k = 0; k <= 600; ++k) {
      rig.evaluate(armPose(0.0, side * k * 0.25 * kPi / 180), st);
      if (bool(st.wrapped[0]) != wrapped) ++transitions, wrapped = st.wrapped[0];
      EXPECT_LT(std::abs(st.length[0] - prevLen), 1e-3) << "side " << side << " step " << k;
      prevLen = st.length[0];
      for (int j = 0; j < rig.numJoints(); ++j) {
        ASSERT_TRUE(st.jointMatrices[j].allFinite());
        // A 0.25 degree twist moves points 3 cm from the axis by 0.13 mm; frames turn by about as much.
        EXPECT_LT((st.jointMatrices[j].col(3) - prev[j].col(3)).norm(), 1e-3) << "joint " << j << " step " << k;
        EXPECT_LT((st.jointMatrices[j].topLeftCorner<3, 3>() - prev[j].topLeftCorner<3, 3>()).norm(), 0.02)
            << "joint " << j << " step " << k;
      }
      prev = st.jointMatrices;
    }
    EXPECT_EQ(transitions, 1) << "side " << side << ": the wrap starts once and stays";
    EXPECT_TRUE(wrapped) << "side " << side << ": a 150 degree twist wraps the muscle round the forearm";
    // Wrapped joints sit outside the cylinder, less the muscle's 4 mm bow off its path (a straight line
    // would pass within a few millimetres of the axis).
    const Mat4 fa = armPose(0.0, side * 150 * kPi / 180).matrices[arm().find("forearm")];
    const Vec3 ax = fa.block<3, 1>(0, 1).normalized(), c = fa.block<3, 1>(0, 3);
    int alongForearm = 0;
    for (int j = 0; j < rig.numJoints(); ++j) {
      const Vec3 d = st.jointMatrices[j].block<3, 1>(0, 3) - c;
      if (d.dot(ax) <= 0) continue;
      ++alongForearm;
      EXPECT_GT((d - d.dot(ax) * ax).norm(), 0.02 - 0.004) << "joint " << j;
    }
    EXPECT_GE(alongForearm, 1) << "side " << side << ": some joint lies along the forearm's cylinder";
  }
}

TEST(MuscleRig, VolumeConstantOverStretchForEveryBulgeFactor) {
  for (double k : {0.0, 1.0, 3.0}) {
    Muscle mu = biceps();
    mu.bulge = k;
    const MuscleRig rig(arm(), {mu});
    MuscleRigState st = rig.makeState();
    const double v0 = enclosedVolume(rig.restSurface(0).vertices, rig.restSurface(0).triangles);
    const double L0 = rig.restLengths()[0];
    double worst = 0;
    for (double lambda : {0.6, 0.7, 0.8, 0.9, 1.1, 1.25, 1.4, 1.5}) {
      // The biceps is nearly parallel to the arm: move the forearm along X until the stretch is reached.
      double dx = (lambda - 1) * L0;
      for (int it = 0; it < 30; ++it) {
        rig.evaluate(stretchPose(dx), st);
        dx += (lambda - st.stretch[0]) * L0;
      }
      rig.evaluate(stretchPose(dx), st, true);
      ASSERT_NEAR(st.stretch[0], lambda, 1e-6);
      const double v = enclosedVolume(st.surfaces[0], rig.restSurface(0).triangles);
      worst = std::max(worst, std::abs(v / v0 - 1));
    }
    std::printf("bulge k=%.0f: worst volume change over stretch 0.6-1.5 = %.4f %%\n", k, 100 * worst);
    EXPECT_LT(worst, 0.005) << "k = " << k;
  }
}

TEST(MuscleRig, BulgeFactorConcentratesChangeInTheBelly) {
  // Contracted to 0.7: with k = 0 every joint scales by 0.7^-1/2; with k = 3 the belly more, the ends less.
  auto scales = [](double k) {
    Muscle mu = biceps();
    mu.bulge = k;
    mu.joints = 8;
    const MuscleRig rig(arm(), {mu});
    MuscleRigState st = rig.makeState();
    const double L0 = rig.restLengths()[0];
    double dx = -0.3 * L0;
    for (int it = 0; it < 30; ++it) rig.evaluate(stretchPose(dx), st), dx += (0.7 - st.stretch[0]) * L0;
    std::vector<double> s;
    for (const Mat4& J : st.jointMatrices) s.push_back(J.col(0).head<3>().norm());
    return s;
  };
  const auto uniform = scales(0.0), belly = scales(3.0);
  for (double s : uniform) EXPECT_NEAR(s, 1 / std::sqrt(0.7), 1e-6);
  EXPECT_GT(belly[4], uniform[4] + 0.02);
  EXPECT_LT(belly[0], uniform[0] - 0.02);
  EXPECT_LT(belly[7], uniform[7] - 0.02);
}

TEST(MuscleRig, EvaluateAllocatesNothingAndIsDeterministic) {
  for (int mode : {0, 1, 2}) {  // sliding joints, joints that do not slide, sliding joints with slide limits
    MuscleRigOptions o;
    o.jointsSlide = mode != 1;
    if (mode == 2) {
      const int J = MuscleRig(arm(), {biceps(), tricepsWrap(), forearmWrap()}).numJoints();
      for (int j = 0; j < J; ++j) o.slideLimits.push_back({0.005 * (1 + j % 3), j % 4 == 0 ? 0.0 : 0.01});
    }
    const MuscleRig rig(arm(), {biceps(), tricepsWrap(), forearmWrap()}, o);
    MuscleRigState a = rig.makeState(), b = rig.makeState();
    const Pose pose = armPose(2.0, 0.8);
    rig.evaluate(pose, a, true);
    const long before = gAllocations.load();
    rig.evaluate(pose, b, true);
    EXPECT_EQ(gAllocations.load() - before, 0) << "mode " << mode;
    for (int j = 0; j < rig.numJoints(); ++j) EXPECT_EQ(a.jointMatrices[j], b.jointMatrices[j]);
    for (int m = 0; m < 3; ++m) EXPECT_EQ(a.surfaces[m], b.surfaces[m]);
  }
}

// ============================================================================
// Bad input
// ============================================================================

TEST(MuscleRig, BadInputIsRejectedClearly) {
  auto expectError = [](const Muscle& m, const char* needle) {
    try {
      MuscleRig rig(arm(), {m});
      ADD_FAILURE() << "no error for " << needle;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  Muscle same = biceps();
  same.insertion.position = same.origin.position;
  expectError(same, "coincide");
  Muscle zero = tricepsWrap();
  zero.wrap.radius = 0.0;
  expectError(zero, "radius");
  expectError(tricepsWrap(0.08), "inside the joint sphere");
  Muscle cyl = forearmWrap();
  cyl.wrap.radius = 0.1;
  expectError(cyl, "inside the cylinder");
  Muscle bone = biceps();
  bone.origin.bone = "tibia";
  expectError(bone, "'tibia' is not in the skeleton");
  Muscle many = biceps();
  many.joints = 500;
  expectError(many, "joints must be in");

  const MuscleRig rig(arm(), {biceps(), tricepsWrap()});
  MuscleRigState st = rig.makeState();
  Pose nan = restPose(arm());
  nan.matrices[1](0, 3) = NAN;
  EXPECT_THROW(rig.evaluate(nan, st), InputError);
  Pose shortPose = restPose(arm());
  shortPose.matrices.pop_back();
  EXPECT_THROW(rig.evaluate(shortPose, st), InputError);
  MuscleRigState wrong;
  EXPECT_THROW(rig.evaluate(restPose(arm()), wrong), InputError);
}

TEST(MuscleRig, DegeneratePosesStayFinite) {
  // Insertion dragged onto the origin, and into the joint sphere: documented fallbacks, no NaN.
  const MuscleRig rig(arm(), {biceps(), tricepsWrap()});
  MuscleRigState st = rig.makeState();
  const Muscle& mu = rig.muscles()[0];
  Pose p = restPose(arm());
  const int fa = arm().find("forearm");
  p.matrices[fa].topRightCorner<3, 1>() += mu.origin.position - mu.insertion.position;
  p.matrices[arm().find("hand")].topRightCorner<3, 1>() += mu.origin.position - mu.insertion.position;
  rig.evaluate(p, st, true);
  ASSERT_EQ(st.jointMatrices.size(), 12u);  // six joints per muscle
  ASSERT_EQ(st.surfaces.size(), 2u);
  for (const Mat4& J : st.jointMatrices) EXPECT_TRUE(J.allFinite());
  for (const Points& s : st.surfaces) EXPECT_TRUE(s.allFinite());
  Pose q = restPose(arm());
  q.matrices[fa].topRightCorner<3, 1>() -= Vec3(0.03, 0, -0.03);
  rig.evaluate(q, st, true);
  for (const Mat4& J : st.jointMatrices) EXPECT_TRUE(J.allFinite());
}

TEST(MuscleRig, ForearmRollIsDistributedAlongMusclesThatReachIt) {
  // A muscle from the upper arm to the forearm: twisting the forearm 60 degrees about its axis turns the
  // joint frames about the path by a share growing from ~0 at the origin to ~60 at the insertion (linear in
  // arc length), or following the bones: little along the upper arm, most along the forearm. The biceps inserts
  // 12 % down the forearm (no joint lies along the forearm proper); a longer flexor reaches 60 % down it.
  const Vec3 sh = head("upper_arm"), el = head("forearm");
  const Muscle longFlexor = spindle("long_flexor", sh + 0.15 * (el - sh) + Vec3(0, 0, 0.02), "upper_arm",
                                    el + 0.6 * (tail("forearm") - el) + Vec3(0, 0, 0.015), "forearm", Vec3::UnitZ(), 0.02, 0.022);
  enum class Mode { Linear, Bones, Off };
  for (const Muscle& mu : {biceps(), longFlexor})
  for (Mode mode : {Mode::Linear, Mode::Bones, Mode::Off}) {
    MuscleRigOptions o;
    o.distributeTwist = mode != Mode::Off;
    o.twistFollowsBones = mode == Mode::Bones;
    const MuscleRig rig(arm(), {mu}, o);
    MuscleRigState st = rig.makeState();
    rig.evaluate(armPose(0.0, 60 * kPi / 180), st, true);
    const Bone& upper = arm().bones[arm().find("upper_arm")];
    const Bone& fore = arm().bones[arm().find("forearm")];
    double prev = -1.0;
    int alongFore = 0, alongUpper = 0;
    for (int k = 0; k < rig.numJoints(); ++k) {
      const Mat3 B = rig.bindMatrices()[k].topLeftCorner<3, 3>();
      const Mat3 R = st.jointMatrices[k].topLeftCorner<3, 3>().colwise().normalized();
      const Vec3 t = R.col(1);
      const double roll = std::atan2(B.col(0).cross(R.col(0)).dot(t), B.col(0).dot(R.col(0))) * 180 / kPi;
      if (mode == Mode::Off) {
        EXPECT_NEAR(roll, 0.0, 0.1) << "joint " << k;  // only the insertion's slight move turns the path
        continue;
      }
      EXPECT_GT(roll, prev - 1e-9) << "joint " << k;
      EXPECT_GT(roll, 0.0);
      EXPECT_LT(roll, 60.0);
      if (mode == Mode::Bones) {  // the share is the rest position's: d_o^2 / (d_o^2 + d_i^2)
        const Vec3 p = rig.bindMatrices()[k].topRightCorner<3, 1>();
        auto d2 = [&](const Bone& b) {
          const Vec3 ab = b.tail - b.head;
          const double u = std::clamp((p - b.head).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
          return (p - b.head - u * ab).squaredNorm();
        };
        if (d2(upper) > 4 * d2(fore)) {
          ++alongFore;
          EXPECT_GT(roll, 0.7 * 60.0) << "joint " << k << " lies along the forearm";
        }
        if (d2(fore) > 4 * d2(upper)) {
          ++alongUpper;
          EXPECT_LT(roll, 0.3 * 60.0) << "joint " << k << " lies along the upper arm";
        }
      }
      prev = roll;
    }
    if (mode == Mode::Linear) EXPECT_GT(prev, 40.0) << "the last joint, near the insertion, turns with the forearm";
    if (mode == Mode::Bones) {
      EXPECT_GT(prev, 25.0) << "the last joint, past the elbow, turns with the forearm";
      std::printf("%s, bone-following twist: %d joints along the upper arm, %d along the forearm\n", mu.name.c_str(),
                  alongUpper, alongFore);
      EXPECT_GE(alongUpper, 1) << mu.name;
      if (mu.name == "long_flexor") EXPECT_GE(alongFore, 1) << "the checks along the forearm ran";
    }
    EXPECT_TRUE(st.surfaces[0].allFinite());
  }
}

TEST(MuscleRig, JointsThatDoNotSlideMoveAlongTheirBoneAsTheBoneDoes) {
  // The biceps across the elbow shortens on flexion: sliding joints ride their stations towards the origin; with
  // jointsSlide = false each joint's motion along its bone (the chain bone nearest at rest) is the bone's, and its
  // frame, scale and offset across the bone are the sliding joint's.
  const Skeleton& s = arm();
  const Muscle mu = biceps();
  MuscleRigOptions slide, still;
  slide.jointsSlide = true;
  still.jointsSlide = false;
  const MuscleRig sliding(s, {mu}, slide), fixed(s, {mu}, still);
  MuscleRigState a = sliding.makeState(), b = fixed.makeState();
  const Pose rest = restPose(s);
  const double size = (tail("forearm") - head("upper_arm")).norm();
  fixed.evaluate(rest, b, true);
  for (int k = 0; k < fixed.numJoints(); ++k)  // rest pose exact
    EXPECT_LT((b.jointMatrices[k] - fixed.bindMatrices()[k]).norm(), 1e-12) << "joint " << k;
  EXPECT_LT((b.surfaces[0] - fixed.restSurface(0).vertices).cwiseAbs().maxCoeff(), 1e-12);
  const Pose pose = armPose(100 * kPi / 180);
  sliding.evaluate(pose, a, true);
  fixed.evaluate(pose, b, true);
  // The surface goes with its joints: the belly's skin-side half (over the upper arm) slides towards the shoulder
  // with sliding joints and stays with the upper arm without.
  {
    const Bone& upper = s.bones[s.find("upper_arm")];
    const Vec3 axis = (upper.tail - upper.head).normalized();
    const Points& restSurface = fixed.restSurface(0).vertices;
    double slid = 0, still = 0;
    int n = 0;
    for (int v = 0; v < restSurface.rows(); ++v) {
      const Vec3 p = restSurface.row(v).transpose();
      if ((p - upper.head).dot(axis) > 0.7 * (upper.tail - upper.head).norm()) continue;  // the upper arm's part
      slid += (a.surfaces[0].row(v).transpose() - p).dot(axis);
      still += (b.surfaces[0].row(v).transpose() - p).dot(axis);
      ++n;
    }
    ASSERT_GT(n, 10);
    std::printf("biceps surface on the upper arm, mean move along it at 100 degrees: sliding %.2f mm, not %.2f mm\n",
                1e3 * slid / n, 1e3 * still / n);
    EXPECT_LT(slid / n, -1e-3 * size);
    EXPECT_LT(std::abs(still / n), 0.1 * std::abs(slid / n));  // what is left: the belly's own shortening about its stations
  }
  double largestSlide = 0.0;
  int alongEach[2] = {0, 0};
  for (int k = 0; k < fixed.numJoints(); ++k) {
    const Vec3 p = fixed.bindMatrices()[k].topRightCorner<3, 1>();
    auto distance = [&](const char* name) {
      const Bone& bone = s.bones[s.find(name)];
      const Vec3 d = bone.tail - bone.head;
      const double t = std::clamp((p - bone.head).dot(d) / d.squaredNorm(), 0.0, 1.0);
      return (bone.head + t * d - p).norm();
    };
    const bool onForearm = distance("forearm") < distance("upper_arm");
    ++alongEach[onForearm];
    const int bone = s.find(onForearm ? "forearm" : "upper_arm");
    const Mat4 carry = pose.matrices[bone] * rest.matrices[bone].inverse();
    const Vec3 carried = (carry * p.homogeneous()).head<3>();
    const Vec3 axis = carry.topLeftCorner<3, 3>() * (s.bones[bone].tail - s.bones[bone].head).normalized();
    const Vec3 moved = b.jointMatrices[k].topRightCorner<3, 1>(), slid = a.jointMatrices[k].topRightCorner<3, 1>();
    EXPECT_NEAR((moved - carried).dot(axis), 0.0, 1e-9 * size) << "joint " << k;
    EXPECT_LT((moved - slid).cross(axis).norm(), 1e-9 * size) << "joint " << k << ": only the motion along the bone changes";
    EXPECT_LT((b.jointMatrices[k].topLeftCorner<3, 3>() - a.jointMatrices[k].topLeftCorner<3, 3>()).norm(), 1e-12);
    largestSlide = std::max(largestSlide, std::abs((slid - carried).dot(axis)));
  }
  EXPECT_GE(alongEach[0], 1);
  EXPECT_GE(alongEach[1], 1);
  EXPECT_GT(largestSlide, 1e-3 * size) << "sliding joints do move along their bone, so the check above can fail";
  EXPECT_LT(a.stretch[0], 0.99) << "the biceps shortens";
}

TEST(MuscleRig, SlideLimitsSaturateEachJointsSlideAlongItsBoneAndNothingElse) {
  // With slideLimits each joint's offset o along its bone (from where the bone carries its rest point) becomes
  // rho tanh(o / rho), rho the limit on o's side; its offset across the bone, frame and scale stay the free slide's.
  const Skeleton& s = arm();
  const Muscle mu = biceps();
  const MuscleRig free(s, {mu});
  const int J = free.numJoints();
  ASSERT_GE(J, 2);
  const double size = (tail("forearm") - head("upper_arm")).norm();
  const Pose rest = restPose(s), pose = armPose(100 * kPi / 180);
  MuscleRigState a = free.makeState();
  free.evaluate(pose, a, true);
  // Limits: half of each joint's free slide on its own side, none the other way.
  MuscleRigOptions limited;
  std::vector<double> freeSlide(J);
  for (int k = 0; k < J; ++k) {
    const Vec3 p = free.bindMatrices()[k].topRightCorner<3, 1>();
    const Vec3 restAxis = free.slideAxes()[k];
    auto distance = [&](const char* name) {  // the chain bone nearest to the joint at rest carries it
      const Bone& bone = s.bones[s.find(name)];
      const Vec3 d = bone.tail - bone.head;
      const double t = std::clamp((p - bone.head).dot(d) / d.squaredNorm(), 0.0, 1.0);
      return (bone.head + t * d - p).norm();
    };
    const int bone = s.find(distance("forearm") < distance("upper_arm") ? "forearm" : "upper_arm");
    const Bone& carrier = s.bones[bone];
    EXPECT_GT((carrier.tail - carrier.head).normalized().dot(restAxis), 1 - 1e-12) << "joint " << k;
    const Mat4 carry = pose.matrices[bone] * rest.matrices[bone].inverse();
    const Vec3 axis = carry.topLeftCorner<3, 3>() * restAxis;
    freeSlide[k] = (a.jointMatrices[k].topRightCorner<3, 1>() - (carry * p.homogeneous()).head<3>()).dot(axis);
    std::array<double, 2> rho = {0.0, 0.0};
    rho[freeSlide[k] > 0 ? 1 : 0] = 0.5 * std::abs(freeSlide[k]);
    limited.slideLimits.push_back(rho);
  }
  const MuscleRig capped(s, {mu}, limited);
  MuscleRigState b = capped.makeState();
  capped.evaluate(rest, b, true);
  for (int k = 0; k < J; ++k) EXPECT_LT((b.jointMatrices[k] - capped.bindMatrices()[k]).norm(), 1e-12);  // rest exact
  EXPECT_LT((b.surfaces[0] - capped.restSurface(0).vertices).cwiseAbs().maxCoeff(), 1e-12);
  capped.evaluate(pose, b, true);
  double largest = 0.0;
  for (int k = 0; k < J; ++k) {
    const double rho = 0.5 * std::abs(freeSlide[k]);
    if (rho < 1e-9 * size) continue;
    largest = std::max(largest, std::abs(freeSlide[k]));
    const Vec3 d = b.jointMatrices[k].topRightCorner<3, 1>() - a.jointMatrices[k].topRightCorner<3, 1>();
    const double expected = rho * std::tanh(freeSlide[k] / rho) - freeSlide[k];  // tanh(2) / 2 of the slide kept
    EXPECT_NEAR(d.norm(), std::abs(expected), 1e-9 * size) << "joint " << k;
    EXPECT_LT(std::abs(freeSlide[k] + expected), rho) << "joint " << k << ": never past its limit";
    EXPECT_LT((b.jointMatrices[k].topLeftCorner<3, 3>() - a.jointMatrices[k].topLeftCorner<3, 3>()).norm(), 1e-12);
  }
  EXPECT_GT(largest, 1e-3 * size) << "the joints do slide, so the checks above can fail";
  EXPECT_EQ(capped.slideLimits().size(), static_cast<size_t>(J));
  limited.slideLimits.pop_back();
  EXPECT_THROW(MuscleRig(s, {mu}, limited), InputError);
}
