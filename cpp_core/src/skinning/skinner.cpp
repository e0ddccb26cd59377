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

#include "myoskin/errors.h"
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

void deformInto(const Skinner::Impl& s, const std::vector<Mat4>& transforms, float* out) {
  std::shared_lock<std::shared_mutex> lock(s.optionsMutex);
  const std::vector<PackedTransform> T = packTransforms(transforms, s.numJoints);
  const RangeKernel kernel = chooseKernel();
  const int grain = std::max(1, s.options.grainSize);
  auto body = [&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, s.numVertices, grain),
        [&](const tbb::blocked_range<int>& r) { runRange(kernel, s, T.data(), r.begin(), r.end(), out); },
        tbb::simple_partitioner());
  };
  if (s.options.threads == 1 || s.numVertices <= grain) {
    runRange(kernel, s, T.data(), 0, s.numVertices, out);
  } else if (s.arena) {
    s.arena->execute(body);
  } else {
    body();
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
  const int nv = static_cast<int>(rest.rows());
  const int kin = weights.influences();
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
  std::unique_lock<std::shared_mutex> lock(impl_->optionsMutex);
  impl_->options = options;
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

Points skin(const Points& rest, const SkinWeights& weights, const std::vector<Mat4>& transforms,
            const SkinnerOptions& options) {
  const Skinner skinner(rest, weights, static_cast<int>(transforms.size()), options);
  Points out;
  skinner.deform(transforms, out);
  return out;
}

}  // namespace myoskin
