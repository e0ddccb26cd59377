// Stages 3-4 of extraction: bumps on a section polygon (constrained Delaunay triangulation, triangle
// classification, the paper's semicircle rule, a significance test) and the weighted ellipse per bump.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "myoskin/types.h"

namespace myoskin {

enum class TriangleKind { Junction = 0, Sleeve = 1, Terminal = 2 };  // number of boundary edges

// The inside triangles of a section polygon's constrained Delaunay triangulation.
struct SectionTriangulation {
  Triangles triangles;             // #T by 3 indices into the polygon, counter-clockwise
  std::vector<TriangleKind> kinds;  // #T
  std::vector<std::array<int, 2>> diagonals;  // the requested diagonals forced into it (polygon indices); with
                                             // one, triangles are ordered by their vertices' distance along the
                                             // polygon from its first end, the same on both sides of the split
};

// Throws InputError for fewer than 3 points, non-finite points or a self-intersecting polygon.
// `diagonals` (polygon index pairs, optional) are forced into the triangulation as constrained edges, so
// that no triangle crosses them: a bilaterally symmetric section split along its mirror axis triangulates
// as two mirror images (an unsplit one cannot: the mirrored point pairs across the axis form cocircular
// trapezoids whose diagonal the Delaunay rule leaves to chance). A diagonal that is not a proper inner
// diagonal (adjacent or equal ends, leaving the polygon, touching the boundary or another diagonal) is
// left out; `diagonals` of the result lists the ones used. The bump stage does not merge across them (a
// split is no chord of the skin) and does not join hills on its two sides.
SectionTriangulation triangulateSection(const Points2& polygon, const std::vector<std::array<int, 2>>& diagonals = {});

// The diagonal along a section's plane y axis (a torso section's mirror axis, CuttingPlane::mirrorAxis): from
// the vertex nearest the +y axis crossing to the vertex nearest the -y axis crossing of the polygon (plane
// coordinates, the plane origin inside). {-1, -1} when the polygon does not cross both half axes.
std::array<int, 2> axisDiagonal(const Points2& polygon);

struct BumpOptions {
  double minProtrusion = 0.0035;     // metres: a bump must stand this far out of its smooth base
  double minRelativeProtrusion = 0.05;  // ... and this fraction of the section's mean radius
  double minWidthFraction = 0.04;    // bump arc length / section perimeter, at least
  double maxWidthFraction = 0.5;     // and at most
  double semicircleTolerance = 0.01;  // a vertex counts as inside the semicircle within this share of its radius
  bool absorbJunctions = true;  // a junction two of whose branches merged up to it joins them and merging goes
                                // on (the chordal-axis pruning the paper cites); false = stop at every junction
                                // (the paper's text literally: densely sampled sections then give tiny regions)
  double supportTolerance = 0.3;  // the base is the candidate shape (lower envelope, or it or a circle refitted
                                  // to the skin within this share of the threshold of it) that most of the
                                  // section follows within that tolerance; 0 = the lower envelope only
  int baseHarmonics = 0;  // > 0: the base is a radial Fourier series of this order (lower envelope, refitted
                          // to its support) instead of a conic: for trunk sections, whose oval, bean or
                          // rounded-rectangle outline no conic follows (SectionBumpOptions::trunkHarmonics)
};

// A bump: a run of consecutive polygon vertices (the skin arc over a muscle belly).
struct Bump {
  int first = 0, last = 0;  // polygon indices of the arc ends (the diameter's endpoints); the arc runs in
                            // increasing index order (counter-clockwise for a counter-clockwise polygon) from
                            // first to last, wrapping around the end of the polygon
  int terminalTriangle = -1;  // where merging started
  int apex = 0;               // polygon index of the point that stands out most
  double protrusion = 0.0;    // metres: the apex's height above the smooth base shape, counted from the
                              // higher of the arc's lowest points on either side of it (its prominence)
  double significance = 0.0;  // protrusion relative to the threshold (>= 1 means kept)
};

// Bumps found by merging from every terminal triangle with the semicircle rule, kept when significant.
// `onSkin` (#P, optional): 0 on the straight chord that closes a clipped profile (SectionProfile::onSkin); such a
// profile's base support fades over a margin of its tolerance (see bump_significance.cpp). Throws InputError when
// its size is not the polygon's.
std::vector<Bump> findBumps(const Points2& polygon, const BumpOptions& options = {},
                            const SectionTriangulation* triangulation = nullptr,
                            const std::vector<char>* onSkin = nullptr);

// A section ellipse in plane coordinates: centre, angle of axis a from the x axis, semi-axes a >= b.
struct Ellipse2 {
  Vec2 center = Vec2::Zero();
  double angle = 0.0;
  double a = 0.0, b = 0.0;
};

// Weighted ellipse fit to a bump's arc (weights highest at the terminal triangle, falling away from it);
// the ellipse lies beneath the skin (inside the polygon, touching the arc from inside).
Ellipse2 fitBumpEllipse(const Points2& polygon, const Bump& bump, const SectionTriangulation& triangulation);

}  // namespace myoskin
