// Jiggle of the muscle masses: one damped spring per muscle, integrated exactly on a fixed time grid.
// Between two grid points the goal moves linearly, so the relative offset d = x - g is a free damped
// oscillator there (propagated by the exact 2x2 matrix exponential: no growth at any step, exact decay), and
// at each grid point the goal's change of velocity enters as a jump of the relative velocity.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include "myoskin/errors.h"
#include "myoskin/secondary_motion.h"

namespace myoskin {

namespace {


// ============================================================================
// Muscle size
// ============================================================================

// Mean section radius sqrt(a b) of a muscle (its rest surface's size when it has no sections).
double meanRadius(const Muscle& m) {
  if (m.sections.empty()) return 0.0;
  double r = 0.0;
  for (const MuscleSection& s : m.sections) r += std::sqrt(s.a * s.b);
  return r / static_cast<double>(m.sections.size());
}

// Volume of the elliptical sections swept along their centres (trapezoids), or one section over the root curve.
double volumeOf(const Muscle& m) {
  double length = 0.0;
  for (size_t i = 1; i < m.rootCurve.size(); ++i) length += (m.rootCurve[i] - m.rootCurve[i - 1]).norm();
  if (m.sections.size() < 2) return m.sections.empty() ? 0.0 : kPi * m.sections[0].a * m.sections[0].b * length;
  double v = 0.0;
  for (size_t i = 1; i < m.sections.size(); ++i) {
    const MuscleSection &s0 = m.sections[i - 1], &s1 = m.sections[i];
    v += 0.5 * kPi * (s0.a * s0.b + s1.a * s1.b) * (s1.center - s0.center).norm();
  }
  return v;
}

void checkOptions(const JiggleOptions& o) {
  if (!(o.timeStep > 0.0) || !(o.timeStep <= 0.1)) throw InputError("jiggle: timeStep must be in (0, 0.1] seconds");
  if (!(o.frequency > 0.0) || !std::isfinite(o.frequency)) throw InputError("jiggle: frequency must be > 0 Hz");
  if (!std::isfinite(o.sizeExponent)) throw InputError("jiggle: sizeExponent must be finite");
  if (!(o.dampingRatio >= 0.0) || !std::isfinite(o.dampingRatio)) throw InputError("jiggle: dampingRatio must be >= 0");
  if (!(o.density > 0.0) || !std::isfinite(o.density)) throw InputError("jiggle: density must be > 0");
  if (!(o.amount >= 0.0) || !std::isfinite(o.amount)) throw InputError("jiggle: amount must be >= 0");
  if (!(o.maxOffset > 0.0) || !std::isfinite(o.maxOffset)) throw InputError("jiggle: maxOffset must be > 0");
  if (o.checkpointFrames < 1) throw InputError("jiggle: checkpointFrames must be >= 1");
}

// Exact propagator exp(A h) of d'' = -(k/m) d - (c/m) d' over one step: [d, v] <- P [d, v].
Eigen::Matrix2d propagator(const JiggleParams& p, double h) {
  Eigen::Matrix2d A;
  A << 0.0, 1.0, -p.stiffness / p.mass, -p.damping / p.mass;
  const double half = 0.5 * A.trace(), det = A.determinant();
  const double q2 = half * half - det;  // exp(Ah) = e^{half h} (C I + S (A - half I))
  double C, S;
  if (q2 > 1e-12 * det) {
    const double q = std::sqrt(q2);
    C = std::cosh(q * h), S = std::sinh(q * h) / q;
  } else if (q2 < -1e-12 * det) {
    const double q = std::sqrt(-q2);
    C = std::cos(q * h), S = std::sin(q * h) / q;
  } else {
    C = 1.0, S = h;
  }
  return std::exp(half * h) * (C * Eigen::Matrix2d::Identity() + S * (A - half * Eigen::Matrix2d::Identity()));
}

}  // namespace

// ============================================================================
// Defaults
// ============================================================================

std::vector<JiggleParams> defaultJiggleParams(const MuscleRig& rig, const JiggleOptions& options) {
  checkOptions(options);
  const std::vector<Muscle>& muscles = rig.muscles();
  std::vector<double> radius(muscles.size());
  for (size_t m = 0; m < muscles.size(); ++m) radius[m] = meanRadius(muscles[m]);
  std::vector<double> sorted = radius;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted.empty() ? 0.0 : sorted[sorted.size() / 2];
  std::vector<JiggleParams> params(muscles.size());
  for (size_t m = 0; m < muscles.size(); ++m) {
    double volume = volumeOf(muscles[m]);
    if (!(volume > 0.0)) volume = 1e-6;  // no sections: a nominal mass (the frequency sets the motion)
    const double ratio = radius[m] > 0.0 && median > 0.0 ? median / radius[m] : 1.0;
    const double f = options.frequency * std::pow(ratio, options.sizeExponent);
    const double omega = 2.0 * kPi * f;
    JiggleParams& p = params[m];
    p.mass = options.density * volume;
    p.stiffness = p.mass * omega * omega;
    p.damping = 2.0 * options.dampingRatio * std::sqrt(p.stiffness * p.mass);
  }
  return params;
}

std::vector<double> defaultJiggleInfluence(const MuscleRig& rig) {
  std::vector<double> influence(rig.numJoints(), 0.0);
  for (int m = 0; m < rig.numMuscles(); ++m) {
    const Muscle& mu = rig.muscles()[m];
    const Vec3 axis = mu.insertion.position - mu.origin.position;
    const double len2 = axis.squaredNorm();
    for (int k = 0; k < rig.jointCount(m); ++k) {
      const int j = rig.jointOffset(m) + k;
      const Vec3 p = rig.bindMatrices()[j].block<3, 1>(0, 3);
      const double t = len2 > 0.0 ? std::clamp((p - mu.origin.position).dot(axis) / len2, 0.0, 1.0) : 0.5;
      influence[j] = std::sin(kPi * t);
    }
  }
  return influence;
}

// ============================================================================
// JiggleTrack
// ============================================================================

struct JiggleTrack::Impl {
  explicit Impl(const MuscleRig& r) : rig(r) {}
  MuscleRig rig;
  std::vector<Pose> poses;
  double startFrame = 0.0, fps = 24.0;
  JiggleOptions options;
  std::vector<JiggleParams> params;
  std::vector<double> influence;
  std::vector<double> limit;                 // #M soft limit (maxOffset x mean radius)
  std::vector<Eigen::VectorXd> surfaceInfluence;  // #M: per rest surface vertex, the joints' influence there
  std::vector<Eigen::Matrix2d> step;         // #M propagators over timeStep
  double stepsPerFrame = 10.0;               // 1 / (fps timeStep)
  // Goals (#F x #M), evaluated lazily per frame.
  std::vector<Vec3> goals;
  std::vector<char> haveGoal;
  MuscleRigState rigState;
  // The working state and the kept ones.
  JiggleState current;
  bool currentValid = false;
  std::map<int64_t, JiggleState> kept;
  std::set<int64_t> keepSteps;               // grid steps of every checkpointFrames-th frame
  JiggleState ahead;                         // scratch: the step after `current`
  std::vector<Vec3> goalA, goalB;            // scratch goals of one step
  std::vector<Vec3> applied;                 // scratch offsets of apply()

  int numMuscles() const { return static_cast<int>(params.size()); }
  int numFrames() const { return static_cast<int>(poses.size()); }

  // Goal of muscle m for frame index i: the influence-weighted mean of its posed joint positions.
  const Vec3* frameGoals(int i) {
    const int M = numMuscles();
    if (!haveGoal[i]) {
      rig.evaluate(poses[i], rigState);
      for (int m = 0; m < M; ++m) {
        Vec3 sum = Vec3::Zero();
        double w = 0.0;
        const int first = rig.jointOffset(m), count = rig.jointCount(m);
        for (int k = 0; k < count; ++k) {
          const double wk = influence[first + k] > 0.0 ? influence[first + k] : 0.0;
          sum += wk * rigState.jointMatrices[first + k].block<3, 1>(0, 3);
          w += wk;
        }
        if (!(w > 0.0)) {
          sum.setZero();
          for (int k = 0; k < count; ++k) sum += rigState.jointMatrices[first + k].block<3, 1>(0, 3);
          w = count;
        }
        goals[static_cast<size_t>(i) * M + m] = sum / w;
      }
      haveGoal[i] = 1;
    }
    return &goals[static_cast<size_t>(i) * M];
  }

  // Goals at grid step k: linear between the frames around it (constant past the last frame).
  void goalsAt(int64_t k, std::vector<Vec3>& out) {
    const double s = static_cast<double>(k) / stepsPerFrame;  // frames from the start
    const int F = numFrames(), M = numMuscles();
    int i = static_cast<int>(std::floor(s + 1e-9));
    double a = s - i;
    if (a < 1e-9) a = 0.0;
    if (i >= F - 1) i = F - 1, a = 0.0;
    const Vec3* g0 = frameGoals(i);
    if (a == 0.0) {
      for (int m = 0; m < M; ++m) out[m] = g0[m];
      return;
    }
    const Vec3* g1 = frameGoals(i + 1);
    for (int m = 0; m < M; ++m) out[m] = g0[m] + a * (g1[m] - g0[m]);  // exact where the goal stands
  }

  void initial(JiggleState& s) {
    const int M = numMuscles();
    s.step = 0;
    s.offset.assign(M, Vec3::Zero());
    s.velocity.assign(M, Vec3::Zero());
    s.goalVelocity.assign(M, Vec3::Zero());
    // Start at rest relative to a goal already moving: no jolt at the start frame.
    goalsAt(0, goalA);
    goalsAt(1, goalB);
    for (int m = 0; m < M; ++m) s.goalVelocity[m] = (goalB[m] - goalA[m]) / options.timeStep;
  }

  // One grid step of s (in place).
  void advance(JiggleState& s) {
    const int M = numMuscles();
    goalsAt(s.step, goalA);
    goalsAt(s.step + 1, goalB);
    for (int m = 0; m < M; ++m) {
      const Vec3 u = (goalB[m] - goalA[m]) / options.timeStep;
      Vec3 v = s.velocity[m] + s.goalVelocity[m] - u;  // x' continuous, so d' jumps by -(change of g')
      const Eigen::Matrix2d& P = step[m];
      const Vec3 d = s.offset[m];
      s.offset[m] = P(0, 0) * d + P(0, 1) * v;
      s.velocity[m] = P(1, 0) * d + P(1, 1) * v;
      s.goalVelocity[m] = u;
    }
    ++s.step;
  }

  // Grid position of a frame: its step and the fraction toward the next one.
  void gridOf(double frame, int64_t& k, double& frac) const {
    if (!std::isfinite(frame) || frame < startFrame - 1e-9 || frame > startFrame + numFrames() - 1 + 1e-9)
      throw InputError("jiggle: frame " + std::to_string(frame) + " is outside the sequence (" +
                       std::to_string(startFrame) + " to " + std::to_string(startFrame + numFrames() - 1) + ")");
    const double x = std::max(0.0, frame - startFrame) * stepsPerFrame;
    k = static_cast<int64_t>(std::floor(x + 1e-9));
    frac = x - static_cast<double>(k);
    if (frac < 1e-9) frac = 0.0;
  }

  // Brings `current` to grid step k: forward from itself when it is at or before k, else from the last kept
  // state at or before k (or the start).
  void seek(int64_t k) {
    if (!currentValid || current.step > k) {
      auto it = kept.upper_bound(k);
      if (it == kept.begin()) {
        initial(current);
      } else {
        --it;
        current = it->second;
      }
      currentValid = true;
    }
    while (current.step < k) {
      advance(current);
      if (keepSteps.count(current.step) && !kept.count(current.step)) kept.emplace(current.step, current);
    }
  }

  // Spring offsets at a frame (interpolated between grid states).
  void spring(double frame, std::vector<Vec3>& out) {
    int64_t k;
    double frac;
    gridOf(frame, k, frac);
    seek(k);
    out.resize(numMuscles());
    if (frac == 0.0) {
      for (int m = 0; m < numMuscles(); ++m) out[m] = current.offset[m];
      return;
    }
    ahead = current;
    advance(ahead);
    for (int m = 0; m < numMuscles(); ++m) out[m] = current.offset[m] + frac * (ahead.offset[m] - current.offset[m]);
  }
};

JiggleTrack::JiggleTrack(const MuscleRig& rig, const PoseSequence& poses, double fps, const JiggleOptions& options,
                         std::vector<JiggleParams> params, std::vector<double> influence)
    : impl_(std::make_unique<Impl>(rig)) {
  checkOptions(options);
  if (!(fps > 0.0) || !std::isfinite(fps)) throw InputError("jiggle: fps must be > 0");
  if (poses.frames.empty()) throw InputError("jiggle: the pose sequence has no frames");
  if (!std::isfinite(poses.startFrame)) throw InputError("jiggle: the start frame is not finite");
  Impl& d = *impl_;
  const int M = rig.numMuscles();
  if (params.empty()) params = defaultJiggleParams(rig, options);
  if (influence.empty()) influence = defaultJiggleInfluence(rig);
  if (static_cast<int>(params.size()) != M)
    throw InputError("jiggle: " + std::to_string(params.size()) + " spring parameters for " + std::to_string(M) + " muscles");
  if (static_cast<int>(influence.size()) != rig.numJoints())
    throw InputError("jiggle: " + std::to_string(influence.size()) + " influences for " +
                     std::to_string(rig.numJoints()) + " muscle joints");
  for (int m = 0; m < M; ++m) {
    const JiggleParams& p = params[m];
    const std::string name = "jiggle: muscle '" + rig.muscles()[m].name + "': ";
    if (!(p.mass > 0.0) || !std::isfinite(p.mass)) throw InputError(name + "mass must be > 0");
    if (!(p.stiffness > 0.0) || !std::isfinite(p.stiffness)) throw InputError(name + "stiffness must be > 0");
    if (!(p.damping >= 0.0) || !std::isfinite(p.damping)) throw InputError(name + "damping must be >= 0");
  }
  for (size_t j = 0; j < influence.size(); ++j)
    if (!(influence[j] >= 0.0) || !std::isfinite(influence[j]))
      throw InputError("jiggle: influence of joint " + std::to_string(j) + " must be finite and >= 0");
  const int B = rig.skeleton().numBones();
  for (size_t f = 0; f < poses.frames.size(); ++f) {
    const Pose& p = poses.frames[f];
    if (static_cast<int>(p.matrices.size()) != B)
      throw InputError("jiggle: frame " + std::to_string(f) + " has " + std::to_string(p.matrices.size()) +
                       " bone matrices for " + std::to_string(B) + " bones");
    for (const Mat4& m : p.matrices)
      if (!m.allFinite()) throw InputError("jiggle: frame " + std::to_string(f) + " has a non-finite bone matrix");
  }
  d.poses = poses.frames;
  d.startFrame = poses.startFrame;
  d.fps = fps;
  d.options = options;
  d.params = std::move(params);
  d.influence = std::move(influence);
  d.stepsPerFrame = 1.0 / (fps * options.timeStep);
  d.limit.resize(M);
  d.step.resize(M);
  for (int m = 0; m < M; ++m) {
    double r = meanRadius(rig.muscles()[m]);
    if (!(r > 0.0)) r = 0.01 * (rig.muscles()[m].insertion.position - rig.muscles()[m].origin.position).norm() + 1e-12;
    d.limit[m] = options.maxOffset * r;
    d.step[m] = propagator(d.params[m], options.timeStep);
  }
  // The surfaces' vertices move with the joints: influence interpolated along origin -> insertion between the
  // joints' rest positions (constant past the end joints).
  d.surfaceInfluence.resize(M);
  for (int m = 0; m < M; ++m) {
    const Muscle& mu = rig.muscles()[m];
    const Vec3 o = mu.origin.position, axis = mu.insertion.position - o;
    const double len2 = std::max(axis.squaredNorm(), 1e-30);
    std::vector<std::pair<double, double>> stations;  // (t, influence) of the joints
    for (int k = 0; k < rig.jointCount(m); ++k) {
      const int j = rig.jointOffset(m) + k;
      stations.emplace_back((rig.bindMatrices()[j].block<3, 1>(0, 3) - o).dot(axis) / len2, d.influence[j]);
    }
    std::sort(stations.begin(), stations.end());
    const Points& sv = rig.restSurface(m).vertices;
    Eigen::VectorXd& w = d.surfaceInfluence[m];
    w.resize(sv.rows());
    for (Eigen::Index v = 0; v < sv.rows(); ++v) {
      const double t = (sv.row(v).transpose() - o).dot(axis) / len2;
      size_t i = 0;
      while (i < stations.size() && stations[i].first < t) ++i;
      if (i == 0)
        w[v] = stations.front().second;
      else if (i == stations.size())
        w[v] = stations.back().second;
      else {
        const auto &a = stations[i - 1], &b = stations[i];
        const double span = b.first - a.first;
        w[v] = span > 0.0 ? a.second + (b.second - a.second) * (t - a.first) / span : b.second;
      }
    }
  }
  d.goals.assign(static_cast<size_t>(d.numFrames()) * M, Vec3::Zero());
  d.haveGoal.assign(d.numFrames(), 0);
  d.rigState = rig.makeState();
  d.goalA.resize(M);
  d.goalB.resize(M);
  for (int f = 0; f < d.numFrames(); f += options.checkpointFrames) {
    int64_t k;
    double frac;
    d.gridOf(d.startFrame + f, k, frac);
    d.keepSteps.insert(k);
  }
}

JiggleTrack::~JiggleTrack() = default;
JiggleTrack::JiggleTrack(JiggleTrack&&) noexcept = default;
JiggleTrack& JiggleTrack::operator=(JiggleTrack&&) noexcept = default;

double JiggleTrack::firstFrame() const { return impl_->startFrame; }
double JiggleTrack::lastFrame() const { return impl_->startFrame + impl_->numFrames() - 1; }
const std::vector<JiggleParams>& JiggleTrack::params() const { return impl_->params; }
const std::vector<double>& JiggleTrack::influence() const { return impl_->influence; }
const JiggleOptions& JiggleTrack::options() const { return impl_->options; }

void JiggleTrack::springOffsets(double frame, std::vector<Vec3>& out) { impl_->spring(frame, out); }

void JiggleTrack::offsets(double frame, std::vector<Vec3>& out) {
  Impl& d = *impl_;
  d.spring(frame, out);
  for (int m = 0; m < d.numMuscles(); ++m) {
    Vec3 o = d.options.amount * out[m];
    const double knee = 0.5 * d.limit[m], n = o.norm();
    if (n > knee) o *= (knee + knee * std::tanh((n - knee) / knee)) / n;  // C1: slope 1 at the knee
    out[m] = o;
  }
}

void JiggleTrack::apply(double frame, MuscleRigState& state) {
  Impl& d = *impl_;
  if (static_cast<int>(state.jointMatrices.size()) != d.rig.numJoints())
    throw InputError("jiggle: the rig state has " + std::to_string(state.jointMatrices.size()) + " joints, the rig " +
                     std::to_string(d.rig.numJoints()));
  std::vector<Vec3>& o = d.applied;
  offsets(frame, o);
  for (int m = 0; m < d.numMuscles(); ++m)
    for (int k = 0; k < d.rig.jointCount(m); ++k) {
      const int j = d.rig.jointOffset(m) + k;
      state.jointMatrices[j].block<3, 1>(0, 3) += d.influence[j] * o[m];
    }
  // Posed surfaces (when evaluated) move with their joints, so a skin solve collides with the jiggled muscles.
  if (state.surfaces.size() == static_cast<size_t>(d.numMuscles()))
    for (int m = 0; m < d.numMuscles(); ++m) {
      Points& sv = state.surfaces[m];
      const Eigen::VectorXd& w = d.surfaceInfluence[m];
      if (sv.rows() != w.size()) continue;  // not evaluated with surfaces
      for (Eigen::Index v = 0; v < sv.rows(); ++v) sv.row(v) += w[v] * o[m].transpose();
    }
}

JiggleState JiggleTrack::stateAt(double frame) {
  int64_t k;
  double frac;
  impl_->gridOf(frame, k, frac);
  impl_->seek(k);
  return impl_->current;
}

int64_t JiggleTrack::stepOf(double frame) const {
  int64_t k;
  double frac;
  impl_->gridOf(frame, k, frac);
  return k;
}

void JiggleTrack::restore(const JiggleState& state) {
  Impl& d = *impl_;
  const size_t M = d.params.size();
  if (state.offset.size() != M || state.velocity.size() != M || state.goalVelocity.size() != M)
    throw InputError("jiggle: the state has " + std::to_string(state.offset.size()) + " muscles, the rig " +
                     std::to_string(M));
  const int64_t lastStep = static_cast<int64_t>(std::ceil((d.numFrames() - 1) * d.stepsPerFrame)) + 1;
  if (state.step < 0 || state.step > lastStep) throw InputError("jiggle: the state's step is outside the sequence");
  for (size_t m = 0; m < M; ++m)
    if (!state.offset[m].allFinite() || !state.velocity[m].allFinite() || !state.goalVelocity[m].allFinite())
      throw InputError("jiggle: the state has a non-finite value");
  // Later kept states came from another history: drop them.
  d.kept.erase(d.kept.upper_bound(state.step), d.kept.end());
  d.kept[state.step] = state;
  d.current = state;
  d.currentValid = true;
}

void JiggleTrack::setPose(int index, const Pose& pose) {
  Impl& d = *impl_;
  if (index < 0 || index >= d.numFrames())
    throw InputError("jiggle: pose index " + std::to_string(index) + " outside the sequence");
  if (static_cast<int>(pose.matrices.size()) != d.rig.skeleton().numBones())
    throw InputError("jiggle: the pose has the wrong number of bones");
  for (const Mat4& m : pose.matrices)
    if (!m.allFinite()) throw InputError("jiggle: the pose has a non-finite bone matrix");
  d.poses[index] = pose;
  d.haveGoal[index] = 0;
  // Grid steps from the frame before it on use its goal.
  const int64_t from = static_cast<int64_t>(std::floor(std::max(0, index - 1) * d.stepsPerFrame + 1e-9));
  d.kept.erase(d.kept.upper_bound(from), d.kept.end());
  if (d.currentValid && d.current.step > from) d.currentValid = false;
}

}  // namespace myoskin
