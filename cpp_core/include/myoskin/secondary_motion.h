// Secondary motion over a pose sequence (Gray & Hutchinson, "Procedural Muscle and Skin Simulation"):
// jiggle of the muscle masses (an inertial spring per muscle whose influence falls off toward the tendons),
// a temporal filter for point caches (jitter off the line through the neighbouring frames is pulled back),
// normal-space sculpt deltas (detail sculpted on one frame re-applied on every frame in the surface's local
// frame), and a simulation that chains them frame by frame into PC2 caches, in chunks that separate processes
// can bake and that stitch bit-identically through small state files.
//
// Time: a pose sequence samples frames start, start + 1, ... at `fps` frames per second. The jiggle is
// integrated on a fixed grid of `JiggleOptions::timeStep` seconds anchored at the start frame; between frames
// each muscle's goal (its belly point under the pose) is interpolated linearly. A frame's result depends only
// on the sequence and the options, never on which frames were evaluated before or in which order.
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "myoskin/deformation.h"
#include "myoskin/mesh.h"
#include "myoskin/pose_io.h"
#include "myoskin/skeleton.h"
#include "myoskin/skinning.h"
#include "myoskin/types.h"

namespace myoskin {

// ============================================================================
// Jiggle: one damped spring per muscle (jiggle.cpp)
// ============================================================================

// Defaults come from each muscle's size; every length is relative to the muscle (its mean section radius).
struct JiggleOptions {
  double timeStep = 1.0 / 240.0;  // internal step in seconds (> 0, <= 0.1); fixed, whatever the frame rate
  double frequency = 5.0;         // Hz: natural frequency of a muscle of the rig's median mean radius (> 0)
  double sizeExponent = 0.5;      // a muscle's frequency scales with (median radius / its radius)^sizeExponent
  double dampingRatio = 0.3;      // fraction of critical damping (>= 0; 0 = undamped, 1 = critical)
  double density = 1060.0;        // mass per unit volume of muscle (kg/m^3 in metres); mass = density x volume
  double amount = 1.0;            // multiplies every offset (>= 0; 0 = no jiggle)
  double maxOffset = 0.5;         // muscle mean radii: offsets pass unchanged up to half of it, then saturate
  int checkpointFrames = 1;       // keep the state every this many frames, so scrubbing back replays from there
};

// One muscle's spring: m d'' + c d' + k d = -m g'' for the offset d of the mass from its goal g.
struct JiggleParams {
  double mass = 1.0;       // > 0
  double stiffness = 1.0;  // > 0
  double damping = 0.0;    // >= 0
};

// Per muscle (#M): mass = density x volume (the sections' elliptical areas over the root curve), stiffness =
// mass (2 pi f)^2 with f = frequency (median radius / mean radius)^sizeExponent, damping = 2 dampingRatio
// sqrt(stiffness mass). Throws InputError on bad options.
std::vector<JiggleParams> defaultJiggleParams(const MuscleRig& rig, const JiggleOptions& options = {});

// Per muscle joint (#J) in [0, 1]: sin(pi t), t the joint's rest position along origin -> insertion, so the
// jiggle fades toward the tendons (the paper's grey-scale map).
std::vector<double> defaultJiggleInfluence(const MuscleRig& rig);

// The integrator's state on its grid (what a chunk of a bake starts from). #M entries each.
struct JiggleState {
  int64_t step = 0;                 // grid step from the start frame (time = step x timeStep)
  std::vector<Vec3> offset;         // d: the mass's offset from its goal
  std::vector<Vec3> velocity;       // d': relative to the goal
  std::vector<Vec3> goalVelocity;   // the goal's velocity over the step that ended here
};

// The stateful jiggle over one pose sequence: built once, then offsets(frame) in any order. States are kept
// every JiggleOptions::checkpointFrames frames, so going back replays from the nearest kept state at or before
// the frame (never from a later, stale one).
class JiggleTrack {
 public:
  // poses: the sequence (>= 1 frame; one frame gives no motion, so zero offsets). params: #M or empty
  // (defaultJiggleParams); influence: #J or empty (defaultJiggleInfluence). Throws InputError on bad
  // options, fps <= 0, a count mismatch, mass/stiffness <= 0, damping < 0, or a non-finite value.
  JiggleTrack(const MuscleRig& rig, const PoseSequence& poses, double fps, const JiggleOptions& options = {},
              std::vector<JiggleParams> params = {}, std::vector<double> influence = {});
  ~JiggleTrack();
  JiggleTrack(JiggleTrack&&) noexcept;
  JiggleTrack& operator=(JiggleTrack&&) noexcept;

  double firstFrame() const;
  double lastFrame() const;
  const std::vector<JiggleParams>& params() const;   // #M
  const std::vector<double>& influence() const;      // #J
  const JiggleOptions& options() const;

  // #M offsets of the muscles' masses at a frame in [firstFrame, lastFrame] (fractional frames interpolate
  // between grid states), times `amount` and softly limited. InputError outside the range.
  void offsets(double frame, std::vector<Vec3>& out);
  // The same before the limit and `amount`: the spring's own offsets (tests of the dynamics).
  void springOffsets(double frame, std::vector<Vec3>& out);
  // Moves each muscle joint of `state` (the rig evaluated at this frame's pose) by influence x its muscle's
  // offset: the joint matrices a bake writes to the muscle joints' Action. Posed surfaces in the state (when
  // evaluated with them) move too, each vertex by the joints' influence interpolated at its place along the muscle.
  void apply(double frame, MuscleRigState& state);

  // The grid state a frame's result starts from (the last grid step at or before the frame).
  JiggleState stateAt(double frame);
  // The grid step of a frame's state (InputError outside the sequence).
  int64_t stepOf(double frame) const;
  // Keeps a state (from stateAt here or in another process) so later frames continue from it.
  void restore(const JiggleState& state);
  // Replaces one frame's pose (index into the sequence) and drops every kept state past it.
  void setPose(int index, const Pose& pose);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// ============================================================================
// Temporal filter for point caches (temporal_filter.cpp)
// ============================================================================

// A vertex is tested against the line segment between its positions on the previous and next frames: its
// distance e from that segment (across the motion, or past a neighbour along it) is accepted up to tolerance =
// relativeTolerance x |next - previous| + absoluteTolerance x lengthScale (smooth motion curves within it: a
// circle sampled at angle theta per frame deviates by theta/4 of the chord). Past it, and further out than the
// previous and next positions are from their own neighbours (when the frames two away are given: the frames next
// to a spike see the spike but are not it), the vertex is pulled back to the tolerance and toward the middle of
// the segment by the share of e past the tolerance (continuous). Lengths are relative to lengthScale (the skin's
// mean edge length).
struct TemporalFilterOptions {
  double relativeTolerance = 0.1;   // of the distance between the neighbouring frames' positions (>= 0)
  double absoluteTolerance = 0.02;  // of lengthScale (>= 0)
  int grainSize = 4096;             // vertices per parallel task
};

// Filters one frame: out = current with each anomalous vertex pulled back (before and after, the frames two away,
// may be null; all #V by 3; out may not alias the inputs). Returns the number of vertices pulled back. Vertices
// not pulled back are copied unchanged (bit for bit).
int filterFrame(const PointsF* before, const PointsF& previous, const PointsF& current, const PointsF& next,
                const PointsF* after, double lengthScale, const TemporalFilterOptions& options, PointsF& out);
// The same without the frames two away (every vertex past the tolerance is pulled back).
int filterFrame(const PointsF& previous, const PointsF& current, const PointsF& next, double lengthScale,
                const TemporalFilterOptions& options, PointsF& out);

// Filters a whole cache (#F frames of #V by 3): each inner frame against its unfiltered neighbours (two on each
// side where there are); the first and last frames (and a cache of one or two frames) pass unchanged. Returns the vertices pulled back in all.
int filterFrames(const std::vector<PointsF>& frames, double lengthScale, const TemporalFilterOptions& options,
                 std::vector<PointsF>& out);

// Mean edge length of a mesh (the filter's lengthScale). Throws InputError on an empty or bad mesh.
double meanEdgeLength(const Points& vertices, const Triangles& triangles);

// ============================================================================
// Normal-space sculpt deltas (sculpt_deltas.cpp)
// ============================================================================

// Detail sculpted on one frame, stored per vertex in the surface's local frame at that frame (normal, tangent
// toward one neighbour along an edge, binormal) and re-applied in the local frame of every other frame, so it
// turns with the surface. A vertex with no usable frame (no triangle, or a degenerate one) keeps its delta in
// world space.
class SculptDeltas {
 public:
  // reference: the surface as simulated at the sculpt frame; sculpted: the same vertices after sculpting (both
  // #V by 3); triangles #F by 3. Throws InputError on mismatched sizes, bad indices or non-finite values.
  SculptDeltas(const Points& reference, const Triangles& triangles, const Points& sculpted);
  // Deltas captured before (localDeltas() and framed() of another SculptDeltas over the same mesh, e.g. stored
  // in a file): #V by 3 local deltas and #V flags (1: in the local frame, 0: in world space). Throws InputError
  // on mismatched sizes, bad indices or non-finite values.
  SculptDeltas(const Triangles& triangles, const Points& localDeltas, const std::vector<char>& framed);
  ~SculptDeltas();
  SculptDeltas(SculptDeltas&&) noexcept;
  SculptDeltas& operator=(SculptDeltas&&) noexcept;

  int numVertices() const;
  const Points& localDeltas() const;   // #V by 3: (tangent, binormal, normal) components; world for frameless
  const std::vector<char>& framed() const;  // #V: 1 where the delta is in the local frame, 0 where in world space
  // positions (#V by 3) with the detail added in their own local frames. out may alias positions. Per-frame
  // buffers are kept inside, so calls are not thread-safe against each other.
  void apply(const PointsF& positions, PointsF& out);
  void apply(const Points& positions, Points& out);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// ============================================================================
// Simulation: skinning -> jiggle -> (skin solve) -> filter -> sculpt, frame by frame (simulation.cpp)
// ============================================================================

struct SimulationOptions {
  double fps = 24.0;                         // frames per second of the pose sequence (> 0)
  bool jiggle = false;                       // needs a rig
  JiggleOptions jiggleOptions;
  std::vector<JiggleParams> jiggleParams;    // #M or empty (defaults by size)
  std::vector<double> jiggleInfluence;       // #J or empty (defaults toward the tendons)
  // The temporal filter acts on what the skin solve adds to the skinned (and jiggled) positions: that motion is
  // the simulation's, where jitter arises; skinning and jiggle pass through it unchanged (without a skin solve
  // the filter has nothing to do). For any other cache use filterFrames.
  bool filter = false;
  TemporalFilterOptions filterOptions;
  double filterLengthScale = 0.0;            // 0: the skin's mean edge length
  // Per skin vertex (#V, each in [0, 1]) or empty: the share of the jiggle that reaches the vertex (the painted
  // map): skin = skinned without jiggle + w (skinned with the jiggled joints - skinned without jiggle), so 0 keeps
  // the vertex exactly where plain skinning puts it and 1 gives the full jiggle. Costs a second skinning per
  // frame; ignored without jiggle.
  std::vector<double> jiggleVertexInfluence;
  // What else shapes the frames, named by the caller (the CLI: the bind's skinning mode, dominance, joints slide,
  // the skin solve): kept in every state with the simulation's own settings (the filter, the jiggle's); a chunk
  // restores only a state made with the same ones.
  std::map<std::string, std::string> settings;
};

// Where a per-frame skin solve (collision against the muscles) plugs in: called on every raw frame after
// skinning, before the filter, with the frame number, its pose, the rig state (jiggled joints and jiggled posed
// surfaces; null without a rig) and the skinned positions to change in place.
using SkinSolveHook = std::function<void(int frame, const Pose& pose, const MuscleRigState* rig, PointsF& skin)>;

// What a chunk of a bake starts from: the jiggle's grid state for a frame and the settings it was made with
// (checked on restore). Written as JSON with doubles that read back exactly.
struct SimulationState {
  int frame = 0;                    // the frame it belongs to (a chunk starting at frame + 2 or later restores it)
  double fps = 0.0;
  double timeStep = 0.0;
  int startFrame = 0;
  std::vector<std::string> muscles; // names, #M (empty without jiggle)
  bool hasJiggle = false;
  JiggleState jiggle;
  // The settings the frames were made with (SimulationOptions::settings and the simulation's own, as text); a state
  // file written before they were kept has none (hasSettings false) and is not checked for them.
  bool hasSettings = false;
  std::map<std::string, std::string> settings;
};

void writeSimulationState(const std::string& path, const SimulationState& state);
SimulationState readSimulationState(const std::string& path);  // InputError on a bad file

class Simulation {
 public:
  // skin: the rest mesh (#V vertices, triangles for the sculpt frames and the filter's length scale); rig may
  // be null (skeleton weights only, no jiggle); skinner: built for skin.vertices over the #B (+ #J) combined
  // joints. poses: the sequence (frames start .. start + #F - 1; start must be a whole frame). Throws InputError.
  Simulation(const Mesh& skin, const Skeleton& skeleton, const MuscleRig* rig, std::shared_ptr<const Skinner> skinner,
             const PoseSequence& poses, const SimulationOptions& options = {});
  ~Simulation();

  int firstFrame() const;
  int lastFrame() const;
  int numVertices() const;

  void setSkinSolve(SkinSolveHook hook);
  // Adds detail sculpted on `frame`: the reference is this simulation's filtered frame (without detail).
  // sculpted: #V by 3.
  void setSculpt(const Points& sculpted, int frame);
  // Adds detail captured before (deltas over this skin's #V vertices).
  void setSculpt(SculptDeltas deltas);
  // Offsets of the rest mesh before skinning per frame of the sequence (e.g. Blender's shape key mix):
  // offsets[f - firstFrame()] is #V by 3 in the skinner's input space, or empty (no offset that frame); an empty
  // list: none. Each offset d moves its skinned vertex by A d, A the vertex's blended skinning transform
  // (Skinner::vertexTransforms), exactly as skinning the offset mesh would. Throws InputError on a bad count.
  void setShapeOffsets(std::vector<PointsF> offsets);

  // The skinned (and jiggled, solved) positions of a frame, before filter and sculpt.
  void rawFrame(int frame, PointsF& out);
  // The final positions of a frame (random access: recomputes the neighbours the filter needs).
  void frame(int frame, PointsF& out);
  // The jiggled muscle joint matrices of a frame (#J, mesh space; the rig's own without jiggle).
  const std::vector<Mat4>& jointMatrices(int frame);

  // Bakes frames [first, last] in order, calling sink(frame, positions) for each. With stateIn (the state a bake
  // ending at first - 1 returned, i.e. of frame first - 2 or earlier, with the same inputs) the jiggle continues
  // from it instead of replaying from the start; the result is bit-identical either way. Returns the state of
  // frame last - 1 (the filter of the next chunk looks two frames back) for the next chunk.
  SimulationState bake(int first, int last, const std::function<void(int, const PointsF&)>& sink,
                       const SimulationState* stateIn = nullptr);
  SimulationState stateAt(int frame);
  void restore(const SimulationState& state);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace myoskin
