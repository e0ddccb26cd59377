// Which decisions of the extraction random round-off flips (issue 13 item 6): every skin vertex moved by uniform noise
// of +-4e-6 of the body's size (mt19937 seeded by the draw), then
//  1. bumps: each section's bumps (stages::profileBumps, as the bump stage's hysteresis sees them) matched by apex (within
//     3 samples) to the unperturbed ones: how many keep their arc, how far their significance moves (median, 90th and
//     99th percentile, largest), and how many jump by more than 1 % with the same arc (the section's base changed);
//  2. chains: every linked chain (ExtractionReport::chainRecords) matched to the other run's chain sharing the most
//     bump centres (same plane, within 0.2 limb radii); printed when it is kept in one run and not in the other, or
//     kept in both with another number of bumps.
// Printed, never asserted.
//   bench_noise_decisions [CHARACTER.glb [DRAWS]]   (default: makehuman_muscular_male, 3 draws)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "muscles/extraction_stages.h"
#include "myoskin/bumps.h"
#include "myoskin/errors.h"
#include "myoskin/io.h"

using namespace myoskin;

namespace {

struct SectionFound {
  std::vector<Bump> bumps;
  int points = 0;
  bool ok = false;
};

// Every section's bumps as the bump stage starts from them (stages::profileBumps: down to the hysteresis's share of
// the threshold, half of it at the defaults), significance relative to the full threshold.
std::vector<SectionFound> sectionBumps(const Character& c) {
  const ExtractionOptions o;
  ExtractionReport rep;
  const stages::BodySurface s = stages::makeBodySurface(c, o);
  const stages::SectionCut cut =
      stages::cutBodySections(s.body, s.scale, s.roles, o.planes, o.profiles, o.bumps.minProtrusion, s.vertexMask, rep);
  std::vector<SectionFound> out(cut.profiles.size());
  for (size_t i = 0; i < cut.profiles.size(); ++i) {
    const SectionProfile& prof = cut.profiles[i];
    if (!prof.ok) continue;
    try {
      out[i].bumps = stages::profileBumps(prof, o.bumps, o.sectionBumps).bumps;
      out[i].points = static_cast<int>(prof.polygon.rows());
      out[i].ok = true;
    } catch (const InputError&) {
    }
  }
  return out;
}

void compareBumps(const std::vector<SectionFound>& base, const std::vector<SectionFound>& other) {
  int total = 0, lost = 0, arcMoved = 0, sameArcJumps = 0, crossed = 0;
  std::vector<double> change;
  for (size_t i = 0; i < base.size() && i < other.size(); ++i) {
    if (!base[i].ok || !other[i].ok) continue;
    const int n = base[i].points;
    auto apart = [n](int a, int b) {
      const int x = std::abs(a - b) % n;
      return std::min(x, n - x);
    };
    for (const Bump& b : base[i].bumps) {
      if (b.significance < 0.5) continue;
      ++total;
      const Bump* near = nullptr;
      for (const Bump& q : other[i].bumps)
        if (apart(q.apex, b.apex) <= 3 && (!near || apart(q.apex, b.apex) < apart(near->apex, b.apex))) near = &q;
      if (!near) {
        ++lost;
        continue;
      }
      const double c = std::abs(near->significance / b.significance - 1.0);
      change.push_back(c);
      const bool arc = apart(near->first, b.first) > 1 || apart(near->last, b.last) > 1;
      arcMoved += arc;
      sameArcJumps += !arc && c > 0.01;
      crossed += (b.significance >= 1.0) != (near->significance >= 1.0);
    }
  }
  std::sort(change.begin(), change.end());
  auto at = [&](double f) { return change.empty() ? 0.0 : change[std::min(change.size() - 1, size_t(f * change.size()))]; };
  std::printf("  bumps %d: not found again %d, arc moved %d, same arc but significance moved > 1 %% %d, across 1.0 %d; "
              "significance moved: median %.1e, 90 %% %.1e, 99 %% %.1e, largest %.2f\n",
              total, lost, arcMoved, sameArcJumps, crossed, at(0.5), at(0.9), at(0.99), change.empty() ? 0.0 : change.back());
}

bool isKept(const std::string& v) { return v == "kept" || v == "spindle" || v == "twin" || v == "forced"; }

void showChain(const char* tag, const ChainRecord& x) {
  std::printf("    %s %-8s %-16s %-10s %2zu bumps, significance", tag, x.family.c_str(), x.bone.c_str(), x.verdict.c_str(),
              x.centres.size());
  for (double s : x.significance) std::printf(" %.2f", s);
  std::printf("\n");
}

void compareChains(const ExtractionResult& base, const ExtractionResult& other) {
  const double near = 0.2 * base.report.limbRadius;
  auto match = [&](const ChainRecord& a, const std::vector<ChainRecord>& list) {
    int best = -1, bestShared = 0;
    for (size_t j = 0; j < list.size(); ++j) {
      if (list[j].family != a.family) continue;
      int shared = 0;
      for (size_t x = 0; x < a.centres.size(); ++x)
        for (size_t y = 0; y < list[j].centres.size(); ++y)
          shared += a.planes[x] == list[j].planes[y] && (a.centres[x] - list[j].centres[y]).norm() < near;
      if (shared > bestShared) bestShared = shared, best = static_cast<int>(j);
    }
    return best;
  };
  std::printf("  muscles %zu -> %zu, chains %zu -> %zu\n", base.muscles.size(), other.muscles.size(),
              base.report.chainRecords.size(), other.report.chainRecords.size());
  for (const ChainRecord& a : base.report.chainRecords) {
    const int j = match(a, other.report.chainRecords);
    if (j < 0) {
      if (isKept(a.verdict)) showChain("gone", a);
      continue;
    }
    const ChainRecord& b = other.report.chainRecords[j];
    if (isKept(a.verdict) != isKept(b.verdict) || (isKept(a.verdict) && a.centres.size() != b.centres.size())) {
      showChain("was ", a);
      showChain("now ", b);
    }
  }
  for (const ChainRecord& b : other.report.chainRecords)
    if (isKept(b.verdict) && match(b, base.report.chainRecords) < 0) showChain("new ", b);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1]
                                    : std::string(MYOSKIN_SHARED_DIR) +
                                          "/characters/makehuman_muscular_male/makehuman_muscular_male.glb";
  const int draws = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  try {
    const Character c = loadCharacter(path);
    const std::vector<SectionFound> baseBumps = sectionBumps(c);
    const ExtractionResult base = extractMuscles(c);
    const Vec3 lo = c.mesh.vertices.colwise().minCoeff().transpose(), hi = c.mesh.vertices.colwise().maxCoeff().transpose();
    const double amplitude = 4e-6 * (hi - lo).maxCoeff();
    for (int d = 0; d < draws; ++d) {
      Character p = c;
      std::mt19937 rng(d + 1);
      std::uniform_real_distribution<double> noise(-amplitude, amplitude);
      for (int v = 0; v < p.mesh.vertices.rows(); ++v)
        for (int k = 0; k < 3; ++k) p.mesh.vertices(v, k) += noise(rng);
      std::printf("%s, noise draw %d\n", path.c_str(), d);
      compareBumps(baseBumps, sectionBumps(p));
      compareChains(base, extractMuscles(p));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_noise_decisions: %s\n", e.what());
    return 1;
  }
}
