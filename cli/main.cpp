// `myoskin`: the command-line tool for batch pipelines (no Blender needed).
//   myoskin info CHARACTER                       counts, topology, bounding box, bones
//   myoskin generate arm -o DIR [--seed N] [--muscle-scale S]   the procedural test character
//   myoskin roles CHARACTER [-o roles.json]      the role extraction gives each bone
//   myoskin extract CHARACTER -o muscles.json    muscle extraction
//   myoskin deform CHARACTER --muscles M --pose P -o out.obj|.pc2
//   myoskin simulate CHARACTER --muscles M --pose SEQ -o out.pc2 [--jiggle] [--filter] [--sculpt S.obj]
// Every failure prints one line "myoskin: error: ..." and exits non-zero.
#include <cstdio>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <stdexcept>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "myoskin/anchored_skin.h"
#include "myoskin/correctives.h"
#include "myoskin/deformation.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/pose_io.h"
#include "myoskin/secondary_motion.h"
#include "myoskin/skin_solve.h"
#include "myoskin/sections.h"
#include "myoskin/skinning.h"
#include "myoskin/volume_blend.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {

// ============================================================================
// Argument parsing
// ============================================================================

struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> options;  // --name value
  std::vector<std::string> flags;              // --name without value
  std::vector<std::string> experts;            // every --expert KEY=VALUE, in order
};

// Options listed in `withValue` take the next argument; anything else starting with -- is a flag.
Args parse(int argc, char** argv, int first, const std::vector<std::string>& withValue) {
  Args args;
  for (int i = first; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "-o") a = "--output";
    if (a.rfind("--", 0) == 0) {
      bool takes = false;
      for (const std::string& w : withValue) takes |= (w == a);
      if (takes) {
        if (i + 1 >= argc) throw InputError(a + " needs a value");
        if (a == "--expert") args.experts.push_back(argv[i + 1]);
        args.options[a] = argv[++i];
      } else {
        args.flags.push_back(a);
      }
    } else {
      args.positional.push_back(a);
    }
  }
  return args;
}

void usage(std::ostream& out) {
  out << "usage: myoskin <command> [arguments]\n"
         "  info CHARACTER [--skeleton SKEL.json] [--bones]   counts, topology, bounding box, bones, meshes\n"
         "  roles CHARACTER [--roles ROLES.json] [-o ROLES.json]   the role extraction gives each bone (limb, spine,\n"
         "          neck, shoulder, pelvis, ignore); edit the written file and pass it to extract --roles\n"
         "  generate arm -o DIR [--seed N] [--muscle-scale S]  write the procedural test arm\n"
         "                                                      (arm.obj, arm.skeleton.json, arm.truth.json)\n"
         "  extract CHARACTER -o muscles.json [--spacing R] [--min-confidence C] [--min-sections N]\n"
         "          [--max-per-region N] [--joint-wrap W] [--no-surfaces] [--mesh NAME] [--roles ROLES.json]\n"
         "          [--options EXPERT.json] [--expert KEY=VALUE ...]\n"
         "          extract muscles from the skin (the whole character: every mesh its skin deforms, or --mesh);\n"
         "          --spacing in limb radii (0 = automatic), --min-confidence in [0, 1], --min-sections significant\n"
         "          sections a muscle needs, --max-per-region (0 = all), --joint-wrap in the muscle's semi-axes\n"
         "          (0 = straight lines); expert tuning: --expert filters.minEvidence=7 (repeatable; --expert list\n"
         "          prints every key and default), --options a JSON object {KEY: VALUE} applied first\n"
         "  deform CHARACTER [--muscles M.json] --pose P.json -o out.obj|out.pc2 [--dominance D] [--threads N]\n"
         "          [--preserve-volume | --volume-blend] [--dq-scale pivot|blended] [--method eq3|anchored]\n"
         "          [--joints-slide on|off] [--relax-iterations N]\n"
         "          skin a pose (.obj) or a sequence of poses (.pc2, Blender's Mesh Cache modifier);\n"
         "          --method anchored anchors the skin to muscle ellipsoids, bone capsules and joint spheres\n"
         "          (Schneider & Wilhelms 1998) instead of Equation 3 (eq3, the default);\n"
         "          --preserve-volume blends the joints as dual quaternions (Blender's Preserve Volume; scaled\n"
         "          joints as Blender 4.x/5.x do, or --dq-scale blended as Blender 3.x); --volume-blend mixes\n"
         "          the linear and the dual-quaternion skin per vertex and adds the joints' volume keys, so joints\n"
         "          keep their volume (the add-on's Volume Blend: the shape keys and two Armature modifiers Bind\n"
         "          adds); --joints-slide off: along its bone a muscle joint moves as the bone does (the add-on's\n"
         "          Joints Slide; on, the default: it rides its station of the action path, as far along its\n"
         "          bone as the skin it carries follows without folding, from the weights); pose\n"
         "          files: {\"bones\": {name: {\"rotation_quaternion\": [w,x,y,z]}}} or {\"frames\": [...]}\n"
         "  simulate CHARACTER --pose SEQUENCE.json -o out.pc2 [--muscles M.json] [--jiggle] [--filter]\n"
         "          [--sculpt SCULPT.obj [--sculpt-frame F]] [--frames A-B] [--state-in S.json] [--state-out S.json]\n"
         "          [--fps F (24)] [--jiggle-frequency HZ (5)] [--jiggle-damping RATIO (0.3)] [--jiggle-amount A (1)]\n"
         "          [--preserve-volume] [--dominance D] [--joints-slide on|off] [--threads N] [--skin-solve]\n"
         "          simulate a sequence to a PC2 cache: jiggle of the muscle masses, a temporal filter against jitter,\n"
         "          detail sculpted on one frame re-applied on every frame; --frames with --state-in/--state-out\n"
         "          bakes chunks in separate processes that stitch to the same result as one run (a state baked\n"
         "          with other settings is refused, naming the setting)\n"
         "CHARACTER is a .glb/.gltf, or an .obj with a <name>.skeleton.json beside it. ROLES.json: {\"bone\": \"role\"}.\n";
}

// ============================================================================
// Commands
// ============================================================================

// The character named on the command line: every command works on a rigged, skinned character.
Character loadArgCharacter(const Args& args, const std::string& command) {
  if (args.positional.size() != 1) throw InputError(command + " needs exactly one CHARACTER file");
  const auto skel = args.options.count("--skeleton") ? args.options.at("--skeleton") : std::string();
  LoadOptions load;
  load.requireWeights = true;
  if (args.options.count("--mesh")) load.meshName = args.options.at("--mesh");
  return loadCharacter(args.positional[0], load, skel);
}

// A role file: {"bone": "role", ...} (or {"roles": {...}}); unknown roles throw, unknown bones are checked by
// classifyBones.
std::map<std::string, BoneRole> readRoles(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the role file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw InputError(path + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (j.is_object() && j.contains("roles")) j = j["roles"];
  if (!j.is_object()) throw InputError(path + ": a role file is an object {\"bone\": \"role\"}");
  std::map<std::string, BoneRole> roles;
  for (const auto& [bone, role] : j.items()) {
    if (!role.is_string()) throw InputError(path + ": the role of '" + bone + "' is not a string");
    try {
      roles[bone] = boneRoleFromName(role.get<std::string>());
    } catch (const InputError& e) {
      throw InputError(path + ": bone '" + bone + "': " + e.what());
    }
  }
  return roles;
}

int cmdRoles(const Args& args) {
  const Character c = loadArgCharacter(args, "roles");
  const std::map<std::string, BoneRole> overrides =
      args.options.count("--roles") ? readRoles(args.options.at("--roles")) : std::map<std::string, BoneRole>{};
  const std::vector<BoneRole> roles = characterBoneRoles(c, overrides);
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  std::map<std::string, int> counts;
  for (int i = 0; i < c.skeleton.numBones(); ++i) {
    const Bone& b = c.skeleton.bones[i];
    const char* role = boneRoleName(roles[i]);
    ++counts[role];
    out[b.name] = role;
    std::printf("%-32s %-9s parent %s\n", b.name.c_str(), role, b.parent >= 0 ? c.skeleton.bones[b.parent].name.c_str() : "-");
  }
  std::printf("roles of %d bones:", c.skeleton.numBones());
  for (const auto& [role, n] : counts) std::printf(" %s %d", role.c_str(), n);
  std::printf("\n");
  if (args.options.count("--output")) {
    std::ofstream f(args.options.at("--output"));
    f << out.dump(2) << "\n";
    if (!f) throw InputError("cannot write " + args.options.at("--output"));
  }
  return 0;
}

int cmdInfo(const Args& args) {
  const Character c = loadArgCharacter(args, "info");
  const TopologyReport topo = analyzeTopology(c.mesh);
  Vec3 lo, hi;
  boundingBox(c.mesh.vertices, lo, hi);
  std::printf("character: %s\n", c.name.c_str());
  std::printf("vertices: %d (welded; %d as stored)\n", c.mesh.numVertices(), c.sourceVertexCount);
  std::printf("triangles: %d\n", c.mesh.numTriangles());
  std::printf("bones: %d\n", c.skeleton.numBones());
  std::printf("skin weights: %s\n",
              c.hasWeights() ? (std::to_string(c.weights.influences()) + " influences per vertex").c_str() : "none");
  std::printf("topology: %d boundary edges, %d non-manifold edges, %d components%s\n", topo.boundaryEdges,
              topo.nonManifoldEdges, topo.components, topo.closed() && topo.manifold() ? " (closed manifold)" : "");
  std::printf("bounding box: min (%.4f, %.4f, %.4f) max (%.4f, %.4f, %.4f) m\n", lo.x(), lo.y(), lo.z(), hi.x(),
              hi.y(), hi.z());
  std::printf("volume: %.6f m^3\n", enclosedVolume(c.mesh.vertices, c.mesh.triangles));
  if (c.pieces.size() > 1) {
    std::printf("meshes: %zu", c.pieces.size());
    for (const MeshPiece& p : c.pieces) std::printf(" %s (%d)", p.name.c_str(), p.vertexCount);
    std::printf("\n");
  }
  const bool all = std::find(args.flags.begin(), args.flags.end(), "--bones") != args.flags.end();
  std::printf("bone names:");
  const int shown = all ? c.skeleton.numBones() : std::min(c.skeleton.numBones(), 12);
  for (int i = 0; i < shown; ++i) std::printf(" %s", c.skeleton.bones[i].name.c_str());
  if (shown < c.skeleton.numBones()) std::printf(" ... (--bones lists all)");
  std::printf("\n");
  return 0;
}

int cmdGenerate(const Args& args) {
  if (args.positional.size() != 1 || args.positional[0] != "arm") throw InputError("generate supports: arm");
  if (!args.options.count("--output")) throw InputError("generate needs -o DIR");
  SyntheticArmOptions options;
  if (args.options.count("--seed")) options.seed = static_cast<unsigned>(std::stoul(args.options.at("--seed")));
  if (args.options.count("--muscle-scale")) options.muscleScale = std::stod(args.options.at("--muscle-scale"));
  const std::filesystem::path dir = args.options.at("--output");
  std::filesystem::create_directories(dir);
  const SyntheticCharacter arm = makeSyntheticArm(options);
  writeObj((dir / "arm.obj").string(), arm.character.mesh.vertices, arm.character.mesh.triangles);
  writeSkeletonJson((dir / "arm.skeleton.json").string(), arm.character);
  std::ofstream truth(dir / "arm.truth.json");
  truth << trueMusclesToJson(arm.muscles) << "\n";
  if (!truth) throw InputError("cannot write " + (dir / "arm.truth.json").string());
  std::printf("wrote %s (%d vertices, %d bones, %zu true muscles)\n", (dir / "arm.obj").string().c_str(),
              arm.character.mesh.numVertices(), arm.character.skeleton.numBones(), arm.muscles.size());
  return 0;
}

double numberOption(const Args& args, const std::string& name, double fallback) {
  if (!args.options.count(name)) return fallback;
  const std::string& text = args.options.at(name);
  try {
    size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument(text);
    return v;
  } catch (const std::exception&) {
    throw InputError(name + " needs a number, got '" + text + "'");
  }
}

// A whole-number option (a count): refuses fractions and values beyond int's range.
int countOption(const Args& args, const std::string& name, int fallback) {
  const double v = numberOption(args, name, fallback);
  if (v != std::floor(v) || std::abs(v) > 1e9) throw InputError(name + " needs a whole number, got '" + args.options.at(name) + "'");
  return static_cast<int>(v);
}

// Expert extraction options from a JSON file: an object {KEY: number or bool} (expertOptions' keys).
void readExpertFile(const std::string& path, ExtractionOptions& options) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the options file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw InputError(path + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!j.is_object()) throw InputError(path + ": an options file is an object {\"key\": value}");
  for (const auto& [key, value] : j.items()) {
    if (!value.is_number() && !value.is_boolean())
      throw InputError(path + ": option '" + key + "' needs a number or true/false");
    setExpertOption(options, key, value.is_boolean() ? (value.get<bool>() ? 1.0 : 0.0) : value.get<double>());
  }
}

// One --expert KEY=VALUE (VALUE a number, true or false).
void applyExpert(const std::string& text, ExtractionOptions& options) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0) throw InputError("--expert needs KEY=VALUE, got '" + text + "'");
  const std::string key = text.substr(0, eq), value = text.substr(eq + 1);
  double v = 0.0;
  if (value == "true") v = 1.0;
  else if (value == "false") v = 0.0;
  else {
    try {
      size_t used = 0;
      v = std::stod(value, &used);
      if (used != value.size()) throw std::invalid_argument(value);
    } catch (const std::exception&) {
      throw InputError("--expert " + key + " needs a number or true/false, got '" + value + "'");
    }
  }
  setExpertOption(options, key, v);
}

int cmdExtract(const Args& args) {
  if (args.experts.size() == 1 && args.experts[0] == "list") {  // every expert key with its type and default
    for (const ExpertOption& e : expertOptions()) std::printf("%s = %.10g (%s)\n", e.key.c_str(), e.defaultValue, e.type.c_str());
    return 0;
  }
  if (args.positional.size() != 1) throw InputError("extract needs exactly one CHARACTER file");
  if (!args.options.count("--output")) throw InputError("extract needs -o muscles.json");
  ExtractionOptions options;
  if (args.options.count("--roles")) options.roleOverrides = readRoles(args.options.at("--roles"));
  // Expert tuning first (the file, then each --expert), the user-facing flags after (their own keys).
  if (args.options.count("--options")) readExpertFile(args.options.at("--options"), options);
  for (const std::string& e : args.experts) applyExpert(e, options);
  options.scale.spacing = numberOption(args, "--spacing", 0.0);  // limb radii
  if (options.scale.spacing < 0) throw InputError("--spacing must be >= 0 limb radii (0 = automatic)");
  options.filters.minConfidence = numberOption(args, "--min-confidence", options.filters.minConfidence);
  if (options.filters.minConfidence < 0 || options.filters.minConfidence > 1) throw InputError("--min-confidence must be in [0, 1]");
  options.link.minSections = countOption(args, "--min-sections", options.link.minSections);
  if (options.link.minSections < 1) throw InputError("--min-sections must be >= 1");
  options.maxPerRegion = countOption(args, "--max-per-region", 0);
  if (options.maxPerRegion < 0) throw InputError("--max-per-region must be >= 0 (0 = all)");
  options.ends.jointWrapFraction = numberOption(args, "--joint-wrap", options.ends.jointWrapFraction);
  if (!(options.ends.jointWrapFraction >= 0)) throw InputError("--joint-wrap must be >= 0 (0 = straight lines)");
  options.buildSurfaces = std::find(args.flags.begin(), args.flags.end(), "--no-surfaces") == args.flags.end();
  const Character c = loadArgCharacter(args, "extract");
  const ExtractionResult r = extractMuscles(c, options);
  // Left-out components, grouped by why, mesh and bone.
  std::map<std::string, std::pair<int, int>> leftOut;  // description -> (components, vertices)
  for (const ExcludedComponent& e : r.report.excluded) {
    std::string piece;
    for (size_t i = 0; i < c.sourceToWelded.size() && piece.empty(); ++i)
      if (c.sourceToWelded[i] == e.firstVertex)
        for (const MeshPiece& p : c.pieces)
          if (static_cast<int>(i) >= p.firstVertex && static_cast<int>(i) < p.firstVertex + p.vertexCount) piece = p.name;
    const std::string what = e.reason + (piece.empty() ? "" : " in mesh '" + piece + "'") +
                             (e.bone.empty() ? "" : " bound to '" + e.bone + "'");
    ++leftOut[what].first;
    leftOut[what].second += e.vertices;
  }
  for (const auto& [what, n] : leftOut)
    std::printf("left out of the analysis: %d %s skin component(s), %d vertices\n", n.first, what.c_str(), n.second);
  if (!r.report.analysed) throw InputError("nothing could be analysed in " + c.name + ": " + r.report.diagnosis);
  writeMusclesJson(args.options.at("--output"), r.muscles);
  if (r.muscles.empty()) std::printf("no muscles: %s\n", r.report.diagnosis.c_str());
  double seconds = 0;
  for (const StageTiming& t : r.report.timings) seconds += t.seconds;
  std::set<std::string> regions;
  for (const Muscle& m : r.muscles) regions.insert(m.region);
  std::printf("extracted %d muscles in %zu regions from %s (%d planes, %d sections, %zu skipped, %d bumps, limb radius %.4g, "
              "%.2f s) -> %s\n",
              r.report.muscles, regions.size(), c.name.c_str(), r.report.planes, r.report.sections,
              r.report.skipped.size(), r.report.bumps, r.report.limbRadius, seconds, args.options.at("--output").c_str());
  if (!r.report.scaleNote.empty()) std::printf("note: %s\n", r.report.scaleNote.c_str());
  return 0;
}

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The anchored-skin deformer over every frame of the pose file (--method anchored).
int deformAnchored(const Args& args, const Character& c, const PoseSequence& poses, const std::string& out, bool pc2) {
  for (const char* o : {"--dominance", "--dq-scale", "--joints-slide"})
    if (args.options.count(o)) throw InputError(std::string("deform: ") + o + " is for --method eq3");
  if (!args.flags.empty()) throw InputError("deform: '" + args.flags[0] + "' is not an option of --method anchored");
  const std::vector<Muscle> muscles =
      args.options.count("--muscles") ? readMusclesJson(args.options.at("--muscles")) : std::vector<Muscle>{};
  AnchoredSkinOptions ao;
  ao.relaxIterations = countOption(args, "--relax-iterations", ao.relaxIterations);
  if (ao.relaxIterations < 0) throw InputError("--relax-iterations must be >= 0");
  ao.threads = countOption(args, "--threads", 0);
  if (ao.threads < 0) throw InputError("--threads must be >= 0 (0 = all cores)");
  const AnchoredComponents comps = deriveComponents(c.skeleton, muscles, c.mesh, c.weights);
  const AnchoredSkin skin(c.mesh, c.weights, comps, c.skeleton, ao);
  if (pc2) {
    writeAnchoredPC2(out, skin, poses.frames, static_cast<float>(poses.startFrame));
  } else {
    Points positions;
    skin.evaluate(poses.frames[0], positions);
    writeObj(out, positions, c.mesh.triangles);
  }
  std::printf("deformed %s (%d vertices, anchored to %d components: %zu muscles, %d seam vertices): %zu frame(s) -> %s\n",
              c.name.c_str(), c.mesh.numVertices(), skin.numComponents(), muscles.size(), skin.report().seamVertices,
              poses.frames.size(), out.c_str());
  return 0;
}

// A character bound for skinning as `deform` and `simulate` do it: the character, its muscle rig (with
// --muscles; combined weights over bones + muscle joints, Equation 3) or none (plain LBS), and the skinner.
struct BoundSkin {
  Character character;
  std::unique_ptr<MuscleRig> rig;
  SkinWeights weights;  // what the skinner skins with (combined with --muscles, else the skeleton's)
  SkinnerOptions options;
  std::shared_ptr<Skinner> skinner;
  std::vector<VolumeKey> volumeKeys;  // --volume-blend: the joints' volume keys (shape keys in Blender)
  std::map<std::string, std::string> settings;  // the bind's settings, kept in simulate's state files
};

// Loads and binds from the command's arguments (--muscles, --dominance, --threads, --preserve-volume,
// --dq-scale); `flags` are the command's other allowed flags (a mistyped one must not pass silently).
BoundSkin bindFromArgs(const Args& args, const std::string& command, const std::vector<std::string>& flags) {
  BoundSkin b;
  b.options.threads = countOption(args, "--threads", 0);
  if (b.options.threads < 0) throw InputError("--threads must be >= 0 (0 = all cores)");
  for (const std::string& f : args.flags)  // a mistyped mode must not fall back to linear skinning silently
    if (f != "--preserve-volume" && std::find(flags.begin(), flags.end(), f) == flags.end())
      throw InputError(command + ": unknown option '" + f + "'");
  b.options.preserveVolume = std::find(args.flags.begin(), args.flags.end(), "--preserve-volume") != args.flags.end();
  const bool volumeBlend = std::find(args.flags.begin(), args.flags.end(), "--volume-blend") != args.flags.end();
  if (volumeBlend && b.options.preserveVolume)
    throw InputError(command + ": --volume-blend and --preserve-volume exclude each other (the blend mixes linear "
                     "and dual quaternions itself)");
  if (args.options.count("--dq-scale")) {
    const std::string mode = args.options.at("--dq-scale");
    if (!b.options.preserveVolume && !volumeBlend)
      throw InputError(command + ": --dq-scale needs --preserve-volume or --volume-blend");
    if (mode == "blended")
      b.options.dualQuatScale = DualQuatScale::Blended;
    else if (mode != "pivot")
      throw InputError("--dq-scale must be pivot (Blender 4.x/5.x) or blended (Blender 3.x), got '" + mode + "'");
  }
  for (const char* o : {"--dominance", "--joints-slide"})
    if (args.options.count(o) && !args.options.count("--muscles"))
      throw InputError(command + ": " + o + " needs --muscles");
  MuscleRigOptions rigOptions;
  if (args.options.count("--joints-slide")) {
    const std::string slide = args.options.at("--joints-slide");
    if (slide != "on" && slide != "off") throw InputError("--joints-slide must be on or off, got '" + slide + "'");
    rigOptions.jointsSlide = slide == "on";
  }
  b.character = loadArgCharacter(args, command);
  const Character& c = b.character;
  b.weights = c.weights;
  if (args.options.count("--muscles")) {
    const std::vector<Muscle> muscles = readMusclesJson(args.options.at("--muscles"));
    b.rig = std::make_unique<MuscleRig>(c.skeleton, muscles, rigOptions);
    HybridWeightOptions ho;
    ho.dominance = numberOption(args, "--dominance", ho.dominance);
    b.weights = computeHybridWeights(c.mesh, c.weights, *b.rig, ho);
    if (rigOptions.jointsSlide) {  // each joint slides no further than the skin it carries follows unfolded (as Bind)
      rigOptions.slideLimits = computeSlideLimits(c.mesh, b.weights, *b.rig);
      b.rig = std::make_unique<MuscleRig>(c.skeleton, muscles, rigOptions);
    }
    char dominance[32];
    std::snprintf(dominance, sizeof dominance, "%.17g", ho.dominance);
    b.settings["bind.dominance"] = dominance;
    b.settings["bind.joints_slide"] = rigOptions.jointsSlide ? "on" : "off";
  }
  b.settings["bind.muscles"] = std::to_string(b.rig ? b.rig->numMuscles() : 0);
  const std::string scale = b.options.dualQuatScale == DualQuatScale::Blended ? ", blended scale" : ", pivot scale";
  b.settings["bind.skinning"] = volumeBlend                  ? "volume blend" + scale
                                : b.options.preserveVolume ? "preserve volume" + scale
                                                           : "linear";
  const int numJoints = c.skeleton.numBones() + (b.rig ? b.rig->numJoints() : 0);
  if (volumeBlend) {  // shares from the skeleton weights; the joints' rest frames shape the dual-quaternion part
    const Eigen::VectorXd share = computeDqsShare(c.skeleton, c.weights, c.mesh);
    b.options.dqsShare.assign(share.data(), share.data() + share.size());
    VolumeKeyOptions keyOptions;
    keyOptions.dualQuatScale = b.options.dualQuatScale;  // --dq-scale: the muscle joints' scale as the skin carries it
    b.volumeKeys = b.rig
                       ? computeVolumeKeys(c.skeleton, c.weights, c.mesh, share, {}, keyOptions, b.rig.get(), &b.weights)
                       : computeVolumeKeys(c.skeleton, c.weights, c.mesh, share, {}, keyOptions);
  }
  if (b.options.preserveVolume || volumeBlend) {
    if (b.rig) {
      b.options.jointRest = combinedRestMatrices(c.skeleton, *b.rig);
    } else {
      for (const auto& bone : c.skeleton.bones) b.options.jointRest.push_back(bone.rest);
    }
  }
  b.skinner = std::make_shared<Skinner>(c.mesh.vertices, b.weights, numJoints, b.options);
  return b;
}

// Skin every frame of the pose file: .obj takes one pose, .pc2 takes the whole sequence.
int cmdDeform(const Args& args) {
  if (args.positional.size() != 1) throw InputError("deform needs exactly one CHARACTER file");
  if (!args.options.count("--pose")) throw InputError("deform needs --pose P.json");
  if (!args.options.count("--output")) throw InputError("deform needs -o out.obj or out.pc2");
  const std::string out = args.options.at("--output");
  const bool pc2 = endsWith(out, ".pc2");
  if (!pc2 && !endsWith(out, ".obj")) throw InputError("deform: -o must end in .obj or .pc2, got '" + out + "'");
  const std::string method = args.options.count("--method") ? args.options.at("--method") : std::string("eq3");
  if (method != "eq3" && method != "anchored")
    throw InputError("deform: --method must be eq3 or anchored, got '" + method + "'");
  if (method == "anchored") {
    const Character c = loadArgCharacter(args, "deform");
    const PoseSequence poses = readPoseJson(args.options.at("--pose"), c.skeleton);
    if (!pc2 && poses.frames.size() != 1)
      throw InputError("deform: the pose file has " + std::to_string(poses.frames.size()) +
                       " frames; write them to a .pc2 (an .obj takes one pose)");
    return deformAnchored(args, c, poses, out, pc2);
  }
  if (args.options.count("--relax-iterations")) throw InputError("deform: --relax-iterations is for --method anchored");
  const BoundSkin b = bindFromArgs(args, "deform", {"--volume-blend"});
  const Character& c = b.character;
  const PoseSequence poses = readPoseJson(args.options.at("--pose"), c.skeleton);
  if (!pc2 && poses.frames.size() != 1)
    throw InputError("deform: the pose file has " + std::to_string(poses.frames.size()) +
                     " frames; write them to a .pc2 (an .obj takes one pose)");
  const MuscleRig* rig = b.rig.get();
  MuscleRigState state;
  if (rig) state = rig->makeState();
  std::vector<Mat4> transforms;
  auto transformsFor = [&](const Pose& pose) {
    if (rig) {
      rig->evaluate(pose, state);
      skinningTransforms(c.skeleton, pose, *rig, state, transforms);
    } else {
      skeletonTransforms(c.skeleton, pose, transforms);
    }
  };
  // The rest skin with the volume keys' weighted offsets of a pose added (as Blender's shape keys come before its
  // Armature modifiers); false when no key moves anything there (the skinner's own rest skin).
  std::vector<Eigen::Quaterniond> localRotations;
  Points keyed;
  auto keysMove = [&](const Pose& pose) {
    if (b.volumeKeys.empty()) return false;
    boneLocalRotations(c.skeleton, pose, localRotations);
    applyVolumeKeys(b.volumeKeys, localRotations, c.mesh.vertices, keyed);
    return keyed != c.mesh.vertices;
  };
  if (pc2) {
    PC2Writer writer(out, c.mesh.numVertices(), static_cast<float>(poses.startFrame), 1.0f);
    PointsF frame;
    for (const Pose& pose : poses.frames) {
      transformsFor(pose);
      if (keysMove(pose))
        frame = skin(keyed, b.weights, transforms, b.options).cast<float>();
      else
        b.skinner->deform(transforms, frame);
      writer.writeFrame(frame);
    }
    writer.close();
  } else {
    Points positions;
    transformsFor(poses.frames[0]);
    if (keysMove(poses.frames[0]))
      positions = skin(keyed, b.weights, transforms, b.options);
    else
      b.skinner->deform(transforms, positions);
    writeObj(out, positions, c.mesh.triangles);
  }
  const std::string keys = ", volume blend with " + std::to_string(b.volumeKeys.size()) + " volume keys";
  const char* mode = !b.options.dqsShare.empty() ? keys.c_str() : b.options.preserveVolume ? ", preserve volume" : "";
  if (rig)
    std::printf("deformed %s (%d vertices, %d bones + %d muscle joints of %d muscles%s): %zu frame(s) -> %s\n",
                c.name.c_str(), c.mesh.numVertices(), c.skeleton.numBones(), rig->numJoints(), rig->numMuscles(),
                mode, poses.frames.size(), out.c_str());
  else
    std::printf("deformed %s (%d vertices, %d bones, skeleton weights only%s): %zu frame(s) -> %s\n",
                c.name.c_str(), c.mesh.numVertices(), c.skeleton.numBones(), mode, poses.frames.size(), out.c_str());
  return 0;
}

// "A-B" (or "A") -> [A, B].
void frameRange(const std::string& text, int& first, int& last) {
  const size_t dash = text.find('-', 1);
  try {
    size_t used = 0;
    first = std::stoi(text.substr(0, dash), &used);
    if (used != (dash == std::string::npos ? text.size() : dash)) throw std::invalid_argument(text);
    last = first;
    if (dash != std::string::npos) {
      const std::string rest = text.substr(dash + 1);
      last = std::stoi(rest, &used);
      if (used != rest.size()) throw std::invalid_argument(text);
    }
  } catch (const std::exception&) {
    throw InputError("--frames needs A-B (whole frames), got '" + text + "'");
  }
  if (last < first) throw InputError("--frames " + text + ": the last frame comes before the first");
}

// Simulate a pose sequence into a PC2 cache: skinning, jiggle, (skin solve), filter, sculpt; a chunk of the
// frames with the state files that stitch chunks into one bake.
int cmdSimulate(const Args& args) {
  if (args.positional.size() != 1) throw InputError("simulate needs exactly one CHARACTER file");
  if (!args.options.count("--pose")) throw InputError("simulate needs --pose SEQUENCE.json");
  if (!args.options.count("--output")) throw InputError("simulate needs -o out.pc2");
  const std::string out = args.options.at("--output");
  if (!endsWith(out, ".pc2")) throw InputError("simulate: -o must end in .pc2, got '" + out + "'");
  auto has = [&](const char* flag) { return std::find(args.flags.begin(), args.flags.end(), flag) != args.flags.end(); };
  if (has("--skin-solve") && !args.options.count("--muscles")) throw InputError("simulate: --skin-solve needs --muscles");
  SimulationOptions so;
  so.fps = numberOption(args, "--fps", so.fps);
  if (!(so.fps > 0)) throw InputError("--fps must be > 0");
  so.jiggle = has("--jiggle");
  so.filter = has("--filter");
  so.jiggleOptions.frequency = numberOption(args, "--jiggle-frequency", so.jiggleOptions.frequency);
  so.jiggleOptions.dampingRatio = numberOption(args, "--jiggle-damping", so.jiggleOptions.dampingRatio);
  so.jiggleOptions.amount = numberOption(args, "--jiggle-amount", so.jiggleOptions.amount);
  if (!so.jiggle && (args.options.count("--jiggle-frequency") || args.options.count("--jiggle-damping") ||
                     args.options.count("--jiggle-amount")))
    throw InputError("simulate: the --jiggle-* settings need --jiggle");
  if (so.jiggle && !args.options.count("--muscles")) throw InputError("simulate: --jiggle needs --muscles");
  if (args.options.count("--sculpt-frame") && !args.options.count("--sculpt"))
    throw InputError("simulate: --sculpt-frame needs --sculpt");
  const BoundSkin b = bindFromArgs(args, "simulate", {"--jiggle", "--filter", "--skin-solve"});
  const Character& c = b.character;
  const PoseSequence poses = readPoseJson(args.options.at("--pose"), c.skeleton);
  so.settings = b.settings;  // a chunk restores only a state baked with the same bind
  Simulation sim(c.mesh, c.skeleton, b.rig.get(), b.skinner, poses, so);
  // The per-frame skin solve: the skinned (jiggled) frame is the goal, the posed muscles collide.
  std::unique_ptr<SkinSolver> solver;
  Points solved;
  if (has("--skin-solve")) {
    solver = std::make_unique<SkinSolver>(c.mesh, *b.rig, defaultGoalWeights(b.weights, c.skeleton.numBones()));
    sim.setSkinSolve([&](int, const Pose&, const MuscleRigState* state, PointsF& skin) {
      solver->solve(skin, *state, solved);
      skin = solved.cast<float>();
    });
  }
  int first = sim.firstFrame(), last = sim.lastFrame();
  if (args.options.count("--frames")) frameRange(args.options.at("--frames"), first, last);
  if (args.options.count("--sculpt")) {
    const std::string path = args.options.at("--sculpt");
    const Mesh sculpt = readObjMesh(path);
    if (sculpt.numVertices() != c.mesh.numVertices())
      throw InputError("simulate: the sculpt " + path + " has " + std::to_string(sculpt.numVertices()) +
                       " vertices, the character " + std::to_string(c.mesh.numVertices()) +
                       " (write it with the character's vertex order, e.g. from `myoskin deform -o frame.obj`)");
    sim.setSculpt(sculpt.vertices, countOption(args, "--sculpt-frame", sim.firstFrame()));
  }
  std::unique_ptr<SimulationState> stateIn;
  if (args.options.count("--state-in"))
    stateIn = std::make_unique<SimulationState>(readSimulationState(args.options.at("--state-in")));
  PC2Writer writer(out, c.mesh.numVertices(), static_cast<float>(first), 1.0f);
  const SimulationState end =
      sim.bake(first, last, [&](int, const PointsF& frame) { writer.writeFrame(frame); }, stateIn.get());
  writer.close();
  if (args.options.count("--state-out")) writeSimulationState(args.options.at("--state-out"), end);
  std::printf("simulated %s (%d vertices, %d muscles%s%s%s%s, %g fps): frames %d-%d -> %s\n", c.name.c_str(),
              c.mesh.numVertices(), b.rig ? b.rig->numMuscles() : 0, so.jiggle ? ", jiggle" : "",
              solver ? ", skin solve" : "",
              so.filter ? ", filter" : "", args.options.count("--sculpt") ? ", sculpt" : "", so.fps, first, last,
              out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "--help")) {
    usage(argc < 2 ? std::cerr : std::cout);
    return argc < 2 ? 2 : 0;
  }
  const std::string command = argv[1];
  try {
    if (command == "info") return cmdInfo(parse(argc, argv, 2, {"--skeleton", "--mesh"}));
    if (command == "roles") return cmdRoles(parse(argc, argv, 2, {"--skeleton", "--mesh", "--roles", "--output"}));
    if (command == "generate") return cmdGenerate(parse(argc, argv, 2, {"--output", "--seed", "--muscle-scale"}));
    if (command == "extract") {
      // The expert flags extract took before its options were cut to five: named with their --expert key.
      const std::map<std::string, std::string> removed = {
          {"--min-evidence", "filters.minEvidence"}, {"--spindle-ends", "filters.spindleEnds"},
          {"--twin-reach", "filters.twinReach"}};
      for (int i = 2; i < argc; ++i)
        if (removed.count(argv[i]))
          throw InputError(std::string(argv[i]) + " is an expert option now: --expert " + removed.at(argv[i]) + "=VALUE");
      const Args args = parse(argc, argv, 2, {"--output", "--skeleton", "--spacing", "--min-confidence", "--min-sections",
                                              "--max-per-region", "--joint-wrap", "--mesh", "--roles", "--options",
                                              "--expert"});
      for (const std::string& f : args.flags)
        if (f != "--no-surfaces") throw InputError("extract: unknown option '" + f + "'");
      return cmdExtract(args);
    }
    if (command == "deform")
      return cmdDeform(
          parse(argc, argv, 2, {"--output", "--muscles", "--pose", "--skeleton", "--dominance", "--threads", "--mesh", "--dq-scale",
                                   "--method", "--relax-iterations", "--joints-slide"}));
    if (command == "simulate")
      return cmdSimulate(parse(argc, argv, 2,
                               {"--output", "--muscles", "--pose", "--skeleton", "--dominance", "--threads", "--mesh",
                                "--dq-scale", "--fps", "--frames", "--state-in", "--state-out", "--sculpt",
                                "--sculpt-frame", "--jiggle-frequency", "--jiggle-damping", "--jiggle-amount",
                                "--joints-slide"}));
    std::fprintf(stderr, "myoskin: error: unknown command '%s' (try myoskin --help)\n", command.c_str());
    return 2;
  } catch (const InputError& e) {
    std::fprintf(stderr, "myoskin: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "myoskin: error: internal: %s\n", e.what());
    return 4;
  }
}
