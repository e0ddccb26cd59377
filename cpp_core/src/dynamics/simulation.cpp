// The simulation over a pose sequence: per frame skinning (Equation 3) with jiggled muscle joints, the skin
// solve hook, the temporal filter on what the skin solve added (against the neighbouring frames) and the sculpt
// deltas; baked in chunks that stitch bit-identically through state files.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "myoskin/errors.h"
#include "myoskin/secondary_motion.h"

namespace myoskin {

// ============================================================================
// State files
// ============================================================================

namespace {

nlohmann::json vecs(const std::vector<Vec3>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (const Vec3& p : v) a.push_back({p.x(), p.y(), p.z()});
  return a;
}

// Text of a setting: a number with the digits that read back exactly; a list of numbers as the FNV-1a hash of
// their bytes (equal lists give equal text).
std::string settingText(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

std::string settingText(const std::vector<double>& values) {
  if (values.empty()) return "default";
  uint64_t h = 1469598103934665603ull;
  for (double v : values) {
    unsigned char bytes[sizeof v];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char b : bytes) h = (h ^ b) * 1099511628211ull;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%zu values, %016llx", values.size(), static_cast<unsigned long long>(h));
  return buf;
}

std::vector<Vec3> vecsFrom(const nlohmann::json& a, const std::string& what) {
  if (!a.is_array()) throw InputError("simulation state: '" + what + "' is not a list");
  std::vector<Vec3> v;
  for (const auto& p : a) {
    if (!p.is_array() || p.size() != 3 || !p[0].is_number() || !p[1].is_number() || !p[2].is_number())
      throw InputError("simulation state: '" + what + "' needs [x, y, z] numbers");
    v.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
    if (!v.back().allFinite()) throw InputError("simulation state: '" + what + "' has a non-finite value");
  }
  return v;
}

}  // namespace

void writeSimulationState(const std::string& path, const SimulationState& s) {
  nlohmann::ordered_json j;
  j["format"] = "myoskin.simulation_state";
  j["version"] = 1;
  j["frame"] = s.frame;
  j["fps"] = s.fps;
  j["time_step"] = s.timeStep;
  j["start_frame"] = s.startFrame;
  j["muscles"] = s.muscles;
  if (s.hasSettings) j["settings"] = s.settings;
  if (s.hasJiggle) {
    j["jiggle"] = {{"step", s.jiggle.step},
                   {"offset", vecs(s.jiggle.offset)},
                   {"velocity", vecs(s.jiggle.velocity)},
                   {"goal_velocity", vecs(s.jiggle.goalVelocity)}};
  }
  std::ofstream f(path);
  f << j.dump(1) << "\n";  // doubles are written with enough digits to read back exactly
  if (!f) throw InputError("cannot write the simulation state " + path);
}

SimulationState readSimulationState(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the simulation state");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw InputError(path + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  try {
    if (!j.is_object() || j.value("format", "") != "myoskin.simulation_state")
      throw InputError("not a simulation state (format 'myoskin.simulation_state')");
    if (j.value("version", 0) != 1) throw InputError("unsupported version");
    SimulationState s;
    s.frame = j.at("frame").get<int>();
    s.fps = j.at("fps").get<double>();
    s.timeStep = j.at("time_step").get<double>();
    s.startFrame = j.at("start_frame").get<int>();
    s.muscles = j.at("muscles").get<std::vector<std::string>>();
    if (j.contains("settings")) {
      s.hasSettings = true;
      s.settings = j["settings"].get<std::map<std::string, std::string>>();
    }
    if (j.contains("jiggle")) {
      const auto& g = j["jiggle"];
      s.hasJiggle = true;
      s.jiggle.step = g.at("step").get<int64_t>();
      s.jiggle.offset = vecsFrom(g.at("offset"), "offset");
      s.jiggle.velocity = vecsFrom(g.at("velocity"), "velocity");
      s.jiggle.goalVelocity = vecsFrom(g.at("goal_velocity"), "goal_velocity");
    }
    return s;
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  } catch (const std::exception& e) {
    throw InputError(path + ": bad simulation state (" + std::string(e.what()) + ")");
  }
}

// ============================================================================
// Simulation
// ============================================================================

struct Simulation::Impl {
  Triangles triangles;
  Skeleton skeleton;
  std::optional<MuscleRig> rig;
  std::shared_ptr<const Skinner> skinner;
  PoseSequence poses;
  SimulationOptions options;
  int start = 0;
  double lengthScale = 0.0;
  std::unique_ptr<JiggleTrack> jiggle;
  MuscleRigState rigState;
  std::vector<Mat4> transforms;
  SkinSolveHook hook;
  std::unique_ptr<SculptDeltas> sculpt;
  std::vector<PointsF> shapeOffsets;      // per frame of the sequence (empty: none) or none at all
  std::vector<Mat4> stillTransforms;      // the frame's transforms without jiggle (per-vertex influence)
  PointsF still;                          // the frame skinned without jiggle
  VertexTransforms affine;                // per vertex blended transforms (shape offsets)
  // A raw frame: the skinned (and jiggled) positions and, with a skin solve, the solved ones and what the solve
  // added (the filter's input).
  struct Frame {
    int frame = INT32_MIN;  // which frame the slot holds
    PointsF skinned, solved, residual;
  };
  Frame slots[5];  // frames f - 2 .. f + 2 (slot = frame mod 5)
  PointsF filteredResidual;

  int last() const { return start + static_cast<int>(poses.frames.size()) - 1; }

  void checkFrame(int f, const char* what) const {
    if (f < start || f > last())
      throw InputError(std::string("simulation: ") + what + " frame " + std::to_string(f) + " is outside the sequence (" +
                       std::to_string(start) + " to " + std::to_string(last()) + ")");
  }

  // Skins frame f with `t`, the frame's shape offsets (if any) moved by each vertex's blended transform.
  void skinWith(int f, const std::vector<Mat4>& t, PointsF& out) {
    skinner->deform(t, out);
    if (shapeOffsets.empty() || shapeOffsets[f - start].rows() == 0) return;
    const PointsF& d = shapeOffsets[f - start];
    skinner->vertexTransforms(t, affine);
    for (Eigen::Index v = 0; v < out.rows(); ++v)
      for (int r = 0; r < 3; ++r)
        out(v, r) += static_cast<float>(affine(v, 4 * r) * d(v, 0) + affine(v, 4 * r + 1) * d(v, 1) +
                                        affine(v, 4 * r + 2) * d(v, 2));
  }

  void raw(int f, Frame& out) {
    checkFrame(f, "the");
    out.frame = INT32_MIN;
    const Pose& pose = poses.frames[f - start];
    const bool perVertex = jiggle && !options.jiggleVertexInfluence.empty();
    if (rig) {
      rig->evaluate(pose, rigState, static_cast<bool>(hook));
      if (perVertex) {
        skinningTransforms(skeleton, pose, *rig, rigState, stillTransforms);
        skinWith(f, stillTransforms, still);
      }
      if (jiggle) jiggle->apply(f, rigState);
      skinningTransforms(skeleton, pose, *rig, rigState, transforms);
    } else {
      skeletonTransforms(skeleton, pose, transforms);
    }
    skinWith(f, transforms, out.skinned);
    if (perVertex) {  // skinned without jiggle + w (skinned with jiggle - skinned without)
      const std::vector<double>& w = options.jiggleVertexInfluence;
      for (Eigen::Index v = 0; v < out.skinned.rows(); ++v)
        out.skinned.row(v) = still.row(v) + static_cast<float>(w[v]) * (out.skinned.row(v) - still.row(v));
    }
    if (hook) {
      out.solved = out.skinned;
      hook(f, pose, rig ? &rigState : nullptr, out.solved);
      out.residual = out.solved - out.skinned;
    }
    out.frame = f;
  }

  // The raw frame f, computed once while it stays among the last five asked for.
  const Frame& get(int f) {
    Frame& slot = slots[((f % 5) + 5) % 5];
    if (slot.frame != f) raw(f, slot);
    return slot;
  }

  const PointsF& result(const Frame& fr) const { return hook ? fr.solved : fr.skinned; }

  // Frame f after the filter (not yet sculpted): the filter acts on what the skin solve added, against the two
  // frames on each side that exist.
  void filtered(int f, PointsF& out) {
    if (!options.filter || !hook || f == start || f == last()) {
      out = result(get(f));
      return;
    }
    const Frame* before = f - 2 >= start ? &get(f - 2) : nullptr;
    const Frame& prev = get(f - 1);
    const Frame& cur = get(f);
    const Frame& next = get(f + 1);
    const Frame* after = f + 2 <= last() ? &get(f + 2) : nullptr;
    filterFrame(before ? &before->residual : nullptr, prev.residual, cur.residual, next.residual,
                after ? &after->residual : nullptr, lengthScale, options.filterOptions, filteredResidual);
    out = cur.solved + (filteredResidual - cur.residual);  // unchanged vertices keep their solved bits
  }

  void invalidate() {
    for (Frame& s : slots) s.frame = INT32_MIN;
  }

  // The caller's settings and the simulation's own: the filter's, the jiggle's and the skin solve's presence.
  std::map<std::string, std::string> settings() const {
    std::map<std::string, std::string> out = options.settings;
    out["simulation.filter"] = options.filter ? "on, tolerances " + settingText(options.filterOptions.relativeTolerance) +
                                                    " " + settingText(options.filterOptions.absoluteTolerance) + ", scale " +
                                                    settingText(options.filterLengthScale)
                                              : "off";
    out["simulation.skin_solve"] = hook ? "on" : "off";
    if (jiggle) {
      const JiggleOptions& o = options.jiggleOptions;
      std::vector<double> params, vertexInfluence(options.jiggleVertexInfluence);
      for (const JiggleParams& p : options.jiggleParams) params.insert(params.end(), {p.mass, p.stiffness, p.damping});
      out["simulation.jiggle"] = settingText({o.frequency, o.sizeExponent, o.dampingRatio, o.density, o.amount,
                                              o.maxOffset}) + "; params " + settingText(params) + "; influence " +
                                 settingText(options.jiggleInfluence) + "; painted " + settingText(vertexInfluence);
    } else {
      out["simulation.jiggle"] = "off";
    }
    return out;
  }

  SimulationState state(int f) {
    SimulationState s;
    s.frame = f;
    s.fps = options.fps;
    s.timeStep = options.jiggleOptions.timeStep;
    s.startFrame = start;
    s.hasSettings = true;
    s.settings = settings();
    if (jiggle) {
      for (const Muscle& m : rig->muscles()) s.muscles.push_back(m.name);
      s.hasJiggle = true;
      s.jiggle = jiggle->stateAt(f);
    }
    return s;
  }
};

Simulation::Simulation(const Mesh& skin, const Skeleton& skeleton, const MuscleRig* rig,
                       std::shared_ptr<const Skinner> skinner, const PoseSequence& poses, const SimulationOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  if (!skinner) throw InputError("simulation: no skinner");
  if (skinner->numVertices() != skin.numVertices())
    throw InputError("simulation: the skinner has " + std::to_string(skinner->numVertices()) + " vertices, the skin " +
                     std::to_string(skin.numVertices()));
  const int joints = skeleton.numBones() + (rig ? rig->numJoints() : 0);
  if (skinner->numJoints() != joints)
    throw InputError("simulation: the skinner has " + std::to_string(skinner->numJoints()) + " joints, the skeleton" +
                     std::string(rig ? " and the rig " : " ") + std::to_string(joints));
  if (rig && rig->skeleton().numBones() != skeleton.numBones())
    throw InputError("simulation: the rig was built for another skeleton");
  if (poses.frames.empty()) throw InputError("simulation: the pose sequence has no frames");
  if (!(options.fps > 0.0) || !std::isfinite(options.fps)) throw InputError("simulation: fps must be > 0");
  if (!std::isfinite(poses.startFrame) || poses.startFrame != std::round(poses.startFrame) ||
      std::abs(poses.startFrame) > 1e9)
    throw InputError("simulation: the start frame must be a whole frame");
  for (size_t f = 0; f < poses.frames.size(); ++f) {
    if (static_cast<int>(poses.frames[f].matrices.size()) != skeleton.numBones())
      throw InputError("simulation: pose " + std::to_string(f) + " has " +
                       std::to_string(poses.frames[f].matrices.size()) + " bones, the skeleton " +
                       std::to_string(skeleton.numBones()));
    for (const Mat4& m : poses.frames[f].matrices)
      if (!m.allFinite()) throw InputError("simulation: pose " + std::to_string(f) + " has a non-finite bone matrix");
  }
  if (options.jiggle && !rig) throw InputError("simulation: jiggle needs muscles (a rig)");
  if (!options.jiggleVertexInfluence.empty()) {
    if (static_cast<int>(options.jiggleVertexInfluence.size()) != skin.numVertices())
      throw InputError("simulation: the jiggle vertex influence has " +
                       std::to_string(options.jiggleVertexInfluence.size()) + " values, the skin " +
                       std::to_string(skin.numVertices()) + " vertices");
    for (size_t v = 0; v < options.jiggleVertexInfluence.size(); ++v) {
      const double w = options.jiggleVertexInfluence[v];
      if (!(w >= 0.0 && w <= 1.0))
        throw InputError("simulation: the jiggle vertex influence of vertex " + std::to_string(v) + " is " +
                         std::to_string(w) + ", outside 0..1");
    }
  }
  d.triangles = skin.triangles;
  d.skeleton = skeleton;
  if (rig) d.rig.emplace(*rig);
  d.skinner = std::move(skinner);
  d.poses = poses;
  d.options = options;
  d.start = static_cast<int>(poses.startFrame);
  if (options.filter) {
    d.lengthScale = options.filterLengthScale > 0.0 ? options.filterLengthScale
                                                     : meanEdgeLength(skin.vertices, skin.triangles);
    PointsF probe(1, 3), out;
    probe.setZero();
    filterFrame(probe, probe, probe, d.lengthScale, options.filterOptions, out);  // validates the options
  }
  if (rig) d.rigState = rig->makeState();
  if (options.jiggle)
    d.jiggle = std::make_unique<JiggleTrack>(*rig, poses, options.fps, options.jiggleOptions, options.jiggleParams,
                                             options.jiggleInfluence);
}

Simulation::~Simulation() = default;

int Simulation::firstFrame() const { return impl_->start; }
int Simulation::lastFrame() const { return impl_->last(); }
int Simulation::numVertices() const { return impl_->skinner->numVertices(); }

void Simulation::setSkinSolve(SkinSolveHook hook) {
  impl_->hook = std::move(hook);
  impl_->invalidate();
}

void Simulation::setSculpt(const Points& sculpted, int frame) {
  Impl& d = *impl_;
  d.checkFrame(frame, "the sculpt");
  d.sculpt.reset();
  PointsF reference;
  d.filtered(frame, reference);
  d.sculpt = std::make_unique<SculptDeltas>(reference.cast<double>(), d.triangles, sculpted);
}

void Simulation::setSculpt(SculptDeltas deltas) {
  Impl& d = *impl_;
  if (deltas.numVertices() != numVertices())
    throw InputError("simulation: the sculpt deltas have " + std::to_string(deltas.numVertices()) +
                     " vertices, the skin " + std::to_string(numVertices()));
  d.sculpt = std::make_unique<SculptDeltas>(std::move(deltas));
}

void Simulation::setShapeOffsets(std::vector<PointsF> offsets) {
  Impl& d = *impl_;
  if (!offsets.empty() && offsets.size() != d.poses.frames.size())
    throw InputError("simulation: " + std::to_string(offsets.size()) + " frames of shape offsets for a sequence of " +
                     std::to_string(d.poses.frames.size()));
  for (size_t f = 0; f < offsets.size(); ++f) {
    const PointsF& o = offsets[f];
    if (o.rows() == 0) continue;
    if (o.rows() != numVertices() || o.cols() != 3)
      throw InputError("simulation: the shape offsets of frame " + std::to_string(d.start + static_cast<int>(f)) +
                       " are " + std::to_string(o.rows()) + " by " + std::to_string(o.cols()) + ", the skin has " +
                       std::to_string(numVertices()) + " vertices");
    if (!o.allFinite())
      throw InputError("simulation: the shape offsets of frame " + std::to_string(d.start + static_cast<int>(f)) +
                       " have a non-finite value");
  }
  d.shapeOffsets = std::move(offsets);
  d.invalidate();
}

void Simulation::rawFrame(int frame, PointsF& out) {
  Impl& d = *impl_;
  out = d.result(d.get(frame));
}

void Simulation::frame(int frame, PointsF& out) {
  Impl& d = *impl_;
  d.filtered(frame, out);
  if (d.sculpt) d.sculpt->apply(out, out);
}

const std::vector<Mat4>& Simulation::jointMatrices(int frame) {
  Impl& d = *impl_;
  d.checkFrame(frame, "the");
  if (!d.rig) throw InputError("simulation: no muscles, so no muscle joints");
  d.rig->evaluate(d.poses.frames[frame - d.start], d.rigState);
  if (d.jiggle) d.jiggle->apply(frame, d.rigState);
  return d.rigState.jointMatrices;
}

SimulationState Simulation::stateAt(int frame) {
  impl_->checkFrame(frame, "the state's");
  return impl_->state(frame);
}

void Simulation::restore(const SimulationState& s) {
  Impl& d = *impl_;
  const std::string why = "simulation: the state was made ";
  if (s.fps != d.options.fps) throw InputError(why + "at " + std::to_string(s.fps) + " fps, this run is at " + std::to_string(d.options.fps));
  if (s.startFrame != d.start) throw InputError(why + "for a sequence starting at frame " + std::to_string(s.startFrame));
  if (s.hasJiggle != static_cast<bool>(d.jiggle)) throw InputError(why + (s.hasJiggle ? "with" : "without") + " jiggle");
  if (s.hasSettings) {  // the first setting that differs, by name
    const std::map<std::string, std::string> now = d.settings();
    for (const auto& [name, value] : now) {
      const auto it = s.settings.find(name);
      const std::string then = it == s.settings.end() ? "nothing" : it->second;
      if (then != value) throw InputError(why + "with " + name + " " + then + ", this run has " + value);
    }
    for (const auto& [name, value] : s.settings)
      if (!now.count(name)) throw InputError(why + "with " + name + " " + value + ", this run has nothing");
  }
  d.checkFrame(s.frame, "the state's");
  d.invalidate();  // raw frames kept from another history
  if (!d.jiggle) return;
  if (s.timeStep != d.options.jiggleOptions.timeStep) throw InputError(why + "with another jiggle time step");
  std::vector<std::string> names;
  for (const Muscle& m : d.rig->muscles()) names.push_back(m.name);
  if (s.muscles != names) throw InputError(why + "for other muscles");
  // The state must be the grid state of its frame.
  if (d.jiggle->stepOf(s.frame) != s.jiggle.step)
    throw InputError(why + "for another frame than it says (grid step " + std::to_string(s.jiggle.step) + ", frame " +
                     std::to_string(s.frame) + " is at step " + std::to_string(d.jiggle->stepOf(s.frame)) + ")");
  d.jiggle->restore(s.jiggle);
}

SimulationState Simulation::bake(int first, int last, const std::function<void(int, const PointsF&)>& sink,
                                 const SimulationState* stateIn) {
  Impl& d = *impl_;
  d.checkFrame(first, "the first");
  d.checkFrame(last, "the last");
  if (last < first) throw InputError("simulation: the last frame comes before the first");
  if (stateIn) {
    // The filter looks two frames back, so a chunk from `first` starts from the state of first - 2 (or earlier:
    // replaying forward from any earlier state gives the same bits).
    const int needed = std::max(d.start, first - 2);
    if (stateIn->frame > needed)
      throw InputError("simulation: the state is for frame " + std::to_string(stateIn->frame) + ", a chunk from frame " +
                       std::to_string(first) + " needs the state of frame " + std::to_string(needed) + " or earlier");
    restore(*stateIn);
    d.invalidate();
  }
  PointsF out;
  for (int f = first; f <= last; ++f) {
    d.filtered(f, out);
    if (d.sculpt) d.sculpt->apply(out, out);
    sink(f, out);
  }
  return d.state(std::max(d.start, last - 1));
}

}  // namespace myoskin
