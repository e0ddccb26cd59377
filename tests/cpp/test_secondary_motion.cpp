// Secondary motion (Gray & Hutchinson): jiggle of the muscle masses, the temporal filter, normal-space sculpt
// deltas and chunked simulation, on a small two-bone limb (a tube of skin over one belly), so each case runs
// in milliseconds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

#include "test_support.h"
#include "myoskin/errors.h"
#include "myoskin/secondary_motion.h"
#include "myoskin/skinning.h"

using namespace myoskin;

namespace {

constexpr double kSize = 0.55;  // the limb's length (the character's size)

// ============================================================================
// The limb: upper bone (0..0.3 on Y), fore bone (0.3..0.55), one belly on the upper bone
// ============================================================================

Skeleton limbSkeleton() {
  Skeleton s;
  Bone a;
  a.name = "upper";
  a.head = Vec3(0, 0, 0);
  a.tail = Vec3(0, 0.3, 0);
  a.rest = boneMatrix(a.head, a.tail, Vec3::UnitX());
  Bone b;
  b.name = "fore";
  b.parent = 0;
  b.head = a.tail;
  b.tail = Vec3(0, 0.55, 0);
  b.rest = boneMatrix(b.head, b.tail, Vec3::UnitX());
  s.bones = {a, b};
  return s;
}

Muscle belly() {
  Muscle m;
  m.name = "belly";
  m.region = "upper";
  m.origin = {"upper", Vec3(0.03, 0.03, 0)};
  m.insertion = {"upper", Vec3(0.03, 0.27, 0)};
  for (int i = 0; i <= 4; ++i) m.rootCurve.push_back(Vec3(0.03, 0.03 + 0.06 * i, 0));
  for (int i = 0; i < 7; ++i) {
    MuscleSection s;
    s.u = -0.75 + 0.25 * i;
    s.center = Vec3(0.03, 0.15 + 0.12 * s.u, 0);
    s.axisA = Vec3::UnitX();
    const double taper = std::cos(0.5 * kPi * s.u);
    s.a = 0.012 + 0.013 * taper;
    s.b = 0.010 + 0.010 * taper;
    s.normal = Vec3::UnitY();
    m.sections.push_back(s);
  }
  m.joints = 4;
  return m;
}

// A tube of skin (radius 0.07) round the two bones, skeleton weights blended over the joint.
struct Limb {
  Skeleton skeleton = limbSkeleton();
  Mesh skin;
  SkinWeights weights;
  std::vector<Muscle> muscles{belly()};
};

const Limb& limb() {
  static const Limb l = [] {
    Limb r;
    const int rings = 40, around = 32;
    r.skin.vertices.resize(rings * around, 3);
    r.weights.joints.resize(rings * around, 2);
    r.weights.weights.resize(rings * around, 2);
    for (int i = 0; i < rings; ++i) {
      const double y = 0.005 + 0.54 * i / (rings - 1);
      const double t = std::clamp((y - 0.26) / 0.08, 0.0, 1.0), w = t * t * (3 - 2 * t);
      for (int k = 0; k < around; ++k) {
        const double a = 2 * kPi * k / around;
        const int v = i * around + k;
        r.skin.vertices.row(v) << 0.07 * std::cos(a), y, 0.07 * std::sin(a);
        r.weights.joints.row(v) << 0, 1;
        r.weights.weights.row(v) << 1 - w, w;
      }
    }
    r.skin.triangles.resize(2 * (rings - 1) * around, 3);
    int f = 0;
    for (int i = 0; i + 1 < rings; ++i)
      for (int k = 0; k < around; ++k) {
        const int a = i * around + k, b = i * around + (k + 1) % around, c = a + around, d = b + around;
        r.skin.triangles.row(f++) << a, c, b;
        r.skin.triangles.row(f++) << b, c, d;
      }
    return r;
  }();
  return l;
}

Pose limbPose(double upperDegrees, double foreDegrees = 0.0) {
  const Skeleton& sk = limb().skeleton;
  std::vector<Eigen::Quaterniond> q(2, Eigen::Quaterniond::Identity());
  q[0] = Eigen::AngleAxisd(upperDegrees * kPi / 180.0, Vec3::UnitZ());
  q[1] = Eigen::AngleAxisd(foreDegrees * kPi / 180.0, Vec3::UnitX());
  return poseFromLocalRotations(sk, q);
}

// The upper bone swings at `speed` degrees per second until `stop` seconds, then holds still; sampled at fps
// for `seconds`.
PoseSequence swingThenStop(double fps, double speed, double stop, double seconds) {
  PoseSequence s;
  s.startFrame = 1;
  const int frames = static_cast<int>(std::lround(seconds * fps)) + 1;
  for (int i = 0; i < frames; ++i) s.frames.push_back(limbPose(speed * std::min(i / fps, stop)));
  return s;
}

// A smooth swing: amplitude degrees at `hz` for `stop` seconds (ending at rest velocity 0 only by chance).
PoseSequence sineSwing(double fps, double amplitude, double hz, double stop, double seconds) {
  PoseSequence s;
  s.startFrame = 1;
  const int frames = static_cast<int>(std::lround(seconds * fps)) + 1;
  for (int i = 0; i < frames; ++i)
    s.frames.push_back(limbPose(amplitude * std::sin(2 * kPi * hz * std::min(i / fps, stop))));
  return s;
}

double analyticDecrement(const JiggleParams& p) {
  const double zeta = p.damping / (2 * std::sqrt(p.stiffness * p.mass));
  return 2 * kPi * zeta / std::sqrt(1 - zeta * zeta);
}

// Logarithmic decrement of the spring's free motion after the stop: the offset projected on its direction at
// the largest swing after the stop; peaks refined by a parabola through the samples; over `periods` periods.
double measuredDecrement(JiggleTrack& track, double fps, double stopSeconds, int periods) {
  std::vector<Vec3> o;
  std::vector<Vec3> path;
  const int first = static_cast<int>(std::ceil(stopSeconds * fps)) + 2;
  for (int f = first; f <= static_cast<int>(track.lastFrame()); ++f) {
    track.springOffsets(f, o);
    path.push_back(o[0]);
  }
  EXPECT_GT(path.size(), 10u);
  Vec3 dir = Vec3::Zero();
  for (const Vec3& p : path)
    if (p.norm() > dir.norm()) dir = p;
  dir.normalize();
  std::vector<double> x;
  for (const Vec3& p : path) x.push_back(p.dot(dir));
  std::vector<double> peaks;
  for (size_t i = 1; i + 1 < x.size(); ++i)
    if (x[i] > x[i - 1] && x[i] >= x[i + 1] && x[i] > 0) {
      const double a = x[i - 1], b = x[i], c = x[i + 1], den = a - 2 * b + c;
      const double s = den != 0 ? 0.5 * (a - c) / den : 0.0;
      peaks.push_back(b - 0.25 * (a - c) * s);
    }
  EXPECT_GT(static_cast<int>(peaks.size()), periods) << "too few oscillations after the stop";
  if (static_cast<int>(peaks.size()) <= periods) return 0.0;
  return std::log(peaks[0] / peaks[periods]) / periods;
}

MuscleRig limbRig() { return MuscleRig(limb().skeleton, limb().muscles); }

}  // namespace

// ============================================================================
// Jiggle
// ============================================================================

TEST(Jiggle, StopsDeadAndSettlesWithItsDamping) {
  const MuscleRig rig = limbRig();
  for (double zeta : {0.1, 0.3}) {
    JiggleOptions o;
    o.dampingRatio = zeta;
    const double fps = 240, stop = 0.5;
    JiggleTrack track(rig, swingThenStop(fps, 120.0, stop, 2.5), fps, o);
    const double expected = analyticDecrement(track.params()[0]);
    const double measured = measuredDecrement(track, fps, stop, zeta < 0.2 ? 3 : 1);
    std::printf("[ Measured ] damping ratio %.2f: logarithmic decrement %.4f, analytic %.4f (%.2f %%)\n", zeta, measured,
                expected, 100 * (measured / expected - 1));
    EXPECT_NEAR(measured, expected, 0.1 * expected);
  }
}

TEST(Jiggle, DefaultsFollowMuscleSize) {
  const MuscleRig rig = limbRig();
  const std::vector<JiggleParams> p = defaultJiggleParams(rig);
  ASSERT_EQ(p.size(), 1u);
  const double f = std::sqrt(p[0].stiffness / p[0].mass) / (2 * kPi);
  EXPECT_NEAR(f, JiggleOptions{}.frequency, 1e-9);  // the median muscle has the reference frequency
  EXPECT_NEAR(p[0].damping / (2 * std::sqrt(p[0].stiffness * p[0].mass)), JiggleOptions{}.dampingRatio, 1e-12);
  // A thicker muscle beside it: heavier and slower.
  std::vector<Muscle> two{belly(), belly()};
  two[1].name = "thick";
  for (MuscleSection& s : two[1].sections) s.a *= 2, s.b *= 2;
  const MuscleRig rig2(limb().skeleton, two);
  const std::vector<JiggleParams> q = defaultJiggleParams(rig2);
  ASSERT_EQ(q.size(), 2u);
  EXPECT_NEAR(q[1].mass / q[0].mass, 4.0, 1e-9);
  EXPECT_LT(q[1].stiffness / q[1].mass, q[0].stiffness / q[0].mass);
  // Influence: fades toward the tendons, largest mid-belly.
  const std::vector<double> w = defaultJiggleInfluence(rig);
  ASSERT_EQ(w.size(), 4u);
  EXPECT_LT(w[0], w[1]);
  EXPECT_LT(w[3], w[2]);
  for (double x : w) EXPECT_TRUE(x > 0.2 && x <= 1.0) << x;
}

TEST(Jiggle, NoGrowthAtAnyFrameRate) {
  const MuscleRig rig = limbRig();
  for (double fps : {12.0, 24.0, 30.0, 60.0, 240.0}) {
    for (double zeta : {0.0, 0.3}) {
      JiggleOptions o;
      o.dampingRatio = zeta;
      JiggleTrack track(rig, sineSwing(fps, 40.0, 1.5, 1.0, 4.0), fps, o);
      std::vector<Vec3> off;
      double during = 0, early = 0, late = 0;  // largest |offset| while moving, 1-2 s and 3-4 s
      for (int f = 1; f <= static_cast<int>(track.lastFrame()); ++f) {
        track.springOffsets(f, off);
        const double t = (f - 1) / fps, n = off[0].norm();
        ASSERT_TRUE(std::isfinite(n));
        if (t <= 1.0) during = std::max(during, n);
        if (t >= 1.0 && t < 2.0) early = std::max(early, n);
        if (t >= 3.0) late = std::max(late, n);
      }
      ASSERT_GT(during, 0.0);
      if (zeta == 0.0)  // undamped: the free oscillation keeps its amplitude (sampling may miss the peak a little)
        EXPECT_LE(late, early * 1.0 + 1e-12 + 0.03 * early) << fps << " fps";
      else
        EXPECT_LT(late, 0.01 * early) << fps << " fps";
    }
  }
}

TEST(Jiggle, SameResultAtDifferentFrameRatesOfOneMotion) {
  // One smooth motion sampled at 24 and 240 fps: at the shared frame times the offsets agree (the goals are
  // interpolated linearly between samples, so they differ by the interpolation only).
  const MuscleRig rig = limbRig();
  JiggleTrack coarse(rig, sineSwing(24, 40.0, 1.0, 1.0, 2.0), 24);
  JiggleTrack fine(rig, sineSwing(240, 40.0, 1.0, 1.0, 2.0), 240);
  std::vector<Vec3> a, b;
  double peak = 0, worst = 0;
  for (int f = 1; f <= 49; ++f) {
    coarse.springOffsets(f, a);
    fine.springOffsets(1 + (f - 1) * 10, b);
    peak = std::max(peak, b[0].norm());
    worst = std::max(worst, (a[0] - b[0]).norm());
  }
  std::printf("[ Measured ] 24 vs 240 fps sampling of one swing: offsets differ by %.1f %% of the peak\n",
              100 * worst / peak);
  ASSERT_GT(peak, 0.0);
  EXPECT_LT(worst, 0.15 * peak);
}

TEST(Jiggle, AnyVisitOrderAndRerunsAreBitIdentical) {
  const MuscleRig rig = limbRig();
  const PoseSequence seq = sineSwing(25, 40.0, 1.3, 1.5, 3.0);  // 25 fps: frames fall between grid steps
  JiggleTrack reference(rig, seq, 25);
  std::vector<std::vector<Vec3>> all;
  std::vector<Vec3> o;
  for (int f = 1; f <= 76; ++f) reference.offsets(f, o), all.push_back(o);
  // A rerun, skipped frames, scrubbing backwards, and random order.
  JiggleTrack rerun(rig, seq, 25), skipping(rig, seq, 25), backwards(rig, seq, 25), shuffled(rig, seq, 25);
  std::vector<int> order(76);
  for (int i = 0; i < 76; ++i) order[i] = i + 1;
  std::mt19937 rng(7);
  std::shuffle(order.begin(), order.end(), rng);
  for (int f = 1; f <= 76; ++f) {
    rerun.offsets(f, o);
    EXPECT_EQ(std::memcmp(o.data(), all[f - 1].data(), sizeof(Vec3)), 0);
  }
  for (int f = 1; f <= 76; f += 7) {
    skipping.offsets(f, o);
    EXPECT_EQ(std::memcmp(o.data(), all[f - 1].data(), sizeof(Vec3)), 0) << "frame " << f;
  }
  for (int f = 76; f >= 1; --f) {
    backwards.offsets(f, o);
    EXPECT_EQ(std::memcmp(o.data(), all[f - 1].data(), sizeof(Vec3)), 0) << "frame " << f;
  }
  ASSERT_FALSE(order.empty());
  for (int f : order) {
    shuffled.offsets(f, o);
    EXPECT_EQ(std::memcmp(o.data(), all[f - 1].data(), sizeof(Vec3)), 0) << "frame " << f;
  }
  // An edited pose changes the frames after it only, and going back never reads a stale state.
  PoseSequence edited = seq;
  edited.frames[40] = limbPose(-60.0);
  JiggleTrack fresh(rig, edited, 25);
  reference.setPose(40, edited.frames[40]);
  for (int f : {76, 20, 41, 42, 60}) {
    std::vector<Vec3> x;
    reference.offsets(f, o);
    fresh.offsets(f, x);
    EXPECT_EQ(std::memcmp(o.data(), x.data(), sizeof(Vec3)), 0) << "frame " << f;
    if (f <= 40) EXPECT_EQ(std::memcmp(o.data(), all[f - 1].data(), sizeof(Vec3)), 0);
  }
  fresh.offsets(60, o);
  EXPECT_GT((o[0] - all[59][0]).norm(), 0.0);
}

TEST(Jiggle, RestStaysExactAndJointsMoveByInfluence) {
  const MuscleRig rig = limbRig();
  PoseSequence still;
  still.frames.assign(30, limbPose(0.0));
  JiggleTrack track(rig, still, 24);
  std::vector<Vec3> o;
  for (int f = 1; f <= 30; ++f) {
    track.offsets(f, o);
    EXPECT_EQ(o[0], Vec3::Zero());
  }
  // Moving: each joint's translation moves by its influence times the muscle's offset, nothing else.
  JiggleTrack moving(rig, swingThenStop(24, 120.0, 0.5, 1.0), 24);
  MuscleRigState s = rig.makeState(), base = rig.makeState();
  const PoseSequence seq = swingThenStop(24, 120.0, 0.5, 1.0);
  rig.evaluate(seq.frames[14], s);
  rig.evaluate(seq.frames[14], base);
  moving.apply(15, s);
  moving.offsets(15, o);
  ASSERT_GT(o[0].norm(), 0.0);
  for (int j = 0; j < rig.numJoints(); ++j) {
    EXPECT_LT((s.jointMatrices[j].block<3, 3>(0, 0) - base.jointMatrices[j].block<3, 3>(0, 0)).norm(), 1e-15);
    const Vec3 moved = s.jointMatrices[j].block<3, 1>(0, 3) - base.jointMatrices[j].block<3, 1>(0, 3);
    EXPECT_LT((moved - moving.influence()[j] * o[0]).norm(), 1e-12 * kSize);
  }
  // Posed surfaces move with the joints: most mid-belly, least at the ends, never more than the offset.
  MuscleRigState ws = rig.makeState(), wbase = rig.makeState();
  rig.evaluate(seq.frames[14], ws, true);
  rig.evaluate(seq.frames[14], wbase, true);
  moving.apply(15, ws);
  ASSERT_GT(ws.surfaces[0].rows(), 0);
  double most = 0, least = 1e9;
  for (Eigen::Index v = 0; v < ws.surfaces[0].rows(); ++v) {
    const Vec3 d = (ws.surfaces[0].row(v) - wbase.surfaces[0].row(v)).transpose();
    EXPECT_LT(d.cross(o[0]).norm(), 1e-12) << "moves along the offset";
    most = std::max(most, d.norm()), least = std::min(least, d.norm());
  }
  EXPECT_LE(most, o[0].norm() * (1 + 1e-12));
  EXPECT_GT(most, 0.9 * o[0].norm());
  EXPECT_LT(least, 0.5 * most);
}

TEST(Jiggle, LargeOffsetsSaturate) {
  const MuscleRig rig = limbRig();
  JiggleOptions o;
  o.frequency = 0.5;  // very soft: a large swing would carry the mass far out
  JiggleTrack track(rig, swingThenStop(24, 720.0, 0.5, 1.0), 24, o);
  std::vector<Vec3> spring, limited;
  double largest = 0, largestSpring = 0;
  for (int f = 1; f <= 25; ++f) {
    track.springOffsets(f, spring);
    track.offsets(f, limited);
    largest = std::max(largest, limited[0].norm());
    largestSpring = std::max(largestSpring, spring[0].norm());
  }
  double radius = 0;
  for (const MuscleSection& s : belly().sections) radius += std::sqrt(s.a * s.b) / belly().sections.size();
  EXPECT_GT(largestSpring, o.maxOffset * radius);
  EXPECT_LE(largest, o.maxOffset * radius * (1 + 1e-12));
}

TEST(Jiggle, BadInput) {
  const MuscleRig rig = limbRig();
  const PoseSequence seq = swingThenStop(24, 90.0, 0.5, 1.0);
  for (JiggleParams p : {JiggleParams{0.0, 1.0, 0.1}, JiggleParams{-1.0, 1.0, 0.1}, JiggleParams{1.0, 0.0, 0.1},
                         JiggleParams{1.0, -2.0, 0.1}, JiggleParams{1.0, 1.0, -0.1}, JiggleParams{NAN, 1.0, 0.1}}) {
    const std::string e = test::inputErrorOf([&] { JiggleTrack(rig, seq, 24, {}, {p}); });
    EXPECT_NE(e.find("belly"), std::string::npos) << e;
  }
  PoseSequence nan = seq;
  nan.frames[3].matrices[0](0, 3) = NAN;
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, nan, 24); }).find("non-finite"), std::string::npos);
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, seq, 0.0); }), "");
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, seq, -24.0); }), "");
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, PoseSequence{}, 24); }), "");
  JiggleOptions bad;
  bad.timeStep = 0;
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, seq, 24, bad); }), "");
  bad = {};
  bad.dampingRatio = -0.5;
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, seq, 24, bad); }), "");
  EXPECT_NE(test::inputErrorOf([&] { JiggleTrack(rig, seq, 24, {}, {}, {1.0, 1.0}); }), "");
  // One frame: nothing moves, so nothing jiggles (the documented fallback).
  PoseSequence one;
  one.frames.push_back(limbPose(30.0));
  JiggleTrack single(rig, one, 24);
  std::vector<Vec3> o;
  single.offsets(1, o);
  EXPECT_EQ(o[0], Vec3::Zero());
  EXPECT_NE(test::inputErrorOf([&] { single.offsets(2, o); }).find("outside"), std::string::npos);
}

// ============================================================================
// Temporal filter
// ============================================================================

namespace {

// #V points along smooth paths p_v(t) sampled at frames t = 0, dt, 2 dt...
std::vector<PointsF> sampled(int frames, int vertices, const std::function<Vec3(int, double)>& path, double dt) {
  std::vector<PointsF> out(frames, PointsF(vertices, 3));
  for (int f = 0; f < frames; ++f)
    for (int v = 0; v < vertices; ++v) out[f].row(v) = path(v, f * dt).cast<float>().transpose();
  return out;
}

}  // namespace

TEST(TemporalFilter, SmoothMotionPassesUnchanged) {
  const double size = 1.0, edge = 0.01;  // a body of size 1 with edges of 1 cm
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> p0, v0, a0;
  for (int v = 0; v < 200; ++v)
    p0.emplace_back(u(rng), u(rng), u(rng)), v0.emplace_back(u(rng), u(rng), u(rng)), a0.emplace_back(u(rng), u(rng), u(rng));
  // Constant acceleration in any direction (thrown), circles, a standing point.
  const auto thrown = sampled(60, 200, [&](int v, double t) { return Vec3(0.5 * p0[v] + 2.0 * v0[v] * t + 4.0 * a0[v] * t * t); }, 1.0 / 240);
  const auto circle = sampled(60, 200, [&](int v, double t) {
    const double w = 2 * kPi * (0.5 + 0.5 * std::abs(p0[v].x())), r = 0.2 + 0.3 * std::abs(p0[v].y());
    return Vec3(r * std::cos(w * t), 0.1 * p0[v].z(), r * std::sin(w * t));
  }, 1.0 / 60);
  const auto still = sampled(10, 200, [&](int v, double) { return Vec3(p0[v]); }, 1.0 / 24);
  for (const auto* cache : {&thrown, &circle, &still}) {
    std::vector<PointsF> out;
    const int pulled = filterFrames(*cache, edge, {}, out);
    EXPECT_EQ(pulled, 0);
    double worst = 0;
    for (size_t f = 0; f < cache->size(); ++f) worst = std::max(worst, double(((*cache)[f] - out[f]).cwiseAbs().maxCoeff()));
    EXPECT_LT(worst, 1e-6 * size);
  }
}

TEST(TemporalFilter, OneFrameSpikeShrinks) {
  const double edge = 0.01;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> p0, dir;
  for (int v = 0; v < 100; ++v) p0.emplace_back(u(rng), u(rng), u(rng)), dir.emplace_back(Vec3(u(rng), u(rng), u(rng)).normalized());
  // Half the points stand, half circle (radius 0.5, 1 degree per frame); a spike of 5 edge lengths on frame 20.
  auto path = [&](int v, double t) {
    if (v % 2 == 0) return Vec3(p0[v]);
    const double a = t * kPi / 180;
    return Vec3(p0[v] + 0.5 * Vec3(std::cos(a), std::sin(a), 0));
  };
  const std::vector<PointsF> clean = sampled(40, 100, path, 1.0);
  std::vector<PointsF> spiked = clean;
  for (int v = 0; v < 100; ++v) spiked[20].row(v) += (0.05 * dir[v]).cast<float>().transpose();
  std::vector<PointsF> out;
  EXPECT_EQ(filterFrames(spiked, edge, {}, out), 100);
  double worstShrink = 1;
  for (int v = 0; v < 100; ++v) {
    const double before = (spiked[20].row(v) - clean[20].row(v)).norm(), after = (out[20].row(v) - clean[20].row(v)).norm();
    worstShrink = std::min(worstShrink, 1 - after / before);
  }
  std::printf("[ Measured ] a one-frame spike of 5 edge lengths shrinks by at least %.1f %%\n", 100 * worstShrink);
  EXPECT_GE(worstShrink, 0.9);
  // The frames around it are tested against the spike and stay within their own tolerance of it.
  for (int f : {19, 21}) EXPECT_LT((out[f] - spiked[f]).cwiseAbs().maxCoeff(), 0.05);
}

TEST(TemporalFilter, BadInput) {
  PointsF a(3, 3), b(4, 3), out;
  a.setZero(), b.setZero();
  EXPECT_NE(test::inputErrorOf([&] { filterFrame(a, a, b, 0.01, {}, out); }), "");
  EXPECT_NE(test::inputErrorOf([&] { filterFrame(a, a, a, 0.0, {}, out); }), "");
  EXPECT_NE(test::inputErrorOf([&] { filterFrame(a, a, a, 0.01, {}, a); }), "");
  TemporalFilterOptions o;
  o.relativeTolerance = -1;
  EXPECT_NE(test::inputErrorOf([&] { filterFrame(a, a, a, 0.01, o, out); }), "");
  // One or two frames: nothing to test against, so they pass unchanged.
  std::vector<PointsF> one{a}, filtered;
  EXPECT_EQ(filterFrames(one, 0.01, {}, filtered), 0);
  ASSERT_EQ(filtered.size(), 1u);
  EXPECT_EQ(filtered[0], a);
}

// ============================================================================
// Sculpt deltas
// ============================================================================

namespace {

// The limb's skin with detail sculpted on part of it: bumps along the normal and a tangential shift.
Points sculptOf(const Points& surface) {
  Points s = surface;
  for (int v = 0; v < s.rows(); ++v) {
    const Vec3 p = surface.row(v);
    const Vec3 radial = Vec3(p.x(), 0, p.z()).normalized();
    const double bump = 0.004 * std::exp(-std::pow((p.y() - 0.15) / 0.03, 2)) * (0.5 + 0.5 * radial.x());
    s.row(v) += (bump * radial + Vec3(0, 0.002 * radial.z(), 0)).transpose();
  }
  return s;
}

}  // namespace

TEST(SculptDeltas, ExactOnTheSculptFrameAndTurnsWithTheSurface) {
  const Mesh& skin = limb().skin;
  const Points sculpted = sculptOf(skin.vertices);
  SculptDeltas deltas(skin.vertices, skin.triangles, sculpted);
  Points out;
  deltas.apply(skin.vertices, out);
  EXPECT_LT((out - sculpted).cwiseAbs().maxCoeff(), 1e-6 * kSize);
  // Turned and moved: the detail turns with it.
  const Mat3 R = Eigen::AngleAxisd(1.1, Vec3(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  const Vec3 t(0.4, -1.0, 2.0);
  Points moved = (skin.vertices * R.transpose()).rowwise() + t.transpose();
  const Points expected = (sculpted * R.transpose()).rowwise() + t.transpose();
  deltas.apply(moved, out);
  EXPECT_LT((out - expected).cwiseAbs().maxCoeff(), 1e-6 * kSize);
  // World-space deltas would not turn: the detail is off by about its own size.
  const Points world = moved + (sculpted - skin.vertices);
  EXPECT_GT((world - expected).cwiseAbs().maxCoeff(), 1e-3);
  // The float path (PC2 frames) and in place.
  PointsF f = moved.cast<float>();
  deltas.apply(f, f);
  EXPECT_LT((f.cast<double>() - expected).cwiseAbs().maxCoeff(), 1e-6 * (kSize + 2.5));
}

TEST(SculptDeltas, BadInput) {
  const Mesh& skin = limb().skin;
  Points shorter = skin.vertices.topRows(10);
  EXPECT_NE(test::inputErrorOf([&] { SculptDeltas(skin.vertices, skin.triangles, shorter); }), "");
  Points nan = skin.vertices;
  nan(5, 1) = NAN;
  EXPECT_NE(test::inputErrorOf([&] { SculptDeltas(skin.vertices, skin.triangles, nan); }), "");
  Triangles bad = skin.triangles;
  bad(0, 0) = 1 << 20;
  EXPECT_NE(test::inputErrorOf([&] { SculptDeltas(skin.vertices, bad, skin.vertices); }), "");
  SculptDeltas d(skin.vertices, skin.triangles, sculptOf(skin.vertices));
  Points out;
  EXPECT_NE(test::inputErrorOf([&] { d.apply(nan, out); }), "");
}

// ============================================================================
// Simulation: chunks stitch bit-identically
// ============================================================================

namespace {

struct Bound {
  MuscleRig rig = limbRig();
  std::shared_ptr<Skinner> skinner;
  Bound() {
    const SkinWeights w = computeHybridWeights(limb().skin, limb().weights, rig);
    skinner = std::make_shared<Skinner>(limb().skin.vertices, w, limb().skeleton.numBones() + rig.numJoints());
  }
};

std::vector<PointsF> bakeAll(Simulation& sim, int first, int last, const SimulationState* in = nullptr,
                             SimulationState* out = nullptr) {
  std::vector<PointsF> frames;
  const SimulationState end = sim.bake(first, last, [&](int, const PointsF& p) { frames.push_back(p); }, in);
  if (out) *out = end;
  return frames;
}

}  // namespace

// A stand-in skin solve: a smooth push outward plus jitter of 0.5 edge lengths on some vertices and frames
// (deterministic), so the filter has something to do.
void jitterySolve(int frame, const Pose&, const MuscleRigState* rig, PointsF& skin) {
  ASSERT_NE(rig, nullptr);
  for (int v = 0; v < skin.rows(); ++v) {
    const float r = std::hypot(skin(v, 0), skin(v, 2));
    const unsigned h = (static_cast<unsigned>(frame) * 2654435761u) ^ (static_cast<unsigned>(v) * 40503u);
    const float jitter = (h % 13 == 0) ? 0.5f * 0.0137f * ((h >> 8) % 3 == 0 ? 1.0f : -1.0f) : 0.0f;
    skin(v, 0) += (0.0005f + jitter) * skin(v, 0) / r;
    skin(v, 2) += 0.0005f * skin(v, 2) / r;
  }
}

TEST(Simulation, ChunkedBakeEqualsSingleBake) {
  const Bound b;
  const PoseSequence seq = sineSwing(24, 50.0, 1.2, 1.2, 2.0);
  SimulationOptions o;
  o.jiggle = true;
  o.filter = true;
  Simulation single(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  single.setSkinSolve(jitterySolve);
  const std::vector<PointsF> all = bakeAll(single, single.firstFrame(), single.lastFrame());
  ASSERT_EQ(all.size(), seq.frames.size());
  // Jiggle moved the skin: the raw frames differ from skinning without it.
  SimulationOptions plain;
  Simulation still(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, plain);
  PointsF p;
  still.frame(30, p);
  EXPECT_GT((p - all[29]).cwiseAbs().maxCoeff(), 1e-4);
  // Three chunks, each a fresh simulation (a separate process), stitched by state files.
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "myoskin_test_chunks";
  std::filesystem::create_directories(dir);
  const int cuts[4] = {1, 14, 30, single.lastFrame() + 1};
  std::vector<PointsF> stitched;
  for (int c = 0; c < 3; ++c) {
    Simulation chunk(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
    chunk.setSkinSolve(jitterySolve);
    SimulationState in, out;
    if (c > 0) in = readSimulationState((dir / ("state" + std::to_string(c) + ".json")).string());
    for (PointsF& f : bakeAll(chunk, cuts[c], cuts[c + 1] - 1, c > 0 ? &in : nullptr, &out)) stitched.push_back(f);
    writeSimulationState((dir / ("state" + std::to_string(c + 1) + ".json")).string(), out);
  }
  ASSERT_EQ(stitched.size(), all.size());
  for (size_t f = 0; f < all.size(); ++f)
    EXPECT_EQ(std::memcmp(stitched[f].data(), all[f].data(), sizeof(float) * all[f].size()), 0) << "frame " << f + 1;
  // A chunk without a state replays from the start: the same again.
  Simulation late(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  late.setSkinSolve(jitterySolve);
  const std::vector<PointsF> tail = bakeAll(late, 30, single.lastFrame());
  for (size_t f = 0; f < tail.size(); ++f)
    EXPECT_EQ(std::memcmp(tail[f].data(), all[29 + f].data(), sizeof(float) * tail[f].size()), 0);
  // Random access equals the bake.
  single.frame(17, p);
  EXPECT_EQ(std::memcmp(p.data(), all[16].data(), sizeof(float) * p.size()), 0);
  // A state from other settings or for another frame is refused.
  SimulationState s = readSimulationState((dir / "state1.json").string());
  EXPECT_EQ(s.frame, 12);  // the chunk 1-13 ends with the state of frame 12: the next chunk's filter looks 2 back
  EXPECT_NE(test::inputErrorOf([&] { bakeAll(late, 12, 20, &s); }).find("frame 12, a chunk from frame 12"),
            std::string::npos);
  SimulationOptions other = o;
  other.fps = 30;
  Simulation at30(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, other);
  EXPECT_NE(test::inputErrorOf([&] { bakeAll(at30, 14, 20, &s); }).find("fps"), std::string::npos);
  // The settings that shape the frames travel with the state (the caller's and the simulation's own): another
  // jiggle amount, no filter, no skin solve or another caller setting is refused by name; equal settings stitch.
  ASSERT_TRUE(s.hasSettings);
  EXPECT_EQ(s.settings.at("simulation.skin_solve"), "on");
  auto refusal = [&](SimulationOptions changed, bool solve) {
    Simulation other(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, changed);
    if (solve) other.setSkinSolve(jitterySolve);
    return test::inputErrorOf([&] { bakeAll(other, 14, 20, &s); });
  };
  SimulationOptions softer = o;
  softer.jiggleOptions.amount = 0.5;
  EXPECT_NE(refusal(softer, true).find("with simulation.jiggle"), std::string::npos);
  SimulationOptions unfiltered = o;
  unfiltered.filter = false;
  EXPECT_NE(refusal(unfiltered, true).find("simulation.filter on"), std::string::npos);
  EXPECT_NE(refusal(o, false).find("simulation.skin_solve on, this run has off"), std::string::npos);
  SimulationOptions tagged = o;
  tagged.settings["bind.joints_slide"] = "off";
  EXPECT_NE(refusal(tagged, true).find("with bind.joints_slide nothing, this run has off"), std::string::npos);
  {
    Simulation same(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
    same.setSkinSolve(jitterySolve);
    const std::vector<PointsF> again = bakeAll(same, 14, 29, &s);
    for (size_t f = 0; f < again.size(); ++f)
      EXPECT_EQ(std::memcmp(again[f].data(), all[13 + f].data(), sizeof(float) * again[f].size()), 0);
  }
  // A state written before settings were kept has none and is not checked for them.
  SimulationState old = s;
  old.hasSettings = false;
  old.settings.clear();
  writeSimulationState((dir / "old.json").string(), old);
  const SimulationState back = readSimulationState((dir / "old.json").string());
  EXPECT_FALSE(back.hasSettings);
  Simulation lenient(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, softer);
  lenient.setSkinSolve(jitterySolve);
  EXPECT_NO_THROW(bakeAll(lenient, 14, 16, &back));
  std::filesystem::remove_all(dir);
}

TEST(Simulation, FilterTakesTheSolvesSpikeAndLeavesTheMotion) {
  const Bound b;
  const PoseSequence seq = sineSwing(24, 50.0, 1.2, 1.2, 2.0);
  const double edge = meanEdgeLength(limb().skin.vertices, limb().skin.triangles);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> dir;
  for (int v = 0; v < limb().skin.vertices.rows(); ++v) dir.push_back(Vec3(u(rng), u(rng), u(rng)).normalized());
  // A smooth solve (each vertex drifting 1 mm round a circle of its own phase) with a one-frame spike of 5 edge
  // lengths on every 7th vertex at frame 20.
  auto solve = [&](bool spike) {
    return [&, spike](int frame, const Pose&, const MuscleRigState*, PointsF& skin) {
      for (int v = 0; v < skin.rows(); ++v) {
        const double a = 0.2 * frame + 0.1 * v;
        skin.row(v) += (0.001 * Vec3(std::cos(a), std::sin(a), 0.3)).cast<float>().transpose();
        if (spike && frame == 20 && v % 7 == 0) skin.row(v) += (5 * edge * dir[v]).cast<float>().transpose();
      }
    };
  };
  SimulationOptions on, off;
  on.jiggle = off.jiggle = true;
  on.filter = true;
  Simulation filtered(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, on);
  Simulation clean(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, off);
  Simulation spiked(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, off);
  filtered.setSkinSolve(solve(true));
  clean.setSkinSolve(solve(false));
  spiked.setSkinSolve(solve(true));
  const std::vector<PointsF> f = bakeAll(filtered, 1, 49), c = bakeAll(clean, 1, 49), s = bakeAll(spiked, 1, 49);
  double worstShrink = 1;
  int spikes = 0;
  for (int v = 0; v < f[19].rows(); v += 7, ++spikes) {
    const double before = (s[19].row(v) - c[19].row(v)).norm(), after = (f[19].row(v) - c[19].row(v)).norm();
    worstShrink = std::min(worstShrink, 1 - after / before);
  }
  ASSERT_GT(spikes, 100);
  std::printf("[ Measured ] simulation: a solve's one-frame spike of 5 edge lengths shrinks by at least %.1f %%\n",
              100 * worstShrink);
  EXPECT_GE(worstShrink, 0.9);
  // Every other frame, jiggle and smooth solve included, passes bit for bit.
  for (int k = 0; k < 49; ++k)
    if (k != 19) EXPECT_EQ(std::memcmp(f[k].data(), s[k].data(), sizeof(float) * f[k].size()), 0) << "frame " << k + 1;
}

TEST(Simulation, RestSequenceEqualsSkinningAndSculptFrameEqualsSculpt) {
  const Bound b;
  PoseSequence seq = swingThenStop(24, 90.0, 0.4, 1.0);
  SimulationOptions o;
  o.jiggle = true;
  o.filter = true;
  Simulation sim(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  // The sculpt frame gives the sculpt; a later frame carries the detail in its own local frame.
  PointsF reference;
  sim.frame(12, reference);
  const Points sculpted = sculptOf(reference.cast<double>());
  sim.setSculpt(sculpted, 12);
  PointsF p;
  sim.frame(12, p);
  EXPECT_LT((p.cast<double>() - sculpted).cwiseAbs().maxCoeff(), 1e-6 * kSize);
  sim.frame(20, p);
  PointsF plain;
  Simulation noSculpt(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  noSculpt.frame(20, plain);
  EXPECT_GT((p - plain).cwiseAbs().maxCoeff(), 1e-3);
  // At rest with jiggle and filter on, the skin equals plain skinning bit for bit.
  PoseSequence rest;
  rest.frames.assign(5, limbPose(0.0));
  Simulation still(limb().skin, limb().skeleton, &b.rig, b.skinner, rest, o);
  const std::vector<PointsF> frames = bakeAll(still, 1, 5);
  PointsF skinned;
  MuscleRigState st = b.rig.makeState();
  b.rig.evaluate(rest.frames[0], st);
  std::vector<Mat4> t;
  skinningTransforms(limb().skeleton, rest.frames[0], b.rig, st, t);
  b.skinner->deform(t, skinned);
  ASSERT_EQ(frames.size(), 5u);
  for (const PointsF& f : frames) EXPECT_EQ(f, skinned);
}

TEST(Simulation, BadInput) {
  const Bound b;
  const PoseSequence seq = swingThenStop(24, 90.0, 0.4, 1.0);
  SimulationOptions o;
  o.jiggle = true;
  EXPECT_NE(test::inputErrorOf([&] { Simulation(limb().skin, limb().skeleton, nullptr, b.skinner, seq, o); }), "");
  PoseSequence nan = seq;
  nan.frames[2].matrices[1](1, 1) = NAN;
  EXPECT_NE(test::inputErrorOf([&] { Simulation(limb().skin, limb().skeleton, &b.rig, b.skinner, nan, o); }), "");
  PoseSequence half = seq;
  half.startFrame = 1.5;
  EXPECT_NE(test::inputErrorOf([&] { Simulation(limb().skin, limb().skeleton, &b.rig, b.skinner, half, o); }), "");
  // One frame with everything on: the skinned frame itself.
  PoseSequence one;
  one.frames.push_back(limbPose(45.0, 30.0));
  o.filter = true;
  Simulation single(limb().skin, limb().skeleton, &b.rig, b.skinner, one, o);
  const std::vector<PointsF> frames = bakeAll(single, 1, 1);
  ASSERT_EQ(frames.size(), 1u);
  PointsF raw;
  single.rawFrame(1, raw);
  EXPECT_EQ(frames[0], raw);
  EXPECT_TRUE(frames[0].allFinite());
  Simulation ok(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  EXPECT_NE(test::inputErrorOf([&] { bakeAll(ok, 0, 3); }).find("outside"), std::string::npos);
  EXPECT_NE(test::inputErrorOf([&] { bakeAll(ok, 5, 3); }), "");
}

TEST(Simulation, VertexInfluenceZeroIsPlainSkinningOneIsFullJiggle) {
  const Bound b;
  const PoseSequence seq = sineSwing(24, 50.0, 1.2, 1.2, 2.0);
  SimulationOptions jig, plain;
  jig.jiggle = true;
  Simulation full(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, jig);
  Simulation still(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, plain);
  // Painted 0 on the first half of the vertices, 1 on the rest.
  const int V = static_cast<int>(limb().skin.vertices.rows());
  SimulationOptions painted = jig;
  painted.jiggleVertexInfluence.assign(V, 1.0);
  std::fill(painted.jiggleVertexInfluence.begin(), painted.jiggleVertexInfluence.begin() + V / 2, 0.0);
  Simulation mixed(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, painted);
  PointsF f, s, m;
  full.frame(30, f);
  still.frame(30, s);
  mixed.frame(30, m);
  ASSERT_GT((f - s).cwiseAbs().maxCoeff(), 1e-4) << "the jiggle must move the skin at this frame";
  EXPECT_EQ(m.topRows(V / 2), s.topRows(V / 2)) << "painted 0: plain skinning, bit for bit";
  EXPECT_EQ(m.bottomRows(V - V / 2), f.bottomRows(V - V / 2)) << "painted 1: the full jiggle, bit for bit";
  // Half: half way.
  painted.jiggleVertexInfluence.assign(V, 0.5);
  Simulation half(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, painted);
  half.frame(30, m);
  EXPECT_LT((m - 0.5f * (f + s)).cwiseAbs().maxCoeff(), 1e-6 * kSize);
  painted.jiggleVertexInfluence[3] = 1.5;
  EXPECT_NE(test::inputErrorOf([&] { Simulation(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, painted); })
                .find("outside 0..1"),
            std::string::npos);
  painted.jiggleVertexInfluence.resize(5);
  EXPECT_NE(test::inputErrorOf([&] { Simulation(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, painted); }), "");
}

TEST(Simulation, ShapeOffsetsEqualSkinningTheOffsetMesh) {
  const Bound b;
  const PoseSequence seq = swingThenStop(24, 90.0, 0.4, 1.0);
  const SkinWeights w = computeHybridWeights(limb().skin, limb().weights, b.rig);
  const int joints = limb().skeleton.numBones() + b.rig.numJoints();
  // An offset (a shape key) on frame 10 only: the same as a skinner built on the offset rest mesh.
  const Points offset = sculptOf(limb().skin.vertices) - limb().skin.vertices;
  std::vector<PointsF> offsets(seq.frames.size());
  offsets[9] = offset.cast<float>();
  SimulationOptions o;
  Simulation sim(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  sim.setShapeOffsets(offsets);
  Mesh shaped = limb().skin;
  shaped.vertices += offsets[9].cast<double>();
  auto shapedSkinner = std::make_shared<Skinner>(shaped.vertices, w, joints);
  Simulation ref(shaped, limb().skeleton, &b.rig, shapedSkinner, seq, o);
  Simulation none(limb().skin, limb().skeleton, &b.rig, b.skinner, seq, o);
  PointsF got, want, plain;
  sim.frame(10, got);
  ref.frame(10, want);
  none.frame(10, plain);
  ASSERT_GT((want - plain).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_LT((got - want).cwiseAbs().maxCoeff(), 1e-6 * kSize);
  sim.frame(11, got);
  none.frame(11, plain);
  EXPECT_EQ(got, plain) << "frames without offsets are plain skinning";
  offsets.pop_back();
  EXPECT_NE(test::inputErrorOf([&] { sim.setShapeOffsets(offsets); }), "");
}

TEST(SculptDeltas, FromStoredLocalDeltasEqualsTheOriginal) {
  const Mesh& skin = limb().skin;
  const Points sculpted = sculptOf(skin.vertices);
  SculptDeltas deltas(skin.vertices, skin.triangles, sculpted);
  SculptDeltas stored(skin.triangles, deltas.localDeltas(), deltas.framed());
  ASSERT_EQ(stored.numVertices(), deltas.numVertices());
  const Mat3 R = Eigen::AngleAxisd(0.7, Vec3(0.1, 0.9, -0.4).normalized()).toRotationMatrix();
  const Points moved = skin.vertices * R.transpose();
  Points a, c;
  deltas.apply(moved, a);
  stored.apply(moved, c);
  EXPECT_EQ(a, c);
  // On the sculpt frame through a simulation: the sculpt to 1e-6 of the size.
  const Bound b;
  PoseSequence rest;
  rest.frames.assign(3, limbPose(0.0));
  Simulation sim(skin, limb().skeleton, &b.rig, b.skinner, rest, SimulationOptions{});
  PointsF reference;
  sim.frame(2, reference);
  SculptDeltas fromFrame(reference.cast<double>(), skin.triangles, sculptOf(reference.cast<double>()));
  sim.setSculpt(SculptDeltas(skin.triangles, fromFrame.localDeltas(), fromFrame.framed()));
  PointsF p;
  sim.frame(2, p);
  EXPECT_LT((p.cast<double>() - sculptOf(reference.cast<double>())).cwiseAbs().maxCoeff(), 1e-6 * kSize);
  std::vector<char> shortFlags(5, 1);
  EXPECT_NE(test::inputErrorOf([&] { SculptDeltas(skin.triangles, deltas.localDeltas(), shortFlags); }), "");
}
