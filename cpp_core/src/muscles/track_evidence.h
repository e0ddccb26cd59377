// Track-level evidence for faint bellies (issue 13, item 6): a chain of bumps linked along one limb segment is judged
// as a whole track, by the shape of its significance profile along its planes, not by any one section's bump.
#pragma once
#include <utility>
#include <vector>

#include "myoskin/extraction.h"

namespace myoskin::detail {

// ============================================================================
// Closed spindles: a belly's track along its limb
// ============================================================================

// What makes a track a closed spindle (ChainFilterOptions::spindleEnds, spindleLength, spindleSteepness). Every
// quantity is relative: significance to the section's protrusion threshold (itself relative to the section's radius),
// steepness is protrusion / skin arc length, the track's length is counted in its own bumps' radii.
struct SpindleOptions {
  double ends = 0.85;       // both end links stay below this share of the track's peak significance (0 = off)
  double minLength = 2.5;   // the track's length (its first to its last bump centre) is at least this many times its
                            // bumps' mean radius sqrt(a b), over 3 or more consecutive planes
  double steepness = 0.04;  // its bumps' mean protrusion / skin arc length, at least
  double tolerance = 0.05;  // the rise to the peak and the fall from it may reverse by this share of the peak between
                            // neighbouring planes: the sampling noise of one section's bump height. Measured on the
                            // generated tune seeds 1-11: 0.02-0.08 keep the same chains; 0.15 adds MakeHuman neutral's
                            // lower-leg chains at spacing x 1.05 and 1.1
};

// The track's (plane order, significance) of its real links, in plane order.
std::vector<std::pair<int, double>> trackProfile(const MuscleChain& chain, const std::vector<SectionBumps>& sections);

// The chain's bumps' mean steepness: protrusion / skin arc length (relative / width of each bump; 0 when unmeasured).
double chainSteepness(const MuscleChain& chain, const std::vector<SectionBumps>& sections);

// True when the chain is a closed spindle: its real links lie on 3 or more consecutive planes over a length of at
// least minLength of their mean radius (a belly is longer than it is wide; a fold or a joint's crease is not), their
// significance rises to a peak and falls from it (each reversal at most `tolerance` of the peak), both end links stay
// below `ends` of the peak, and its bumps are steep on average. The shape is the evidence: no link need reach the
// significance threshold (a faint belly's bumps lie at 0.5-1 of it over its whole length), while a body contour cut
// off by the plane range (a fold running into a joint), soft relief that comes and goes along the limb (several
// peaks) or a broad low swell does not have it.
bool closedSpindle(const MuscleChain& chain, const std::vector<SectionBumps>& sections, const SpindleOptions& options);

}  // namespace myoskin::detail
