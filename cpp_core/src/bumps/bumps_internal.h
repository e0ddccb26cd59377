// Internals shared by the bump stage (stages 3-4): the cleaned section polygon, triangle adjacency and the
// regions merged by the semicircle rule. Not part of the public API.
#pragma once
#include <array>
#include <vector>

#include "myoskin/bumps.h"
#include "myoskin/types.h"

namespace myoskin::detail {

// A section polygon after validation: consecutive exact duplicates (also across the wrap) are merged.
struct SectionPolygon {
  std::vector<Vec2> points;    // #M distinct consecutive points, the caller's coordinates
  std::vector<int> original;   // #M: cleaned index -> polygon row (the first row of its duplicate run)
  std::vector<int> cleanedOf;  // #P: polygon row -> cleaned index
  int orientation = 1;         // +1 counter-clockwise, -1 clockwise (sign of the area)
  double area = 0.0;           // absolute area
  Vec2 centroid = Vec2::Zero();  // area centroid
  double scale = 1.0;          // a power of two with max |coordinate| * scale in [0.5, 1)

  int size() const { return static_cast<int>(points.size()); }
  int next(int i) const { return i + 1 == size() ? 0 : i + 1; }
  int prev(int i) const { return i == 0 ? size() - 1 : i - 1; }
  // Number of edges from i to j going forward (0 when i == j).
  int forward(int i, int j) const { return j >= i ? j - i : j - i + size(); }
};

// Validates and cleans a polygon. Throws InputError for fewer than 3 distinct points, non-finite or
// out-of-range (> 1e150) coordinates, or zero area.
SectionPolygon cleanSection(const Points2& polygon);

// Inside triangles in cleaned indices with their neighbours.
struct TriangleAdjacency {
  std::vector<std::array<int, 3>> vertices;   // cleaned indices, counter-clockwise in space
  std::vector<std::array<int, 3>> neighbours;  // across the edge opposite vertex k; -1 on the polygon boundary
  std::vector<int> boundaryEdges;              // 0 junction, 1 sleeve, 2 terminal, 3 (a lone triangle)
};

// Adjacency of a triangulation of `section` (rows index the original polygon). Throws InputError when the
// triangles are not a triangulation of the polygon (wrong count, bad indices, edges used more than twice).
TriangleAdjacency buildAdjacency(const SectionPolygon& section, const Triangles& triangles);

// A region merged by the semicircle rule: a state where merging stopped (a candidate bump).
struct MergedRegion {
  enum class Stop { Outside, Junction, Met };  // a vertex fell outside / reached a junction / met a region
  int terminal = -1;          // the terminal triangle where merging started (the first one for combined regions)
  std::vector<int> terminals;  // all terminal triangles merged into the region
  int tip = -1;               // the terminal triangle's vertex between its two boundary edges (cleaned index)
  int first = -1, last = -1;  // arc ends = the diameter, cleaned indices; the arc runs forward from first
  int triangles = 0;          // triangles merged (>= 1)
  int junction = -1;          // the junction triangle it stopped at (Stop::Junction)
  Stop stop = Stop::Outside;
  bool absorbed = false;      // later merged through its junction into a larger region
};

// The paper's semicircle rule from every terminal triangle. `tolerance` is relative to the radius. With
// `absorbJunctions`, a junction triangle two of whose branches merged up to it (both inside their
// semicircles) joins them into one region that merges on across its third edge (the branch pruning of the
// chordal axis the paper cites, ref. 21); every stopped state is returned, including absorbed ones.
// Merging never crosses a diagonal in `splits` (cleaned index pairs; a region whose diameter is one stops there).
std::vector<MergedRegion> semicircleRegions(const SectionPolygon& section, const TriangleAdjacency& adjacency,
                                            double tolerance, bool absorbJunctions,
                                            const std::vector<std::array<int, 2>>& splits = {});

}  // namespace myoskin::detail
