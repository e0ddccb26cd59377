// Stage 5a of the extraction: the sections' bumps linked into chains; forced regions mark their chains.
#include <algorithm>

#include "muscles/extraction_stages.h"

namespace myoskin::stages {

// ============================================================================
// Linking
// ============================================================================

std::vector<MuscleChain> linkSectionChains(const SectionBumpsResult& found, const LinkOptions& link,
                                           const SectionBumpOptions& options, size_t forcedRegions,
                                           ExtractionReport& rep) {
  const std::vector<SectionBumps>& sections = found.sections;
  const std::vector<std::vector<int>>& forcedOf = found.forcedOf;
  LinkOptions linkOptions = link;  // faint links (below weakFraction) kept only near their chain's peak
  if (options.faintRelative > 0 && options.faintFraction < options.weakFraction) {
    linkOptions.faintBelow = std::clamp(options.weakFraction, 1e-3, 1.0);
    linkOptions.faintRelative = options.faintRelative;
  }
  std::vector<MuscleChain> chains = linkBumps(sections, linkOptions, &rep.branches);
  rep.chains = static_cast<int>(chains.size());
  // Each forced region keeps one chain: the one with the most links from that region.
  for (MuscleChain& c : chains) c.forced = false;
  for (size_t r = 0; r < forcedRegions; ++r) {
    int best = -1, bestCount = 0;
    for (size_t c = 0; c < chains.size(); ++c) {
      int count = 0;
      for (const ChainLink& l : chains[c].links)
        if (l.bump >= 0 && forcedOf[l.section][l.bump] == static_cast<int>(r)) ++count;
      if (count > bestCount) best = static_cast<int>(c), bestCount = count;
    }
    if (best >= 0) chains[best].forced = true;
  }
  return chains;
}

}  // namespace myoskin::stages
