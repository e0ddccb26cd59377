// Stage 5: link the bumps of consecutive sections of one cutting-plane family into muscle chains,
// with transition sections where chains split or merge (the paper's auxiliary transition curve).
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <tuple>

#include "muscles/muscle_util.h"
#include "myoskin/extraction.h"

namespace myoskin {

Vec3 planePoint(const CuttingPlane& plane, const Vec2& p) { return plane.origin + p.x() * plane.xAxis + p.y() * plane.yAxis; }

namespace {


Vec3 ellipseCenter3(const SectionBumps& s, const Ellipse2& e) { return planePoint(s.plane, e.center); }

Vec3 ellipseAxis3(const CuttingPlane& plane, const Ellipse2& e) {
  return (std::cos(e.angle) * plane.xAxis + std::sin(e.angle) * plane.yAxis).normalized();
}

// The test and cost of linking ellipse ea (section sa) to eb (section sb). Returns a negative cost when
// the pair fails the test.
double linkCost(const SectionBumps& sa, const Ellipse2& ea, const SectionBumps& sb, const Ellipse2& eb,
                const LinkOptions& o) {
  const Vec3 n = sa.plane.normal.normalized();
  const Vec3 ca = ellipseCenter3(sa, ea), cb = ellipseCenter3(sb, eb);
  Vec3 d = cb - ca;
  d -= d.dot(n) * n;
  const double lateral = d.norm();
  const double meanA = 0.5 * (ea.a + eb.a);
  if (!(meanA > 0) || lateral > o.maxLateralFactor * meanA) return -1;
  // Angle around the bone: the centres seen from each plane's bone point, both projected on plane a.
  Vec3 va = ca - sa.plane.origin, vb = cb - sb.plane.origin;
  va -= va.dot(n) * n;
  vb -= vb.dot(n) * n;
  const double ra = va.norm(), rb = vb.norm();
  double dAngle = 0, limit = o.maxAngle;
  if (ra > 1e-9 && rb > 1e-9) {
    dAngle = std::atan2(va.cross(vb).dot(n), va.dot(vb));
    dAngle = std::abs(dAngle);
    // Angular extents must overlap: half-widths seen from the bone.
    const double wa = std::atan2(ea.a, ra), wb = std::atan2(eb.a, rb);
    limit = std::min(o.maxAngle, wa + wb);
  }
  if (dAngle > limit) return -1;
  return lateral / meanA + dAngle / std::max(o.maxAngle, 1e-9);
}

// Ellipse e of section `from` expressed in the frame of section `to` (centre projected, axis projected).
Ellipse2 reexpress(const SectionBumps& from, const Ellipse2& e, const SectionBumps& to) {
  const Vec3 c = ellipseCenter3(from, e) - to.plane.origin;
  const Vec3 ax = ellipseAxis3(from.plane, e);
  Ellipse2 r = e;
  r.center = Vec2(c.dot(to.plane.xAxis), c.dot(to.plane.yAxis));
  r.angle = std::atan2(ax.dot(to.plane.yAxis), ax.dot(to.plane.xAxis));
  return r;
}

// The average of two ellipses of the same plane (axis angles averaged modulo pi).
Ellipse2 averageEllipse(const Ellipse2& x, const Ellipse2& y) {
  Ellipse2 r;
  r.center = 0.5 * (x.center + y.center);
  r.a = 0.5 * (x.a + y.a);
  r.b = 0.5 * (x.b + y.b);
  double d = y.angle - x.angle;
  while (d > kPi / 2) d -= kPi;
  while (d < -kPi / 2) d += kPi;
  r.angle = x.angle + 0.5 * d;
  if (r.b > r.a) std::swap(r.a, r.b);
  return r;
}

double meanA(const MuscleChain& c) {
  double s = 0.0;
  for (const ChainLink& l : c.links) s += l.ellipse.a;
  return c.links.empty() ? 0.0 : s / c.links.size();
}

// Alternating fragments of one belly (its apex alternates between two heads, so the link test's turn limit
// splits it into two chains): x and y share no plane, no link of one lies more than 1 + maxGap planes from the
// other's nearest link, their plane ranges overlap (they alternate, not follow one another), and at least one pair
// of links of the two within that reach passes the link test.
bool alternatingFragments(const MuscleChain& x, const MuscleChain& y, const std::vector<SectionBumps>& sections,
                          const LinkOptions& o) {
  std::vector<const ChainLink*> lx, ly;
  for (const ChainLink& l : x.links)
    if (l.bump >= 0) lx.push_back(&l);
  for (const ChainLink& l : y.links)
    if (l.bump >= 0) ly.push_back(&l);
  if (lx.empty() || ly.empty()) return false;
  auto orderOf = [&](const ChainLink* l) { return sections[l->section].plane.order; };
  const int reach = 1 + std::max(0, o.maxGap);
  bool linked = false;
  auto covered = [&](const std::vector<const ChainLink*>& from, const std::vector<const ChainLink*>& to) {
    for (const ChainLink* a : from) {
      int nearest = std::numeric_limits<int>::max();
      for (const ChainLink* b : to) {
        const int d = orderOf(b) - orderOf(a);
        nearest = std::min(nearest, std::abs(d));
        if (d == 0) return false;  // a shared plane: two bellies side by side, not fragments
        if (!linked && std::abs(d) <= reach) {
          const ChainLink* first = d > 0 ? a : b;
          const ChainLink* second = d > 0 ? b : a;
          linked = linkCost(sections[first->section], first->ellipse, sections[second->section], second->ellipse, o) >= 0;
        }
      }
      if (nearest > reach) return false;
    }
    return true;
  };
  // Alternating, not consecutive: the two chains' plane ranges overlap.
  auto range = [&](const std::vector<const ChainLink*>& ls) {
    int lo = std::numeric_limits<int>::max(), hi = std::numeric_limits<int>::min();
    for (const ChainLink* l : ls) lo = std::min(lo, orderOf(l)), hi = std::max(hi, orderOf(l));
    return std::make_pair(lo, hi);
  };
  const auto [x0, x1] = range(lx);
  const auto [y0, y1] = range(ly);
  if (!(std::max(x0, y0) < std::min(x1, y1))) return false;
  return covered(lx, ly) && covered(ly, lx) && linked;
}

// Fragments of one belly (the bump stage split it in some sections, a branch rejoined): chains of one
// family instance whose centres come within mergeFactor x the larger mean a at the same or a neighbouring
// plane (real links only, not transition sections) become one chain; at a shared plane the two ellipses
// are averaged.
void mergeFragments(std::vector<MuscleChain>& chains, const std::vector<SectionBumps>& sections, const LinkOptions& o) {
  auto orderOf = [&](const ChainLink& l) { return sections[l.section].plane.order; };
  for (bool changed = true; changed;) {
    changed = false;
    for (size_t i = 0; i < chains.size() && !changed; ++i)
      for (size_t j = i + 1; j < chains.size() && !changed; ++j) {
        MuscleChain &x = chains[i], &y = chains[j];
        if (x.family != y.family || x.familyIndex != y.familyIndex) continue;
        const double reach = o.mergeFactor * std::max(meanA(x), meanA(y));
        bool close = false;
        for (const ChainLink& lx : x.links)
          for (const ChainLink& ly : y.links)
            if (lx.bump >= 0 && ly.bump >= 0 && std::abs(orderOf(lx) - orderOf(ly)) <= 1 &&
                (ellipseCenter3(sections[lx.section], lx.ellipse) - ellipseCenter3(sections[ly.section], ly.ellipse)).norm() <= reach)
              close = true;
        if (!close && o.mergeAlternating) close = alternatingFragments(x, y, sections, o);
        if (!close) continue;
        std::map<int, ChainLink> byOrder;
        for (const ChainLink& l : x.links) byOrder[orderOf(l)] = l;
        for (const ChainLink& l : y.links) {
          auto it = byOrder.find(orderOf(l));
          if (it == byOrder.end()) {
            byOrder[orderOf(l)] = l;
          } else if (it->second.section == l.section) {
            ChainLink m = it->second.bump >= 0 ? it->second : l;
            m.ellipse = averageEllipse(it->second.ellipse, l.ellipse);
            it->second = m;
          } else if (it->second.bump < 0 && l.bump >= 0) {
            it->second = l;
          }
        }
        x.links.clear();
        for (auto& [order, l] : byOrder) x.links.push_back(l);
        chains.erase(chains.begin() + static_cast<long>(j));
        changed = true;
      }
  }
}

double linkSignificance(const ChainLink& l, const std::vector<SectionBumps>& sections) {
  const std::vector<double>& sig = sections[l.section].significance;
  return l.bump >= 0 && l.bump < static_cast<int>(sig.size()) ? sig[l.bump] : 0.0;
}

// Faint links (significance below faintBelow) stay only where they reach faintRelative of the chain's peak;
// a transition section whose neighbouring real link goes goes with it.
void trimFaintLinks(std::vector<MuscleChain>& chains, const std::vector<SectionBumps>& sections, const LinkOptions& o) {
  for (MuscleChain& ch : chains) {
    double peak = 0.0;
    for (const ChainLink& l : ch.links) peak = std::max(peak, linkSignificance(l, sections));
    const double keepAt = std::min(o.faintBelow, o.faintRelative * peak);
    auto faint = [&](const ChainLink& l) {
      if (l.bump < 0) return false;
      if (!sections[l.section].forced.empty() && sections[l.section].forced[l.bump]) return false;
      return linkSignificance(l, sections) < keepAt;
    };
    std::vector<ChainLink> kept;
    for (size_t i = 0; i < ch.links.size(); ++i) {
      const ChainLink& l = ch.links[i];
      if (faint(l)) continue;
      if (l.bump < 0 && ((i + 1 < ch.links.size() && faint(ch.links[i + 1])) || (i > 0 && faint(ch.links[i - 1])))) continue;
      kept.push_back(l);
    }
    ch.links = std::move(kept);
  }
  chains.erase(std::remove_if(chains.begin(), chains.end(),
                              [](const MuscleChain& c) {
                                for (const ChainLink& l : c.links)
                                  if (l.bump >= 0) return false;
                                return true;
                              }),
               chains.end());
}

struct OpenChain {
  int chain;      // index into the output
  int lastOrder;  // order of its last real link
  bool closed = false;
};

}  // namespace

std::vector<MuscleChain> linkBumps(const std::vector<SectionBumps>& sections, const LinkOptions& options,
                                   int* branchCount) {
  int branches = 0;
  // Family instances, each with its sections sorted by order.
  std::map<std::pair<std::string, int>, std::vector<int>> families;
  for (int i = 0; i < static_cast<int>(sections.size()); ++i)
    families[{sections[i].plane.family, sections[i].plane.familyIndex}].push_back(i);

  std::vector<MuscleChain> chains;
  for (auto& [key, ids] : families) {
    std::stable_sort(ids.begin(), ids.end(),
                     [&](int x, int y) { return sections[x].plane.order < sections[y].plane.order; });
    std::vector<OpenChain> open;
    for (int si : ids) {
      const SectionBumps& s = sections[si];
      const int order = s.plane.order;
      const int nb = static_cast<int>(s.ellipses.size());
      // Close chains that fell out of the gap window.
      for (OpenChain& oc : open)
        if (!oc.closed && order - oc.lastOrder > 1 + options.maxGap) oc.closed = true;
      // Candidate pairs (cost, open chain, bump).
      std::vector<std::tuple<double, int, int>> pairs;
      for (int oi = 0; oi < static_cast<int>(open.size()); ++oi) {
        if (open[oi].closed || open[oi].lastOrder >= order) continue;
        const std::vector<ChainLink>& links = chains[open[oi].chain].links;
        const ChainLink& tail = links.back();
        const SectionBumps& ts = sections[tail.section];
        // The bump before the tail too, so a chain cannot turn from one belly onto its neighbour in a few
        // small steps (the biceps sliding onto the brachialis): at most one turn per maxAngle.
        const ChainLink* before = links.size() >= 2 && links[links.size() - 2].bump >= 0 ? &links[links.size() - 2] : nullptr;
        for (int b = 0; b < nb; ++b) {
          const double c = linkCost(ts, tail.ellipse, s, s.ellipses[b], options);
          if (c < 0) continue;
          if (before && linkCost(sections[before->section], before->ellipse, s, s.ellipses[b], options) < 0) continue;
          pairs.emplace_back(c, oi, b);
        }
      }
      std::sort(pairs.begin(), pairs.end());
      std::vector<int> bumpTaken(nb, -1);          // open-chain index that took the bump
      std::vector<char> chainTaken(open.size(), 0);
      std::vector<ChainLink> previousTail(open.size());
      for (const auto& [c, oi, b] : pairs) {
        if (chainTaken[oi] || bumpTaken[b] >= 0) continue;
        chainTaken[oi] = 1;
        bumpTaken[b] = oi;
        MuscleChain& ch = chains[open[oi].chain];
        previousTail[oi] = ch.links.back();
        ch.links.push_back(ChainLink{si, b, s.ellipses[b]});
        open[oi].lastOrder = order;
      }
      // Merges: a chain that did not continue but whose tail fits a bump another chain took ends in a
      // transition section in this plane (average of its tail, re-expressed here, and that bump).
      if (options.branches) {
        for (int oi = 0; oi < static_cast<int>(open.size()); ++oi) {
          if (open[oi].closed || chainTaken[oi] || open[oi].lastOrder >= order) continue;
          MuscleChain& ch = chains[open[oi].chain];
          const ChainLink tail = ch.links.back();
          if (tail.bump < 0) continue;
          double best = -1;
          int bestB = -1;
          for (int b = 0; b < nb; ++b) {
            if (bumpTaken[b] < 0) continue;
            const double c = linkCost(sections[tail.section], tail.ellipse, s, s.ellipses[b], options);
            if (c >= 0 && (best < 0 || c < best)) best = c, bestB = b;
          }
          if (bestB >= 0) {
            const Ellipse2 t = averageEllipse(reexpress(sections[tail.section], tail.ellipse, s), s.ellipses[bestB]);
            ch.links.push_back(ChainLink{si, -1, t});
            open[oi].closed = true;
            ++branches;
          }
        }
      }
      // Unassigned bumps start chains; a split (the bump also fits the previous tail of a chain that
      // continued here) starts with a transition section in that tail's plane.
      for (int b = 0; b < nb; ++b) {
        if (bumpTaken[b] >= 0) continue;
        MuscleChain ch;
        ch.family = key.first;
        ch.familyIndex = key.second;
        if (options.branches) {
          double best = -1;
          int bestO = -1;
          for (int oi = 0; oi < static_cast<int>(chainTaken.size()); ++oi) {
            if (!chainTaken[oi] || previousTail[oi].bump < 0) continue;
            const ChainLink& pt = previousTail[oi];
            const double c = linkCost(sections[pt.section], pt.ellipse, s, s.ellipses[b], options);
            if (c >= 0 && (best < 0 || c < best)) best = c, bestO = oi;
          }
          if (bestO >= 0) {
            const ChainLink& pt = previousTail[bestO];
            const Ellipse2 t = averageEllipse(pt.ellipse, reexpress(s, s.ellipses[b], sections[pt.section]));
            ch.links.push_back(ChainLink{pt.section, -1, t});
            ++branches;
          }
        }
        ch.links.push_back(ChainLink{si, b, s.ellipses[b]});
        chains.push_back(std::move(ch));
        open.push_back(OpenChain{static_cast<int>(chains.size()) - 1, order});
      }
    }
  }

  mergeFragments(chains, sections, options);
  if (options.faintBelow > 0 && options.faintRelative > 0) trimFaintLinks(chains, sections, options);
  for (MuscleChain& ch : chains) {
    ch.realSections = ch.strongSections = 0;
    std::map<int, int> boneVotes;
    for (const ChainLink& l : ch.links) {
      if (l.bump >= 0) {
        ++ch.realSections;
        const std::vector<double>& sig = sections[l.section].significance;
        ch.strongSections += l.bump >= static_cast<int>(sig.size()) || sig[l.bump] >= 1.0;
        if (!sections[l.section].forced.empty() && sections[l.section].forced[l.bump]) ch.forced = true;
      }
      ++boneVotes[sections[l.section].plane.bone];
    }
    int best = -1;
    for (const auto& [bone, n] : boneVotes)
      if (best < 0 || n > boneVotes[best]) best = bone;
    ch.bone = best;
    ch.confidence = chainConfidence(ch, sections, options);
  }
  std::stable_sort(chains.begin(), chains.end(), [&](const MuscleChain& x, const MuscleChain& y) {
    const CuttingPlane& px = sections[x.links.front().section].plane;
    const CuttingPlane& py = sections[y.links.front().section].plane;
    const Ellipse2& ex = x.links.front().ellipse;
    const Ellipse2& ey = y.links.front().ellipse;
    return std::make_tuple(x.family, x.familyIndex, px.order, std::atan2(ex.center.y(), ex.center.x())) <
           std::make_tuple(y.family, y.familyIndex, py.order, std::atan2(ey.center.y(), ey.center.x()));
  });
  if (branchCount) *branchCount = branches;
  return chains;
}

double chainConfidence(const MuscleChain& chain, const std::vector<SectionBumps>& sections, const LinkOptions& options) {
  if (chain.links.empty()) return 0.0;
  const double count = std::min(1.0, chain.realSections / (2.0 * std::max(1, options.minSections)));
  double sig = 0;
  int ns = 0;
  for (const ChainLink& l : chain.links)
    if (l.bump >= 0 && l.bump < static_cast<int>(sections[l.section].significance.size()))
      sig += sections[l.section].significance[l.bump], ++ns;
  const double significance = ns ? 1.0 - std::exp(-(sig / ns) / 2.0) : 0.0;
  // Consistency: relative changes of a, b and lateral centre steps between consecutive links.
  double variation = 0;
  int nv = 0;
  for (size_t i = 1; i < chain.links.size(); ++i) {
    const ChainLink& p = chain.links[i - 1];
    const ChainLink& q = chain.links[i];
    const double ma = 0.5 * (p.ellipse.a + q.ellipse.a), mb = 0.5 * (p.ellipse.b + q.ellipse.b);
    if (!(ma > 0) || !(mb > 0)) continue;
    const SectionBumps& sp = sections[p.section];
    Vec3 d = planePoint(sections[q.section].plane, q.ellipse.center) - planePoint(sp.plane, p.ellipse.center);
    d -= d.dot(sp.plane.normal) * sp.plane.normal;
    variation += (std::abs(p.ellipse.a - q.ellipse.a) / ma + std::abs(p.ellipse.b - q.ellipse.b) / mb + d.norm() / ma) / 3.0;
    ++nv;
  }
  const double consistency = 1.0 / (1.0 + (nv ? variation / nv : 0.0) * 4.0);
  const double c = std::cbrt(count * significance * consistency);
  return std::clamp(c, 0.0, 1.0);
}

}  // namespace myoskin
