// PC2 point caches (Blender's Mesh Cache modifier, 3ds Max): a 32-byte header, then frames of float32 xyz.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>

#include "myoskin/errors.h"
#include "myoskin/skinning.h"

namespace myoskin {

namespace {

constexpr char kSignature[12] = {'P', 'O', 'I', 'N', 'T', 'C', 'A', 'C', 'H', 'E', '2', '\0'};
constexpr std::streamoff kSamplesOffset = 28;  // signature 12 + version 4 + points 4 + start 4 + rate 4
constexpr std::streamoff kHeaderSize = 32;

template <typename T>
void put(std::ofstream& out, T value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
T get(std::ifstream& in) {
  T value{};
  in.read(reinterpret_cast<char*>(&value), sizeof(T));
  return value;
}

}  // namespace

// ============================================================================
// Writer
// ============================================================================

struct PC2Writer::File {
  std::ofstream out;
};

PC2Writer::PC2Writer(const std::string& path, int numPoints, float startFrame, float sampleRate)
    : file_(std::make_unique<File>()), path_(path), numPoints_(numPoints) {
  if (numPoints < 1) throw InputError("pc2: needs at least one point, got " + std::to_string(numPoints));
  if (!std::isfinite(startFrame) || !std::isfinite(sampleRate) || sampleRate <= 0)
    throw InputError("pc2: start frame and sample rate must be finite and the rate > 0");
  file_->out.open(path, std::ios::binary | std::ios::trunc);
  if (!file_->out) throw InputError("pc2: cannot write " + path);
  file_->out.write(kSignature, sizeof(kSignature));
  put<int32_t>(file_->out, 1);
  put<int32_t>(file_->out, numPoints);
  put<float>(file_->out, startFrame);
  put<float>(file_->out, sampleRate);
  put<int32_t>(file_->out, 0);  // patched on close
  if (!file_->out) throw InputError("pc2: cannot write " + path);
}

PC2Writer::~PC2Writer() {
  try {
    close();
  } catch (...) {
  }
}

void PC2Writer::writeFrame(const float* positions) {
  if (!file_ || !file_->out.is_open()) throw InputError("pc2: " + path_ + " is already closed");
  for (int i = 0; i < 3 * numPoints_; ++i)
    if (!std::isfinite(positions[i]))
      throw InputError("pc2: frame " + std::to_string(frames_) + " point " + std::to_string(i / 3) +
                       " has a NaN or infinite coordinate");
  file_->out.write(reinterpret_cast<const char*>(positions), sizeof(float) * 3 * numPoints_);
  if (!file_->out) throw InputError("pc2: cannot write " + path_);
  ++frames_;
}

void PC2Writer::writeFrame(const PointsF& positions) {
  if (positions.rows() != numPoints_)
    throw InputError("pc2: frame " + std::to_string(frames_) + " has " + std::to_string(positions.rows()) +
                     " points, the cache " + std::to_string(numPoints_));
  writeFrame(positions.data());
}

void PC2Writer::writeFrame(const Points& positions) {
  if (positions.rows() != numPoints_)
    throw InputError("pc2: frame " + std::to_string(frames_) + " has " + std::to_string(positions.rows()) +
                     " points, the cache " + std::to_string(numPoints_));
  const PointsF f = positions.cast<float>();
  writeFrame(f.data());
}

void PC2Writer::close() {
  if (!file_ || !file_->out.is_open()) return;
  file_->out.seekp(kSamplesOffset);
  put<int32_t>(file_->out, frames_);
  file_->out.close();
  if (!file_->out) throw InputError("pc2: cannot finish " + path_);
}

void writePC2(const std::string& path, const std::vector<PointsF>& frames, float startFrame, float sampleRate) {
  if (frames.empty()) throw InputError("pc2: no frames to write");
  PC2Writer writer(path, static_cast<int>(frames[0].rows()), startFrame, sampleRate);
  for (const PointsF& f : frames) writer.writeFrame(f);
  writer.close();
}

// ============================================================================
// Reader
// ============================================================================

PointCache readPC2(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError("pc2: cannot open " + path);
  const std::streamoff size = in.tellg();
  in.seekg(0);
  if (size < kHeaderSize) throw InputError("pc2: " + path + " is too short for a PC2 header");
  char signature[12];
  in.read(signature, sizeof(signature));
  if (std::memcmp(signature, kSignature, sizeof(kSignature)) != 0)
    throw InputError("pc2: " + path + " is not a PC2 file (no POINTCACHE2 signature)");
  const int32_t version = get<int32_t>(in);
  PointCache cache;
  cache.numPoints = get<int32_t>(in);
  cache.startFrame = get<float>(in);
  cache.sampleRate = get<float>(in);
  const int32_t samples = get<int32_t>(in);
  if (version != 1) throw InputError("pc2: " + path + " has version " + std::to_string(version) + ", expected 1");
  if (cache.numPoints < 0 || samples < 0) throw InputError("pc2: " + path + " has negative counts");
  // (With no points any frame count matches the 32-byte file: 10^9 empty frames were allocated.)
  if (cache.numPoints == 0) throw InputError("pc2: " + path + " has no points (the writer needs at least one)");
  // The header's counts (up to 2^31 each) must account for the file's bytes exactly; their product can exceed
  // 64 bits (signed overflow), so it is computed in 128 bits.
  const __int128 expected = kHeaderSize + static_cast<__int128>(samples) * cache.numPoints * 3 * sizeof(float);
  if (static_cast<__int128>(size) != expected)
    throw InputError("pc2: " + path + " is " + std::to_string(size) + " bytes, the header promises " +
                     (expected > INT64_MAX ? std::string("more than 2^63")
                                           : std::to_string(static_cast<long long>(expected))));
  cache.frames.resize(samples);
  for (PointsF& f : cache.frames) {
    f.resize(cache.numPoints, 3);
    in.read(reinterpret_cast<char*>(f.data()), sizeof(float) * 3 * cache.numPoints);
  }
  if (!in) throw InputError("pc2: cannot read " + path);
  return cache;
}

}  // namespace myoskin
