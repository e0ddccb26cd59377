// Action paths (Yang & Zhang 2006, "Muscle Movement"; DESIGN.md section 5): the path a muscle's root
// follows from origin to insertion under the current pose. Three kinds:
//   straight     one line origin -> insertion;
//   joint wrap   line - circular arc over a sphere at a joint - line, in the plane of O, I and the centre;
//   bone wrap    line - helix on a cylinder round a bone - line (the cylinder unrolled makes the helix
//                and both lines one straight geodesic: heights grow with one constant slope).
// A path is at most three analytic pieces, C1 continuous; points, tangents and a rotation-minimising
// frame (exact per piece: constant on lines, rotation about the plane normal on arcs, the helix's
// Frenet frame turned by -torsion * arc length) are evaluated in O(1) at any arc length.
#pragma once
#include "myoskin/types.h"

namespace myoskin::paths {

// ============================================================================
// Geometry of one posed path
// ============================================================================

enum class PieceKind { Line, Arc, Helix };

struct PathPiece {
  PieceKind kind = PieceKind::Line;
  double length = 0.0;
  // Line: from a to b.
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
  // Arc: centre, radius, unit start direction (centre -> start point), unit in-plane direction of
  // travel at the start, signed angle swept (radians, >= 0; direction is carried by `travel`).
  Vec3 center = Vec3::Zero(), start = Vec3::UnitX(), travel = Vec3::UnitY();
  double radius = 0.0, angle = 0.0;
  // Helix on the cylinder (axisOrigin + h * axis, radius r, in-plane basis e1, e2): angle phi1 at the
  // start, side (+1: phi grows, -1: phi falls), dphi >= 0 swept, h1 start height, slope dh/dpsi.
  Vec3 axisOrigin = Vec3::Zero(), e1 = Vec3::UnitX(), e2 = Vec3::UnitZ(), axis = Vec3::UnitY();
  double phi1 = 0.0, dphi = 0.0, h1 = 0.0, slope = 0.0;
  int side = 1;
};

struct ActionPath {
  PathPiece pieces[3];
  int count = 0;
  double length = 0.0;
  bool wrapped = false;
};

// ============================================================================
// Construction (posed origin O, insertion I in mesh space)
// ============================================================================

// Straight line O -> I.
void straightPath(const Vec3& O, const Vec3& I, ActionPath& path);

// Around a sphere (centre J, radius r), both ways round: each is the geodesic in the plane of O, I and J where the
// bend at J is larger than the sphere's angular radius r / min(|O - J|, |I - J|) (at most 0.1); within that band
// `side` (a direction from J: the muscle's side of the joint) draws the plane towards itself, and fixes it alone when
// O, I, J are collinear (action_path.cpp). Each way is straight when the line O-I clears the sphere that way. When O
// or I lie inside the sphere the radius used shrinks to 0.999 of their distance to J (documented fallback; the path
// stays continuous and finite).
//
// shortWay goes round inside the bend, longWay round its outside; longWeight in [0, 1] is smoothstep(c / 0.5), c the
// cosine of `side` with the outside of the bend (the long arc's bisector, over |side|: its part across the plane
// counts as none): 1 for a side within 60 degrees of the outside, 0 for one in the bend or beside the joint. The two
// ways blended by it (MuscleRig) move continuously with O, I and side except where the plane turns (above); the
// weight itself flips between 0 and 1 where the ways trade names at a straight limb (the same path either side).
// jointWrapPath is the way that weighs more (the short way on a tie).
void jointWrapWays(const Vec3& O, const Vec3& I, const Vec3& J, double r, const Vec3& side, ActionPath& shortWay,
                   ActionPath& longWay, double& longWeight);
void jointWrapPath(const Vec3& O, const Vec3& I, const Vec3& J, double r, const Vec3& side, ActionPath& path);

// Around the infinite cylinder through axisOrigin along unit `axis` (e1, e2 complete a right-handed
// frame: e1 x e2 = axis), radius r, going round with phi increasing (side = +1, phi measured from e1
// towards e2) or decreasing (side = -1). Straight when no wrap is needed on that side. The side is kept
// as posed: when I's angle round the axis passes O's against the side, the path goes from straight to
// almost a full turn (pick the side that matches the rest layout). O or I inside the cylinder: the radius
// shrinks as for the sphere.
void boneWrapPath(const Vec3& O, const Vec3& I, const Vec3& axisOrigin, const Vec3& e1, const Vec3& e2,
                  const Vec3& axis, double r, int side, ActionPath& path);

// ============================================================================
// Evaluation
// ============================================================================

// Point and unit tangent at arc length sigma in [0, length] (clamped).
void pointAt(const ActionPath& path, double sigma, Vec3& point, Vec3& tangent);

// Rotation-minimising frame carried from the start frame F0 (columns X, Y = tangent at 0, Z) to arc
// length sigma. Returns the frame (orthonormal, Y = tangent at sigma).
Mat3 frameAt(const ActionPath& path, const Mat3& F0, double sigma);

// Frames at several increasing arc lengths at once (cheaper than frameAt per station): frames[i] at
// sigmas[i]; sigmas must be non-decreasing.
void framesAt(const ActionPath& path, const Mat3& F0, const double* sigmas, int n, Mat3* frames, Vec3* points);

}  // namespace myoskin::paths
