// Hybrid skinning speed (issue 5): a ~100k-vertex skin (the synthetic arm, midpoint-subdivided once),
// 60 skeleton bones + 400 muscle joints (40 muscles x 10 joints), 4 and 8 influences per vertex.
// Prints ms per frame of Skinner::deform for 1 and 2 threads, a memory-bandwidth bound (bytes moved per
// frame / copy bandwidth measured in this run on a buffer of the same size, and on a 512 MiB buffer) and
// the ratio to it. With --export DIR it also writes the skin, weights and these figures for
// benchmarks/bench_blender_skinning.py, which times Blender's Armature modifier on the same mesh and
// weights and prints the ratio (./myoskin.sh bench runs both).
// Usage: bench_skinning [--export DIR] [--frames N]
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "myoskin/skinning.h"
#include "myoskin/subdivide.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

constexpr int kBones = 60, kMuscles = 40, kJointsPerMuscle = 10, kJoints = kBones + kMuscles * kJointsPerMuscle;

using Clock = std::chrono::steady_clock;
double seconds(Clock::time_point a) { return std::chrono::duration<double>(Clock::now() - a).count(); }

// Spatially coherent weights: skeleton bones by position along the arm, muscle joints by position along
// and around it (8 sectors x 5 spans of muscles), weights quantised to 1/64 (few Blender group calls).
SkinWeights benchWeights(const Points& v, int k) {
  const double x0 = v.col(0).minCoeff(), x1 = v.col(0).maxCoeff();
  const int bonesPer = k == 4 ? 2 : 3, jointsPer = k - bonesPer;
  SkinWeights w;
  w.joints.resize(v.rows(), k);
  w.weights.resize(v.rows(), k);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> level(8, 64);
  for (Eigen::Index i = 0; i < v.rows(); ++i) {
    const double s = (v(i, 0) - x0) / (x1 - x0);
    const double angle = std::atan2(v(i, 2), v(i, 1)) + kPi;
    const int bone = std::clamp(static_cast<int>(s * kBones), 0, kBones - bonesPer);
    const int sector = std::clamp(static_cast<int>(angle / (2 * kPi) * 8), 0, 7);
    const int span = std::clamp(static_cast<int>(s * 5), 0, 4);
    const int muscle = sector * 5 + span;
    const double along = s * 5 - span;
    const int joint = std::clamp(static_cast<int>(along * kJointsPerMuscle), 0, kJointsPerMuscle - jointsPer);
    for (int b = 0; b < bonesPer; ++b) w.joints(i, b) = bone + b;
    for (int j = 0; j < jointsPer; ++j) w.joints(i, bonesPer + j) = kBones + muscle * kJointsPerMuscle + joint + j;
    for (int c = 0; c < k; ++c) w.weights(i, c) = level(rng) / 64.0;
  }
  return w;
}

// Rotations (and for muscle joints non-uniform scale) that change every frame.
std::vector<Mat4> frameTransforms(int frame) {
  std::vector<Mat4> t(kJoints, Mat4::Identity());
  for (int j = 0; j < kJoints; ++j) {
    const double a = 0.3 * std::sin(0.05 * frame + j);
    t[j].block<3, 3>(0, 0) = Eigen::AngleAxisd(a, Vec3(0.3, 0.5, 0.8).normalized()).toRotationMatrix();
    if (j >= kBones) t[j].block<3, 3>(0, 0) *= Eigen::Vector3d(1.1, 0.9, 1.1).asDiagonal();
    t[j].block<3, 1>(0, 3) = Vec3(0.01 * a, 0.0, -0.01 * a);
  }
  return t;
}

// Best-of ms per frame over `frames` deformations (after a warm-up); cpuPerWall receives the process CPU
// time over the wall time of the best repetition (about the number of threads that really ran).
double msPerFrame(const Skinner& s, const std::vector<std::vector<Mat4>>& transforms, int frames, double& cpuPerWall) {
  PointsF out(s.numVertices(), 3);
  for (int i = 0; i < 20; ++i) s.deform(transforms[i % transforms.size()], out);
  double best = 1e30;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = Clock::now();
    const std::clock_t c0 = std::clock();
    for (int f = 0; f < frames; ++f) s.deform(transforms[f % transforms.size()], out);
    const double wall = seconds(t0), cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
    if (1e3 * wall / frames < best) best = 1e3 * wall / frames, cpuPerWall = cpu / wall;
  }
  return best;
}

// Copy bandwidth (bytes read + written per second) for a buffer of `bytes`, with `threads` threads.
double copyBandwidth(size_t bytes, int threads) {
  const size_t half = std::max<size_t>(bytes / 2, 1 << 12);
  std::vector<char> src(half, 1), dst(half, 0);
  tbb::task_arena arena(threads);
  auto copy = [&] {
    arena.execute([&] {
      tbb::parallel_for(0, threads, [&](int t) {
        const size_t a = half * t / threads, b = half * (t + 1) / threads;
        std::memcpy(dst.data() + a, src.data() + a, b - a);
      });
    });
  };
  for (int i = 0; i < 3; ++i) copy();
  const int reps = static_cast<int>(std::clamp<size_t>((size_t(2) << 30) / half, 4, 2000));
  double best = 1e30;
  for (int r = 0; r < 3; ++r) {
    const auto t0 = Clock::now();
    for (int i = 0; i < reps; ++i) copy();
    best = std::min(best, seconds(t0) / reps);
  }
  if (dst[half / 2] != 1) std::printf("(copy check failed)\n");
  return 2.0 * half / best;
}

template <typename T>
void writeRaw(const std::filesystem::path& p, const T* data, size_t count) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(data), sizeof(T) * count);
}

}  // namespace

int main(int argc, char** argv) {
  std::string exportDir;
  int frames = 100;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--export") && i + 1 < argc) exportDir = argv[++i];
    else if (!std::strcmp(argv[i], "--frames") && i + 1 < argc) frames = std::max(1, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: bench_skinning [--export DIR] [--frames N]\n");
      return 2;
    }
  }
  SyntheticArmOptions ao;
  ao.segmentsAround = 72;
  const Character skin = subdivideMidpoint(makeSyntheticArm(ao).character, 1);
  const Points& v = skin.mesh.vertices;
  std::printf("skin: %d vertices, %d triangles; %d skeleton bones + %d muscle joints\n", skin.mesh.numVertices(),
              skin.mesh.numTriangles(), kBones, kJoints - kBones);
  std::vector<std::vector<Mat4>> transforms;
  for (int f = 0; f < 16; ++f) transforms.push_back(frameTransforms(f));

  std::string json = "{\"vertices\": " + std::to_string(v.rows()) + ", \"triangles\": " +
                     std::to_string(skin.mesh.numTriangles()) + ", \"bones\": " + std::to_string(kBones) +
                     ", \"joints\": " + std::to_string(kJoints) + ", \"core\": {";
  for (int k : {4, 8}) {
    const SkinWeights w = benchWeights(v, k);
    Skinner skinner(v, w, kJoints);
    const size_t bytes = skinner.bytesPerFrame();
    std::printf("\n%d influences: %.2f MB moved per frame\n", k, bytes / 1e6);
    for (int threads : {1, 2}) {
      skinner.setOptions({4096, threads});
      double cpuPerWall = 0;
      const double ms = msPerFrame(skinner, transforms, frames, cpuPerWall);
      const double bwSame = copyBandwidth(bytes, threads), bwDram = copyBandwidth(size_t(512) << 20, threads);
      const double boundSame = 1e3 * bytes / bwSame, boundDram = 1e3 * bytes / bwDram;
      std::printf("  %d thread%s: %7.3f ms/frame (cpu/wall %.2f) | copy bandwidth %.1f GB/s (same-size buffer), %.1f GB/s "
                  "(512 MiB) -> bound %.3f / %.3f ms | ratio to bound %.2f / %.2f\n",
                  threads, threads > 1 ? "s" : " ", ms, cpuPerWall, bwSame / 1e9, bwDram / 1e9, boundSame, boundDram,
                  ms / boundSame, ms / boundDram);
      json += std::string(json.back() == '{' ? "" : ", ") + "\"k" + std::to_string(k) + "_t" +
              std::to_string(threads) + "\": " + std::to_string(ms);
    }
    if (!exportDir.empty()) {
      const std::filesystem::path dir(exportDir);
      std::filesystem::create_directories(dir);
      writeRaw(dir / ("joints_k" + std::to_string(k) + ".i32"), w.joints.data(), w.joints.size());
      writeRaw(dir / ("weights_k" + std::to_string(k) + ".f64"), w.weights.data(), w.weights.size());
    }
  }
  json += "}}\n";
  if (!exportDir.empty()) {
    const std::filesystem::path dir(exportDir);
    writeRaw(dir / "vertices.f64", v.data(), v.size());
    writeRaw(dir / "triangles.i32", skin.mesh.triangles.data(), skin.mesh.triangles.size());
    std::ofstream(dir / "core.json") << json;
    std::printf("\nexported the skin, weights and core figures to %s (for bench_blender_skinning.py)\n",
                exportDir.c_str());
  }
  return 0;
}
