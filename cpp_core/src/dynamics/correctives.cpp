// Pose-space correctives: rest-space offsets of a sculpt, the per-bone radial basis functions that drive them.
#include "myoskin/correctives.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "myoskin/errors.h"

namespace myoskin {

namespace {


std::string degrees(double radians) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", radians * 180.0 / kPi);
  return buf;
}

double angleBetween(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

}  // namespace

// ============================================================================
// Rest-space offsets
// ============================================================================

// d_v = A_v^-1 (target_v - b_v) - input_v from the skinner's per-vertex affine maps.
Points restSpaceOffsets(const Skinner& skinner, const std::vector<Mat4>& transforms, const Points& input,
                        const Points& target) {
  const int nv = skinner.numVertices();
  if (input.rows() != nv)
    throw InputError("corrective: the input has " + std::to_string(input.rows()) + " vertices, the skin " +
                     std::to_string(nv));
  if (target.rows() != nv)
    throw InputError("corrective: the sculpt has " + std::to_string(target.rows()) + " vertices, the skin " +
                     std::to_string(nv) + " (sculpt the skin mesh itself, or a copy with the same vertices)");
  for (int v = 0; v < nv; ++v) {
    if (!target.row(v).allFinite())
      throw InputError("corrective: sculpt vertex " + std::to_string(v) + " has a NaN or infinite coordinate");
    if (!input.row(v).allFinite())
      throw InputError("corrective: input vertex " + std::to_string(v) + " has a NaN or infinite coordinate");
  }
  VertexTransforms affine;
  skinner.vertexTransforms(transforms, affine);
  Points out(nv, 3);
  for (int v = 0; v < nv; ++v) {
    Mat3 a;
    Vec3 b;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) a(r, c) = affine(v, 4 * r + c);
      b[r] = affine(v, 4 * r + 3);
    }
    // A blended transform of rigid joints is a rotation times a scale near 1; a collapsed one (opposite
    // rotations blended half and half) has no inverse worth taking.
    const double det = a.determinant();
    const double size = a.cwiseAbs().maxCoeff();
    if (!std::isfinite(det) || !(std::abs(det) > 1e-9 * size * size * size))
      throw InputError("corrective: the skinning transform of vertex " + std::to_string(v) +
                       " collapses (determinant " + std::to_string(det) + "): no offset maps onto the sculpt there");
    out.row(v) = (a.lu().solve(target.row(v).transpose() - b) - input.row(v).transpose()).transpose();
  }
  return out;
}

// ============================================================================
// Bone directions and kernels
// ============================================================================

Eigen::Quaterniond boneLocalRotation(const Skeleton& skeleton, const Pose& pose, int bone) {
  if (bone < 0 || bone >= skeleton.numBones())
    throw InputError("corrective: bone index " + std::to_string(bone) + " outside 0.." +
                     std::to_string(skeleton.numBones() - 1));
  if (static_cast<int>(pose.matrices.size()) != skeleton.numBones())
    throw InputError("corrective: pose has " + std::to_string(pose.matrices.size()) + " matrices, the skeleton " +
                     std::to_string(skeleton.numBones()) + " bones");
  const Bone& b = skeleton.bones[bone];
  const Mat4 parentDelta = b.parent < 0 ? Mat4::Identity()
                                        : Mat4(pose.matrices[b.parent] * skeleton.bones[b.parent].rest.inverse());
  const Mat4 local = (parentDelta * b.rest).inverse() * pose.matrices[bone];
  if (!local.allFinite())
    throw InputError("corrective: bone '" + b.name + "' has a NaN or infinite pose matrix");
  Mat3 r = local.block<3, 3>(0, 0);
  for (int c = 0; c < 3; ++c) {
    const double n = r.col(c).norm();
    if (!(n > 0.0)) throw InputError("corrective: bone '" + b.name + "' is scaled to zero in this pose");
    r.col(c) /= n;
  }
  if (r.determinant() < 0.0) r = -r;
  Eigen::Quaterniond q(r);
  q.normalize();
  return q;
}

void boneLocalRotations(const Skeleton& skeleton, const Pose& pose, std::vector<Eigen::Quaterniond>& out) {
  out.resize(skeleton.bones.size());
  for (int i = 0; i < skeleton.numBones(); ++i) out[i] = boneLocalRotation(skeleton, pose, i);
}

Vec3 boneDirection(const Eigen::Quaterniond& q) {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  return {2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)};
}

// 1 - s / rho^2 with s = (1 - u.a) / 2 and u.a = a0 2 (xy - wz) + a1 (1 - 2 (xx + zz)) + a2 2 (yz + wx).
Eigen::Vector4d correctiveKernel(const Vec3& a, double falloff) {
  const double rho = std::sin(0.5 * falloff);
  const double inv = 1.0 / (rho * rho);
  return {1.0 - 0.5 * (1.0 - a[1]) * inv, a[0] * inv, -a[1] * inv, a[2] * inv};
}

double correctiveKernelValue(const Eigen::Vector4d& k, const Eigen::Quaterniond& q) {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  const double t = k[0] + k[1] * (x * y - w * z) + k[2] * (x * x + z * z) + k[3] * (y * z + w * x);
  return t > 0.0 ? t * t * t : 0.0;
}

// ============================================================================
// The drivers: one radial basis function per bone
// ============================================================================

CorrectiveDrivers::CorrectiveDrivers(std::vector<CorrectivePose> poses, const CorrectiveOptions& options)
    : poses_(std::move(poses)) {
  if (!(options.falloff > 0.0 && options.falloff <= kPi))
    throw InputError("corrective: falloff must be in (0, 180] degrees, got " + degrees(options.falloff));
  if (!(options.minSeparation >= 0.0))
    throw InputError("corrective: min separation must be >= 0 degrees");
  std::set<std::string> names;
  std::vector<int> boneOrder;
  for (CorrectivePose& p : poses_) {
    if (p.name.empty()) throw InputError("corrective: a corrective has an empty name");
    if (!names.insert(p.name).second) throw InputError("corrective: two correctives are called '" + p.name + "'");
    if (p.bone < 0) throw InputError("corrective '" + p.name + "': no driving bone (index " + std::to_string(p.bone) + ")");
    if (!p.direction.allFinite() || !(p.direction.norm() > 1e-9))
      throw InputError("corrective '" + p.name + "': the bone direction is zero, NaN or infinite");
    p.direction.normalize();
    if (p.falloff <= 0.0) p.falloff = options.falloff;
    if (!(p.falloff <= kPi))
      throw InputError("corrective '" + p.name + "': falloff must be in (0, 180] degrees, got " + degrees(p.falloff));
    if (std::find(boneOrder.begin(), boneOrder.end(), p.bone) == boneOrder.end()) boneOrder.push_back(p.bone);
  }
  for (int bone : boneOrder) {
    BoneCorrectiveRbf rbf;
    rbf.bone = bone;
    double restFalloff = kPi;
    std::vector<Vec3> samples{Vec3::UnitY()};
    for (int k = 0; k < numCorrectives(); ++k) {
      const CorrectivePose& p = poses_[k];
      if (p.bone != bone) continue;
      const double toRest = angleBetween(p.direction, Vec3::UnitY());
      if (toRest < options.minSeparation)
        throw InputError("corrective '" + p.name + "': its bone is at its rest direction (" + degrees(toRest) +
                         " degrees away): a corrective there would change the rest pose; bend the bone");
      for (int other : rbf.correctives) {
        const double apart = angleBetween(p.direction, poses_[other].direction);
        if (apart < options.minSeparation)
          throw InputError("corrective '" + p.name + "' and '" + poses_[other].name +
                           "' are driven by the same pose of their bone (" + degrees(apart) +
                           " degrees apart): sculpt into the existing one, or remove it first");
      }
      rbf.correctives.push_back(k);
      samples.push_back(p.direction);
      restFalloff = std::min(restFalloff, p.falloff);
    }
    const int n = static_cast<int>(rbf.correctives.size());
    rbf.kernels.push_back(correctiveKernel(Vec3::UnitY(), restFalloff));
    for (int k : rbf.correctives) rbf.kernels.push_back(correctiveKernel(poses_[k].direction, poses_[k].falloff));
    // phi(i, j) = kernel j at sample i; targets: 0 at rest, the identity over the poses.
    Eigen::MatrixXd phi(n + 1, n + 1);
    for (int i = 0; i <= n; ++i) {
      const Vec3& u = samples[i];
      for (int j = 0; j <= n; ++j) {
        const Eigen::Vector4d& k = rbf.kernels[j];
        // The kernel at a direction u (the polynomial in q rewritten in u: k0 + k1 u0/2 + k2 (1 - u1)/2 + k3 u2/2).
        const double t = k[0] + 0.5 * k[1] * u[0] + 0.5 * k[2] * (1.0 - u[1]) + 0.5 * k[3] * u[2];
        phi(i, j) = t > 0.0 ? t * t * t : 0.0;
      }
    }
    Eigen::MatrixXd targets = Eigen::MatrixXd::Zero(n + 1, n);
    targets.bottomRows(n).setIdentity();
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(phi);
    if (!lu.isInvertible() || lu.rcond() < 1e-10)
      throw InputError("corrective: the poses of the bone driving '" + poses_[rbf.correctives[0]].name +
                       "' are too close together for their falloff (kernel matrix singular): use a smaller falloff");
    rbf.coefficients = lu.solve(targets);
    if (!rbf.coefficients.allFinite())
      throw InputError("corrective: the poses of the bone driving '" + poses_[rbf.correctives[0]].name +
                       "' give no finite interpolation");
    bones_.push_back(std::move(rbf));
  }
}

int CorrectiveDrivers::find(const std::string& name) const {
  for (int k = 0; k < numCorrectives(); ++k)
    if (poses_[k].name == name) return k;
  return -1;
}

void CorrectiveDrivers::weights(const std::vector<Eigen::Quaterniond>& localRotations, Eigen::VectorXd& out) const {
  if (out.size() != numCorrectives()) out.resize(numCorrectives());
  out.setZero();
  for (const BoneCorrectiveRbf& rbf : bones_) {
    if (rbf.bone >= static_cast<int>(localRotations.size()))
      throw InputError("corrective: driving bone " + std::to_string(rbf.bone) + " outside the " +
                       std::to_string(localRotations.size()) + " local rotations");
    const Eigen::Quaterniond& q = localRotations[rbf.bone];
    for (size_t j = 0; j < rbf.kernels.size(); ++j) {
      const double phi = correctiveKernelValue(rbf.kernels[j], q);
      if (phi == 0.0) continue;
      for (size_t c = 0; c < rbf.correctives.size(); ++c)
        out[rbf.correctives[c]] += rbf.coefficients(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(c)) * phi;
    }
  }
}

void applyCorrectives(const Points& base, const std::vector<Points>& offsets, const Eigen::VectorXd& weights,
                      Points& out) {
  if (static_cast<Eigen::Index>(offsets.size()) != weights.size())
    throw InputError("corrective: " + std::to_string(offsets.size()) + " offsets for " +
                     std::to_string(weights.size()) + " weights");
  for (size_t k = 0; k < offsets.size(); ++k)
    if (offsets[k].rows() != base.rows())
      throw InputError("corrective: offsets " + std::to_string(k) + " have " + std::to_string(offsets[k].rows()) +
                       " rows for " + std::to_string(base.rows()) + " vertices");
  if (out.rows() != base.rows()) out.resize(base.rows(), 3);
  out = base;
  for (size_t k = 0; k < offsets.size(); ++k)
    if (weights[static_cast<Eigen::Index>(k)] != 0.0) out.noalias() += weights[static_cast<Eigen::Index>(k)] * offsets[k];
}

}  // namespace myoskin
