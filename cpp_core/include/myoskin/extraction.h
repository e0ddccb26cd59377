// Stages 5-9 of muscle extraction (DESIGN.md section 4; Yang & Zhang 2006, "Muscle Extraction"):
// link the bumps of consecutive sections into muscles, extend the root curve to origin and insertion
// with Hermite curves, loft a closed surface, name the muscles; plus the one-shot pipeline
// extractMuscles() that runs every stage (planes, profiles, bumps, ellipses, linking, ends, surface).
#pragma once
#include <map>
#include <string>
#include <vector>

#include "myoskin/bumps.h"
#include "myoskin/character.h"
#include "myoskin/muscle.h"
#include "myoskin/sections.h"
#include "myoskin/synthetic_character.h"
#include "myoskin/types.h"

namespace myoskin {

class SkinWinding;  // muscle_shape.h

// ============================================================================
// Options and results of the one-shot pipeline
// ============================================================================

struct LinkOptions {
  // Two bumps of consecutive sections link when the lateral distance of their ellipse centres (the
  // component perpendicular to the first plane's normal) is at most maxLateralFactor * the mean of
  // their semi-axes a, AND their angular positions around the bone differ by at most maxAngle radians.
  double maxLateralFactor = 0.9;
  double maxAngle = 0.45;       // radians (~26 degrees)
  int maxGap = 2;               // sections that may be missing between two linked bumps
  int minSections = 3;          // a muscle needs at least this many significant sections (and enough evidence:
                                // ChainFilterOptions::minEvidence)
  bool branches = true;         // join merging/splitting chains with a transition section
  double mergeFactor = 0.5;     // fragments of one belly (chains of a family whose centres come within this
                                // times their larger mean semi-axis a at the same or a neighbouring plane)
                                // are merged into one chain
  bool mergeAlternating = true;  // alternating fragments of one belly are merged too: chains of a family that share no
                                 // plane, alternate (their plane ranges overlap, every link within 1 + maxGap planes of
                                 // the other chain) and link somewhere (a pair within that reach passes the link test).
                                 // A belly whose apex alternates between two heads turns more than maxAngle over two
                                 // links, so the chain's turn limit splits it. Measured on MakeHuman at the default
                                 // spacing: the calf's gastrocnemius (planes 17, 18, 20 and 19, 22: evidence 5.1 and
                                 // 2.3) becomes one muscle (evidence 7.4, 4 strong sections), both sides; the neutral
                                 // body gains its inner upper arms at spacing x 0.925 only (8 against 20)
  double faintBelow = 0.0;      // faint links: real links whose significance is below faintBelow are kept only
  double faintRelative = 0.0;   // where they reach faintRelative x their chain's peak significance (after fragments
                                // merged; a transition section next to a dropped link goes too); 0 = keep every link
};

struct EndOptions {
  // The root curve's straight extension is searched for the nearest bone point up to this fraction of
  // the visible (sectioned) length beyond each end; near-ties (within tieTolerance metres) prefer the
  // point further out, so a muscle that runs parallel to its bone gets a tendon of that length.
  double maxExtensionFraction = 0.35;
  double tieTolerance = 0.005;  // measured on MakeHuman (spacing x 1.025): 4 mm put a calf muscle's insertion 1.1 cm
                                // apart on the two legs (its extension runs almost parallel to the shin)
  int samplesPerEnd = 6;        // Hermite samples added to the root curve on each side
  // A muscle whose origin and insertion lie on different bones of one chain crosses a joint: it gets a joint
  // wrap there (the sphere on the crossed bone's head farthest from the straight line; radius this times the
  // muscle's mean semi-axis b, at most 0.8 of either end's distance from the joint), so its action line bends
  // round the joint with the skeleton instead of cutting the corner. Measured on the synthetic arm (seeds 0-3,
  // shoulder swing 60 degrees): skin volume -1.1 to -1.8 % instead of -1.5 to -9.8 % (plain LBS -0.1 %);
  // 0 = straight lines (the paper's default).
  double jointWrapFraction = 0.3;
  // A limb or shoulder-girdle muscle (not a trunk muscle) whose ends lie on one segment split by twist bones
  // (twistSplits) acts on no joint (the end search
  // looks one bone further, which is the twist split): its end nearer a real joint is carried over it onto the next
  // bone, this fraction of that bone's length (or, at the proximal end, of the segment's first bone) past the joint,
  // as the biceps inserts on the forearm; an end the end search found across a real joint from the belly is
  // brought to at most this fraction of its bone's length past the joint, as the gastrocnemius arises just above
  // the knee. 0 = off.
  double spanCarry = 0.2;
  // A leg muscle's distal end that still lies on its belly's segment, the leg's last (the calf found from the thigh
  // down the shin, the tibialis anterior), is carried over the ankle onto the foot, spanCarry of the foot past the
  // joint along the shin, on the belly's side (spanDistalJoint): the calf's tendon reaches the heel behind the
  // ankle, so plantar flexion shortens it. Feet only (an extremity across the limb): the forearm's muscles onto
  // the hand cost the elbow (see spanDistalJoint). false = off.
  bool spanDistal = true;
};

struct SurfaceOptions {
  int ringVertices = 32;        // vertices around each lofted ellipse
  int capRings = 8;             // rings of each tapered cap (the pole vertex comes after them)
  int smoothingPasses = 2;      // 1-2-1 passes along the muscle over the rings' plane normals, ellipse angles (unwrapped)
                                // and semi-axes, after a median of three over the centres and semi-axes (a single
                                // outlying section), so neighbouring rings turn and grow smoothly; 0 = the sections as cut
  bool containInSkin = true;    // extraction: pull every lofted surface inside the skin (containMuscleSurface,
                                // muscle_shape.h), so that at rest no muscle vertex lies outside it
  double skinMargin = 0.1;      // ... keeping each ring vertex this share of its ring radius inside the skin
  double maxCapLength = 6.0;    // a tapered cap reaches at most this many end-ring radii (sqrt(a b)) towards its pole:
                                // a long tendon (the calf's onto the heel) would draw the taper into a needle
};

// Bumps per section (stage 3-4, extraction_stages.h findSectionBumps): the hysteresis, the trunk's Fourier base,
// the mesh-resolution floor and forced regions' floor. Lengths in metres at the reference body scale (BodyScaleOptions).
struct SectionBumpOptions {
  double forcedMinProtrusion = 0.0005;         // metres: bumps weaker than this are not forced either
  double weakFraction = 0.8;                   // hysteresis: bumps down to this share of the significance
                                               // threshold are linked too, so a muscle whose bump fades
                                               // towards its tendons (or under a neighbour) is followed further;
                                               // a muscle needs link.minSections significant sections.
                                               // 1 = none (the faint links below are separate). Measured (faintRelative 0): 0.8 follows the synthetic seed 2's
                                               // brachialis over 5 sections (46 % of its length: a miss), 0.5 over 7
                                               // (61 %: recall and precision 1.0 on seeds 0-3; with
                                               // profiles.mirrorLimbs MakeHuman's calves stay mirrored), but 0.5 also
                                               // lengthens the synthetic arm's biceps towards the elbow: the hybrid
                                               // skinning's elbow region at 35 degrees grows +6.5 % (0.6: +4.4 %)
                                               // where LBS loses 3.6 % (0.8: +2.9 %), failing test_hybrid_skinning
  double faintFraction = 0.5;                  // a second, conditional hysteresis: bumps from this share of the threshold
  double faintRelative = 0.36;                 // up to weakFraction are linked too, but a chain keeps them only where they
                                               // reach faintRelative of its own peak significance: a faint muscle is followed
                                               // further as it fades (under a neighbour, towards its tendons), a strong one is
                                               // not stretched over its tendons' soft relief (faintRelative 0 = off; linking
                                               // options LinkOptions::faintBelow/faintRelative). Measured on the synthetic arm:
                                               // seed 2's brachialis (peak 1.52) keeps its tails at 0.73 and 0.61 (7 sections,
                                               // 61 % covered: recall and precision 1.0 on seeds 0-3); the biceps' (peak 2.9)
                                               // at 0.62-0.70 stay off; seed 1's forearm flexors (peak 1.79) keep a 0.59 elbow
                                               // tail below faintRelative 0.335, and then the hybrid skinning's whole-arm volume
                                               // at 140 degrees grows more (+0.84 %) than LBS loses (-0.82 %). Works for
                                               // faintRelative 0.335-0.395.
  int trunkHarmonics = 4;                      // trunk sections (abdomen, chest, neck) measure bumps against a radial
                                               // Fourier base of this order (BumpOptions::baseHarmonics): a trunk's
                                               // bean or rounded-rectangle outline is not an oval, and against a conic
                                               // its whole flanks stood out as half-trunk "muscles"; 0 = conic base
  int minBumpCrossings = 3;                    // a bump must contain at least this many points where its section
                                               // crosses mesh edges: a narrower one is the mesh's own faceting (a
                                               // low-poly limb's corners stand out like bellies), not relief the
                                               // mesh resolves. 0 = off
};

// Chain filters (stage 5, filterChains): the length, evidence and height floors a linked chain must pass, and the
// cues that keep a chain below them (closed spindle, mirror twin). Heights are relative to the section's mean radius,
// evidence in sections of the default spacing, reaches in the chains' semi-axes: all body-relative.
struct ChainFilterOptions {
  double minEvidence = 6.6;                    // a muscle's evidence, the sum of its linked bumps' significance (faint and
                                               // weak links included) times plane spacing / the default spacing (1/80 of
                                               // the skin's largest extent), must reach this: 4 sections at 1.65x the
                                               // threshold, or 3 strong bellies at 2.2x. It varies smoothly with the plane
                                               // grid where a count of sections over the threshold jumps. Measured: synthetic
                                               // seed 2's brachialis 7.5 (the faintest true muscle); MakeHuman at the default
                                               // spacing: the muscular thigh's chain 6.75 (kept), the neutral forearm's 6.51
                                               // (dropped), so the two bodies' shortest chains lie close together; neutral
                                               // at most half of muscular at every spacing x 0.9-1.1 for 6.25-7.0 (with
                                               // link.minSections 4 instead: 5 of 9 spacings fail). 0 = off
  double minRelative = 0.09;                   // a muscle's bumps must on average stand out at least this share of
                                               // their sections' mean radius (a belly is large for its limb; soft
                                               // body contours of thick sections are not); forced ones are kept.
                                               // The average takes the bumps the hysteresis links outright (at least
                                               // SectionBumpOptions::weakFraction of the threshold): faint tail links
                                               // extend a muscle without diluting its height.
                                               // Measured: synthetic muscles 0.106-0.33, MakeHuman neutral's
                                               // flattest contours 0.083-0.085 (0 = off; continuous chains: continuousEvidence)
  double continuousEvidence = 7.75;            // a continuous limb chain, whose linked bumps of at least weakFraction
                                               // stand out in every plane between its ends and whose evidence (see
                                               // minEvidence) reaches this, is held to the height one bump needs
                                               // (BumpOptions::minRelativeProtrusion, 0.05) instead of minRelative: a big
                                               // belly on a thick limb rounds the whole section, so its relief against the
                                               // base is small but steady; soft contours of that height come and go along
                                               // the limb. Measured on MakeHuman, spacing x 0.9-1.1: the muscular male's
                                               // quadriceps stand out 0.061-0.074 of the thigh's radius over 6-8 consecutive
                                               // planes (evidence 8.85-10.2; kept at every spacing, both sides); the neutral
                                               // body's flattest chains that miss minRelative (0.076-0.087) skip 2-4 planes
                                               // or are short (its only continuous one: evidence 7.25 at x 0.95), so its
                                               // counts do not change; at x 1.1 a knee-side thigh chain (evidence 8.07 and
                                               // 8.19, mean height 0.090 and 0.091) is kept on both sides, not one. Works
                                               // for evidence 7.5-8.0 (7.0 adds the neutral chain; counting strong sections
                                               // instead, 4 gives an unpaired calf at x 1.05 and 5 loses the quadriceps at
                                               // x 0.95). Its height was a fitted share of minRelative (0.6, working for
                                               // 0.5-0.67), which the bump floor 0.05 / 0.09 = 0.556 replaces with the same
                                               // results on every tuning and held-out set. A huge value = off
  // The trunk families (abdomen, neck: planes across the whole body, bumps against the Fourier base, trunkHarmonics)
  // have no height floor: the evidence floor decides them. Their floor minRelativeTrunk (0.05) was removed when turning
  // it off changed nothing (bench_floor_ablation: tune seeds 1-11 muscular and smooth, MakeHuman muscular and neutral at
  // spacings x 0.9-1.1, the shared characters' muscles; the neutral body's trunk chains are too short to count anyway).
  // A cue of shape, not height (issue 13, track-level evidence; the test lives in muscles/track_evidence.cpp): a limb
  // chain that misses the floors above (too short: minSections, minEvidence; or too flat: minRelative) is still a muscle
  // when its whole track is a closed spindle, as a belly is: its bumps' significance along 3 or more consecutive planes
  // rises to a peak and falls from it (reversals within 5 % of the peak), both end links stay below spindleEnds of the
  // peak (the belly tapers on both sides within the sectioned length), the track is at least spindleLength times its
  // bumps' mean radius long (a belly is longer than wide; a crease or a fold at a joint is not), and its bumps are
  // steep: protrusion / skin arc length at least spindleSteepness on average (a rounded cap, not a broad low swell). No
  // link need be significant: a faint belly's bumps lie at 0.5-1 of the threshold over its whole length, and the shape
  // along the track is the evidence. History: first (bench_spindle_cue, tune seeds 1-3) a significant peak, 4 planes,
  // ends 0.75, steepness 0.05; then ends 0.85, steepness 0.04 (tune seeds 1-11 biped recall 0.914 -> 0.934, held-out
  // biped 0.826 -> 0.868, quadruped 0.953 -> 0.969). Then the peak requirement dropped, 5 % reversals allowed and 4 planes
  // replaced by 2.5 radii (bench_track_dump, tune seeds 1-11, smooth bodies, MakeHuman at spacings x 0.9-1.1): tune
  // biped recall 0.934 -> 0.960 (with confidence-dropped chains kept as mirror twins), quadruped 0.949 -> 0.955,
  // precision unchanged, no smooth-body muscle, MakeHuman counts unchanged at every spacing. Measured windows: reversals
  // 0.02-0.08 of the peak (0.15 adds neutral lower-leg chains at x 1.05 and 1.1); length 2.0-2.75 radii (3.0 loses a
  // kept triceps spindle at 2.8; the neutral body's 3-plane spindle-shaped chains are 1.5-2.1 radii long, the true
  // brachialis ones 3.9-4.1). 0 = off (spindleEnds)
  double spindleEnds = 0.85;
  double spindleLength = 2.5;
  double spindleSteepness = 0.04;
  // Mirror twins (issue 13): on a body with a mirror plane (a torso plane on it, CuttingPlane::mirrorAxis), a limb chain
  // that misses the floors above or minConfidence (and is no closed spindle) is kept when its mirror twin passed them: a chain of the
  // same family on the other limb, at least half of whose bump centres, mirrored, lie within twinReach times the larger
  // of the two chains' mean semi-axis a of this chain's centres, and half of this one's of its (the same belly on both
  // sides; the floors decide on each side's own sampling of it). Only a missing pair member is restored: not when a kept
  // chain on the dropped one's limb is the twin already (a second fragment of a paired belly), and twins of twins are
  // not kept. Chains the confidence floor dropped are restored the same way. A twin skips minConfidence: its own confidence is a short chain's (why the floors dropped it), its kept
  // twin carries the evidence. Measured: tune bipeds (seeds 1-3) recall 0.907 -> 0.963 (with the confidence floor
  // 0.944), precision 1.0; no twin on the shared characters or the smooth bodies. 0 = off
  double twinReach = 1.0;
  double minConfidence = 0.5;                  // drop muscles below this confidence (forced ones, closed spindles
                                               // and mirror twins are kept: their evidence is their shape or their
                                               // twin, not their height)
};

// The smallest non-zero BodyScaleOptions::spacing, in limb radii (the automatic spacing is about 0.4 on the
// MakeHuman and Godot bodies): a smaller one is a value in metres given where limb radii are taken.
constexpr double kMinSpacingRadii = 0.05;

// Body scale (stage 0, makeScaleContext): the power of ten (or, continuous, the factor) the character is scaled by
// for the analysis, and the plane spacing in limb radii.

struct BodyScaleOptions {
  double spacing = 0.0;                        // cutting-plane spacing in limb radii (bodyLimbRadius; 2 = a limb's
                                               // diameter); 0 = planes.spacing (in the character's units), which
                                               // itself 0 = automatic (1/80 of the skin's largest extent)
  double referenceLimbRadius = 0.0;            // body scale: the defaults' lengths (every one but planes.spacing,
                                               // which is in the character's own units, and the stages' inner
                                               // tolerances) hold for a character in metres. Its units are found from
                                               // its limb radius (bodyLimbRadius): the power of ten that brings that
                                               // nearest to this radius (exactly to it with `continuous`); the
                                               // character is scaled by it about the origin for the analysis and the
                                               // muscles scaled back, so the same character in mm, cm, m or exported
                                               // x100 / x0.01 gives the same muscles. 0 = kReferenceLimbRadius; < 0 =
                                               // analyse in the file's own units (`continuous` then does nothing)
  bool continuous = false;                     // true: scale the character to the reference limb radius exactly, not
                                               // by a power of ten, so every length of the defaults is relative to the
                                               // limb radius and any scale (feet, inches, a character modelled 1.7
                                               // units tall) gives the same muscles. Not the default: at their own size
                                               // the bodies the floors were measured on change (README "Units and
                                               // placement")
};

// Every option of the pipeline, stage by stage: the expert object (expertOptions()). The user-facing few, each
// body-relative (README "Muscle extraction"; Python extract_muscles' keywords, the CLI's and batch's flags):
//   scale.spacing (plane spacing in limb radii, 0 = automatic), filters.minConfidence (0-1), link.minSections
//   (significant sections a muscle needs), maxPerRegion (0 = all), ends.jointWrapFraction (joint wrap radius in the
//   muscle's semi-axes b, 0 = straight lines); data, not knobs: roleOverrides, vertexMask, forcedRegions.
struct ExtractionOptions {
  PlaneOptions planes;          // spacing etc. of the cutting planes (sections.h)
  ProfileOptions profiles;      // profile resampling (sections.h)
  BumpOptions bumps;            // significance thresholds (bumps.h)
  std::map<std::string, BoneRole> roleOverrides;  // bone name -> role (wins over the heuristics)
  LinkOptions link;
  EndOptions ends;
  SurfaceOptions surface;
  bool buildSurfaces = true;    // loft a surface mesh per muscle

  // User control (paper, "User Control").
  std::vector<char> vertexMask;                // #V (welded skin); empty = whole skin. Extract only here.
  std::vector<std::vector<char>> forcedRegions;  // one #V mask per forced muscle: the dominant bump inside
                                                 // the region is extracted even below significance
  SectionBumpOptions sectionBumps;             // stages 3-4: hysteresis, trunk base, mesh-resolution floor
  ChainFilterOptions filters;                  // stage 5: floors and the spindle / twin cues
  BodyScaleOptions scale;                      // stage 0: units detection
  int maxPerRegion = 0;                        // keep at most this many (most confident) per region; 0 = all
};

struct SkippedSection {
  int section = -1;             // index into the cut planes
  std::string bone;
  std::string family;
  std::string reason;
};

struct StageTiming {
  std::string stage;
  double seconds = 0.0;
};

struct ExcludedComponent {
  int vertices = 0;                   // welded vertices of the component
  std::string bone;                   // the one bone it is bound to ("rigid"), else empty
  std::string reason;                 // "small" or "rigid" (bodySurfaceMask)
  int firstVertex = -1;               // lowest vertex index in it (to find it again)
};

// One linked chain of bumps and what the floors made of it (ExtractionReport::chainRecords): the cue of shape per chain.
struct ChainRecord {
  std::string family;                 // its planes' family ("limb", "shoulder", "abdomen", "neck")
  std::string bone;                   // the bone of most of its planes
  std::vector<Vec3> centres;          // its bumps' ellipse centres in plane order (character units)
  std::vector<double> significance;   // per bump, relative to the protrusion threshold (>= 1 significant)
  std::vector<double> relative;       // per bump, its protrusion / its section's mean radius
  std::vector<int> planes;            // per bump, its plane's order along the family (CuttingPlane::order)
  std::vector<double> radius;         // per bump, its ellipse's mean radius sqrt(a b) (character units)
  double steepness = 0.0;             // its bumps' mean protrusion / skin arc length (spindleSteepness)
  bool spindle = false;               // a closed spindle (spindleEnds; limb families only)
  std::string verdict;                // "kept" (before family dominance), "spindle" (kept below the floors as a closed
                                      // spindle), "twin" (kept below them as a kept chain's mirror twin, twinReach),
                                      // "forced", or dropped: "short", "flat", "confidence"
};

struct ExtractionReport {
  double limbRadius = 0.0;            // the body's limb radius in the character's units (bodyLimbRadius)
  double scale = 1.0;                 // factor the character was scaled by for the analysis (a power of ten: its
                                      // units; any factor with scale.continuous)
  std::vector<ExcludedComponent> excluded;  // skin components left out of the analysis (eyes, teeth, props)
  std::string scaleNote;              // when the body, in the units found, is far from the size the defaults are stated
                                      // for (limb radius outside 2/3 to 1.5 times the reference limb radius; the bodies
                                      // they were measured on span 0.74-1.37 of it; a character in feet or inches, or
                                      // twice life size): its muscles depend on its size, and scale.continuous removes
                                      // that. Empty otherwise, with scale.continuous or a reference < 0, and when no
                                      // limb was analysed (the limb radius is then a fallback)
  std::string diagnosis;              // when no muscle was found: why (no limb chain, every section skipped and
                                      // why, or no significant relief); empty otherwise
  bool analysed = false;              // at least one section was analysed (false: nothing could be looked at)
  int bones = 0, activeBones = 0;     // bones, bones with a role other than Ignore
  int planes = 0;
  int sections = 0;                   // profiles that gave a clean loop
  int mirrored = 0;                   // trunk profiles made exactly mirror-symmetric (within one sample spacing)
  int split = 0;                      // trunk sections triangulated as two halves along their mirror axis
  int bumps = 0;                      // significant bumps over all sections
  int chains = 0;                     // linked chains before the minimum-section filter
  int branches = 0;                   // transition sections placed at merges/splits
  int muscles = 0;                    // muscles returned
  int droppedShort = 0, droppedConfidence = 0, droppedRegionLimit = 0;  // short: too few significant sections or
                                                                       // too little evidence (minEvidence)
  int droppedFlat = 0;                // muscles whose bumps stand out less than minRelative on average
  int droppedContour = 0;             // shoulder chains that are the trunk's contour: strongest at the family's first
                                      // plane, only falling towards the joint (chain_filters.cpp, trunkContour)
  int spindles = 0;                   // chains below those floors kept as closed spindles (spindleEnds)
  int twins = 0;                      // chains below those floors kept as mirror twins of kept ones (twinReach)
  std::vector<ChainRecord> chainRecords;  // every linked chain with two or more bumps, in linking order
  int droppedOverlap = 0;             // muscles of a dominated family where families overlap
  int forced = 0;                     // muscles from forced regions
  std::vector<SkippedSection> skipped;
  std::vector<StageTiming> timings;
};

struct ExtractionResult {
  std::vector<Muscle> muscles;
  ExtractionReport report;
};

// Throws InputError for an invalid character, a mask of the wrong size or an option out of its range.
ExtractionResult extractMuscles(const Character& character, const ExtractionOptions& options = {});

// ============================================================================
// Expert options by name (CLI --expert KEY=VALUE / --options FILE.json, Python extract_muscles(options={...}))
// ============================================================================

// One tunable option of ExtractionOptions: its key (the field path, e.g. "filters.minEvidence"), its type
// ("double", "int" or "bool") and its default. The user-facing five (ExtractionOptions) are not among them.
struct ExpertOption {
  std::string key;
  std::string type;
  double defaultValue = 0.0;
};

// Every expert option, in ExtractionOptions' order.
std::vector<ExpertOption> expertOptions();

// Sets one expert option by key. Throws InputError on an unknown key, a non-finite value, a non-integer value for
// an int, or a value other than 0 / 1 for a bool (ranges are checked by extractMuscles).
void setExpertOption(ExtractionOptions& options, const std::string& key, double value);

// The current value of one expert option (bools as 0 / 1). Throws InputError on an unknown key.
double expertOption(const ExtractionOptions& options, const std::string& key);

// ============================================================================
// Body scale and the parts of the skin that are analysed
// ============================================================================

// The limb radius of a character in metres that the units detection aims at (makehuman_muscular_male's, on which
// the defaults were measured; the neutral body's is 0.049, the synthetic arm's 0.041-0.044, the low-poly male's 0.060,
// the soldier's 0.071): a limb radius from 1.75 cm to 17.5 cm is taken as metres (BodyScaleOptions::continuous: every
// limb radius is brought to it exactly).
constexpr double kReferenceLimbRadius = 0.0554;

// The body's limb radius: the median distance of the skin on limb bones (roles[b] == Limb, by each vertex's
// dominant bone) from its bone segment; without limb skin, of all weighted skin from its dominant bone; without
// weights, 1/40 of the skin's largest extent. Scales with the character; independent of units and placement.
double bodyLimbRadius(const Character& character, const std::vector<BoneRole>& roles);

// Skin components (connected over triangles) that are not body surface: small ones, whose bounding-box diagonal
// is under `smallShare` of the largest component's (eyes, teeth, buttons), and rigid ones, whose every vertex is
// bound with weight >= 0.99 to one and the same bone (helmets, armour plates, hair, props). The largest component
// is always kept. Returns per vertex 1 = analysed, 0 = left out; `excluded` describes each left-out component.
std::vector<char> bodySurfaceMask(const Character& character, std::vector<ExcludedComponent>& excluded,
                                  double smallShare = 0.1);

// ============================================================================
// Stages, exposed for tests and tools
// ============================================================================

// One section's bumps as linking sees them (ellipses in the plane's 2D frame).
struct SectionBumps {
  CuttingPlane plane;
  std::vector<Ellipse2> ellipses;
  std::vector<double> significance;  // per ellipse (>= 1 significant)
  std::vector<double> relative;      // per ellipse, optional: the bump's protrusion / the section's mean radius
  std::vector<double> width;         // per ellipse, optional: the bump's skin arc length / the section's mean radius
                                     // (with `relative`: the bump's steepness, ChainFilterOptions::spindleSteepness)
  std::vector<char> forced;          // per ellipse, optional (empty = none forced)
};

// 3D position of a plane-frame 2D point.
Vec3 planePoint(const CuttingPlane& plane, const Vec2& p);

// A linked chain: one ellipse per used section, in increasing plane order. A transition section (the
// average of the two ellipses where branches join) has bump = -1 and carries its own ellipse.
struct ChainLink {
  int section = -1;   // index into the SectionBumps list
  int bump = -1;      // index of the ellipse in that section, -1 for a transition section
  Ellipse2 ellipse;   // copy of the ellipse (plane coordinates of `section`)
};
struct MuscleChain {
  std::string family;
  int familyIndex = 0;
  int bone = -1;                 // bone of the plane with the most links
  std::vector<ChainLink> links;
  int realSections = 0;          // links with bump >= 0
  int strongSections = 0;        // real links whose bump is significant (significance >= 1)
  double confidence = 0.0;       // in [0, 1]
  bool forced = false;
};

// Links bumps across consecutive planes of each family instance (family, familyIndex), ordered by
// CuttingPlane::order. Rule: for each section in order, every open chain whose last link lies at most
// 1 + maxGap orders back is a candidate; all (chain, bump) pairs that pass the distance/angle test are
// sorted by cost (lateral distance / mean a + angle / maxAngle) and assigned greedily, one bump per chain.
// Unassigned bumps start new chains. Branches: a new chain whose first bump also passes the test
// against a chain that continued (a split), or a chain that ends while its last bump passes the test
// against a bump another chain took (a merge), gets a transition section — the average ellipse of the
// two, placed in the plane of the shared-side section — so both branches meet at the junction.
// Returns every chain (also short ones; filter with strongSections >= minSections), sorted by family,
// familyIndex, then first plane order, then angle.
std::vector<MuscleChain> linkBumps(const std::vector<SectionBumps>& sections, const LinkOptions& options = {},
                                   int* branchCount = nullptr);

// Confidence of a chain in [0, 1]: the geometric mean of (a) section count, min(1, n / (2 minSections)),
// (b) mean significance, 1 - exp(-mean / 2), (c) consistency, 1 / (1 + relative variation of a, b and
// lateral centre steps between consecutive links).
double chainConfidence(const MuscleChain& chain, const std::vector<SectionBumps>& sections,
                       const LinkOptions& options = {});

// Families overlap (a shoulder's planes and the upper arm's planes both cut the deltoid): among muscles of
// different families (`families`, one per muscle) whose centre lines overlap — at least `minOverlap` of one
// muscle's section centres within the larger mean semi-axis a of the other's centre line — only the one from
// the dominating family is kept (more sections, then higher confidence). Returns keep flags (#muscles).
std::vector<char> dominantMuscles(const std::vector<Muscle>& muscles, const std::vector<std::string>& families,
                                  double minOverlap = 0.5);

// Cubic Hermite curve p(t) on [0, 1] with end points p0, p1 and end tangents m0, m1 (derivatives).
Vec3 hermite(const Vec3& p0, const Vec3& m0, const Vec3& p1, const Vec3& m1, double t);

// Turns a chain into a muscle: sections in 3D (normal oriented origin -> insertion), root curve
// = origin, Hermite extension, ellipse centres, Hermite extension, insertion. Origin/insertion: the
// nearest point on a bone (the chain's bone, its parent or a child, whichever is nearest) to the
// straight extension of the root curve (EndOptions). u by arc length of the full root curve.
Muscle buildMuscleEnds(const MuscleChain& chain, const std::vector<SectionBumps>& sections,
                       const Skeleton& skeleton, const EndOptions& options = {});

// Same, from 3D sections given directly (centres in order; normals may point either way; u ignored).
// `bone` is the muscle's bone index in `skeleton`.
Muscle buildMuscleEnds(const std::vector<MuscleSection>& sections, int bone, const Skeleton& skeleton,
                       const EndOptions& options = {});

// Lofts the muscle's sections into a closed, outward-oriented, watertight triangle mesh (#rings x ringVertices ring
// vertices from the origin end to the insertion end, then the origin pole and the insertion pole). Rings follow a
// frame transported along the centres; their planes, ellipse angles (unwrapped mod 180 degrees, or 90 with the axes
// swapped) and semi-axes are smoothed along the muscle (SurfaceOptions::smoothingPasses), so neighbouring rings turn
// smoothly; a ring reaching through its predecessor's plane is laid parallel to it (or left out when its centre lies
// behind). Each end tapers over capRings rings parallel to its end ring, shrinking by 1 - 3t^2 + 2t^3, to a pole: the root
// curve point beyond the end lying farthest ahead of the end ring (the origin or insertion when the tendon runs on),
// or, when none lies half the ring's mean radius ahead, a rounded cap of that height. Not clamped to the skin
// (extraction does that: SurfaceOptions::containInSkin).
Mesh loftMuscleSurface(const Muscle& muscle, const SurfaceOptions& options = {});

// Carries a muscle that spans no real joint over its nearer one (EndOptions::spanCarry), then rebuilds its root
// curve ends and joint wrap (not its surface: loftMuscleSurface). `twist` from twistSplits. Does nothing when
// spanCarry is 0, the ends already lie on different segments, or there is no bone across the joint.
void spanRealJoint(Muscle& muscle, const Skeleton& skeleton, const std::vector<char>& twist, const EndOptions& options);

// Carries a limb muscle's distal end, when it lies on the segment of `bellyBone` (the bone its bumps were found on)
// and that segment is its limb's last (the next bone across its distal real joint is no limb bone of `roles`, the
// role map) and that next bone is a foot (turned more than 45 degrees from the segment's axis: a lever across the
// limb; a hand continues its forearm), over that joint onto the next bone
// (EndOptions::spanCarry of that bone past the joint, along the segment), keeping the end section's offset from the
// segment's axis: on the belly's side of the joint, so the calf's tendon reaches the heel behind the ankle and
// shortens on plantar flexion. A muscle without a wrap gets a joint wrap of that offset's radius there (the tibialis
// anterior's tendon stays in front of the ankle on plantar flexion); one it has stays. The root curve's ends are
// rebuilt. Does nothing when spanDistal is off, spanCarry is 0, or the distal end already lies across that joint.
// With `skin` the offset shrinks (by eighths; spanCarry past the joint, else at the joint's level) until the end lies
// inside the skin by 0.1 of the end section's b (SurfaceOptions::skinMargin's share).
void spanDistalJoint(Muscle& muscle, const Skeleton& skeleton, const std::vector<char>& twist,
                     const std::vector<BoneRole>& roles, int bellyBone, const EndOptions& options,
                     const SkinWinding* skin = nullptr);

// The root curve's Hermite ends rebuilt to muscle.origin/insertion (positions), section u by arc length; the
// surface is left as it was. Throws InputError on no sections or NaN positions.
void reattachEnds(Muscle& muscle, const EndOptions& options = {});

// After the user moved muscle.origin/insertion (positions, mesh space): rebuilds the Hermite ends of the
// root curve to the new attachment points, recomputes section u by arc length and re-lofts the surface.
// The sections (the visible, extracted part) are kept. Throws InputError on no sections or NaN positions.
void reattachMuscle(Muscle& muscle, const EndOptions& options = {}, const SurfaceOptions& surface = {});

// ============================================================================
// Measurement (DESIGN.md section 8)
// ============================================================================

struct ExtractionAccuracy {
  int trueMuscles = 0, foundMuscles = 0, matched = 0;
  double recall = 0.0, precision = 0.0;
  double meanCenterError = 0.0;  // mean distance of matched root-curve points to the true centre line,
                                 // relative to the true muscle's peak radius
  std::vector<int> matchOfTrue;  // per true muscle: index of its found muscle, or -1
  std::vector<double> coverageOfTrue;  // per true muscle: the best coverage of its visible length by any found muscle
};

// A found muscle matches a true one when its root curve stays within half the true muscle's (peak)
// radius of the true centre line over at least `minCoverage` of the true muscle's visible length (the true
// line is sampled densely; a sample is covered when the found root curve passes within the distance).
// Visible length: where the muscle raises the skin (TrueMuscle::relief, interpolated between centre-line
// points) by at least visibleReliefShare of its peak relief -- extraction finds muscles by the relief they
// give the skin, so length buried under a neighbour, in the trunk or in the fat layer towards the tendons
// does not count; a true muscle without relief values counts its whole length.
// Matching is one-to-one, greedy by coverage. meanCenterError uses the matched muscles' section centres.
ExtractionAccuracy measureExtraction(const std::vector<Muscle>& found, const std::vector<TrueMuscle>& truth,
                                     double minCoverage = 0.6, double visibleReliefShare = 0.5);

}  // namespace myoskin
