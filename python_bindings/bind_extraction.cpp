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
  d["dropped_contour"] = r.droppedContour;
  d["spindles"] = r.spindles;
  d["twins"] = r.twins;
  d["forced"] = r.forced;
  d["limb_radius"] = r.limbRadius;
  d["scale"] = r.scale;
  d["analysed"] = r.analysed;
  d["diagnosis"] = r.diagnosis;
  d["scale_note"] = r.scaleNote;
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

// The expert keywords extract_muscles took before its options were cut to five: their ExtractionOptions keys.
const std::map<std::string, std::string> kRemovedKeywords = {
    {"min_relative", "filters.minRelative"},
    {"weak_fraction", "sectionBumps.weakFraction"},
    {"mirror_limbs", "profiles.mirrorLimbs"},
    {"faint_relative", "sectionBumps.faintRelative"},
    {"min_evidence", "filters.minEvidence"},
    {"continuous_evidence", "filters.continuousEvidence"},
    {"reference_limb_radius", "scale.referenceLimbRadius"},
    {"spindle_ends", "filters.spindleEnds"},
    {"twin_reach", "filters.twinReach"},
    {"span_distal", "ends.spanDistal"},
};

}  // namespace

void bindExtraction(py::module_& m) {
  m.def(
      "extract_muscles",
      [](const Character& character, double spacing, double minConfidence, int minSections, int maxPerRegion,
         double jointWrap, const py::object& vertexMask, const py::object& forcedRegions,
         const std::map<std::string, std::string>& boneRoles, bool buildSurfaces, const py::object& expert,
         const py::kwargs& removed) {
        for (const auto& [name, value] : removed) {  // the old expert keywords: a TypeError naming the new key
          const std::string key = name.cast<std::string>();
          if (key == "continuous_fraction")  // gone altogether: a continuous chain is held to one bump's floor
            throw py::type_error("extract_muscles(): 'continuous_fraction' was removed: a continuous chain is held to "
                                 "one bump's height floor (bumps.minRelativeProtrusion); options="
                                 "{'filters.continuousEvidence': 1e9} turns the continuous rule off");
          const auto it = kRemovedKeywords.find(key);
          if (it == kRemovedKeywords.end())
            throw py::type_error("extract_muscles() got an unexpected keyword argument '" + key + "'");
          throw py::type_error("extract_muscles(): '" + key + "' is an expert option now: pass options={'" +
                               it->second + "': ...} (extraction_options() lists them)");
        }
        ExtractionOptions o;
        if (!std::isfinite(spacing) || spacing < 0) throw InputError("spacing must be >= 0 limb radii (0 = automatic)");
        o.scale.spacing = spacing;
        o.filters.minConfidence = minConfidence;
        o.link.minSections = minSections;
        o.maxPerRegion = maxPerRegion;
        o.ends.jointWrapFraction = jointWrap;
        for (const auto& [bone, role] : boneRoles) o.roleOverrides[bone] = boneRoleFromName(role);
        o.buildSurfaces = buildSurfaces;
        if (!expert.is_none()) {
          if (!py::isinstance<py::dict>(expert))
            throw py::type_error("extract_muscles(): options must be a dict {key: value} of expert options");
          for (const auto& [k, v] : py::reinterpret_borrow<py::dict>(expert)) {
            const std::string key = py::str(k).cast<std::string>();
            // Any real number (numpy scalars included; strings and None are not numbers here).
            if (py::isinstance<py::str>(v) || v.is_none() || !PyNumber_Check(v.ptr()) || PyComplex_Check(v.ptr()))
              throw InputError("expert option " + key + " needs a number or a bool");
            setExpertOption(o, key, py::float_(py::reinterpret_borrow<py::object>(v)).cast<double>());
          }
        }
        if (!vertexMask.is_none()) o.vertexMask = toMask(vertexMask, "vertex_mask");
        if (!forcedRegions.is_none())
          for (const py::handle& h : forcedRegions) o.forcedRegions.push_back(toMask(h, "forced_regions item"));
        ExtractionResult r;
        {
          py::gil_scoped_release release;
          r = extractMuscles(character, o);  // validates every option (InputError -> ValueError)
        }
        return py::make_tuple(py::cast(r.muscles), reportToDict(r.report));
      },
      py::arg("character"), py::arg("spacing") = 0.0, py::arg("min_confidence") = ExtractionOptions{}.filters.minConfidence,
      py::arg("min_sections") = LinkOptions{}.minSections, py::arg("max_per_region") = 0,
      py::arg("joint_wrap") = EndOptions{}.jointWrapFraction, py::kw_only(), py::arg("vertex_mask") = py::none(),
      py::arg("forced_regions") = py::none(), py::arg("bone_roles") = std::map<std::string, std::string>{},
      py::arg("build_surfaces") = true, py::arg("options") = py::none(),
      "Extract muscles from a character's skin (Yang & Zhang 2006). The five user-facing options, each relative to "
      "the body:\n"
      "  spacing: distance between cutting planes in limb radii (the body's median limb radius, report['limb_radius']; "
      "0 = automatic, 1/80 of the body's largest extent);\n"
      "  min_confidence: drop muscles below this confidence, in [0, 1] (forced ones are kept);\n"
      "  min_sections: significant sections a muscle needs (>= 1);\n"
      "  max_per_region: keep the most confident per region (0 = all);\n"
      "  joint_wrap: a muscle crossing a joint wraps round it on a sphere of this times its mean semi-axis b "
      "(0 = straight lines).\n"
      "Data (keyword only): vertex_mask (#V booleans: extract only there), forced_regions (list of #V masks, one "
      "muscle forced per region), bone_roles ({bone name: role} overriding the detected roles: ignore, limb, "
      "shoulder, neck, spine, pelvis), build_surfaces (loft a surface per muscle).\n"
      "options: expert tuning, not user-facing: a dict {key: value} of ExtractionOptions field paths "
      "(e.g. {'filters.minEvidence': 7.0, 'ends.spanDistal': False}); extraction_options() lists every key with its "
      "default. The old expert keywords (min_relative, weak_fraction, min_evidence, twin_reach, ...) raise a "
      "TypeError naming their key. Bad values raise ValueError. Returns (muscles, report) where report has per-stage "
      "counts, skipped sections with reasons, timings per stage (seconds), limb_radius and scale (the body scale), "
      "excluded (skin components left out: small or rigidly bound), analysed (any section looked at), diagnosis "
      "(why nothing was found, else empty) and scale_note (why the muscles depend on the body's size when it is far "
      "from the size the defaults are stated for, else empty).");

  m.def(
      "extraction_options",
      []() {
        py::dict d;
        for (const ExpertOption& e : expertOptions()) {
          if (e.type == "bool") d[py::str(e.key)] = e.defaultValue != 0.0;
          else if (e.type == "int") d[py::str(e.key)] = static_cast<int>(e.defaultValue);
          else d[py::str(e.key)] = e.defaultValue;
        }
        return d;
      },
      "The expert extraction options, {key: default} (ExtractionOptions' field paths, extraction.h documents each): "
      "tuning for extract_muscles(options={...}), not user-facing.");

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
