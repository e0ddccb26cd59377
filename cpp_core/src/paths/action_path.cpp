// Action paths: straight, round a joint sphere, round a bone cylinder; points, tangents and
// rotation-minimising frames in closed form per piece.
#include "paths/action_path.h"

#include <algorithm>
#include <cmath>

namespace myoskin::paths {

namespace {

constexpr double kTwoPi = 2 * kPi;

// Angle in [0, 2 pi).
double wrapAngle(double a) {
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}

PathPiece linePiece(const Vec3& a, const Vec3& b) {
  PathPiece p;
  p.kind = PieceKind::Line;
  p.a = a;
  p.b = b;
  p.length = (b - a).norm();
  return p;
}

void finish(ActionPath& path, bool wrapped) {
  path.length = 0;
  for (int i = 0; i < path.count; ++i) path.length += path.pieces[i].length;
  path.wrapped = wrapped;
}

// Frenet frame (T, N, B) of the helix piece at psi (angle swept so far).
void helixFrenet(const PathPiece& h, double psi, Vec3& T, Vec3& N, Vec3& B) {
  const double phi = h.phi1 + h.side * psi;
  const Vec3 radial = std::cos(phi) * h.e1 + std::sin(phi) * h.e2;
  const Vec3 around = -std::sin(phi) * h.e1 + std::cos(phi) * h.e2;
  T = (h.radius * h.side * around + h.slope * h.axis).normalized();
  N = -radial;
  B = T.cross(N);
}

// Frame carried from the start of `piece` (frame Fs) to local arc length s within it.
Mat3 frameInPiece(const PathPiece& piece, const Mat3& Fs, double s) {
  switch (piece.kind) {
    case PieceKind::Line: return Fs;
    case PieceKind::Arc: {
      const Vec3 n = piece.start.cross(piece.travel);
      return Eigen::AngleAxisd(s / piece.radius, n).toRotationMatrix() * Fs;
    }
    case PieceKind::Helix: {
      const double speed = std::sqrt(piece.radius * piece.radius + piece.slope * piece.slope);
      const double tau = piece.side * piece.slope / (speed * speed);
      Vec3 T0, N0, B0, T, N, B;
      helixFrenet(piece, 0.0, T0, N0, B0);
      helixFrenet(piece, s / speed, T, N, B);
      const Vec3 X0 = Fs.col(0);
      const double theta = std::atan2(X0.dot(B0), X0.dot(N0)) - tau * s;
      Mat3 F;
      F.col(0) = std::cos(theta) * N + std::sin(theta) * B;
      F.col(1) = T;
      F.col(2) = F.col(0).cross(T);
      return F;
    }
  }
  return Fs;
}

// Point and tangent at local arc length s within a piece.
void pointInPiece(const PathPiece& piece, double s, Vec3& point, Vec3& tangent) {
  switch (piece.kind) {
    case PieceKind::Line: {
      const Vec3 d = piece.b - piece.a;
      tangent = piece.length > 1e-300 ? Vec3(d / piece.length) : piece.travel;
      point = piece.a + s * tangent;
      return;
    }
    case PieceKind::Arc: {
      const double th = s / piece.radius;
      point = piece.center + piece.radius * (std::cos(th) * piece.start + std::sin(th) * piece.travel);
      tangent = -std::sin(th) * piece.start + std::cos(th) * piece.travel;
      return;
    }
    case PieceKind::Helix: {
      const double speed = std::sqrt(piece.radius * piece.radius + piece.slope * piece.slope);
      const double psi = s / speed;
      const double phi = piece.phi1 + piece.side * psi;
      point = piece.axisOrigin + piece.radius * (std::cos(phi) * piece.e1 + std::sin(phi) * piece.e2) +
              (piece.h1 + piece.slope * psi) * piece.axis;
      Vec3 N, B;
      helixFrenet(piece, psi, tangent, N, B);
      return;
    }
  }
}

// Piece containing arc length sigma (clamped) and the local arc length within it.
int locate(const ActionPath& path, double sigma, double& local) {
  sigma = std::clamp(sigma, 0.0, path.length);
  for (int i = 0; i < path.count; ++i) {
    if (sigma <= path.pieces[i].length || i + 1 == path.count) {
      local = std::min(sigma, path.pieces[i].length);
      return i;
    }
    sigma -= path.pieces[i].length;
  }
  local = 0;
  return 0;
}

}  // namespace

// ============================================================================
// Construction
// ============================================================================

void straightPath(const Vec3& O, const Vec3& I, ActionPath& path) {
  path.count = 1;
  path.pieces[0] = linePiece(O, I);
  path.pieces[0].travel = Vec3::UnitY();
  finish(path, false);
}

// The widest bend (sine) within which a joint wrap's side draws its plane (jointWrapWays): 0.1, about 6 degrees.
constexpr double kSideBand = 0.1;
// The side's cosine with the outside of the bend (the long arc's bisector) from which a joint wrap takes the long way
// alone: 0.5 (a side within 60 degrees of the outside); from 0 to it the two ways blend (jointWrapWays).
constexpr double kWayRamp = 0.5;

namespace {

// The wrap in the plane (ex, ey) round the sphere (J, rr) from O (angle 0) to I (angle aI), counter-clockwise for
// dir = 1, clockwise for -1; straight when the line clears the sphere that way.
void planarWrap(const Vec3& O, const Vec3& I, const Vec3& J, double rr, double dO, double dI, const Vec3& ex,
                const Vec3& ey, double ccw, int dir, ActionPath& path) {
  const double sweep = dir > 0 ? ccw : kTwoPi - ccw;
  const double dOa = std::acos(rr / dO), dIa = std::acos(rr / dI);
  const double span = sweep - dOa - dIa;
  if (span <= 0) return straightPath(O, I, path);
  const Vec3 n = ex.cross(ey);
  const double a1 = dir * dOa;
  const Vec3 start = std::cos(a1) * ex + std::sin(a1) * ey;
  const double a2 = dir * (sweep - dIa);
  const Vec3 T1 = J + rr * start;
  const Vec3 T2 = J + rr * (std::cos(a2) * ex + std::sin(a2) * ey);
  path.count = 3;
  path.pieces[0] = linePiece(O, T1);
  PathPiece& arc = path.pieces[1];
  arc = PathPiece();
  arc.kind = PieceKind::Arc;
  arc.center = J;
  arc.radius = rr;
  arc.start = start;
  arc.travel = (dir * n).cross(start);
  arc.angle = span;
  arc.length = rr * span;
  path.pieces[2] = linePiece(T2, I);
  finish(path, true);
}

}  // namespace

void jointWrapWays(const Vec3& O, const Vec3& I, const Vec3& J, double r, const Vec3& side, ActionPath& shortWay,
                   ActionPath& longWay, double& longWeight) {
  longWeight = 0.0;
  const Vec3 o = O - J, i = I - J;
  const double dO = o.norm(), dI = i.norm();
  if (!(r > 0) || dO < 1e-12 || dI < 1e-12) {
    straightPath(O, I, shortWay);
    longWay = shortWay;
    return;
  }
  const Vec3 ex = o / dO;
  const double rr = std::min({r, 0.999 * dO, 0.999 * dI});
  // The plane of the wrap holds O and J, and I where the path bends by more than beta, the sphere's angular
  // radius rr / min(dO, dI) capped at kSideBand (the geodesic). As O, J and I come into line (a straight limb at
  // rest) that plane would swing with any rounding, a quarter turn round the joint for a bend too small to see,
  // so within beta the side direction (the muscle's side of the joint) draws it: its in-plane axis ey is the
  // principal axis of
  //   a a^T + w s s^T,  a = I's offset across ex / dI (|a| = sine of the bend), s = the unit side across ex,
  //   w = beta^2 (1 - |a|^2 / beta^2)^2 for |a| < beta, else 0;
  // continuous in O, I and side except where a lies across s with |a|^2 = w (a bend across the side, where
  // the plane turns from the side's to the bend's). Within beta I lies off the plane and the path is not the
  // geodesic; the cap keeps that band to bends of a few degrees for the wide wraps (an ankle's retinaculum).
  Vec3 s = side - side.dot(ex) * ex;
  if (s.norm() < 1e-12 * std::max(side.norm(), 1e-300)) s = ex.unitOrthogonal();  // no usable side
  s.normalize();
  const Vec3 v = ex.cross(s);
  const Vec3 bend = (i - i.dot(ex) * ex) / dI;  // a
  const double beta2 = std::pow(std::min(rr / std::min(dO, dI), kSideBand), 2), bend2 = bend.squaredNorm();
  const double w = bend2 < beta2 ? beta2 * std::pow(1.0 - bend2 / beta2, 2) : 0.0;
  const double au = bend.dot(s), av = bend.dot(v);
  const double phi = 0.5 * std::atan2(2.0 * au * av, au * au + w - av * av);
  const Vec3 ey = std::cos(phi) * s + std::sin(phi) * v;

  // In the plane: O at angle 0, I at angle aI. The long way goes round the outside of the bend; the side's cosine c
  // with that way's bisector (its in-plane share included) weighs it: smoothstep(c / kWayRamp), so a side in the bend
  // or beside the joint (c <= 0) takes the short way, one within 60 degrees of the outside the long way. Where the two
  // ways trade names (a straight line through J, where the side draws the plane and so names one way clearly) the
  // weight flips between 0 and 1 with the same path either side. A NaN side weighs 0.
  const double aI = std::atan2(i.dot(ey), i.dot(ex));
  const double ccw = wrapAngle(aI);
  const int longDir = ccw > kPi ? 1 : -1;  // the counter-clockwise way is the long one when it sweeps past pi
  const double sideNorm = side.norm();
  const double c = sideNorm > 0
                       ? longDir * (side.dot(ex) * std::cos(0.5 * ccw) + side.dot(ey) * std::sin(0.5 * ccw)) / sideNorm
                       : 0.0;
  const double t = std::clamp(c / kWayRamp, 0.0, 1.0);
  longWeight = std::isfinite(t) ? t * t * (3.0 - 2.0 * t) : 0.0;
  planarWrap(O, I, J, rr, dO, dI, ex, ey, ccw, -longDir, shortWay);
  planarWrap(O, I, J, rr, dO, dI, ex, ey, ccw, longDir, longWay);
}

void jointWrapPath(const Vec3& O, const Vec3& I, const Vec3& J, double r, const Vec3& side, ActionPath& path) {
  ActionPath shortWay, longWay;
  double longWeight;
  jointWrapWays(O, I, J, r, side, shortWay, longWay, longWeight);
  path = longWeight > 0.5 ? longWay : shortWay;
}

void boneWrapPath(const Vec3& O, const Vec3& I, const Vec3& axisOrigin, const Vec3& e1, const Vec3& e2,
                  const Vec3& axis, double r, int side, ActionPath& path) {
  const Vec3 o = O - axisOrigin, i = I - axisOrigin;
  const double hO = o.dot(axis), hI = i.dot(axis);
  const double xO = o.dot(e1), yO = o.dot(e2), xI = i.dot(e1), yI = i.dot(e2);
  const double rhoO = std::hypot(xO, yO), rhoI = std::hypot(xI, yI);
  if (!(r > 0) || rhoO < 1e-12 || rhoI < 1e-12) return straightPath(O, I, path);
  side = side >= 0 ? 1 : -1;
  const double rr = std::min({r, 0.999 * rhoO, 0.999 * rhoI});
  const double phiO = std::atan2(yO, xO), phiI = std::atan2(yI, xI);
  const double sweep = side > 0 ? wrapAngle(phiI - phiO) : wrapAngle(phiO - phiI);
  const double dOa = std::acos(rr / rhoO), dIa = std::acos(rr / rhoI);
  const double span = sweep - dOa - dIa;
  if (span <= 0) return straightPath(O, I, path);

  // Unrolled, the whole path is one straight line: the height grows linearly with horizontal length.
  const double lO = std::sqrt(rhoO * rhoO - rr * rr), lI = std::sqrt(rhoI * rhoI - rr * rr);
  const double arcLen = rr * span;
  const double rise = (hI - hO) / (lO + arcLen + lI);
  const double h1 = hO + rise * lO, h2 = h1 + rise * arcLen;
  const double phi1 = phiO + side * dOa, phi2 = phi1 + side * span;
  auto onCylinder = [&](double phi, double h) {
    return axisOrigin + rr * (std::cos(phi) * e1 + std::sin(phi) * e2) + h * axis;
  };
  path.count = 3;
  path.pieces[0] = linePiece(O, onCylinder(phi1, h1));
  PathPiece& hx = path.pieces[1];
  hx = PathPiece();
  hx.kind = PieceKind::Helix;
  hx.axisOrigin = axisOrigin;
  hx.e1 = e1;
  hx.e2 = e2;
  hx.axis = axis;
  hx.radius = rr;
  hx.phi1 = phi1;
  hx.dphi = span;
  hx.h1 = h1;
  hx.slope = rise * rr;
  hx.side = side;
  hx.length = std::hypot(arcLen, h2 - h1);
  path.pieces[2] = linePiece(onCylinder(phi2, h2), I);
  finish(path, true);
}

// ============================================================================
// Evaluation
// ============================================================================

void pointAt(const ActionPath& path, double sigma, Vec3& point, Vec3& tangent) {
  double local;
  const int k = locate(path, sigma, local);
  pointInPiece(path.pieces[k], local, point, tangent);
}

Mat3 frameAt(const ActionPath& path, const Mat3& F0, double sigma) {
  Mat3 F;
  Vec3 p;
  framesAt(path, F0, &sigma, 1, &F, &p);
  return F;
}

void framesAt(const ActionPath& path, const Mat3& F0, const double* sigmas, int n, Mat3* frames, Vec3* points) {
  int piece = 0;
  double pieceStart = 0;
  Mat3 Fs = F0;  // frame at the start of `piece`
  for (int q = 0; q < n; ++q) {
    const double sigma = std::clamp(sigmas[q], 0.0, path.length);
    while (piece + 1 < path.count && sigma > pieceStart + path.pieces[piece].length) {
      Fs = frameInPiece(path.pieces[piece], Fs, path.pieces[piece].length);
      pieceStart += path.pieces[piece].length;
      ++piece;
    }
    const double local = std::min(sigma - pieceStart, path.pieces[piece].length);
    Vec3 tangent;
    pointInPiece(path.pieces[piece], local, points[q], tangent);
    frames[q] = frameInPiece(path.pieces[piece], Fs, local);
  }
}

}  // namespace myoskin::paths
