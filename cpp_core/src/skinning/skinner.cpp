// The Equation 3 skinner: structure-of-arrays float32 rest skin, packed sparse influences, TBB threads.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

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

  void makeArena() {
    arena.reset();
    if (options.threads > 0) arena = std::make_unique<tbb::task_arena>(options.threads);
  }
};

namespace {

constexpr int kMaxJoints = std::numeric_limits<uint16_t>::max() - 1;

std::string where(int v, int k) { return "vertex " + std::to_string(v) + " slot " + std::to_string(k); }

// Transforms as float 3 x 4 row-major blocks, with one extra identity block at index #J.
std::vector<float> packTransforms(const std::vector<Mat4>& transforms, int numJoints) {
  if (static_cast<int>(transforms.size()) != numJoints)
    throw InputError("skinning: " + std::to_string(transforms.size()) + " transforms for " +
                     std::to_string(numJoints) + " joints");
  std::vector<float> packed(12 * (static_cast<size_t>(numJoints) + 1));
  for (int j = 0; j <= numJoints; ++j) {
    const Mat4 m = j < numJoints ? transforms[j] : Mat4::Identity();
    if (!m.allFinite()) throw InputError("skinning: transform " + std::to_string(j) + " has a NaN or infinite value");
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) packed[12 * j + 4 * r + c] = static_cast<float>(m(r, c));
  }
  return packed;
}

// Blend the vertex's K matrices, then transform its rest position.
template <int K, typename Out>
void kernel(const Skinner::Impl& s, const float* T, int begin, int end, int slots, Out* out) {
  const int k = K > 0 ? K : slots;
  for (int v = begin; v < end; ++v) {
    const uint16_t* jv = s.joint.data() + static_cast<size_t>(v) * k;
    const float* wv = s.weight.data() + static_cast<size_t>(v) * k;
    float m[12];
    {
      const float* t = T + 12 * jv[0];
      const float w = wv[0];
      for (int e = 0; e < 12; ++e) m[e] = w * t[e];
    }
    for (int i = 1; i < k; ++i) {
      const float* t = T + 12 * jv[i];
      const float w = wv[i];
      for (int e = 0; e < 12; ++e) m[e] += w * t[e];
    }
    const float px = s.x[v], py = s.y[v], pz = s.z[v];
    out[3 * static_cast<size_t>(v) + 0] = m[0] * px + m[1] * py + m[2] * pz + m[3];
    out[3 * static_cast<size_t>(v) + 1] = m[4] * px + m[5] * py + m[6] * pz + m[7];
    out[3 * static_cast<size_t>(v) + 2] = m[8] * px + m[9] * py + m[10] * pz + m[11];
  }
}

template <typename Out>
void runRange(const Skinner::Impl& s, const float* T, int begin, int end, Out* out) {
  switch (s.slots) {
    case 1: kernel<1>(s, T, begin, end, 1, out); break;
    case 2: kernel<2>(s, T, begin, end, 2, out); break;
    case 3: kernel<3>(s, T, begin, end, 3, out); break;
    case 4: kernel<4>(s, T, begin, end, 4, out); break;
    case 5: kernel<5>(s, T, begin, end, 5, out); break;
    case 6: kernel<6>(s, T, begin, end, 6, out); break;
    case 7: kernel<7>(s, T, begin, end, 7, out); break;
    case 8: kernel<8>(s, T, begin, end, 8, out); break;
    default: kernel<0>(s, T, begin, end, s.slots, out); break;
  }
}

template <typename Out>
void deformInto(const Skinner::Impl& s, const std::vector<Mat4>& transforms, Out* out) {
  const std::vector<float> T = packTransforms(transforms, s.numJoints);
  const int grain = std::max(1, s.options.grainSize);
  auto body = [&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, s.numVertices, grain),
        [&](const tbb::blocked_range<int>& r) { runRange(s, T.data(), r.begin(), r.end(), out); },
        tbb::simple_partitioner());
  };
  if (s.options.threads == 1 || s.numVertices <= grain) {
    runRange(s, T.data(), 0, s.numVertices, out);
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
  if (out.rows() != impl_->numVertices) out.resize(impl_->numVertices, 3);
  deformInto(*impl_, transforms, out.data());
}

Points skin(const Points& rest, const SkinWeights& weights, const std::vector<Mat4>& transforms,
            const SkinnerOptions& options) {
  const Skinner skinner(rest, weights, static_cast<int>(transforms.size()), options);
  Points out;
  skinner.deform(transforms, out);
  return out;
}

}  // namespace myoskin
