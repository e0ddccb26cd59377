// Procedural muscular test characters with known muscles (ground truth for extraction tests,
// the demo and benchmarks). Deterministic for a given options struct.
#pragma once
#include <string>
#include <vector>

#include "myoskin/character.h"

namespace myoskin {

// A known muscle: centre line (polyline, origin -> insertion) and belly radius at each point.
struct TrueMuscle {
  std::string name;
  std::string bone;  // the bone it lies along
  std::vector<Vec3> centerLine;
  std::vector<double> radius;   // radius of the muscle's cross-section at each centre-line point
  double peakRadius = 0.0;
};

struct SyntheticArmOptions {
  unsigned seed = 1;            // varies muscle sizes/placement slightly (0 = the canonical arm)
  double muscleScale = 1.0;     // 0 gives a smooth arm with no muscles
  int ringsPerMetre = 400;      // skin resolution along the arm
  int segmentsAround = 96;      // skin resolution around the arm
};

struct SyntheticCharacter {
  Character character;
  std::vector<TrueMuscle> muscles;
};

// A right arm along +X from the shoulder (clavicle, upper_arm, forearm, hand), Z up, palm down, with
// deltoid, biceps, triceps, brachialis and forearm flexor/extensor bellies as bumps of the skin.
// Closed, manifold, outward-oriented skin; smooth skeleton weights blended across the elbow and wrist.
//
// Conventions: the arm axis is the X axis (y = z = 0); the cross-section angle theta is measured around
// +X from +Y towards +Z. +Z = anterior (biceps, elbow crease), -Z = posterior (triceps), -Y = lateral
// (deltoid insertion, brachialis, forearm extensors), +Y = medial (forearm flexors); the hand is flat in
// the XY plane with the palm facing -Z. Bones: clavicle (root, from the origin) -> upper_arm -> forearm
// -> hand, rest matrices boneMatrix(head, tail, -Y) (Blender roll 0: bone Z = world +Z).
// Ground truth: each TrueMuscle's centre line is the centre of the elliptical muscle cross-section (in the
// plane x = const) under its skin bump; the bump's skin is that ellipse pushed out radially by a 3 mm skin
// layer and smoothly merged with the muscle-free arm. radius = sqrt(a * b) of that ellipse. The centre
// line covers the part of the belly whose radius exceeds 10 % of its peak.
// Throws InputError for ringsPerMetre < 20, segmentsAround < 8 or a negative/non-finite muscleScale.
SyntheticCharacter makeSyntheticArm(const SyntheticArmOptions& options = {});

// Ground truth as JSON (format "myoskin.true_muscles", version 1), positions in metres:
// {"format","version","muscles":[{"name","bone","center_line":[[x,y,z],...],"radius":[...],"peak_radius"}]}
std::string trueMusclesToJson(const std::vector<TrueMuscle>& muscles);
// Parses and validates (finite values, matching sizes, non-negative radii); throws InputError.
std::vector<TrueMuscle> trueMusclesFromJson(const std::string& text);

}  // namespace myoskin
