// Expert options by name: one table of ExtractionOptions' tunable fields, shared by the CLI (--expert, --options)
// and Python (extract_muscles(options={...})).
#include <cmath>
#include <type_traits>

#include "myoskin/errors.h"
#include "myoskin/extraction.h"

namespace myoskin {

namespace {

// One field: its key (the field path) and type ('d', 'i', 'b'), and where it lives in an ExtractionOptions.
struct ExpertField {
  const char* key;
  char type;
  void* (*at)(ExtractionOptions&);
};

#define MYOSKIN_FIELD(path, T, code)                                        \
  ExpertField {                                                                   \
    #path, code, [](ExtractionOptions& o) -> void* {                        \
      static_assert(std::is_same_v<decltype(o.path), T>, #path " is no " #T); \
      return &o.path;                                                       \
    }                                                                       \
  }
#define MYOSKIN_DOUBLE(path) MYOSKIN_FIELD(path, double, 'd')
#define MYOSKIN_INT(path) MYOSKIN_FIELD(path, int, 'i')
#define MYOSKIN_BOOL(path) MYOSKIN_FIELD(path, bool, 'b')

// Every expert option (the user-facing five, planes.spacing, the derived link.faint* and profiles.minPerimeter, and
// profiles.sampleSpacing, a resolution that profiles.samples overrides, left out).
const std::vector<ExpertField>& expertFields() {
  static const std::vector<ExpertField> table = {
    MYOSKIN_DOUBLE(planes.endMargin),
    MYOSKIN_DOUBLE(planes.bendAngle),
    MYOSKIN_DOUBLE(planes.shoulderStart),
    MYOSKIN_DOUBLE(planes.shoulderSpacing),
    MYOSKIN_DOUBLE(planes.shoulderClip),
    MYOSKIN_INT(profiles.samples),
    MYOSKIN_DOUBLE(profiles.minRegionShare),
    MYOSKIN_DOUBLE(profiles.trunkClipShare),
    MYOSKIN_BOOL(profiles.mirrorLimbs),
    MYOSKIN_DOUBLE(bumps.minProtrusion),
    MYOSKIN_DOUBLE(bumps.minRelativeProtrusion),
    MYOSKIN_DOUBLE(bumps.minWidthFraction),
    MYOSKIN_DOUBLE(bumps.maxWidthFraction),
    MYOSKIN_DOUBLE(bumps.semicircleTolerance),
    MYOSKIN_BOOL(bumps.absorbJunctions),
    MYOSKIN_DOUBLE(bumps.supportTolerance),
    MYOSKIN_INT(bumps.baseHarmonics),
    MYOSKIN_DOUBLE(link.maxLateralFactor),
    MYOSKIN_DOUBLE(link.maxAngle),
    MYOSKIN_INT(link.maxGap),
    MYOSKIN_BOOL(link.branches),
    MYOSKIN_DOUBLE(link.mergeFactor),
    MYOSKIN_BOOL(link.mergeAlternating),
    MYOSKIN_DOUBLE(ends.maxExtensionFraction),
    MYOSKIN_DOUBLE(ends.tieTolerance),
    MYOSKIN_INT(ends.samplesPerEnd),
    MYOSKIN_DOUBLE(ends.spanCarry),
    MYOSKIN_BOOL(ends.spanDistal),
    MYOSKIN_INT(surface.ringVertices),
    MYOSKIN_INT(surface.capRings),
    MYOSKIN_INT(surface.smoothingPasses),
    MYOSKIN_BOOL(surface.containInSkin),
    MYOSKIN_DOUBLE(surface.skinMargin),
    MYOSKIN_DOUBLE(surface.maxCapLength),
    MYOSKIN_DOUBLE(sectionBumps.forcedMinProtrusion),
    MYOSKIN_DOUBLE(sectionBumps.weakFraction),
    MYOSKIN_DOUBLE(sectionBumps.faintFraction),
    MYOSKIN_DOUBLE(sectionBumps.faintRelative),
    MYOSKIN_INT(sectionBumps.trunkHarmonics),
    MYOSKIN_INT(sectionBumps.minBumpCrossings),
    MYOSKIN_DOUBLE(filters.minEvidence),
    MYOSKIN_DOUBLE(filters.minRelative),
    MYOSKIN_DOUBLE(filters.continuousEvidence),
    MYOSKIN_DOUBLE(filters.spindleEnds),
    MYOSKIN_DOUBLE(filters.spindleLength),
    MYOSKIN_DOUBLE(filters.spindleSteepness),
    MYOSKIN_DOUBLE(filters.twinReach),
    MYOSKIN_DOUBLE(scale.referenceLimbRadius),
    MYOSKIN_BOOL(scale.continuous),
  };
  return table;
}

#undef MYOSKIN_BOOL
#undef MYOSKIN_INT
#undef MYOSKIN_DOUBLE
#undef MYOSKIN_FIELD

const ExpertField& expertField(const std::string& key) {
  for (const ExpertField& f : expertFields())
    if (key == f.key) return f;
  throw InputError("unknown expert extraction option '" + key +
                   "' (the keys are ExtractionOptions' field paths, e.g. filters.minEvidence: myoskin extract "
                   "--expert list, Python extraction_options())");
}

double readField(const ExpertField& f, ExtractionOptions& o) {
  void* p = f.at(o);
  if (f.type == 'd') return *static_cast<double*>(p);
  if (f.type == 'i') return *static_cast<int*>(p);
  return *static_cast<bool*>(p) ? 1.0 : 0.0;
}

}  // namespace

// ============================================================================
// Expert options
// ============================================================================

std::vector<ExpertOption> expertOptions() {
  std::vector<ExpertOption> out;
  ExtractionOptions defaults;
  for (const ExpertField& f : expertFields())
    out.push_back({f.key, f.type == 'd' ? "double" : f.type == 'i' ? "int" : "bool", readField(f, defaults)});
  return out;
}

void setExpertOption(ExtractionOptions& options, const std::string& key, double value) {
  const ExpertField& f = expertField(key);
  if (!std::isfinite(value)) throw InputError("expert option " + key + " must be finite");
  void* p = f.at(options);
  if (f.type == 'd') {
    *static_cast<double*>(p) = value;
  } else if (f.type == 'i') {
    if (value != std::round(value) || std::abs(value) > 1e9)
      throw InputError("expert option " + key + " must be an integer, got " + std::to_string(value));
    *static_cast<int*>(p) = static_cast<int>(value);
  } else {
    if (value != 0.0 && value != 1.0) throw InputError("expert option " + key + " must be true/false (1/0)");
    *static_cast<bool*>(p) = value != 0.0;
  }
}

double expertOption(const ExtractionOptions& options, const std::string& key) {
  return readField(expertField(key), const_cast<ExtractionOptions&>(options));  // only read
}

}  // namespace myoskin
