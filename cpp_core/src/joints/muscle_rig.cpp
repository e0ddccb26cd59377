// MuscleRig: a muscle's rest geometry stored in the frame of its rest action path, re-mapped onto the
// posed path each evaluate(). Stations evenly spaced in normalised arc length carry a transform
//   M_j = T(P_j) R(F_j) diag(s_j, lambda, s_j)       (Y = path tangent, Blender's bone convention);
// muscle joints sit on stations (so their matrices are exactly translation * rotation * scale, which a
// Blender bone can hold), and surface vertices blend the two stations around their rest path parameter.
#include <algorithm>
#include <cmath>
#include <limits>

#include "joints/bulge.h"
#include "muscles/muscle_util.h"
#include "myoskin/deformation.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "paths/action_path.h"

namespace myoskin {

namespace {

constexpr int kMaxRigJoints = 64;
constexpr int kMaxRigStations = 2 * kMaxRigJoints + 1;
constexpr double kMinMuscleStretch = 1e-3, kMaxMuscleStretch = 1e3;

// Orthonormal rotation part of a posed bone matrix (posed bones may carry scale).
Mat3 orthonormalRotationOf(const Mat4& m) {
  Mat3 r = m.topLeftCorner<3, 3>();
  Vec3 y = r.col(1).normalized();
  Vec3 x = (r.col(0) - r.col(0).dot(y) * y).normalized();
  Mat3 out;
  out.col(0) = x;
  out.col(1) = y;
  out.col(2) = x.cross(y);
  return out;
}

Vec3 transformPoint(const Mat4& m, const Vec3& p) { return m.topLeftCorner<3, 3>() * p + m.topRightCorner<3, 1>(); }

// The bone of the chain from bone a to bone b (through their common ancestor; both paths to the roots when there is
// none) whose segment lies nearest to p.
int nearestChainBone(const Skeleton& skeleton, int a, int b, const Vec3& p) {
  std::vector<int> upA, upB;
  for (int x = a; x >= 0; x = skeleton.bones[x].parent) upA.push_back(x);
  for (int x = b; x >= 0; x = skeleton.bones[x].parent) upB.push_back(x);
  std::vector<int> chain;
  for (int x : upA) {
    chain.push_back(x);
    if (std::find(upB.begin(), upB.end(), x) != upB.end()) break;
  }
  for (int x : upB) {
    if (std::find(chain.begin(), chain.end(), x) != chain.end()) break;
    chain.push_back(x);
  }
  int best = a;
  double bestDistance = std::numeric_limits<double>::infinity();
  for (int x : chain) {
    const double distance = (p - detail::closestOnSegment(p, skeleton.bones[x].head, skeleton.bones[x].tail)).norm();
    if (distance < bestDistance) best = x, bestDistance = distance;
  }
  return best;
}

// A rest point carried by a bone (MuscleRigOptions::jointsSlide = false, and the slide limits): the bone, the point and
// the bone's unit axis in the bone's rest frame.
struct BoneCarry {
  int bone = 0;
  Vec3 restLocal = Vec3::Zero(), axisLocal = Vec3::UnitY();
};

BoneCarry carryOnChain(const Skeleton& skeleton, const Pose& rest, int a, int b, const Vec3& p) {
  BoneCarry c;
  c.bone = nearestChainBone(skeleton, a, b, p);
  const Mat4 inverse = rest.matrices[c.bone].inverse();
  const Bone& bone = skeleton.bones[c.bone];
  c.restLocal = inverse.topLeftCorner<3, 4>() * p.homogeneous();
  c.axisLocal = (inverse.topLeftCorner<3, 3>() * (bone.tail - bone.head)).normalized();
  return c;
}

// p with its offset along the carrying bone's posed axis from the carried rest point removed.
Vec3 alongAsTheBone(const BoneCarry& c, const Pose& pose, const Vec3& p) {
  const Mat4& B = pose.matrices[c.bone];
  const Vec3 axis = (orthonormalRotationOf(B) * c.axisLocal).normalized();
  return p - (p - transformPoint(B, c.restLocal)).dot(axis) * axis;
}

// p with its offset o along the carrying bone's posed axis from the carried rest point made rho tanh(o / rho), rho
// the limit on o's side (rho[0] towards the bone's head, rho[1] towards its tail; 0 = none).
Vec3 slideLimited(const BoneCarry& c, const Pose& pose, const Vec3& p, const std::array<double, 2>& rho) {
  if (rho[0] <= 0 && rho[1] <= 0) return p;  // no limit either way: nothing to transform
  const Mat4& B = pose.matrices[c.bone];
  const Vec3 axis = (orthonormalRotationOf(B) * c.axisLocal).normalized();
  const double o = (p - transformPoint(B, c.restLocal)).dot(axis);
  const double r = rho[o > 0 ? 1 : 0];
  return r > 0 ? Vec3(p + (r * std::tanh(o / r) - o) * axis) : p;
}

// A frame with Y along `y` whose X is the component of `xHint` perpendicular to it.
Mat3 frameFromY(const Vec3& y, const Vec3& xHint) {
  Vec3 Y = y.normalized();
  Vec3 X = xHint - xHint.dot(Y) * Y;
  if (X.norm() < 1e-9) X = Y.unitOrthogonal();
  X.normalize();
  Mat3 F;
  F.col(0) = X;
  F.col(1) = Y;
  F.col(2) = X.cross(Y);
  return F;
}

bool finiteMatrix(const Mat4& m) { return m.allFinite(); }

// A blend of two frames: (1 - w) a + w b by slerp.
Mat3 slerpFrames(const Mat3& a, const Mat3& b, double w) {
  return Eigen::Quaterniond(a).slerp(w, Eigen::Quaterniond(b)).normalized().toRotationMatrix();
}

}  // namespace

// ============================================================================
// The rest model of one muscle
// ============================================================================

struct MuscleModel {
  int originBone = -1, insertionBone = -1, wrapBone = -1, sideBone = -1;
  WrapType wrap = WrapType::None;
  double radius = 0.0;
  int side = 1;
  Vec3 originLocal, insertionLocal;  // in the rest frames of their bones
  Vec3 sideLocal = Vec3::Zero();     // joint wrap: side direction in sideBone's rest frame
  double restLength = 0.0;
  // A joint wrap's two ways round (PosedWays) share them, so a frame depends on the path's shape alone, not on which
  // way it is called: the start of the way that weighs more at rest, the end of the rest path (the ways blended).
  Vec3 tangentLocal;                 // rest start tangent in the origin bone's frame
  Mat3 frameLocal;                   // rest start frame in the origin bone's frame
  Vec3 endTangentLocal;              // rest end tangent in the insertion bone's frame
  Mat3 endFrameLocal;                // rest end frame in the insertion bone's frame
  int stations = 0, jointStride = 0, joints = 0;  // joint k sits on station (2k + 1) * jointStride
  std::vector<double> twistShare;    // #stations: share of the end twist each station turns by
  std::vector<Vec3> jointOffset;     // #joints rest root-curve point in its station's frame
  std::vector<BoneCarry> jointCarry;    // #joints the chain bone nearest to each joint at rest (jointsSlide = false,
                                        // slideLimit)
  std::vector<BoneCarry> stationCarry;  // #stations the same for each rest station
  std::vector<std::array<double, 2>> slideLimit;    // #joints MuscleRigOptions::slideLimits (0 = none)
  std::vector<std::array<double, 2>> stationLimit;  // #stations the joints' limits interpolated as 1 / rho (0 = none)
  joints::BulgeProfile bulge;
  // Surface: each vertex blends stations j and j + 1 with weights (1 - alpha, alpha); local
  // coordinates in each station's rest frame.
  Mesh surface;
  std::vector<int> vertexStation;
  std::vector<double> vertexAlpha;
  std::vector<Vec3> localA, localB;
};

// The posed action path: path[0] alone (weight 1), or a joint wrap's short way path[0] and long way path[1] with their
// weights (summing to 1; a way of weight 0 is not evaluated).
struct PosedWays {
  paths::ActionPath path[2];
  double weight[2] = {1.0, 0.0};
  double length() const { return weight[0] * path[0].length + weight[1] * path[1].length; }
  bool wrapped() const { return path[weight[1] > weight[0] ? 1 : 0].wrapped; }
};

// Per pose, once: each weighing way's start frame and the blended path's end twist.
struct PosedFrames {
  Mat3 start[2];
  double twist = 0.0;
};

struct MuscleRig::Impl {
  Skeleton skeleton;
  std::vector<Muscle> muscles;
  std::vector<MuscleModel> models;
  std::vector<std::string> jointNames;
  std::vector<int> jointMuscle, jointParent, offsets;
  std::vector<Mat4> bind;
  std::vector<double> restLengths;

  // Posed origin/insertion and the action path of muscle m (both ways round a joint wrap).
  void posedWays(int m, const Pose& pose, PosedWays& ways) const;
  // Start frame of a posed path (rest frame carried by the origin bone, turned onto the tangent).
  Mat3 startFrame(int m, const Pose& pose, const paths::ActionPath& path) const;
  // Twist (radians about the end tangent) from the frame carried to the path's end to the frame the
  // insertion bone carries there; shared along the path by MuscleModel::twistShare.
  double endTwist(int m, const Pose& pose, const Mat3& carried) const;
  // The start frames of the ways that weigh and the end twist of their blend (the frame carried to each way's end,
  // blended by slerp). For the rest model (`restEnd`): no twist, and that carried end frame out.
  void posedFrames(int m, const Pose& pose, const PosedWays& ways, PosedFrames& frames, Mat3* restEnd = nullptr) const;
  // Frames and points at stations st[0..n) (increasing), the ways blended by their weights (points linearly, frames
  // by slerp), then turned by their share of the end twist.
  void stationsAt(int m, const PosedWays& ways, const PosedFrames& frames, const int* st, int n, Mat3* F,
                  Vec3* P) const;
  bool distributeTwist = true;
  bool twistFollowsBones = true;
  bool jointsSlide = true;
  std::vector<std::array<double, 2>> slideLimits;  // #J (0 = none)
  std::vector<Vec3> slideAxes;                      // #J rest axis of each joint's carrying bone
};

void MuscleRig::Impl::posedWays(int m, const Pose& pose, PosedWays& ways) const {
  const MuscleModel& mm = models[m];
  const Vec3 O = transformPoint(pose.matrices[mm.originBone], mm.originLocal);
  const Vec3 I = transformPoint(pose.matrices[mm.insertionBone], mm.insertionLocal);
  ways.weight[0] = 1.0, ways.weight[1] = 0.0;
  paths::ActionPath& path = ways.path[0];
  switch (mm.wrap) {
    case WrapType::None: paths::straightPath(O, I, path); return;
    case WrapType::Joint: {
      const Mat4& wb = pose.matrices[mm.wrapBone];
      const Vec3 side = orthonormalRotationOf(pose.matrices[mm.sideBone]) * mm.sideLocal;
      double longWeight;
      paths::jointWrapWays(O, I, wb.topRightCorner<3, 1>(), mm.radius, side, ways.path[0], ways.path[1], longWeight);
      ways.weight[0] = 1.0 - longWeight, ways.weight[1] = longWeight;
      return;
    }
    case WrapType::Bone: {
      const Mat4& wb = pose.matrices[mm.wrapBone];
      const Mat3 R = orthonormalRotationOf(wb);
      // Right-handed (e1, e2, axis) = (Z, X, Y) of the bone.
      paths::boneWrapPath(O, I, wb.topRightCorner<3, 1>(), R.col(2), R.col(0), R.col(1), mm.radius, mm.side, path);
      return;
    }
  }
}

// The frame a bone carries onto a path tangent: its rest frame (local to the bone) turned by the least
// rotation that takes the rest tangent to the posed one (both in the bone's frame).
Mat3 boneCarriedFrame(const Mat4& boneMatrix, const Vec3& restTangentLocal, const Mat3& restFrameLocal, Vec3 t,
                      bool degenerate) {
  const Mat3 R = orthonormalRotationOf(boneMatrix);
  if (degenerate) t = R * restTangentLocal;  // origin on the insertion: keep the rest direction
  const Vec3 tLocal = R.transpose() * t;
  const Mat3 turn = Eigen::Quaterniond::FromTwoVectors(restTangentLocal, tLocal).toRotationMatrix();
  const Mat3 F = R * turn * restFrameLocal;
  return frameFromY(t, F.col(0));  // re-orthonormalise exactly onto the tangent
}

Mat3 MuscleRig::Impl::startFrame(int m, const Pose& pose, const paths::ActionPath& path) const {
  const MuscleModel& mm = models[m];
  Vec3 p, t;
  paths::pointAt(path, 0.0, p, t);
  return boneCarriedFrame(pose.matrices[mm.originBone], mm.tangentLocal, mm.frameLocal, t, path.length < 1e-12);
}

double MuscleRig::Impl::endTwist(int m, const Pose& pose, const Mat3& carried) const {
  const MuscleModel& mm = models[m];
  const Mat3 target = boneCarriedFrame(pose.matrices[mm.insertionBone], mm.endTangentLocal, mm.endFrameLocal,
                                       carried.col(1), false);
  const Vec3 a = carried.col(0), b = target.col(0);
  return std::atan2(a.cross(b).dot(carried.col(1)), a.dot(b));  // in (-pi, pi]: a roll past 180 degrees wraps
}

void MuscleRig::Impl::posedFrames(int m, const Pose& pose, const PosedWays& ways, PosedFrames& frames,
                                  Mat3* restEnd) const {
  const bool twists = distributeTwist && !restEnd && ways.length() >= 1e-12;
  Mat3 ends[2];
  for (int k = 0; k < 2; ++k) {
    if (!(ways.weight[k] > 0.0)) continue;
    frames.start[k] = startFrame(m, pose, ways.path[k]);
    if (twists || restEnd) ends[k] = paths::frameAt(ways.path[k], frames.start[k], ways.path[k].length);
  }
  frames.twist = 0.0;
  if (!twists && !restEnd) return;
  const double w = ways.weight[1];
  const Mat3 carried = w > 0.0 && w < 1.0 ? slerpFrames(ends[0], ends[1], w) : ends[w > 0.0 ? 1 : 0];
  if (restEnd) *restEnd = carried;
  if (twists) frames.twist = endTwist(m, pose, carried);
}

void MuscleRig::Impl::stationsAt(int m, const PosedWays& ways, const PosedFrames& frames, const int* st, int n,
                                 Mat3* F, Vec3* P) const {
  const MuscleModel& mm = models[m];
  const int last = mm.stations - 1;
  double sig[kMaxRigStations];
  Mat3 Fk[kMaxRigStations];
  Vec3 Pk[kMaxRigStations];
  const double w = ways.weight[1];
  const bool both = w > 0.0 && w < 1.0;
  for (int k = 0; k < 2; ++k) {
    if (!(ways.weight[k] > 0.0)) continue;
    const paths::ActionPath& path = ways.path[k];
    for (int i = 0; i < n; ++i) sig[i] = path.length * st[i] / last;
    paths::framesAt(path, frames.start[k], sig, n, k == 1 && both ? Fk : F, k == 1 && both ? Pk : P);
  }
  if (both)
    for (int i = 0; i < n; ++i) P[i] = (1.0 - w) * P[i] + w * Pk[i], F[i] = slerpFrames(F[i], Fk[i], w);
  if (frames.twist != 0.0)
    for (int i = 0; i < n; ++i)
      F[i] = Eigen::AngleAxisd(frames.twist * mm.twistShare[st[i]], F[i].col(1)).toRotationMatrix() * F[i];
}

// ============================================================================
// Construction
// ============================================================================

MuscleRig::MuscleRig(const Skeleton& skeleton, const std::vector<Muscle>& muscles, const MuscleRigOptions& options) {
  validateSkeleton(skeleton);
  validateMuscles(muscles);
  auto impl = std::make_shared<Impl>();
  impl->distributeTwist = options.distributeTwist;
  impl->twistFollowsBones = options.twistFollowsBones;
  impl->jointsSlide = options.jointsSlide;
  impl->skeleton = skeleton;
  impl->muscles = muscles;
  const Pose rest = restPose(skeleton);
  auto boneIndex = [&](const Muscle& mu, const std::string& name, const char* what) {
    const int b = skeleton.find(name);
    if (b < 0) throw InputError("muscle '" + mu.name + "': " + what + " bone '" + name + "' is not in the skeleton");
    return b;
  };

  for (size_t m = 0; m < muscles.size(); ++m) {
    const Muscle& mu = muscles[m];
    MuscleModel mm;
    mm.originBone = boneIndex(mu, mu.origin.bone, "origin");
    mm.insertionBone = boneIndex(mu, mu.insertion.bone, "insertion");
    const Vec3 O = mu.origin.position, I = mu.insertion.position;
    if ((I - O).norm() < 1e-6)
      throw InputError("muscle '" + mu.name + "': origin and insertion coincide (less than 1 micrometre apart)");
    mm.originLocal = rest.matrices[mm.originBone].inverse().topLeftCorner<3, 4>() * O.homogeneous();
    mm.insertionLocal = rest.matrices[mm.insertionBone].inverse().topLeftCorner<3, 4>() * I.homogeneous();
    mm.wrap = mu.wrap.type;
    mm.side = mu.wrap.side >= 0 ? 1 : -1;
    if (mm.wrap != WrapType::None) {
      mm.wrapBone = boneIndex(mu, mu.wrap.bone, "wrap");
      mm.radius = mu.wrap.radius;
      if (!std::isfinite(mm.radius) || mm.radius <= 0)
        throw InputError("muscle '" + mu.name + "': wrap radius must be positive and finite");
      const Bone& wb = skeleton.bones[mm.wrapBone];
      if (mm.wrap == WrapType::Joint) {
        const Vec3 J = wb.head;
        if ((O - J).norm() <= mm.radius || (I - J).norm() <= mm.radius)
          throw InputError("muscle '" + mu.name + "': origin or insertion lies inside the joint sphere of '" +
                           wb.name + "' (radius " + std::to_string(mm.radius) + " m)");
        // Side: towards the muscle's belly from the joint centre, carried by the joint's parent bone.
        Vec3 belly = 0.5 * (O + I);
        double best = std::numeric_limits<double>::infinity();
        for (const Vec3& c : mu.rootCurve)
          if ((c - J).norm() < best) best = (c - J).norm(), belly = c;
        Vec3 side = belly - J;
        const Vec3 along = (I - O).normalized();
        side -= side.dot(along) * along;
        if (side.norm() < 1e-9) side = along.unitOrthogonal();
        side = mm.side * side.normalized();
        mm.sideBone = wb.parent >= 0 ? wb.parent : mm.wrapBone;
        mm.sideLocal = orthonormalRotationOf(rest.matrices[mm.sideBone]).transpose() * side;
      } else {
        const Vec3 axis = (wb.tail - wb.head).normalized();
        auto radial = [&](const Vec3& p) { Vec3 d = p - wb.head; return (d - d.dot(axis) * axis).norm(); };
        if (radial(O) <= mm.radius || radial(I) <= mm.radius)
          throw InputError("muscle '" + mu.name + "': origin or insertion lies inside the cylinder round '" +
                           wb.name + "' (radius " + std::to_string(mm.radius) + " m)");
      }
    }
    mm.joints = options.jointsOverride > 0 ? options.jointsOverride : mu.joints;
    if (mm.joints < 1 || mm.joints > kMaxRigJoints)
      throw InputError("muscle '" + mu.name + "': joints must be in [1, " + std::to_string(kMaxRigJoints) + "], got " +
                       std::to_string(mm.joints));
    mm.jointStride = std::max(1, (32 + mm.joints - 1) / mm.joints);
    mm.stations = 2 * mm.joints * mm.jointStride + 1;
    while (mm.stations > kMaxRigStations) --mm.jointStride, mm.stations = 2 * mm.joints * mm.jointStride + 1;
    impl->models.push_back(mm);

    // Rest path (the way round that weighs more) and its start frame (X from the origin bone's X, made perpendicular
    // to the tangent).
    PosedWays ways;
    impl->posedWays(static_cast<int>(m), rest, ways);
    const paths::ActionPath& path = ways.path[ways.weight[1] > ways.weight[0] ? 1 : 0];
    MuscleModel& mr = impl->models.back();
    mr.restLength = ways.length();
    const Mat3 Rb = orthonormalRotationOf(rest.matrices[mr.originBone]);
    Vec3 p0, t0;
    paths::pointAt(path, 0.0, p0, t0);
    mr.tangentLocal = Rb.transpose() * t0;
    Mat3 F0 = frameFromY(t0, Rb.col(0));
    mr.frameLocal = Rb.transpose() * F0;

    // Rest stations (no end twist: zero on the rest path but for rounding) and the rest end frame.
    const int S = mr.stations;
    std::vector<int> all(S);
    for (int j = 0; j < S; ++j) all[j] = j;
    std::vector<Mat3> F(S);
    std::vector<Vec3> P(S);
    Mat3 Fe;
    PosedFrames restFrames;
    impl->posedFrames(static_cast<int>(m), rest, ways, restFrames, &Fe);
    impl->stationsAt(static_cast<int>(m), ways, restFrames, all.data(), S, F.data(), P.data());
    const Mat3 Ri = orthonormalRotationOf(rest.matrices[mr.insertionBone]);
    mr.endTangentLocal = Ri.transpose() * Fe.col(1);
    mr.endFrameLocal = Ri.transpose() * Fe;

    for (int j = 0; j < S; ++j) mr.stationCarry.push_back(carryOnChain(skeleton, rest, mr.originBone, mr.insertionBone, P[j]));

    // Twist share per station: linear in arc length, or by the rest distances to the two bones.
    mr.twistShare.resize(S);
    const Bone &ob = skeleton.bones[mr.originBone], &ib = skeleton.bones[mr.insertionBone];
    for (int j = 0; j < S; ++j) {
      mr.twistShare[j] = static_cast<double>(j) / (S - 1);
      if (!impl->twistFollowsBones || mr.originBone == mr.insertionBone) continue;
      const double dO = (P[j] - detail::closestOnSegment(P[j], ob.head, ob.tail)).squaredNorm();
      const double dI = (P[j] - detail::closestOnSegment(P[j], ib.head, ib.tail)).squaredNorm();
      mr.twistShare[j] = dO + dI > 1e-30 ? dO / (dO + dI) : 0.5;
    }
    if (impl->twistFollowsBones && mr.originBone != mr.insertionBone) mr.twistShare.front() = 0.0, mr.twistShare.back() = 1.0;

    // Path parameter (fractional station index) and the two stations' local coordinates of a point.
    auto project = [&](const Vec3& v, int& j, double& alpha) {
      double best = std::numeric_limits<double>::infinity();
      j = 0, alpha = 0;
      for (int s = 0; s + 1 < S; ++s) {
        const Vec3 d = P[s + 1] - P[s];
        const double len2 = d.squaredNorm();
        const double t = len2 > 1e-30 ? std::clamp((v - P[s]).dot(d) / len2, 0.0, 1.0) : 0.0;
        const double dist = (v - P[s] - t * d).squaredNorm();
        if (dist < best) best = dist, j = s, alpha = t;
      }
    };

    // Surface (lofted when the muscle has none) and its vertices' path coordinates.
    mr.surface = mu.surface.numVertices() > 0 ? mu.surface : loftMuscleSurface(mu, SurfaceOptions{});
    const int nv = mr.surface.numVertices();
    mr.vertexStation.resize(nv);
    mr.vertexAlpha.resize(nv);
    mr.localA.resize(nv);
    mr.localB.resize(nv);
    for (int v = 0; v < nv; ++v) {
      const Vec3 x = mr.surface.vertices.row(v).transpose();
      int j;
      double alpha;
      project(x, j, alpha);
      mr.vertexStation[v] = j;
      mr.vertexAlpha[v] = alpha;
      mr.localA[v] = F[j].transpose() * (x - P[j]);
      mr.localB[v] = F[j + 1].transpose() * (x - P[j + 1]);
    }

    // Bulge profile from the rest surface's slice areas at the stations.
    std::vector<double> areas(S);
    for (int j = 0; j < S; ++j) areas[j] = joints::sliceArea(mr.surface, P[j], F[j].col(1));
    mr.bulge = joints::makeBulgeProfile(areas, mu.bulge);

    // Joints: on stations (2k + 1) * stride, at the rest root curve's point of that path parameter.
    std::vector<std::pair<double, Vec3>> curve;  // (fractional station, point)
    for (const Vec3& c : mu.rootCurve) {
      int j;
      double alpha;
      project(c, j, alpha);
      curve.emplace_back(j + alpha, c);
    }
    std::stable_sort(curve.begin(), curve.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    const int first = static_cast<int>(impl->bind.size());
    impl->offsets.push_back(first);
    for (int k = 0; k < mr.joints; ++k) {
      const int j = (2 * k + 1) * mr.jointStride;
      Vec3 c = P[j];
      if (!curve.empty()) {
        auto it = std::lower_bound(curve.begin(), curve.end(), double(j),
                                   [](const auto& e, double x) { return e.first < x; });
        if (it == curve.begin()) c = it->second;
        else if (it == curve.end()) c = curve.back().second;
        else {
          const auto& lo = *(it - 1);
          const double w = it->first > lo.first ? (j - lo.first) / (it->first - lo.first) : 0.0;
          c = (1 - w) * lo.second + w * it->second;
        }
      }
      mr.jointOffset.push_back(F[j].transpose() * (c - P[j]));
      Mat4 B = Mat4::Identity();
      B.topLeftCorner<3, 3>() = F[j];
      B.topRightCorner<3, 1>() = c;
      impl->bind.push_back(B);
      impl->jointNames.push_back(mu.name + ".j" + std::to_string(k));
      impl->jointMuscle.push_back(static_cast<int>(m));
      impl->jointParent.push_back(mr.originBone);
      mr.jointCarry.push_back(carryOnChain(skeleton, rest, mr.originBone, mr.insertionBone, c));
      const Bone& carrier = skeleton.bones[mr.jointCarry.back().bone];
      impl->slideAxes.push_back((carrier.tail - carrier.head).normalized());
    }
    impl->restLengths.push_back(mr.restLength);
  }
  const size_t J = impl->bind.size();
  impl->slideLimits.assign(J, {0.0, 0.0});
  if (!options.slideLimits.empty() && options.slideLimits.size() != J)
    throw InputError("MuscleRig: slideLimits has " + std::to_string(options.slideLimits.size()) +
                     " entries, the rig has " + std::to_string(J) + " joints");
  for (size_t m = 0, j = 0; m < impl->models.size(); ++m) {
    MuscleModel& mr = impl->models[m];
    mr.slideLimit.assign(mr.joints, {0.0, 0.0});
    for (int k = 0; k < mr.joints; ++k, ++j)
      for (int side = 0; side < 2 && !options.slideLimits.empty(); ++side)
        if (std::isfinite(options.slideLimits[j][side]) && options.slideLimits[j][side] > 0)
          mr.slideLimit[k][side] = impl->slideLimits[j][side] = options.slideLimits[j][side];
    // Stations between two joints' stations take 1 / rho interpolated linearly (0 where a joint has no limit), so the
    // surface does not step where neighbouring joints' limits differ; beyond the end joints, theirs.
    mr.stationLimit.assign(mr.stations, {0.0, 0.0});
    for (int st = 0; st < mr.stations; ++st) {
      const double t = std::clamp((double(st) / mr.jointStride - 1.0) / 2.0, 0.0, double(mr.joints - 1));
      const int k0 = std::min(static_cast<int>(t), mr.joints - 1), k1 = std::min(k0 + 1, mr.joints - 1);
      for (int side = 0; side < 2; ++side) {
        auto inverse = [&](int k) { return mr.slideLimit[k][side] > 0 ? 1.0 / mr.slideLimit[k][side] : 0.0; };
        const double kappa = (1 - (t - k0)) * inverse(k0) + (t - k0) * inverse(k1);
        mr.stationLimit[st][side] = kappa > 0 ? 1.0 / kappa : 0.0;
      }
    }
  }
  impl_ = impl;
}

// ============================================================================
// Queries
// ============================================================================

int MuscleRig::numMuscles() const { return static_cast<int>(impl_->models.size()); }
int MuscleRig::numJoints() const { return static_cast<int>(impl_->bind.size()); }
int MuscleRig::jointOffset(int m) const { return impl_->offsets.at(m); }
int MuscleRig::jointCount(int m) const { return impl_->models.at(m).joints; }
const std::vector<std::string>& MuscleRig::jointNames() const { return impl_->jointNames; }
const std::vector<int>& MuscleRig::jointMuscle() const { return impl_->jointMuscle; }
const std::vector<int>& MuscleRig::jointParentBone() const { return impl_->jointParent; }
const std::vector<Mat4>& MuscleRig::bindMatrices() const { return impl_->bind; }
const std::vector<double>& MuscleRig::restLengths() const { return impl_->restLengths; }
const std::vector<Muscle>& MuscleRig::muscles() const { return impl_->muscles; }
const Skeleton& MuscleRig::skeleton() const { return impl_->skeleton; }
bool MuscleRig::jointsSlide() const { return impl_->jointsSlide; }
const std::vector<std::array<double, 2>>& MuscleRig::slideLimits() const { return impl_->slideLimits; }
const std::vector<Vec3>& MuscleRig::slideAxes() const { return impl_->slideAxes; }
const Mesh& MuscleRig::restSurface(int m) const { return impl_->models.at(m).surface; }

MuscleRigState MuscleRig::makeState() const {
  MuscleRigState s;
  const int M = numMuscles();
  s.jointMatrices.assign(numJoints(), Mat4::Identity());
  s.length.assign(M, 0.0);
  s.stretch.assign(M, 1.0);
  s.wrapped.assign(M, 0);
  s.surfaces.resize(M);
  for (int m = 0; m < M; ++m) s.surfaces[m] = impl_->models[m].surface.vertices;
  return s;
}

// ============================================================================
// Evaluation
// ============================================================================

void MuscleRig::evaluate(const Pose& pose, MuscleRigState& state, bool withSurfaces) const {
  const Impl& im = *impl_;
  if (static_cast<int>(pose.matrices.size()) != im.skeleton.numBones())
    throw InputError("MuscleRig::evaluate: pose has " + std::to_string(pose.matrices.size()) +
                     " bone matrices, the skeleton has " + std::to_string(im.skeleton.numBones()));
  for (size_t b = 0; b < pose.matrices.size(); ++b)
    if (!finiteMatrix(pose.matrices[b]))
      throw InputError("MuscleRig::evaluate: pose matrix of bone '" + im.skeleton.bones[b].name + "' is not finite");
  bool fits = state.jointMatrices.size() == im.bind.size() && state.length.size() == im.models.size() &&
              state.stretch.size() == im.models.size() && state.wrapped.size() == im.models.size() &&
              state.surfaces.size() == im.models.size();
  for (size_t m = 0; fits && withSurfaces && m < im.models.size(); ++m)
    fits = state.surfaces[m].rows() == im.models[m].surface.numVertices();
  if (!fits) throw InputError("MuscleRig::evaluate: state was not made by this rig's makeState()");

  int st[kMaxRigStations];
  Mat3 F[kMaxRigStations];
  Vec3 P[kMaxRigStations];
  for (int m = 0; m < numMuscles(); ++m) {
    const MuscleModel& mm = im.models[m];
    PosedWays ways;
    im.posedWays(m, pose, ways);
    PosedFrames frames;
    im.posedFrames(m, pose, ways, frames);
    const double length = ways.length();
    const double lambda = std::clamp(length / mm.restLength, kMinMuscleStretch, kMaxMuscleStretch);
    const double mu = joints::bulgeMu(mm.bulge, lambda);
    state.length[m] = length;
    state.stretch[m] = lambda;
    state.wrapped[m] = ways.wrapped() ? 1 : 0;
    const int S = mm.stations;

    // Joints: frames at their stations only (joint k on station (2k + 1) * jointStride).
    for (int k = 0; k < mm.joints; ++k) st[k] = (2 * k + 1) * mm.jointStride;
    im.stationsAt(m, ways, frames, st, mm.joints, F, P);
    for (int k = 0; k < mm.joints; ++k) {
      const int j = (2 * k + 1) * mm.jointStride;
      const double s = joints::bulgeScale(mm.bulge, j, mu, lambda);
      Mat3 RS = F[k];
      RS.col(0) *= s;
      RS.col(1) *= lambda;
      RS.col(2) *= s;
      Mat4& J = state.jointMatrices[im.offsets[m] + k];
      J.setIdentity();
      J.topLeftCorner<3, 3>() = RS;
      J.topRightCorner<3, 1>() = P[k] + RS * mm.jointOffset[k];
      if (!im.jointsSlide)  // the motion along the joint's bone is the bone's
        J.topRightCorner<3, 1>() = alongAsTheBone(mm.jointCarry[k], pose, J.topRightCorner<3, 1>());
      else
        J.topRightCorner<3, 1>() = slideLimited(mm.jointCarry[k], pose, J.topRightCorner<3, 1>(), mm.slideLimit[k]);
    }
    if (!withSurfaces) continue;

    // Surface: every station, then each vertex blends its two stations.
    for (int j = 0; j < S; ++j) st[j] = j;
    im.stationsAt(m, ways, frames, st, S, F, P);
    if (!im.jointsSlide)  // the surface's stations move along their bones as the joints do
      for (int j = 0; j < S; ++j) P[j] = alongAsTheBone(mm.stationCarry[j], pose, P[j]);
    else
      for (int j = 0; j < S; ++j) {
        P[j] = slideLimited(mm.stationCarry[j], pose, P[j], mm.stationLimit[j]);
      }
    for (int j = 0; j < S; ++j) {
      const double s = joints::bulgeScale(mm.bulge, j, mu, lambda);
      F[j].col(0) *= s;
      F[j].col(1) *= lambda;
      F[j].col(2) *= s;
    }
    Points& out = state.surfaces[m];
    for (int v = 0; v < static_cast<int>(mm.vertexStation.size()); ++v) {
      const int j = mm.vertexStation[v];
      const double a = mm.vertexAlpha[v];
      const Vec3 x = (1 - a) * (P[j] + F[j] * mm.localA[v]) + a * (P[j + 1] + F[j + 1] * mm.localB[v]);
      out.row(v) = x.transpose();
    }
  }
}

}  // namespace myoskin
