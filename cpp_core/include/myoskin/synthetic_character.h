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
  // Per centre-line point (or empty = unknown): how far the muscle raises the skin there, along the ray from the limb
  // axis through the point, over the same body without this muscle (>= 0, the character's units). Where a muscle
  // dives to its tendons, lies under a neighbour or inside the trunk's union, the skin does not show it: the visible
  // length (measureExtraction) is where relief >= half the muscle's peak relief.
  std::vector<double> relief;
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

// ============================================================================
// Varied whole bodies (issue 13, "Any character": a test set that cannot be tuned to)
// ============================================================================

enum class BodyKind { Biped, Quadruped };
// How the bones are called: Rigify-like rig names (upper_arm.L, thigh.R, hips, spine, neck, head), Blender's defaults
// in creation order (Bone, Bone.001, ...), German (Oberarm.L, Oberschenkel.R, Wirbelsäule), Japanese (上腕.L, 太もも.R),
// or none ("joint_0", "joint_1", ...). Only names change: skin, weights and bone order are the same under every scheme.
enum class BoneNaming { Rig, BlenderDefault, German, Japanese, Unnamed };

struct SyntheticBodyOptions {
  unsigned seed = 1;                 // proportions (limb lengths and radii, trunk, pose) and muscle jitter; 0 = canonical
  BodyKind kind = BodyKind::Biped;
  double muscleScale = 1.0;          // 0 gives a smooth body with no muscles
  double scale = 1.0;                // overall size factor applied last (1 = metres; 0.01, 100: other units)
  BoneNaming naming = BoneNaming::Rig;
  bool split = false;                // several meshes (trunk + head, arms or front legs, legs), as a glTF loader reads
                                     // them: pieces that meet at open boundaries, welded by position (Character::pieces)
  double cellSize = 0.0;             // skin resolution: grid spacing of the surface extraction in metres (before
                                     // `scale`); 0 = 9 mm (a limb radius is 6 of them)
};

// A whole character: the skin is the zero set of a smooth union (polynomial smooth minimum, 3 cm) of star-shaped
// generalized cylinders around straight axes with rounded ends -- the trunk, neck and head, tail, and the limbs, whose
// skin is the synthetic arm's (muscle-free limb merged with elliptical muscle bellies, limb_model.h) -- meshed by
// marching tetrahedra on a regular grid: one closed, manifold, outward-oriented skin (also when split).
//   Biped (about 1.75 m, Z up, facing -Y, left side at +X, A-pose): hips (root) -> spine -> chest -> neck -> head;
//     chest -> shoulder -> upper_arm -> forearm -> hand on each side; hips -> thigh -> shin -> foot on each side.
//     Muscles per arm: biceps, triceps, brachialis, forearm flexors and extensors; per leg: quadriceps,
//     hamstrings, gastrocnemius, tibialis anterior.
//   Quadruped (trunk along Y, head at -Y): hips (root) -> spine -> chest -> neck -> head; hips -> tail -> tail.001 ->
//     tail.002; chest -> shoulder (scapula) -> front_thigh -> front_shin -> front_foot; hips -> thigh -> shin -> foot.
//     Muscles per front leg: triceps, biceps, forearm extensors and flexors; per hind leg: quadriceps, hamstrings,
//     gastrocnemius, tibialis anterior.
// Left and right are mirror images. Proportions vary with the seed: limb lengths +-12 %, limb thickness +-15 %, trunk
// size +-10 %, the arms' A-pose angle 30-50 degrees, overall size +-10 %. Weights: inverse eighth power of the distance
// to each bone segment, four heaviest, normalised (smooth, blended over about a limb radius at each joint).
// Ground truth as the arm's (TrueMuscle, names like "biceps.L", bone = the bone's name under the naming scheme),
// in the character's space and units. Throws InputError for a negative or non-finite muscleScale, a scale or
// cellSize that is not finite and positive (cellSize 0 = default), or a cellSize above 2 cm.
SyntheticCharacter makeSyntheticBody(const SyntheticBodyOptions& options = {});

const char* bodyKindName(BodyKind kind);        // "biped", "quadruped"
const char* boneNamingName(BoneNaming naming);  // "rig", "blender", "german", "japanese", "unnamed"

// Ground truth as JSON (format "myoskin.true_muscles", version 1), positions in metres:
// {"format","version","muscles":[{"name","bone","center_line":[[x,y,z],...],"radius":[...],"peak_radius","relief":[...]}]}
// ("relief" is optional when read: one value per centre-line point, or absent/empty = unknown)
std::string trueMusclesToJson(const std::vector<TrueMuscle>& muscles);
// Parses and validates (finite values, matching sizes, non-negative radii and relief); throws InputError.
std::vector<TrueMuscle> trueMusclesFromJson(const std::string& text);

}  // namespace myoskin
