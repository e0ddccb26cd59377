// Muscle extraction: extract_muscles(character, ...) -> (list[Muscle], report dict). GIL released.
#include <cmath>
#include <map>
#include <string>

#include "bindings.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/muscle_shape.h"
#include "myoskin/subdivide.h"

namespace myoskin::python {

namespace {

// A #V mask from any 1-D array-like (bool or int); non-zero = inside.
std::vector<char> toMask(const py::handle& obj, const char* what) {
  const auto arr = py::array_t<int8_t, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!arr) throw InputError(std::string(what) + " must be a 1-D array of booleans");
  if (arr.ndim() != 1) throw InputError(std::string(what) + " must be 1-D");
  std::vector<char> mask(static_cast<size_t>(arr.shape(0)));
  for (py::ssize_t i = 0; i < arr.shape(0); ++i) mask[i] = arr.at(i) != 0;
  return mask;
}

py::dict reportToDict(const ExtractionReport& r) {
  py::dict d;
  d["bones"] = r.bones;
  d["active_bones"] = r.activeBones;
  d["planes"] = r.planes;
  d["sections"] = r.sections;
  d["bumps"] = r.bumps;
  d["chains"] = r.chains;
  d["branches"] = r.branches;
  d["muscles"] = r.muscles;
  d["dropped_short"] = r.droppedShort;
  d["dropped_confidence"] = r.droppedConfidence;
  d["dropped_region_limit"] = r.droppedRegionLimit;
  d["dropped_overlap"] = r.droppedOverlap;
  d["mirrored"] = r.mirrored;
  d["split"] = r.split;
  d["dropped_flat"] = r.droppedFlat;
  d["spindles"] = r.spindles;
  d["twins"] = r.twins;
  d["forced"] = r.forced;
  d["limb_radius"] = r.limbRadius;
  d["scale"] = r.scale;
  d["analysed"] = r.analysed;
  d["diagnosis"] = r.diagnosis;
  py::list excluded;
  for (const ExcludedComponent& c : r.excluded) {
    py::dict e;
    e["vertices"] = c.vertices;
    e["bone"] = c.bone;
    e["reason"] = c.reason;
    e["first_vertex"] = c.firstVertex;
    excluded.append(e);
  }
  d["excluded"] = excluded;
  py::list skipped;
  for (const SkippedSection& s : r.skipped) {
    py::dict e;
    e["section"] = s.section;
    e["bone"] = s.bone;
    e["family"] = s.family;
    e["reason"] = s.reason;
    skipped.append(e);
  }
  d["skipped"] = skipped;
  py::dict timings;
  for (const StageTiming& t : r.timings) timings[py::str(t.stage)] = t.seconds;
  d["timings"] = timings;
  return d;
}

// Ground truth from the dicts make_synthetic_arm returns (name, bone, center_line, radius, peak_radius; relief optional).
std::vector<TrueMuscle> truthFromDicts(const py::list& truth) {
  std::vector<TrueMuscle> out;
  for (const py::handle& h : truth) {
    const py::dict d = py::reinterpret_borrow<py::dict>(h);
    TrueMuscle t;
    t.name = d["name"].cast<std::string>();
    t.bone = d["bone"].cast<std::string>();
    const Points line = d["center_line"].cast<Points>();
    for (Eigen::Index i = 0; i < line.rows(); ++i) t.centerLine.push_back(line.row(i).transpose());
    t.radius = d["radius"].cast<std::vector<double>>();
    t.peakRadius = d["peak_radius"].cast<double>();
    if (d.contains("relief")) t.relief = d["relief"].cast<std::vector<double>>();
    if (t.radius.size() != t.centerLine.size())
      throw InputError("true muscle '" + t.name + "': radius and center_line sizes differ");
    if (!t.relief.empty() && t.relief.size() != t.centerLine.size())
      throw InputError("true muscle '" + t.name + "': relief and center_line sizes differ");
    out.push_back(std::move(t));
  }
  return out;
}

}  // namespace

void bindExtraction(py::module_& m) {
  m.def(
      "extract_muscles",
      [](const Character& character, double spacing, const py::object& vertexMask, double minConfidence,
         int minSections, int maxPerRegion, const py::object& forcedRegions, bool buildSurfaces,
         double minRelative, double weakFraction, double minRelativeTrunk, bool mirrorLimbs, double faintRelative,
         double minEvidence, double jointWrap, double continuousFraction, double continuousEvidence,
         const std::map<std::string, std::string>& boneRoles, double referenceLimbRadius, double spindleEnds,
         double twinReach, bool spanDistal) {
        ExtractionOptions o;
        o.ends.spanDistal = spanDistal;
        if (!std::isfinite(referenceLimbRadius)) throw InputError("reference_limb_radius must be finite");
        o.scale.referenceLimbRadius = referenceLimbRadius;
        for (const auto& [bone, role] : boneRoles) o.roleOverrides[bone] = boneRoleFromName(role);
        if (spacing < 0) throw InputError("spacing must be >= 0 (0 = automatic)");
        if (minConfidence < 0 || minConfidence > 1) throw InputError("min_confidence must be in [0, 1]");
        if (minSections < 1) throw InputError("min_sections must be >= 1");
        if (!(minRelative >= 0)) throw InputError("min_relative must be >= 0");
        if (!(weakFraction > 0 && weakFraction <= 1)) throw InputError("weak_fraction must be in (0, 1]");
        if (!(minRelativeTrunk >= 0)) throw InputError("min_relative_trunk must be >= 0");
        if (!(jointWrap >= 0)) throw InputError("joint_wrap must be >= 0");
        o.ends.jointWrapFraction = jointWrap;
        if (!(faintRelative >= 0 && faintRelative <= 1)) throw InputError("faint_relative must be in [0, 1]");
        o.sectionBumps.faintRelative = faintRelative;
        if (!(minEvidence >= 0)) throw InputError("min_evidence must be >= 0");
        o.filters.minEvidence = minEvidence;
        if (!(continuousFraction > 0 && continuousFraction <= 1)) throw InputError("continuous_fraction must be in (0, 1]");
        if (!(continuousEvidence >= 0)) throw InputError("continuous_evidence must be >= 0");
        o.filters.continuousFraction = continuousFraction;
        o.filters.continuousEvidence = continuousEvidence;
        if (!(spindleEnds >= 0 && spindleEnds <= 1)) throw InputError("spindle_ends must be in [0, 1]");
        o.filters.spindleEnds = spindleEnds;
        o.filters.twinReach = twinReach;  // validated by the core (InputError -> ValueError)
        o.filters.minRelative = minRelative;
        o.filters.minRelativeTrunk = minRelativeTrunk;
        o.profiles.mirrorLimbs = mirrorLimbs;
        o.sectionBumps.weakFraction = weakFraction;
        o.planes.spacing = spacing;
        o.filters.minConfidence = minConfidence;
        o.link.minSections = minSections;
        o.maxPerRegion = std::max(0, maxPerRegion);
        o.buildSurfaces = buildSurfaces;
        if (!vertexMask.is_none()) o.vertexMask = toMask(vertexMask, "vertex_mask");
        if (!forcedRegions.is_none())
          for (const py::handle& h : forcedRegions) o.forcedRegions.push_back(toMask(h, "forced_regions item"));
        ExtractionResult r;
        {
          py::gil_scoped_release release;
          r = extractMuscles(character, o);
        }
        return py::make_tuple(py::cast(r.muscles), reportToDict(r.report));
      },
      py::arg("character"), py::arg("spacing") = 0.0, py::arg("vertex_mask") = py::none(),
      py::arg("min_confidence") = ExtractionOptions{}.filters.minConfidence, py::arg("min_sections") = LinkOptions{}.minSections, py::arg("max_per_region") = 0,
      py::arg("forced_regions") = py::none(), py::arg("build_surfaces") = true,
      py::arg("min_relative") = ExtractionOptions{}.filters.minRelative,
      py::arg("weak_fraction") = ExtractionOptions{}.sectionBumps.weakFraction,
      py::arg("min_relative_trunk") = ExtractionOptions{}.filters.minRelativeTrunk,
      py::arg("mirror_limbs") = ProfileOptions{}.mirrorLimbs,
      py::arg("faint_relative") = ExtractionOptions{}.sectionBumps.faintRelative,
      py::arg("min_evidence") = ExtractionOptions{}.filters.minEvidence,
      py::arg("joint_wrap") = EndOptions{}.jointWrapFraction,
      py::arg("continuous_fraction") = ExtractionOptions{}.filters.continuousFraction,
      py::arg("continuous_evidence") = ExtractionOptions{}.filters.continuousEvidence,
      py::arg("bone_roles") = std::map<std::string, std::string>{},
      py::arg("reference_limb_radius") = 0.0,
      py::arg("spindle_ends") = ExtractionOptions{}.filters.spindleEnds, py::arg("twin_reach") = ExtractionOptions{}.filters.twinReach,
      py::arg("span_distal") = EndOptions{}.spanDistal,
      "Extract muscles from a character's skin (Yang & Zhang 2006). spacing: metres between cutting planes "
      "(0 = automatic); vertex_mask: #V booleans, extract only there; forced_regions: list of #V masks, one "
      "muscle forced per region; min_confidence: drop weaker muscles; max_per_region: keep the most confident "
      "per region (0 = all); min_relative: drop muscles whose bumps stand out less than this share of their "
      "sections' mean radius on average; min_relative_trunk: the same for the abdomen and neck families (instead of "
      "min_relative, against their Fourier base); mirror_limbs: average mirrored left/right limb profiles (exactly mirrored limbs); weak_fraction: hysteresis, bumps down to this share of the significance threshold "
      "extend muscles (1 = off); faint_relative: fainter bumps (down to half the threshold) extend a muscle only where "
      "they reach this share of its peak significance (0 = off); min_evidence: a muscle's summed bump significance, in "
      "sections of the default spacing, must reach this (0 = off); continuous_fraction: a limb muscle that stands out in every plane "
      "between its ends with at least continuous_evidence needs only this share of min_relative (1 = off); joint_wrap: a muscle crossing a joint wraps round it "
      "on a sphere of this times its mean semi-axis b (0 = straight lines); bone_roles: {bone name: role} overriding the "
      "detected roles (ignore, limb, shoulder, neck, spine, pelvis); reference_limb_radius: the limb radius every default length "
      "holds for (0 = the built-in reference, < 0 = the character's own units); spindle_ends: a limb chain below the "
      "length and height floors is kept when it is a closed spindle whose ends stay below this share of its peak "
      "(0 = off); twin_reach: such a limb chain is also kept when its mirror twin on the other limb passed the floors (its "
      "centres within this times the chains' mean semi-axis a of the twin's, mirrored; 0 = off); span_distal: a leg muscle's distal end on the shin is carried over the ankle onto the "
      "foot on the belly's side (the calf onto the heel; False = off). Returns (muscles, report) where report has per-stage "
      "counts, skipped sections with reasons, timings per stage (seconds), limb_radius and scale (the body scale), "
      "excluded (skin components left out: small or rigidly bound), analysed (any section looked at) and diagnosis "
      "(why nothing was found, else empty).");

  m.def(
      "bone_roles",
      [](const Character& character, const std::map<std::string, std::string>& overrides) {
        std::map<std::string, BoneRole> o;
        for (const auto& [bone, role] : overrides) o[bone] = boneRoleFromName(role);
        const std::vector<BoneRole> roles = characterBoneRoles(character, o);
        py::dict d;
        for (int i = 0; i < character.skeleton.numBones(); ++i)
          d[py::str(character.skeleton.bones[i].name)] = boneRoleName(roles[i]);
        return d;
      },
      py::arg("character"), py::arg("overrides") = std::map<std::string, std::string>{},
      "The role extraction gives each bone ({name: role}), from the bone tree and the skin, names only as hints; "
      "`overrides` ({name: role}) win. Raises ValueError on an unknown bone or role.");

  m.def(
      "measure_extraction",
      [](const std::vector<Muscle>& found, const py::list& truth, double minCoverage, double visibleReliefShare) {
        const ExtractionAccuracy a = measureExtraction(found, truthFromDicts(truth), minCoverage, visibleReliefShare);
        py::dict d;
        d["true_muscles"] = a.trueMuscles;
        d["found_muscles"] = a.foundMuscles;
        d["matched"] = a.matched;
        d["recall"] = a.recall;
        d["precision"] = a.precision;
        d["mean_center_error"] = a.meanCenterError;
        d["match_of_true"] = a.matchOfTrue;
        return d;
      },
      py::arg("found"), py::arg("truth"), py::arg("min_coverage") = 0.6, py::arg("visible_relief_share") = 0.5,
      "Recall/precision of found muscles against ground truth (make_synthetic_arm's dicts): a found muscle "
      "matches a true one when its root curve stays within half the true peak radius of the true centre "
      "line over at least min_coverage of the true visible length (where the dict's 'relief' is at least "
      "visible_relief_share of its peak; the whole length without 'relief'). mean_center_error is relative to "
      "the radius. Raises ValueError when relief and center_line sizes differ.");

  m.def(
      "reattach_muscle",
      [](Muscle muscle, int samplesPerEnd, int ringVertices, int capRings, const Character* character) {
        if (samplesPerEnd < 1 || ringVertices < 3 || capRings < 1)
          throw InputError("reattach_muscle: samples_per_end >= 1, ring_vertices >= 3, cap_rings >= 1");
        EndOptions ends;
        ends.samplesPerEnd = samplesPerEnd;
        SurfaceOptions surface;
        surface.ringVertices = ringVertices;
        surface.capRings = capRings;
        {
          py::gil_scoped_release release;
          reattachMuscle(muscle, ends, surface);
          if (character) {  // kept inside the skin at rest, as extraction does
            validateMesh(character->mesh, "reattach_muscle: character mesh");
            const SkinWinding skin(character->mesh.vertices, character->mesh.triangles);
            containMuscleSurface(muscle.surface, ringVertices, skin, surface.skinMargin);
          }
        }
        return muscle;
      },
      py::arg("muscle"), py::arg("samples_per_end") = EndOptions{}.samplesPerEnd,
      py::arg("ring_vertices") = SurfaceOptions{}.ringVertices, py::arg("cap_rings") = SurfaceOptions{}.capRings,
      py::arg("character") = nullptr,
      "A copy of `muscle` re-attached to its (moved) origin/insertion positions: Hermite ends of the root curve "
      "rebuilt, section u recomputed by arc length, surface re-lofted; the sections are kept. With `character`, the "
      "surface is kept inside its skin at rest as extraction does (muscle_shape.h containMuscleSurface).");

  m.def(
      "subdivide",
      [](const Character& c, int levels) {
        py::gil_scoped_release release;
        return subdivideMidpoint(c, levels);
      },
      py::arg("character"), py::arg("levels") = 1,
      "Midpoint subdivision of the skin (each triangle -> 4, `levels` times), weights interpolated.");
}

}  // namespace myoskin::python
