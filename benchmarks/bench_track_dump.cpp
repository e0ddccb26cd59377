// Every limb chain of bumps as the floors and the closed-spindle test (track_evidence.h) see it (issue 13, track
// evidence): the generated tune characters and their smooth twins, then MakeHuman muscular and neutral at plane spacings
// x 0.9-1.1. One JSON object per line: per character a summary (found, true, matched), its skipped sections, and per
// limb chain its bumps' significance, height relative to the section radius, ellipse radius sqrt(a b), plane order, its
// length (first to last centre), steepness, verdict and the true muscle it lies on ("name:found" / "name:missed", "F"
// for none). Printed, never asserted: for choosing the spindle test's settings on tune seeds only.
//   bench_track_dump [first_seed last_seed [makehuman 0|1]]   (default: 1 11 1)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/synthetic_character.h"
#include "tuning_sets.h"
#include "line_distance.h"

using namespace myoskin;
using myoskin::bench::lineDistance;

namespace {
void dump(const std::string& set, const Character& c, const std::vector<TrueMuscle>& truth, const ExtractionOptions& o) {
  const ExtractionResult r = extractMuscles(c, o);
  const ExtractionAccuracy acc = measureExtraction(r.muscles, truth);
  std::printf("{\"set\":\"%s\",\"summary\":1,\"found\":%zu,\"true\":%zu,\"matched\":%d}\n", set.c_str(), r.muscles.size(),
              truth.size(), acc.matched);
  for (const SkippedSection& sk : r.report.skipped)
    std::printf("{\"set\":\"%s\",\"skip\":1,\"section\":%d,\"bone\":\"%s\",\"family\":\"%s\",\"reason\":\"%s\"}\n", set.c_str(),
                sk.section, sk.bone.c_str(), sk.family.c_str(), sk.reason.c_str());
  for (const ChainRecord& ch : r.report.chainRecords) {
    if (ch.family != "limb") continue;
    std::string label = "F";
    for (size_t t = 0; t < truth.size(); ++t) {
      int near = 0;
      for (const Vec3& p : ch.centres) near += lineDistance(p, truth[t].centerLine) < 0.75 * truth[t].peakRadius;
      if (2 * near >= static_cast<int>(ch.centres.size()))
        label = truth[t].name + (acc.matchOfTrue[t] >= 0 ? ":found" : ":missed");
    }
    std::printf("{\"set\":\"%s\",\"bone\":\"%s\",\"verdict\":\"%s\",\"label\":\"%s\",\"steep\":%.4f,\"sig\":[", set.c_str(),
                ch.bone.c_str(), ch.verdict.c_str(), label.c_str(), ch.steepness);
    for (size_t k = 0; k < ch.significance.size(); ++k) std::printf("%s%.3f", k ? "," : "", ch.significance[k]);
    std::printf("],\"rel\":[");
    for (size_t k = 0; k < ch.relative.size(); ++k) std::printf("%s%.4f", k ? "," : "", ch.relative[k]);
    std::printf("],\"radius\":[");
    for (size_t k = 0; k < ch.radius.size(); ++k) std::printf("%s%.5f", k ? "," : "", ch.radius[k]);
    std::printf("],\"length\":%.5f,\"limb\":%.5f", ch.centres.size() > 1 ? (ch.centres.back() - ch.centres.front()).norm() : 0.0, r.report.limbRadius);
    std::printf(",\"planes\":[");
    for (size_t k = 0; k < ch.planes.size(); ++k) std::printf("%s%d", k ? "," : "", ch.planes[k]);
    std::printf("]}\n");
  }
}
}  // namespace

int main(int argc, char** argv) {
  unsigned first = 1, last = 11;
  if (argc >= 3) first = std::atoi(argv[1]), last = std::atoi(argv[2]);
  const bool makehuman = argc < 4 || std::atoi(argv[3]) != 0;
  ExtractionOptions base;
  base.buildSurfaces = false;
  bench::forEachTuningBody(first, last, base, dump);
  if (!makehuman) return 0;
  bench::forEachMakeHumanSpacing(base, dump);
  return 0;
}
