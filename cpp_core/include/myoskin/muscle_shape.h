// Muscle surfaces that read as muscles (issue 14 item 4): inside/outside the skin by winding number, the shape
// measures of a lofted muscle (watertight, self-intersections, twist, spikes, vertices outside the skin) and the
// containment that keeps a lofted muscle inside the skin at rest.
#pragma once
#include <memory>

#include "myoskin/mesh.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Inside the skin
// ============================================================================

// The generalized winding number of a triangle soup (Jacobson et al. 2013), evaluated hierarchically (Barill et
// al. 2018, first-order far field): about 1 inside a closed outward skin and 0 outside, and still a usable
// inside/outside answer for an open skin or one in several pieces. Built once on the skin (#V by 3, #F by 3), then
// queried (thread-safe, no allocation per query). Throws InputError on an empty or non-finite mesh or bad indices.
class SkinWinding {
 public:
  SkinWinding(const Points& vertices, const Triangles& triangles);

  double windingNumber(const Vec3& p) const;
  bool inside(const Vec3& p) const { return windingNumber(p) >= 0.5; }
  double distance(const Vec3& p) const;  // unsigned distance to the nearest triangle

  struct Impl;

 private:
  std::shared_ptr<const Impl> impl_;
};

// ============================================================================
// Shape measures of one lofted muscle surface
// ============================================================================

struct MuscleShape {
  bool watertight = false;    // closed 2-manifold, consistently oriented, one component, positive volume
  double volume = 0.0;        // enclosed (positive when outward)
  int selfIntersections = 0;  // intersecting triangle pairs (selfIntersections in skinning.h)
  double maxTwist = 0.0;      // degrees: the largest turn of an elongated ring's major axis (aspect >= 1.25) to the
                              // next ring's, mod 180 and projected into the ring plane
  double maxSpike = 0.0;      // the largest |(v - mean of v's neighbours) . normal| over the ring vertices, in units of v's ring's
                              // mean radius (at least a quarter of the largest ring's): a few hundredths on a smooth
                              // loft, tenths where a ring juts out of its neighbours
  double maxDihedral = 0.0;   // degrees: the largest angle between the normals of two triangles sharing an edge
  int outside = 0;            // surface vertices outside the skin (winding number < 0.5); 0 without a skin
  double maxOutside = 0.0;    // their largest distance from the skin in units of the limb radius
};

// Measures a surface lofted by loftMuscleSurface (rings of `ringVertices` vertices from the origin to the
// insertion, then the origin and the insertion pole). `skin` may be null (then no outside figures);
// `limbRadius` > 0 scales maxOutside. Throws InputError when the surface does not have that layout.
MuscleShape measureMuscleShape(const Mesh& surface, int ringVertices, const SkinWinding* skin = nullptr,
                               double limbRadius = 1.0);

// ============================================================================
// Keeping a muscle inside the skin
// ============================================================================

// Pulls a lofted surface (loftMuscleSurface's layout, as above) inside the skin: each ring vertex moves towards its
// ring's centre by the largest share s in [0, 1] for which the point (1 + margin) s of the way out still lies inside
// the skin (so it stays `margin` of its own radius inside); the shares are then eroded and averaged over a few
// neighbours around and along the rings (never above a vertex's own share), so a clamped stretch stays smooth.
// End rings whose centres lie outside the skin (a tendon running past the end of an open skin) are cut off, the end
// closing at the point where the centre line leaves the skin (the surface keeps the layout, with fewer rings); a ring
// inside them whose centre lies outside is pulled towards the nearest ring centre inside; a pole outside moves
// towards its ring's centre the same way. Nothing moves when no ring centre lies inside. Returns the vertices moved
// or cut off.
int containMuscleSurface(Mesh& surface, int ringVertices, const SkinWinding& skin, double margin = 0.1);

}  // namespace myoskin
