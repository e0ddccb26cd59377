// Extraction stages 3-4: CDT of a section, triangle kinds, bumps (semicircle rule + significance) and the
// ellipse under each bump; a fuzz test over hostile polygons.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <utility>

#include "myoskin/bumps.h"
#include "myoskin/errors.h"
#include "test_support.h"

using namespace myoskin;

namespace {


// A limb section: circle of radius R (5 cm) with smooth bulges of height h (metres) and angular
// half-width w (radians) at the given angles, sampled at n points counter-clockwise.
Points2 bumpySection(const std::vector<double>& angles, double h = 0.006, double w = 0.45, int n = 160,
                     double R = 0.05, double aspect = 1.0) {
  Points2 p(n, 2);
  for (int i = 0; i < n; ++i) {
    const double t = 2 * kPi * i / n;
    double r = R;
    for (double a : angles) {
      const double d = std::remainder(t - a, 2 * kPi);
      if (std::abs(d) < w) r += h * std::pow(std::cos(0.5 * kPi * d / w), 2);
    }
    p(i, 0) = r * std::cos(t) * aspect;
    p(i, 1) = r * std::sin(t);
  }
  return p;
}

double polygonArea(const Points2& p) {
  double a = 0;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const Eigen::Index j = (i + 1) % p.rows();
    a += 0.5 * (p(i, 0) * p(j, 1) - p(j, 0) * p(i, 1));
  }
  return a;
}

double apexAngle(const Points2& p, const Bump& b) { return std::atan2(p(b.apex, 1), p(b.apex, 0)); }

bool inside(const Points2& poly, const Vec2& q) {
  bool in = false;
  for (Eigen::Index i = 0, j = poly.rows() - 1; i < poly.rows(); j = i++)
    if ((poly(i, 1) > q.y()) != (poly(j, 1) > q.y()) &&
        q.x() < (poly(j, 0) - poly(i, 0)) * (q.y() - poly(i, 1)) / (poly(j, 1) - poly(i, 1)) + poly(i, 0))
      in = !in;
  return in;
}

}  // namespace

// ============================================================================
// Triangulation
// ============================================================================

TEST(SectionCdt, CoversThePolygonWithKinds) {
  const Points2 p = bumpySection({0.3, 2.0});
  const SectionTriangulation t = triangulateSection(p);
  ASSERT_EQ(t.triangles.rows(), p.rows() - 2);  // a simple polygon with n vertices: n - 2 triangles
  double area = 0;
  int boundaryEdges = 0;
  for (Eigen::Index f = 0; f < t.triangles.rows(); ++f) {
    Points2 tri(3, 2);
    for (int k = 0; k < 3; ++k) tri.row(k) = p.row(t.triangles(f, k));
    EXPECT_GT(polygonArea(tri), 0.0);  // counter-clockwise
    area += polygonArea(tri);
    int kind = 0;
    for (int k = 0; k < 3; ++k) {
      const int a = t.triangles(f, k), b = t.triangles(f, (k + 1) % 3);
      kind += (b == (a + 1) % p.rows()) || (a == (b + 1) % p.rows());
    }
    EXPECT_EQ(kind, static_cast<int>(t.kinds[f]));
    boundaryEdges += kind;
  }
  EXPECT_NEAR(area, polygonArea(p), 1e-12 * polygonArea(p));
  EXPECT_EQ(boundaryEdges, p.rows());
  int terminals = 0;
  for (TriangleKind k : t.kinds) terminals += k == TriangleKind::Terminal;
  EXPECT_GE(terminals, 2);
}

// ============================================================================
// Bumps
// ============================================================================

TEST(Bumps, SmoothSectionsGiveNone) {
  EXPECT_TRUE(findBumps(bumpySection({})).empty());                             // circle
  EXPECT_TRUE(findBumps(bumpySection({}, 0, 0.4, 160, 0.05, 1.6)).empty());     // ellipse 1.6 : 1
  Points2 wobble(200, 2);  // a smooth oval with a gentle second-order wobble
  for (int i = 0; i < 200; ++i) {
    const double t = 2 * kPi * i / 200, r = 0.05 * (1 + 0.08 * std::cos(2 * t) + 0.02 * std::sin(t));
    wobble.row(i) << r * std::cos(t), r * std::sin(t);
  }
  EXPECT_TRUE(findBumps(wobble).empty());
}

// A trunk-like outline: a rounded rectangle 1.6 : 1 (superellipse, exponent 2.5) of half-width 0.16 m with a
// shallow front notch (the sternum), plus optional bellies of height h at the given angles.
Points2 trunkSection(const std::vector<double>& angles, double h = 0.012, int n = 320) {
  Points2 p(n, 2);
  for (int i = 0; i < n; ++i) {
    const double t = 2 * kPi * i / n, c = std::cos(t), sn = std::sin(t);
    double r = 1.0 / std::pow(std::pow(std::abs(c) / 0.16, 2.5) + std::pow(std::abs(sn) / 0.1, 2.5), 0.4);
    r -= 0.006 * std::exp(-std::pow(std::remainder(t + 0.5 * kPi, 2 * kPi) / 0.12, 2));  // notch at the front
    for (double a : angles) {
      const double d = std::remainder(t - a, 2 * kPi);
      if (std::abs(d) < 0.3) r += h * std::pow(std::cos(0.5 * kPi * d / 0.3), 2);
    }
    p.row(i) << r * c, r * sn;
  }
  return p;
}

TEST(Bumps, TrunkOutlineAgainstAFourierBase) {
  // Measured: against a conic the plain rounded rectangle gives bumps at its flanks (whole sides that no
  // oval follows); the order-4 radial Fourier base follows it: no bump, and two 12 mm bellies either side of
  // the notch are found where they are.
  BumpOptions conic, fourier;
  fourier.baseHarmonics = 4;
  const Points2 plain = trunkSection({});
  const std::vector<Bump> flanks = findBumps(plain, conic);
  std::printf("rounded-rectangle trunk: %zu bumps against a conic, %zu against the Fourier base\n", flanks.size(),
              findBumps(plain, fourier).size());
  for (const Bump& b : findBumps(plain, fourier)) std::printf("  fourier bump at %.2f rad: %.4f m\n", apexAngle(plain, b), b.protrusion);
  EXPECT_FALSE(flanks.empty());
  EXPECT_TRUE(findBumps(plain, fourier).empty());
  const std::vector<double> bellies = {-0.5 * kPi - 0.45, -0.5 * kPi + 0.45};
  const Points2 chest = trunkSection(bellies);
  const std::vector<Bump> found = findBumps(chest, fourier);
  ASSERT_EQ(found.size(), 2u);
  for (double a : bellies) {
    double best = 1e9;
    for (const Bump& b : found) best = std::min(best, std::abs(std::remainder(apexAngle(chest, b) - a, 2 * kPi)));
    EXPECT_LT(best, 10 * kPi / 180) << "belly at " << a;
  }
  for (const Bump& b : found) EXPECT_GT(b.protrusion, 0.006);
}

TEST(Bumps, OneTwoThreeBulgesAtTheirAngles) {
  const std::vector<std::vector<double>> cases = {{1.0}, {0.5, 2.6}, {0.0, 2.1, 4.2}};
  for (const auto& angles : cases) {
    const Points2 p = bumpySection(angles);
    const std::vector<Bump> bumps = findBumps(p);
    ASSERT_EQ(bumps.size(), angles.size()) << angles.size() << " bulges";
    for (double a : angles) {
      double best = 1e9;
      for (const Bump& b : bumps) best = std::min(best, std::abs(std::remainder(apexAngle(p, b) - a, 2 * kPi)));
      EXPECT_LT(best, 15 * kPi / 180) << "bulge at " << a;
    }
    for (const Bump& b : bumps) {
      EXPECT_GE(b.significance, 1.0);
      EXPECT_GT(b.protrusion, 0.003);
      EXPECT_GE(b.terminalTriangle, 0);
    }
  }
}

TEST(Bumps, InvariantUnderStartIndexScaleAndRigidMotion) {
  const Points2 p = bumpySection({0.4, 2.5}, 0.007);
  const size_t count = findBumps(p).size();
  ASSERT_EQ(count, 2u);
  for (int shift : {1, 37, 101}) {
    Points2 q(p.rows(), 2);
    for (Eigen::Index i = 0; i < p.rows(); ++i) q.row(i) = p.row((i + shift) % p.rows());
    EXPECT_EQ(findBumps(q).size(), count) << shift;
  }
  const double c = std::cos(0.7), s = std::sin(0.7);
  Points2 moved(p.rows(), 2);
  for (Eigen::Index i = 0; i < p.rows(); ++i) moved.row(i) << c * p(i, 0) - s * p(i, 1) + 3.0, s * p(i, 0) + c * p(i, 1) - 1.0;
  EXPECT_EQ(findBumps(moved).size(), count);
  Points2 big = 2.0 * p;  // relative thresholds scale; the absolute one only lowers the bar
  EXPECT_EQ(findBumps(big).size(), count);
  // Clockwise input is handled (same bumps).
  Points2 cw = p.colwise().reverse();
  EXPECT_EQ(findBumps(cw).size(), count);
  // Deterministic.
  const auto a = findBumps(p), b = findBumps(p);
  ASSERT_EQ(b.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(a[i].first == b[i].first && a[i].last == b[i].last && a[i].apex == b[i].apex);
}

// A clipped profile (a shoulder's): four fifths of an elliptical section with one belly, closed by a straight
// chord through the body, sampled as finely as the skin. With its onSkin mask (its base support then fades over a
// margin of the tolerance) the belly is found on the skin, at its angle, standing out about as far as on the whole
// section, wherever the chord runs; the protrusion changes continuously with a scale of 1 + k 1e-6 along y (the
// round-off Blender's importer leaves along a body's height; measured over k = 0..400 on the -2.0..3.3 arc: steps of
// at most 5.5e-9 m, where a hard support cut jumps 6.1e-5 m at k = 337).
TEST(Bumps, AClippedProfileFindsItsBellyOnTheSkinContinuously) {
  const double a = 0.065, b = 0.045, h = 0.008, belly = 1.2, w = 0.5;
  const int arcPoints = 240;
  // The section from angle `from` to `to` with the belly; a chord back to the start unless `to` closes the turn.
  auto section = [&](double from, double to, std::vector<char>& onSkin) {
    std::vector<Vec2> pts;
    for (int i = 0; i < arcPoints; ++i) {
      const double t = from + (to - from) * i / arcPoints;
      const double d = std::remainder(t - belly, 2 * kPi);
      const double out = std::abs(d) < w ? h * std::pow(std::cos(0.5 * kPi * d / w), 2) : 0.0;
      pts.push_back(Vec2(a * std::cos(t), b * std::sin(t)) + out * Vec2(b * std::cos(t), a * std::sin(t)).normalized());
    }
    onSkin.assign(pts.size(), 1);
    if (to - from < 2 * kPi - 1e-9) {
      const double spacing = (pts[1] - pts[0]).norm();
      const Vec2 end = pts.back(), start = pts.front();
      const int chord = static_cast<int>(std::round((start - end).norm() / spacing));
      for (int k = 1; k < chord; ++k) pts.push_back(end + (start - end) * (static_cast<double>(k) / chord)), onSkin.push_back(0);
    }
    Points2 p(pts.size(), 2);
    for (size_t i = 0; i < pts.size(); ++i) p.row(i) = pts[i].transpose();
    return p;
  };
  auto onTheSkin = [](const Points2& p, const std::vector<char>& onSkin, std::vector<Bump> bumps) {
    bumps.erase(std::remove_if(bumps.begin(), bumps.end(), [&](const Bump& x) {
                  for (int i = x.first;; i = (i + 1) % static_cast<int>(p.rows())) {
                    if (!onSkin[i]) return true;
                    if (i == x.last) return false;
                  }
                }),
                bumps.end());
    return bumps;
  };
  std::vector<char> all;
  const Points2 whole = section(-kPi, kPi, all);
  const std::vector<Bump> reference = findBumps(whole);
  ASSERT_EQ(reference.size(), 1u);
  int measured = 0;
  for (const auto& [from, to] : std::vector<std::pair<double, double>>{{-1.6, 3.6}, {-1.2, 3.9}, {-2.0, 3.3}}) {
    ++measured;
    std::vector<char> onSkin;
    const Points2 p = section(from, to, onSkin);
    const std::vector<Bump> bumps = onTheSkin(p, onSkin, findBumps(p, {}, nullptr, &onSkin));
    std::printf("  arc %.1f..%.1f rad: %zu bump(s) on the skin, protrusion %.5f m (whole section %.5f m)\n", from, to,
                bumps.size(), bumps.empty() ? 0.0 : bumps[0].protrusion, reference[0].protrusion);
    ASSERT_EQ(bumps.size(), 1u) << from << ".." << to;
    const double at = std::atan2(p(bumps[0].apex, 1) / b, p(bumps[0].apex, 0) / a);
    EXPECT_LT(std::abs(std::remainder(at - belly, 2 * kPi)), 0.1) << from << ".." << to;
    EXPECT_NEAR(bumps[0].protrusion, reference[0].protrusion, 0.1 * reference[0].protrusion) << from << ".." << to;
  }
  EXPECT_EQ(measured, 3);
  std::vector<char> onSkin;
  const Points2 p = section(-2.0, 3.3, onSkin);
  double previous = -1.0, largestStep = 0.0;
  for (int k = 0; k <= 400; ++k) {
    Points2 q = p;
    q.col(1) *= 1.0 + 1e-6 * k;
    const std::vector<Bump> bumps = onTheSkin(q, onSkin, findBumps(q, {}, nullptr, &onSkin));
    ASSERT_EQ(bumps.size(), 1u) << k;
    if (previous >= 0.0) largestStep = std::max(largestStep, std::abs(bumps[0].protrusion - previous));
    previous = bumps[0].protrusion;
  }
  std::printf("  y scaled by 1 + k 1e-6, k = 0..400: the protrusion's largest step %.2e m\n", largestStep);
  EXPECT_LT(largestStep, 1e-4 * h);
  std::vector<char> wrongSize(3, 1);
  EXPECT_THROW(findBumps(whole, {}, nullptr, &wrongSize), InputError);
}

TEST(BumpEllipse, MirroredSectionGivesMirroredBumpsAndEllipses) {
  // Mirrored limbs (left/right) give mirrored sections: bumps and ellipses must be exact mirror images.
  // (An arc-length offset once made the ellipse weights depend on where the belly's core started along
  // the arc, so a mirrored arc got another ellipse: the left and right calves linked differently.)
  // Lopsided bellies (steep on one side, a long tail on the other) on an oval limb, 3 mm apart samples.
  const Eigen::Index n = 150;
  Points2 p(n, 2);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double t = 2 * kPi * i / n;
    double r = 0.05;
    for (double a : {0.5, 2.6, 4.3}) {
      const double d = std::remainder(t - a, 2 * kPi), w = d < 0 ? 0.25 : 0.7;
      r += 0.008 * std::exp(-(d / w) * (d / w));
    }
    p.row(i) << 1.15 * r * std::cos(t), r * std::sin(t);
  }
  Points2 m(n, 2);  // x -> -x, reversed so it stays counter-clockwise
  for (Eigen::Index i = 0; i < n; ++i) m.row(i) << -p(n - 1 - i, 0), p(n - 1 - i, 1);
  const SectionTriangulation tp = triangulateSection(p), tm = triangulateSection(m);
  const std::vector<Bump> bp = findBumps(p, {}, &tp), bm = findBumps(m, {}, &tm);
  ASSERT_EQ(bp.size(), 3u);
  ASSERT_EQ(bm.size(), bp.size());
  for (const Bump& b : bp) {
    const Ellipse2 e = fitBumpEllipse(p, b, tp);
    bool found = false;
    for (const Bump& c : bm) {
      if (c.apex != n - 1 - b.apex) continue;
      found = true;
      EXPECT_NEAR(c.protrusion, b.protrusion, 1e-12);
      const Ellipse2 f = fitBumpEllipse(m, c, tm);
      EXPECT_NEAR(f.center.x(), -e.center.x(), 1e-9);
      EXPECT_NEAR(f.center.y(), e.center.y(), 1e-9);
      EXPECT_NEAR(f.a, e.a, 1e-9);
      EXPECT_NEAR(f.b, e.b, 1e-9);
    }
    EXPECT_TRUE(found) << "apex " << b.apex;
  }
}

// ============================================================================
// Ellipses
// ============================================================================

// A torso-like oval, exactly mirror-symmetric about the y axis (sample k mirrors sample n - k, sample 0 on +y),
// with two mirrored pairs of bellies of different heights.
Points2 mirroredTorso(int n = 240) {
  Points2 p(n, 2);
  for (int i = 0; i < n; ++i) {
    const double t = 0.5 * kPi + 2 * kPi * i / n;
    double r = 0.12;
    for (const auto& [a, h] : {std::pair{0.5, 0.012}, std::pair{kPi - 0.5, 0.012}, std::pair{-1.1, 0.008},
                               std::pair{kPi + 1.1, 0.008}}) {
      const double d = std::remainder(t - a, 2 * kPi);
      if (std::abs(d) < 0.4) r += h * std::pow(std::cos(0.5 * kPi * d / 0.4), 2);
    }
    p.row(i) << 1.4 * r * std::cos(t), r * std::sin(t);
  }
  for (int k = 0; k <= n / 2; ++k) {  // exact mirror pairs
    const int j = (n - k) % n;
    const double x = 0.5 * (p(k, 0) - p(j, 0)), y = 0.5 * (p(k, 1) + p(j, 1));
    p.row(k) << x, y;
    p.row(j) << -x, y;
  }
  return p;
}

TEST(SectionCdt, SplitAlongTheMirrorAxisGivesMirroredTrianglesAndBumps) {
  const int n = 240;
  const Points2 p = mirroredTorso(n);
  const std::array<int, 2> axis = axisDiagonal(p);
  EXPECT_EQ(axis[0], 0);
  EXPECT_EQ(axis[1], n / 2);
  const SectionTriangulation t = triangulateSection(p, {axis});
  ASSERT_EQ(t.diagonals.size(), 1u);
  ASSERT_EQ(t.triangles.rows(), n - 2);
  std::set<std::array<int, 3>> tris;
  auto sorted = [](std::array<int, 3> a) { std::sort(a.begin(), a.end()); return a; };
  for (Eigen::Index f = 0; f < t.triangles.rows(); ++f) tris.insert(sorted({t.triangles(f, 0), t.triangles(f, 1), t.triangles(f, 2)}));
  int unmatched = 0;
  for (const auto& a : tris) unmatched += !tris.count(sorted({(n - a[0]) % n, (n - a[1]) % n, (n - a[2]) % n}));
  EXPECT_EQ(unmatched, 0);
  // Every bump has its mirror image (arc, apex, height and ellipse), and none spans the split.
  const std::vector<Bump> bumps = findBumps(p, {}, &t);
  EXPECT_EQ(bumps.size(), 4u);
  for (const Bump& b : bumps) {
    EXPECT_FALSE((b.first == 0 && b.last == n / 2) || (b.first == n / 2 && b.last == 0));
    int mirrors = 0;
    for (const Bump& c : bumps) {
      if (c.apex != (n - b.apex) % n) continue;
      ++mirrors;
      EXPECT_EQ(c.first, (n - b.last) % n);
      EXPECT_EQ(c.last, (n - b.first) % n);
      EXPECT_NEAR(c.protrusion, b.protrusion, 1e-12);
      const Ellipse2 e = fitBumpEllipse(p, b, t), f = fitBumpEllipse(p, c, t);
      EXPECT_NEAR(f.center.x(), -e.center.x(), 1e-9);
      EXPECT_NEAR(f.center.y(), e.center.y(), 1e-9);
      EXPECT_NEAR(f.a, e.a, 1e-9);
      EXPECT_NEAR(f.b, e.b, 1e-9);
    }
    EXPECT_EQ(mirrors, 1) << "apex " << b.apex;
  }
}

TEST(SectionCdt, ImproperDiagonalsAreLeftOut) {
  const int n = 240;
  const Points2 p = mirroredTorso(n);
  // Adjacent, equal, out of range, and one crossing an earlier one.
  const SectionTriangulation t = triangulateSection(p, {{0, 1}, {5, 5}, {-1, 3}, {0, n}, {0, n / 2}, {n / 4, 3 * n / 4}});
  ASSERT_EQ(t.diagonals.size(), 1u);
  EXPECT_EQ(t.diagonals[0], (std::array<int, 2>{0, n / 2}));
  EXPECT_EQ(t.triangles.rows(), n - 2);
  // A U shape: the chord between the tips of its arms runs outside it; one between its two inner corners and the
  // base runs along the boundary's outside too. Both are left out and the triangulation stays whole.
  Points2 u(8, 2);
  u << 0, 0, 3, 0, 3, 3, 2, 3, 2, 1, 1, 1, 1, 3, 0, 3;
  const SectionTriangulation tu = triangulateSection(u, {{2, 7}, {3, 6}});
  EXPECT_TRUE(tu.diagonals.empty());
  EXPECT_EQ(tu.triangles.rows(), 6);
  const SectionTriangulation inner = triangulateSection(u, {{0, 5}});  // a proper inner diagonal
  EXPECT_EQ(inner.diagonals.size(), 1u);
  EXPECT_EQ(inner.triangles.rows(), 6);
}

TEST(BumpEllipse, UnderTheSkinNearTheBelly) {
  // A limb disc (R = 5 cm) united with a muscle disc of radius r centred at distance d: the ellipse under
  // the bump should sit near the muscle disc.
  const double R = 0.05, r = 0.02, d = 0.045, angle = 0.8;
  const Vec2 m(d * std::cos(angle), d * std::sin(angle));
  Points2 p(240, 2);
  for (int i = 0; i < 240; ++i) {
    const double t = 2 * kPi * i / 240;
    const Vec2 dir(std::cos(t), std::sin(t));
    // Radius of the union along dir: max of the limb circle and the muscle circle's far intersection.
    double rad = R;
    const double bproj = m.dot(dir), disc = bproj * bproj - (m.squaredNorm() - r * r);
    if (disc >= 0) rad = std::max(rad, bproj + std::sqrt(disc));
    p.row(i) = rad * dir.transpose();
  }
  const SectionTriangulation t = triangulateSection(p);
  const auto bumps = findBumps(p, {}, &t);
  ASSERT_EQ(bumps.size(), 1u);
  const Ellipse2 e = fitBumpEllipse(p, bumps[0], t);
  const double centreError = (e.center - m).norm() / r, radiusError = std::abs(std::sqrt(e.a * e.b) - r) / r;
  std::printf("ellipse: centre error %.2f r, mean radius error %.0f %%, a %.4f b %.4f\n", centreError,
              100 * radiusError, e.a, e.b);
  EXPECT_LT(centreError, 0.6);
  EXPECT_LT(radiusError, 0.5);
  EXPECT_GE(e.a, e.b);
  EXPECT_GT(e.b, 0.0);
  for (int k = 0; k < 64; ++k) {  // beneath the skin
    const double s = 2 * kPi * k / 64;
    const Vec2 q = e.center + e.a * std::cos(s) * Vec2(std::cos(e.angle), std::sin(e.angle)) +
                   e.b * std::sin(s) * Vec2(-std::sin(e.angle), std::cos(e.angle));
    EXPECT_TRUE(inside(p, q)) << k;
  }
}

TEST(BumpEllipse, TallBellyOnItsAxisWhateverTheRoundOff) {
  // A narrow, tall belly exactly mirror-symmetric about the +y axis: the raw fit is taller than wide, so it is widened
  // to maxAspect : 1 across the bump. Its centre stays on the axis, and a round-off sized turn of the section (as
  // between Blender's import and the CLI's loader) moves it by round-off only: widening across the bump does not move
  // the top, so the centre does not move sideways (it once moved by the whole widening, to one side or the other
  // depending on the sign of a dot product that is zero up to round-off).
  const int n = 240;
  // A limb disc (R = 5 cm) united with a belly ellipse of semi-axes 1 cm across and 1.4 cm up, centred on its rim.
  const double R = 0.05, bx = 0.01, ay = 0.014;
  auto section = [&](double turn) {
    Points2 p(n, 2);
    for (int i = 0; i < n; ++i) {
      const double t = 0.5 * kPi + 2 * kPi * i / n;
      const Vec2 dir(std::cos(t), std::sin(t)), m(0.0, R);
      const double qa = dir.x() * dir.x() / (bx * bx) + dir.y() * dir.y() / (ay * ay),
                   qb = -2 * dir.y() * m.y() / (ay * ay), qc = m.y() * m.y() / (ay * ay) - 1;
      const double disc = qb * qb - 4 * qa * qc;
      const double r = disc >= 0 ? std::max(R, (-qb + std::sqrt(disc)) / (2 * qa)) : R;
      p.row(i) << r * dir.x(), r * dir.y();
    }
    for (int k = 1; k < n / 2; ++k) p.row(n - k) << -p(k, 0), p(k, 1);  // exact mirror pairs
    p(0, 0) = p(n / 2, 0) = 0.0;                                          // and the axis points on the axis
    const Eigen::Matrix2d rot = Eigen::Rotation2Dd(turn).toRotationMatrix();
    return Points2((p * rot.transpose()).eval());
  };
  const Points2 p = section(0.0);
  const SectionTriangulation t = triangulateSection(p);
  const std::vector<Bump> bumps = findBumps(p, {}, &t);
  ASSERT_EQ(bumps.size(), 1u);
  const Ellipse2 e = fitBumpEllipse(p, bumps[0], t);
  std::printf("tall belly: centre (%.6f, %.6f), a %.5f b %.5f, angle %.3f\n", e.center.x(), e.center.y(), e.a, e.b,
              e.angle);
  EXPECT_NEAR(e.a, 1.2 * e.b, 1e-9 * R);  // widened to the aspect limit (a fit, not the round fallback)
  EXPECT_NEAR(e.center.x(), 0.0, 1e-9);
  for (double turn : {1e-9, -1e-9, 3e-7}) {
    const Points2 q = section(turn);
    const SectionTriangulation tq = triangulateSection(q);
    const std::vector<Bump> bq = findBumps(q, {}, &tq);
    ASSERT_EQ(bq.size(), 1u) << turn;
    const Ellipse2 f = fitBumpEllipse(q, bq[0], tq);
    const Vec2 back = Eigen::Rotation2Dd(-turn).toRotationMatrix() * f.center;
    EXPECT_LT((back - e.center).norm(), 1e-6 * R) << turn;
    EXPECT_NEAR(f.a, e.a, 1e-6 * R) << turn;
  }
}

TEST(BumpEllipse, SpikeOfRepeatedPointsGetsAFiniteEllipse) {
  // A spike whose tip is one skin point repeated (consecutive duplicate vertices; found by fuzz_bumps): the belly
  // (the arc above 35 % of the apex height) would be the repeated points alone, with no extent, so the fit keeps the
  // whole arc and gives a finite belly of positive size under the spike.
  const double R = 0.05;
  std::vector<Vec2> pts;
  for (int i = 0; i < 120; ++i) {
    const double t = 2 * kPi * i / 120;
    pts.push_back(R * Vec2(std::cos(t), std::sin(t)));
    if (i == 30)
      for (int k = 0; k < 8; ++k) pts.push_back(1.3 * R * Vec2(std::cos(t + kPi / 120), std::sin(t + kPi / 120)));
  }
  Points2 p(static_cast<Eigen::Index>(pts.size()), 2);
  for (size_t i = 0; i < pts.size(); ++i) p.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
  Bump b;
  b.first = 30, b.apex = 31, b.last = 39;
  const SectionTriangulation t = triangulateSection(p);
  const Ellipse2 e = fitBumpEllipse(p, b, t);
  EXPECT_TRUE(e.center.allFinite() && std::isfinite(e.a) && std::isfinite(e.angle));
  EXPECT_GT(e.b, 0.0);
  EXPECT_LT((e.center - p.row(31).transpose()).norm(), 0.5 * R);  // under the spike
  EXPECT_TRUE(inside(p, e.center));
}

TEST(BumpEllipse, BumpOfCoincidentPointsIsRefusedAndALoopGetsABellyInside) {
  // A bump whose points all coincide (three copies of one skin vertex) has no extent: an InputError that says so.
  const double R = 0.05;
  std::vector<Vec2> pts;
  for (int i = 0; i < 120; ++i) {
    pts.push_back(R * Vec2(std::cos(2 * kPi * i / 120), std::sin(2 * kPi * i / 120)));
    if (i == 30) pts.push_back(pts.back()), pts.push_back(pts.back());
  }
  Points2 p(static_cast<Eigen::Index>(pts.size()), 2);
  for (size_t i = 0; i < pts.size(); ++i) p.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
  Bump b;
  b.first = 30, b.apex = 31, b.last = 32;
  const std::string refused = test::inputErrorOf([&] { fitBumpEllipse(p, b, SectionTriangulation{}); });
  EXPECT_NE(refused.find("no extent"), std::string::npos) << refused;
  // A skin loop that leaves a vertex and comes back to a copy of it (the bump's ends coincide): a finite belly of
  // positive size inside the loop.
  const double rho = 0.01;
  const Vec2 c = R * Vec2(0, 1), n(0, 1), tangent(-1, 0), q = c + rho * n;
  std::vector<Vec2> loop{Vec2(R, 0), c};
  for (int k = 1; k < 24; ++k) {
    const double phi = 2 * kPi * k / 24;
    loop.push_back(q - rho * (std::cos(phi) * n + std::sin(phi) * tangent));
  }
  loop.push_back(c);
  loop.push_back(Vec2(-R, 0));
  loop.push_back(Vec2(0, -R));
  Points2 l(static_cast<Eigen::Index>(loop.size()), 2);
  for (size_t i = 0; i < loop.size(); ++i) l.row(static_cast<Eigen::Index>(i)) = loop[i].transpose();
  b.first = 1, b.apex = 13, b.last = 25;
  const Ellipse2 e = fitBumpEllipse(l, b, SectionTriangulation{});
  EXPECT_TRUE(e.center.allFinite() && std::isfinite(e.a) && std::isfinite(e.angle));
  EXPECT_GT(e.b, 0.0);
  EXPECT_LE(e.a, 2 * rho);
  EXPECT_LT((e.center - q).norm(), 0.5 * R);  // beside the loop, not across the body (the fit pulls it under the skin)
}

TEST(BumpStage, SpeedPerSection) {
  const Points2 p = bumpySection({0.3, 1.9, 4.0}, 0.006, 0.45, 200);
  const auto t0 = std::chrono::steady_clock::now();
  int n = 0;
  for (int rep = 0; rep < 50; ++rep) {
    const SectionTriangulation t = triangulateSection(p);
    for (const Bump& b : findBumps(p, {}, &t)) n += fitBumpEllipse(p, b, t).a > 0;
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / 50;
  std::printf("200-point section: %.3f ms for triangulation + bumps + ellipses (%d ellipses per run)\n", ms, n / 50);
  EXPECT_EQ(n, 150);  // every run fits an ellipse under each of the three bulges (50 runs)
}

// ============================================================================
// Fuzz: hostile polygons never crash, never escape as anything but InputError, never give NaN
// ============================================================================

TEST(BumpStage, FuzzHostilePolygons) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::mt19937 diag(777);  // a separate stream, so the polygons are the same with or without diagonals
  int valid = 0, rejected = 0, bumpsSeen = 0, forced = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int kind = trial % 7;
    const int n = 3 + static_cast<int>(u(rng) * 120);
    Points2 p(n, 2);
    const double scale = std::pow(10.0, -6 + 10 * u(rng));
    for (int i = 0; i < n; ++i) {
      const double t = 2 * kPi * i / n;
      const double r = scale * (0.5 + u(rng));
      p.row(i) << r * std::cos(t), r * std::sin(t);  // random star-shaped
    }
    if (kind == 1) p.row(n / 2) = p.row(0);                                     // self-touching
    if (kind == 2) for (int i = 0; i < n / 2; ++i) p.row(i) << scale * i, 0.0;  // collinear run
    if (kind == 3 && n > 3) p.row(1) = p.row(0);                                // duplicate consecutive
    if (kind == 4) for (int i = 0; i < n; ++i) p.row(i) << u(rng) * scale, u(rng) * scale;  // random mess
    if (kind == 5) p(static_cast<int>(u(rng) * n), 0) = std::nan("");           // NaN
    if (kind == 6) p.setZero();                                                 // degenerate
    // Every other trial forces diagonals too: the mirror axis (if any) and a random index pair, proper or not.
    std::vector<std::array<int, 2>> diagonals;
    if (trial % 2) {
      diagonals.push_back(axisDiagonal(p));
      diagonals.push_back({static_cast<int>(diag() % n), static_cast<int>(diag() % n)});
    }
    try {
      const SectionTriangulation t = triangulateSection(p, diagonals);
      EXPECT_LE(t.diagonals.size(), diagonals.size());
      forced += static_cast<int>(t.diagonals.size());
      for (const Bump& b : findBumps(p, {}, &t)) {
        const Ellipse2 e = fitBumpEllipse(p, b, t);
        ASSERT_TRUE(std::isfinite(e.center.x()) && std::isfinite(e.center.y()) && std::isfinite(e.a) && std::isfinite(e.b));
        ++bumpsSeen;
      }
      ++valid;
    } catch (const InputError& e) {
      EXPECT_GT(std::string(e.what()).size(), 10u);
      ++rejected;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "trial " << trial << " (kind " << kind << "): " << e.what();
    }
  }
  std::printf("fuzz: %d valid, %d rejected with InputError, %d bumps fitted, %d diagonals forced\n", valid, rejected,
              bumpsSeen, forced);
  EXPECT_GT(valid, 1000);
  EXPECT_GT(forced, 100);
  EXPECT_GT(rejected, 500);
  EXPECT_GT(bumpsSeen, 0);  // the finiteness check above ran on fitted ellipses
}
