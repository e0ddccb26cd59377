// The Equation 3 skinner: structure-of-arrays float32 rest skin, packed sparse influences, TBB threads.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <mutex>
#include <shared_mutex>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>

#include <Eigen/Geometry>

#include "myoskin/errors.h"
#include "myoskin/memory_budget.h"
#include "myoskin/skinning.h"

namespace myoskin {

// ============================================================================
// Layout
// ============================================================================

struct Skinner::Impl {
  int numVertices = 0;
  int numJoints = 0;
  int slots = 0;       // packed influences per vertex
  int restCount = 0;   // vertices that stay at rest
  SkinnerOptions options;
  std::vector<float> x, y, z;        // rest positions (SoA)
  std::vector<uint16_t> joint;       // #V * slots; index numJoints = the identity (rest / padding)
  std::vector<float> weight;         // #V * slots, normalised per vertex
  std::unique_ptr<tbb::task_arena> arena;  // when options.threads > 0
  mutable std::shared_mutex optionsMutex;  // deform (shared) against setOptions (exclusive): the arena
                                           // must not be replaced while a deform runs in it

  std::vector<float> shareF;         // per vertex 1 - options.dqsShare in float32 (Blender's vertex group weight, the
                                     // linear result's weight), empty = off

  void setShare() {
    shareF.resize(options.dqsShare.size());
    for (size_t v = 0; v < shareF.size(); ++v) shareF[v] = static_cast<float>(1.0 - options.dqsShare[v]);
  }

  void makeArena() {
    arena.reset();
    if (options.threads > 0) arena = std::make_unique<tbb::task_arena>(options.threads);
  }
};

namespace {

constexpr int kMaxJoints = std::numeric_limits<uint16_t>::max() - 1;

std::string where(int v, int k) { return "vertex " + std::to_string(v) + " slot " + std::to_string(k); }

// Eight floats: one AVX register, or two SSE registers on older CPUs (GCC vector extension).
typedef float v8 __attribute__((vector_size(32)));
typedef float v4 __attribute__((vector_size(16)));

// One joint's transform as two v8 blocks of its columns: (c0, c1) and (c2, c3), each column x, y, z, 0.
struct alignas(32) PackedTransform {
  v8 a, b;
};

// Transforms packed, with one extra identity at index #J (rest vertices and padding slots point there).
std::vector<PackedTransform> packTransforms(const std::vector<Mat4>& transforms, int numJoints) {
  if (static_cast<int>(transforms.size()) != numJoints)
    throw InputError("skinning: " + std::to_string(transforms.size()) + " transforms for " +
                     std::to_string(numJoints) + " joints");
  std::vector<PackedTransform> packed(static_cast<size_t>(numJoints) + 1);
  for (int j = 0; j <= numJoints; ++j) {
    const Mat4 m = j < numJoints ? transforms[j] : Mat4::Identity();
    if (!m.allFinite()) throw InputError("skinning: transform " + std::to_string(j) + " has a NaN or infinite value");
    float c[16];
    for (int col = 0; col < 4; ++col) {
      for (int r = 0; r < 3; ++r) c[4 * col + r] = static_cast<float>(m(r, col));
      c[4 * col + 3] = 0.0f;
    }
    std::memcpy(&packed[j].a, c, sizeof(v8));
    std::memcpy(&packed[j].b, c + 8, sizeof(v8));
  }
  return packed;
}

// AVX2/FMA kernel: blend the vertex's K transforms as column pairs, then apply to its rest position.
template <int K>
inline __attribute__((always_inline)) void bodyVector(const uint16_t* joint, const float* weight, const float* x,
                                                      const float* y, const float* z, const PackedTransform* T,
                                                      int slots, int begin, int end, float* out) {
  const int k = K > 0 ? K : slots;
  for (int v = begin; v < end; ++v) {
    const uint16_t* jv = joint + static_cast<size_t>(v) * k;
    const float* wv = weight + static_cast<size_t>(v) * k;
    v8 acc0 = wv[0] * T[jv[0]].a;
    v8 acc1 = wv[0] * T[jv[0]].b;
    for (int i = 1; i < k; ++i) {
      acc0 += wv[i] * T[jv[i]].a;
      acc1 += wv[i] * T[jv[i]].b;
    }
    const float px = x[v], py = y[v], pz = z[v];
    const v8 p0 = {px, px, px, px, py, py, py, py};
    const v8 p1 = {pz, pz, pz, pz, 1.0f, 1.0f, 1.0f, 1.0f};
    const v8 s = acc0 * p0 + acc1 * p1;
    const v4 lo = {s[0], s[1], s[2], s[3]};
    const v4 hi = {s[4], s[5], s[6], s[7]};
    const v4 r = lo + hi;
    std::memcpy(out + 3 * static_cast<size_t>(v), &r, 3 * sizeof(float));
  }
}

// Portable kernel (any x86-64 / other CPUs): the same arithmetic on the 12 used floats of each block.
template <int K>
inline void bodyScalar(const uint16_t* joint, const float* weight, const float* x, const float* y, const float* z,
                       const PackedTransform* T, int slots, int begin, int end, float* out) {
  const int k = K > 0 ? K : slots;
  static constexpr int used[12] = {0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14};
  for (int v = begin; v < end; ++v) {
    const uint16_t* jv = joint + static_cast<size_t>(v) * k;
    const float* wv = weight + static_cast<size_t>(v) * k;
    float m[12] = {};
    for (int i = 0; i < k; ++i) {
      const float* t = reinterpret_cast<const float*>(&T[jv[i]]);
      for (int e = 0; e < 12; ++e) m[e] += wv[i] * t[used[e]];
    }
    const float px = x[v], py = y[v], pz = z[v];
    float* o = out + 3 * static_cast<size_t>(v);
    o[0] = m[0] * px + m[3] * py + m[6] * pz + m[9];
    o[1] = m[1] * px + m[4] * py + m[7] * pz + m[10];
    o[2] = m[2] * px + m[5] * py + m[8] * pz + m[11];
  }
}

#define MYOSKIN_SKIN_SWITCH(BODY)                                            \
  switch (slots) {                                                          \
    case 1: BODY<1>(joint, weight, x, y, z, T, 1, begin, end, out); break;  \
    case 2: BODY<2>(joint, weight, x, y, z, T, 2, begin, end, out); break;  \
    case 3: BODY<3>(joint, weight, x, y, z, T, 3, begin, end, out); break;  \
    case 4: BODY<4>(joint, weight, x, y, z, T, 4, begin, end, out); break;  \
    case 5: BODY<5>(joint, weight, x, y, z, T, 5, begin, end, out); break;  \
    case 6: BODY<6>(joint, weight, x, y, z, T, 6, begin, end, out); break;  \
    case 7: BODY<7>(joint, weight, x, y, z, T, 7, begin, end, out); break;  \
    case 8: BODY<8>(joint, weight, x, y, z, T, 8, begin, end, out); break;  \
    default: BODY<0>(joint, weight, x, y, z, T, slots, begin, end, out); break; \
  }

void skinRangeScalar(const uint16_t* joint, const float* weight, const float* x, const float* y, const float* z,
                     const PackedTransform* T, int slots, int begin, int end, float* out) {
  MYOSKIN_SKIN_SWITCH(bodyScalar)
}

#if defined(__x86_64__) && defined(__GNUC__)
#define MYOSKIN_HAVE_AVX2_KERNEL 1
// Compiled for AVX2 + FMA and chosen at run time when the CPU has them.
__attribute__((target("avx2,fma"))) void skinRangeAvx2(const uint16_t* joint, const float* weight, const float* x,
                                                       const float* y, const float* z, const PackedTransform* T,
                                                       int slots, int begin, int end, float* out) {
  MYOSKIN_SKIN_SWITCH(bodyVector)
}

bool cpuHasAvx2() {
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
}
#endif

using RangeKernel = void (*)(const uint16_t*, const float*, const float*, const float*, const float*,
                             const PackedTransform*, int, int, int, float*);

// The AVX2 kernel when the CPU has it, unless MYOSKIN_SCALAR_SKINNING is set (tests of the portable path).
RangeKernel chooseKernel() {
#ifdef MYOSKIN_HAVE_AVX2_KERNEL
  if (cpuHasAvx2() && !std::getenv("MYOSKIN_SCALAR_SKINNING")) return skinRangeAvx2;
#endif
  return skinRangeScalar;
}

void runRange(RangeKernel kernel, const Skinner::Impl& s, const PackedTransform* T, int begin, int end, float* out) {
  kernel(s.joint.data(), s.weight.data(), s.x.data(), s.y.data(), s.z.data(), T, s.slots, begin, end, out);
}

// ----------------------------------------------------------------------------
// Preserve volume: Blender's dual quaternion skinning (BLI math_rotation: mat4_to_dquat,
// add_weighted_dq_dq_pivot, normalize_dq, mul_v3m3_dq; BKE armature_deform with full_deform off, the
// Armature modifier's evaluation). Quaternions are (w, x, y, z) like Blender's.
// ----------------------------------------------------------------------------

// One joint's dual quaternion: rotation quat, dual part trans, and (hasScale) the 3x4 scale matrix
// (columns s0..s2 and translation s3) applied before the rotation.
struct JointDQ {
  float quat[4];
  float trans[4];
  float scale[12];  // column-major 3x4
  float hasScale;   // 1 or 0 (Blender's scale_weight)
};

// Blender's is_orthonormal_m3 (columns orthogonal and of unit length within 1e-5).
bool isOrthonormal(const Eigen::Matrix3d& m) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < i; ++j)
      if (std::abs(m.col(i).dot(m.col(j))) > 1e-5) return false;
    if (std::abs(m.col(i).squaredNorm() - 1.0) > 1e-5) return false;
  }
  return true;
}

// Rotation quaternion (w, x, y, z) of a matrix whose columns are normalised first (Blender's mat4_to_quat).
Eigen::Vector4d rotationQuat(const Eigen::Matrix3d& m) {
  Eigen::Matrix3d n = m;
  for (int c = 0; c < 3; ++c) {
    const double len = n.col(c).norm();
    if (len > 0.0) n.col(c) /= len;
  }
  if (n.determinant() < 0.0) n = -n;  // Blender's mat3_normalized_to_quat_with_checks
  const Eigen::Quaterniond q(n);
  return {q.w(), q.x(), q.y(), q.z()};
}

// mat4_to_dquat(basemat = the joint's rest matrix, mat = its skinning transform), in float64.
JointDQ jointDualQuat(const Mat4& mat, const Mat4& basemat) {
  JointDQ d{};
  const Mat4 baseRS = mat * basemat;
  const Eigen::Vector3d dscale = baseRS.block<3, 3>(0, 0).colwise().norm().transpose() - Eigen::Vector3d::Ones();
  const Eigen::Matrix3d mat3 = mat.block<3, 3>(0, 0);
  Eigen::Matrix3d rot;
  Eigen::Vector3d t;
  if (!isOrthonormal(mat3) || mat3.determinant() < 0.0 || dscale.squaredNorm() > 1e-8) {
    // orthogonalize_m4(baseRS, Y): keep the bone's Y axis, Z = X x Y, X = Y x Z
    Eigen::Matrix3d o = baseRS.block<3, 3>(0, 0);
    const Eigen::Vector3d y = o.col(1).normalized();
    const Eigen::Vector3d z = o.col(0).cross(y).normalized();
    const Eigen::Vector3d x = y.cross(z);
    o.col(0) = x;
    o.col(1) = y;
    o.col(2) = z;
    const Eigen::Vector4d bq = rotationQuat(o);
    Mat4 baseR = Mat4::Identity();
    baseR.block<3, 3>(0, 0) = Eigen::Quaterniond(bq[0], bq[1], bq[2], bq[3]).toRotationMatrix();
    baseR.block<3, 1>(0, 3) = baseRS.block<3, 1>(0, 3);
    const Mat4 baseinv = basemat.inverse();
    const Mat4 R = baseR * baseinv;
    const Mat4 S = baseR.inverse() * baseRS;
    const Mat4 scale = basemat * S * baseinv;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 3; ++r) d.scale[3 * c + r] = static_cast<float>(scale(r, c));
    d.hasScale = 1.0f;
    rot = R.block<3, 3>(0, 0);
    t = R.block<3, 1>(0, 3);
  } else {
    rot = mat3;
    t = mat.block<3, 1>(0, 3);
  }
  const Eigen::Vector4d q = rotationQuat(rot);
  const Eigen::Vector4d tr(-0.5 * (t[0] * q[1] + t[1] * q[2] + t[2] * q[3]),
                           0.5 * (t[0] * q[0] + t[1] * q[3] - t[2] * q[2]),
                           0.5 * (-t[0] * q[3] + t[1] * q[0] + t[2] * q[1]),
                           0.5 * (t[0] * q[2] - t[1] * q[1] + t[2] * q[0]));
  for (int i = 0; i < 4; ++i) {
    d.quat[i] = static_cast<float>(q[i]);
    d.trans[i] = static_cast<float>(tr[i]);
  }
  return d;
}

// Joint dual quaternions, with the identity at index #J (rest vertices and padding slots).
std::vector<JointDQ> packDualQuats(const std::vector<Mat4>& transforms, const Skinner::Impl& s) {
  if (static_cast<int>(transforms.size()) != s.numJoints)
    throw InputError("skinning: " + std::to_string(transforms.size()) + " transforms for " +
                     std::to_string(s.numJoints) + " joints");
  std::vector<JointDQ> dq(static_cast<size_t>(s.numJoints) + 1);
  for (int j = 0; j < s.numJoints; ++j) {
    if (!transforms[j].allFinite())
      throw InputError("skinning: transform " + std::to_string(j) + " has a NaN or infinite value");
    Mat4 m = transforms[j];
    m.row(3) << 0.0, 0.0, 0.0, 1.0;  // the last row is ignored, as in the linear path
    dq[j] = jointDualQuat(m, s.options.jointRest.empty() ? Mat4::Identity() : s.options.jointRest[j]);
  }
  dq[s.numJoints] = JointDQ{{1.0f, 0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f, 0.0f}, {}, 0.0f};
  return dq;
}

// Per vertex: add_weighted_dq_dq_pivot (Pivot: pivot = the rest position, the scale matrix discarded after
// its translation at the pivot is taken into the dual part) or add_weighted_dq_dq (Blended: scale matrices
// summed with unflipped weights) over its influences, normalize_dq (weights normalised at build time; the
// joints without scale make up the identity's share), then mul_v3m3_dq.
template <bool Blended>
void skinRangeDualQuat(const Skinner::Impl& s, const JointDQ* D, int begin, int end, float* out) {
  const int k = s.slots;
  for (int v = begin; v < end; ++v) {
    const uint16_t* jv = s.joint.data() + static_cast<size_t>(v) * k;
    const float* wv = s.weight.data() + static_cast<size_t>(v) * k;
    float co[3] = {s.x[v], s.y[v], s.z[v]};
    float sq[4] = {0.0f, 0.0f, 0.0f, 0.0f}, st[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    float sm[12] = {}, scaleWeight = 0.0f, total = 0.0f;
    for (int i = 0; i < k; ++i) {
      float w = wv[i];
      if (w == 0.0f) continue;
      total += w;
      const JointDQ& d = D[jv[i]];
      const float* q = d.quat;
      float tr[4] = {d.trans[0], d.trans[1], d.trans[2], d.trans[3]};
      if (Blended) {
        if (d.hasScale != 0.0f) {
          for (int e = 0; e < 12; ++e) sm[e] += w * d.scale[e];
          scaleWeight += w;
        }
      } else if (d.hasScale != 0.0f) {
        const float* m = d.scale;
        float dst[3];
        for (int r = 0; r < 3; ++r) dst[r] = m[r] * co[0] + m[3 + r] * co[1] + m[6 + r] * co[2] + m[9 + r] - co[r];
        tr[0] -= 0.5f * (q[1] * dst[0] + q[2] * dst[1] + q[3] * dst[2]);
        tr[1] += 0.5f * (q[0] * dst[0] + q[2] * dst[2] - q[3] * dst[1]);
        tr[2] += 0.5f * (q[0] * dst[1] + q[3] * dst[0] - q[1] * dst[2]);
        tr[3] += 0.5f * (q[0] * dst[2] + q[1] * dst[1] - q[2] * dst[0]);
      }
      if (q[0] * sq[0] + q[1] * sq[1] + q[2] * sq[2] + q[3] * sq[3] < 0.0f) w = -w;
      for (int c = 0; c < 4; ++c) {
        sq[c] += w * q[c];
        st[c] += w * tr[c];
      }
    }
    if (Blended && scaleWeight != 0.0f) {  // normalize_dq's scale, then applied before the rotation
      const float add = total - scaleWeight, inv = 1.0f / total;
      sm[0] += add;
      sm[4] += add;
      sm[8] += add;
      float r[3];
      for (int c = 0; c < 3; ++c) r[c] = (sm[c] * co[0] + sm[3 + c] * co[1] + sm[6 + c] * co[2] + sm[9 + c]) * inv;
      co[0] = r[0];
      co[1] = r[1];
      co[2] = r[2];
    }
    const float w = sq[0], x = sq[1], y = sq[2], z = sq[3];
    const float t0 = st[0], t1 = st[1], t2 = st[2], t3 = st[3];
    float len2 = w * w + x * x + y * y + z * z;
    if (len2 > 0.0f) len2 = 1.0f / len2;
    // rotation (rows of Blender's column-major M) and translation
    const float r0 = (w * w + x * x - y * y - z * z) * co[0] + 2 * (x * y - w * z) * co[1] + 2 * (x * z + w * y) * co[2];
    const float r1 = 2 * (x * y + w * z) * co[0] + (w * w + y * y - x * x - z * z) * co[1] + 2 * (y * z - w * x) * co[2];
    const float r2 = 2 * (x * z - w * y) * co[0] + 2 * (y * z + w * x) * co[1] + (w * w + z * z - x * x - y * y) * co[2];
    const float tx = 2 * (-t0 * x + w * t1 - t2 * z + y * t3);
    const float ty = 2 * (-t0 * y + t1 * z - x * t3 + w * t2);
    const float tz = 2 * (-t0 * z + x * t2 + w * t3 - t1 * y);
    float* o = out + 3 * static_cast<size_t>(v);
    o[0] = (r0 + tx) * len2;
    o[1] = (r1 + ty) * len2;
    o[2] = (r2 + tz) * len2;
  }
}

template <class Range>
void parallelRanges(const Skinner::Impl& s, const Range& range) {
  const int grain = std::max(1, s.options.grainSize);
  auto body = [&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, s.numVertices, grain),
        [&](const tbb::blocked_range<int>& r) { range(r.begin(), r.end()); }, tbb::simple_partitioner());
  };
  if (s.options.threads == 1 || s.numVertices <= grain) {
    range(0, s.numVertices);
  } else if (s.arena) {
    s.arena->execute(body);
  } else {
    body();
  }
}

// Blender's mix of the second (dual-quaternion, Multi Modifier) Armature modifier with the first (linear) one, in
// float32, as measured on Blender 3.4.1: the vertex group's weight g = 1 - s is the linear result's weight,
// result = (1 - g) * dual quaternion + (1 - (1 - g)) * linear (g = 0, a vertex not in the group: the dual-quaternion
// result; g = 1: the linear one, each bit for bit).
void volumeBlendRange(const float* groupWeight, const float* dualQuat, int begin, int end, float* out) {
  for (int v = begin; v < end; ++v) {
    const float dqWeight = 1.0f - groupWeight[v];
    const float linearWeight = 1.0f - dqWeight;
    for (int c = 0; c < 3; ++c) {
      const size_t i = 3 * static_cast<size_t>(v) + c;
      out[i] = dqWeight * dualQuat[i] + linearWeight * out[i];
    }
  }
}

void deformInto(const Skinner::Impl& s, const std::vector<Mat4>& transforms, float* out) {
  std::shared_lock<std::shared_mutex> lock(s.optionsMutex);
  if (!s.shareF.empty()) {  // volume blend: linear, dual quaternions, then Blender's mix
    const std::vector<JointDQ> D = packDualQuats(transforms, s);
    const std::vector<PackedTransform> T = packTransforms(transforms, s.numJoints);
    const RangeKernel kernel = chooseKernel();
    std::vector<float> dq(3 * static_cast<size_t>(s.numVertices));
    const bool blended = s.options.dualQuatScale == DualQuatScale::Blended;
    parallelRanges(s, [&](int begin, int end) {
      runRange(kernel, s, T.data(), begin, end, out);
      if (blended)
        skinRangeDualQuat<true>(s, D.data(), begin, end, dq.data());
      else
        skinRangeDualQuat<false>(s, D.data(), begin, end, dq.data());
      volumeBlendRange(s.shareF.data(), dq.data(), begin, end, out);
    });
    return;
  }
  if (s.options.preserveVolume) {
    const std::vector<JointDQ> D = packDualQuats(transforms, s);
    if (s.options.dualQuatScale == DualQuatScale::Blended)
      parallelRanges(s, [&](int begin, int end) { skinRangeDualQuat<true>(s, D.data(), begin, end, out); });
    else
      parallelRanges(s, [&](int begin, int end) { skinRangeDualQuat<false>(s, D.data(), begin, end, out); });
    return;
  }
  const std::vector<PackedTransform> T = packTransforms(transforms, s.numJoints);
  const RangeKernel kernel = chooseKernel();
  parallelRanges(s, [&](int begin, int end) { runRange(kernel, s, T.data(), begin, end, out); });
}

void validateOptions(const SkinnerOptions& o, int numJoints, int numVertices) {
  if (!o.dqsShare.empty()) {
    if (static_cast<int>(o.dqsShare.size()) != numVertices)
      throw InputError("skinning: " + std::to_string(o.dqsShare.size()) + " dual-quaternion shares for " +
                       std::to_string(numVertices) + " vertices");
    for (size_t v = 0; v < o.dqsShare.size(); ++v)
      if (!(o.dqsShare[v] >= 0.0 && o.dqsShare[v] <= 1.0))
        throw InputError("skinning: vertex " + std::to_string(v) + " has a dual-quaternion share " +
                         std::to_string(o.dqsShare[v]) + ", outside [0, 1]");
  }
  if (o.jointRest.empty()) return;
  if (static_cast<int>(o.jointRest.size()) != numJoints)
    throw InputError("skinning: " + std::to_string(o.jointRest.size()) + " joint rest matrices for " +
                     std::to_string(numJoints) + " joints");
  for (size_t j = 0; j < o.jointRest.size(); ++j) {
    const Mat4& m = o.jointRest[j];
    if (!m.allFinite())
      throw InputError("skinning: joint rest matrix " + std::to_string(j) + " has a NaN or infinite value");
    if (!(std::abs(m.block<3, 3>(0, 0).determinant()) > 1e-12))
      throw InputError("skinning: joint rest matrix " + std::to_string(j) + " is singular");
  }
}

}  // namespace

// ============================================================================
// Construction: validate, pack the non-empty influences, normalise
// ============================================================================

Skinner::Skinner(const Points& rest, const SkinWeights& weights, int numJoints, const SkinnerOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  if (numJoints < 1) throw InputError("skinning: needs at least one joint, got " + std::to_string(numJoints));
  if (numJoints > kMaxJoints)
    throw InputError("skinning: " + std::to_string(numJoints) + " joints, at most " + std::to_string(kMaxJoints));
  if (rest.rows() == 0) throw InputError("skinning: the rest skin has no vertices");
  if (weights.joints.rows() != weights.weights.rows() || weights.joints.cols() != weights.weights.cols())
    throw InputError("skinning: weight joints are " + std::to_string(weights.joints.rows()) + " by " +
                     std::to_string(weights.joints.cols()) + " but weights are " +
                     std::to_string(weights.weights.rows()) + " by " + std::to_string(weights.weights.cols()));
  if (weights.numVertices() != rest.rows())
    throw InputError("skinning: " + std::to_string(weights.numVertices()) + " weight rows for " +
                     std::to_string(rest.rows()) + " vertices");
  validateOptions(options, numJoints, static_cast<int>(rest.rows()));
  const int nv = static_cast<int>(rest.rows());
  const int kin = weights.influences();
  requireMemory(skinnerMemoryEstimate(nv, kin), "skinning " + std::to_string(nv) + " vertices");
  int slots = 1;
  for (int v = 0; v < nv; ++v) {
    if (!rest.row(v).allFinite())
      throw InputError("skinning: vertex " + std::to_string(v) + " has a NaN or infinite coordinate");
    int used = 0;
    for (int k = 0; k < kin; ++k) {
      const int j = weights.joints(v, k);
      const double w = weights.weights(v, k);
      if (!std::isfinite(w)) throw InputError("skinning: " + where(v, k) + " has a NaN or infinite weight");
      if (w < 0.0) throw InputError("skinning: " + where(v, k) + " has a negative weight " + std::to_string(w));
      if (j < -1 || j >= numJoints)
        throw InputError("skinning: " + where(v, k) + " uses joint " + std::to_string(j) + ", outside 0.." +
                         std::to_string(numJoints - 1));
      if (j >= 0 && w > 0.0) ++used;
    }
    slots = std::max(slots, used);
  }
  s.numVertices = nv;
  s.numJoints = numJoints;
  s.slots = slots;
  s.options = options;
  s.setShare();
  s.x.resize(nv);
  s.y.resize(nv);
  s.z.resize(nv);
  s.joint.assign(static_cast<size_t>(nv) * slots, static_cast<uint16_t>(numJoints));
  s.weight.assign(static_cast<size_t>(nv) * slots, 0.0f);
  for (int v = 0; v < nv; ++v) {
    s.x[v] = static_cast<float>(rest(v, 0));
    s.y[v] = static_cast<float>(rest(v, 1));
    s.z[v] = static_cast<float>(rest(v, 2));
    double total = 0.0;
    for (int k = 0; k < kin; ++k)
      if (weights.joints(v, k) >= 0) total += weights.weights(v, k);
    if (options.sumTolerance > 0.0 && std::abs(total - 1.0) > options.sumTolerance)
      throw InputError("skinning: vertex " + std::to_string(v) + " weights sum to " + std::to_string(total) +
                       ", not 1 (tolerance " + std::to_string(options.sumTolerance) + ")");
    const size_t base = static_cast<size_t>(v) * slots;
    if (total <= kRestWeightThreshold) {  // stays at rest: the identity block with weight 1
      s.weight[base] = 1.0f;
      ++s.restCount;
      continue;
    }
    int slot = 0;
    for (int k = 0; k < kin; ++k) {
      const int j = weights.joints(v, k);
      const double w = weights.weights(v, k);
      if (j < 0 || w <= 0.0) continue;
      s.joint[base + slot] = static_cast<uint16_t>(j);
      s.weight[base + slot] = static_cast<float>(w / total);
      ++slot;
    }
  }
  s.makeArena();
}

Skinner::~Skinner() = default;
Skinner::Skinner(Skinner&&) noexcept = default;
Skinner& Skinner::operator=(Skinner&&) noexcept = default;

int Skinner::numVertices() const { return impl_->numVertices; }
int Skinner::numJoints() const { return impl_->numJoints; }
int Skinner::influences() const { return impl_->slots; }
int Skinner::restVertices() const { return impl_->restCount; }
const SkinnerOptions& Skinner::options() const { return impl_->options; }

void Skinner::setOptions(const SkinnerOptions& options) {
  validateOptions(options, impl_->numJoints, impl_->numVertices);
  std::unique_lock<std::shared_mutex> lock(impl_->optionsMutex);
  impl_->options = options;
  impl_->setShare();
  impl_->makeArena();
}

size_t Skinner::bytesPerFrame() const {
  const Impl& s = *impl_;
  const size_t perVertex = 3 * sizeof(float)                                   // rest position read
                           + s.slots * (sizeof(uint16_t) + sizeof(float))       // influences read
                           + 3 * sizeof(float);                                 // result written
  return perVertex * s.numVertices + 12 * sizeof(float) * (s.numJoints + 1);
}

// ============================================================================
// Deform
// ============================================================================

void Skinner::deform(const std::vector<Mat4>& transforms, float* out) const { deformInto(*impl_, transforms, out); }

void Skinner::deform(const std::vector<Mat4>& transforms, PointsF& out) const {
  if (out.rows() != impl_->numVertices) out.resize(impl_->numVertices, 3);
  deformInto(*impl_, transforms, out.data());
}

void Skinner::deform(const std::vector<Mat4>& transforms, Points& out) const {
  PointsF f(impl_->numVertices, 3);
  deformInto(*impl_, transforms, f.data());
  out = f.cast<double>();
}

// ============================================================================
// Per-vertex affine maps (the inverse skinning of correctives.h)
// ============================================================================

namespace {

using Mat34 = Eigen::Matrix<double, 3, 4>;

// The rotation rows of mul_v3m3_dq for a blended quaternion (w, x, y, z), before the 1/|q|^2 normalisation.
Mat3 dqRotation(const Eigen::Vector4d& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  Mat3 r;
  r << w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y),
      2 * (x * y + w * z), w * w + y * y - x * x - z * z, 2 * (y * z - w * x),
      2 * (x * z - w * y), 2 * (y * z + w * x), w * w + z * z - x * x - y * y;
  return r;
}

// The translation of mul_v3m3_dq as a linear map of the blended dual part (t0..t3).
Mat34 dqTranslation(const Eigen::Vector4d& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  Mat34 m;
  m << -x, w, -z, y,
       -y, z, w, -x,
       -z, -y, x, w;
  return 2.0 * m;
}

// One vertex's dual-quaternion blend as an affine map of its input position (skinRangeDualQuat, in float64).
template <bool Blended>
Mat34 dualQuatAffine(const Skinner::Impl& s, const JointDQ* D, int v) {
  const int k = s.slots;
  const uint16_t* jv = s.joint.data() + static_cast<size_t>(v) * k;
  const float* wv = s.weight.data() + static_cast<size_t>(v) * k;
  Eigen::Vector4d sq = Eigen::Vector4d::Zero(), st0 = Eigen::Vector4d::Zero();
  Eigen::Matrix<double, 4, 3> stLinear = Eigen::Matrix<double, 4, 3>::Zero();  // st(co) = st0 + stLinear co
  Mat34 sm = Mat34::Zero();
  double scaleWeight = 0.0, total = 0.0;
  for (int i = 0; i < k; ++i) {
    double w = wv[i];
    if (w == 0.0) continue;
    total += w;
    const JointDQ& d = D[jv[i]];
    const Eigen::Vector4d q(d.quat[0], d.quat[1], d.quat[2], d.quat[3]);
    Eigen::Vector4d tr(d.trans[0], d.trans[1], d.trans[2], d.trans[3]);
    Eigen::Matrix<double, 4, 3> trLinear = Eigen::Matrix<double, 4, 3>::Zero();
    if (d.hasScale != 0.0f) {
      Mat34 m;
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r) m(r, c) = d.scale[3 * c + r];
      if (Blended) {
        sm += w * m;
        scaleWeight += w;
      } else {  // dst = M co + m - co, added to the dual part through L(q)
        Eigen::Matrix<double, 4, 3> L;
        L << -q[1], -q[2], -q[3],
              q[0], -q[3], q[2],
              q[3], q[0], -q[1],
             -q[2], q[1], q[0];
        L *= 0.5;
        tr += L * m.col(3);
        trLinear = L * (m.leftCols<3>() - Mat3::Identity());
      }
    }
    if (q.dot(sq) < 0.0) w = -w;
    sq += w * q;
    st0 += w * tr;
    stLinear += w * trLinear;
  }
  Mat3 C = Mat3::Identity();
  Vec3 c = Vec3::Zero();
  if (Blended && scaleWeight != 0.0) {
    C = (sm.leftCols<3>() + (total - scaleWeight) * Mat3::Identity()) / total;
    c = sm.col(3) / total;
  }
  double len2 = sq.squaredNorm();
  if (len2 > 0.0) len2 = 1.0 / len2;
  const Mat3 R = dqRotation(sq);
  const Mat34 T = dqTranslation(sq);
  Mat34 out;
  out.leftCols<3>() = len2 * (R * C + T * stLinear);
  out.col(3) = len2 * (R * c + T * st0);
  return out;
}

// One vertex's linear blend sum w_i T_i as an affine map.
Mat34 linearAffine(const Skinner::Impl& s, const std::vector<Mat4>& transforms, int v) {
  const int k = s.slots;
  const uint16_t* jv = s.joint.data() + static_cast<size_t>(v) * k;
  const float* wv = s.weight.data() + static_cast<size_t>(v) * k;
  Mat34 m = Mat34::Zero();
  for (int i = 0; i < k; ++i) {
    if (wv[i] == 0.0f) continue;
    const double w = wv[i];
    if (jv[i] >= s.numJoints)
      m.leftCols<3>() += w * Mat3::Identity();
    else
      m += w * transforms[jv[i]].topRows<3>();
  }
  return m;
}

}  // namespace

void Skinner::vertexTransforms(const std::vector<Mat4>& transforms, VertexTransforms& out) const {
  const Impl& s = *impl_;
  std::shared_lock<std::shared_mutex> lock(s.optionsMutex);
  if (out.rows() != s.numVertices) out.resize(s.numVertices, 12);
  auto store = [&](int v, const Mat34& m) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) out(v, 4 * r + c) = m(r, c);
  };
  if (!s.shareF.empty()) {  // the blend of two affine maps is affine
    const std::vector<JointDQ> D = packDualQuats(transforms, s);
    const bool blended = s.options.dualQuatScale == DualQuatScale::Blended;
    parallelRanges(s, [&](int begin, int end) {
      for (int v = begin; v < end; ++v) {
        const double share = 1.0 - static_cast<double>(s.shareF[v]);
        const Mat34 lin = linearAffine(s, transforms, v);
        if (share == 0.0) {
          store(v, lin);
          continue;
        }
        const Mat34 dq = blended ? dualQuatAffine<true>(s, D.data(), v) : dualQuatAffine<false>(s, D.data(), v);
        store(v, (1.0 - share) * lin + share * dq);
      }
    });
    return;
  }
  if (s.options.preserveVolume) {
    const std::vector<JointDQ> D = packDualQuats(transforms, s);
    const bool blended = s.options.dualQuatScale == DualQuatScale::Blended;
    parallelRanges(s, [&](int begin, int end) {
      for (int v = begin; v < end; ++v)
        store(v, blended ? dualQuatAffine<true>(s, D.data(), v) : dualQuatAffine<false>(s, D.data(), v));
    });
    return;
  }
  packTransforms(transforms, s.numJoints);  // the same checks as deform (count, finite)
  parallelRanges(s, [&](int begin, int end) {
    for (int v = begin; v < end; ++v) store(v, linearAffine(s, transforms, v));
  });
}

Points skin(const Points& rest, const SkinWeights& weights, const std::vector<Mat4>& transforms,
            const SkinnerOptions& options) {
  const Skinner skinner(rest, weights, static_cast<int>(transforms.size()), options);
  Points out;
  skinner.deform(transforms, out);
  return out;
}

}  // namespace myoskin
