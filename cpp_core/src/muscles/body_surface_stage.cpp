// Stage 0 of the extraction: the body surface (small and rigidly bound skin components left out, vertices
// renumbered, masks remapped), its bone roles and its scale context (units from the limb radius, spacing, mean edge
// length).
#include <cmath>

#include "muscles/extraction_stages.h"
#include "myoskin/secondary_motion.h"  // meanEdgeLength

namespace myoskin::stages {

// ============================================================================
// Scale context
// ============================================================================

ScaleContext makeScaleContext(const Character& body, const std::vector<BoneRole>& roles,
                              const BodyScaleOptions& options, double spacing) {
  // The character's units are found from its limb radius: the power of ten that brings it nearest the reference, or
  // (continuous) the factor that brings it there exactly.
  ScaleContext s;
  s.limbRadius = bodyLimbRadius(body, roles);
  s.reference = options.referenceLimbRadius == 0 ? kReferenceLimbRadius : options.referenceLimbRadius;
  if (s.reference > 0 && s.limbRadius > 0)
    s.factor = options.continuous ? s.reference / s.limbRadius
                                  : std::pow(10.0, std::round(std::log10(s.reference / s.limbRadius)));
  if (options.spacing > 0) spacing = options.spacing * s.limbRadius;  // limb radii -> the character's units
  s.planeSpacing = spacing * s.factor;
  return s;
}

// ============================================================================
// Body surface
// ============================================================================

BodySurface makeBodySurface(const Character& character, const ExtractionOptions& options) {
  const int nv = character.mesh.numVertices();
  BodySurface out;
  // The body surface: small and rigidly bound components left out, vertices renumbered.
  std::vector<ExcludedComponent>& excluded = out.excluded;
  const std::vector<char> keep = bodySurfaceMask(character, excluded);
  std::vector<int> newIndex(nv, -1);
  Character body;
  body.name = character.name;
  body.skeleton = weightedSkeleton(character);
  std::vector<char> used(nv, 0);
  for (int f = 0; f < character.mesh.numTriangles(); ++f)
    for (int c = 0; c < 3; ++c) used[character.mesh.triangles(f, c)] = 1;
  int count = 0;
  for (int v = 0; v < nv; ++v)
    if (used[v] && keep[v]) newIndex[v] = count++;
  body.mesh.vertices.resize(count, 3);
  if (character.hasWeights()) {
    body.weights.joints.resize(count, character.weights.influences());
    body.weights.weights.resize(count, character.weights.influences());
  }
  for (int v = 0; v < nv; ++v) {
    if (newIndex[v] < 0) continue;
    body.mesh.vertices.row(newIndex[v]) = character.mesh.vertices.row(v);
    if (character.hasWeights()) {
      body.weights.joints.row(newIndex[v]) = character.weights.joints.row(v);
      body.weights.weights.row(newIndex[v]) = character.weights.weights.row(v);
    }
  }
  std::vector<Eigen::Vector3i> tris;
  for (int f = 0; f < character.mesh.numTriangles(); ++f) {
    const Eigen::Vector3i t = character.mesh.triangles.row(f).transpose();
    if (newIndex[t[0]] >= 0 && newIndex[t[1]] >= 0 && newIndex[t[2]] >= 0)
      tris.emplace_back(newIndex[t[0]], newIndex[t[1]], newIndex[t[2]]);
  }
  body.mesh.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) body.mesh.triangles.row(static_cast<Eigen::Index>(f)) = tris[f].transpose();
  auto remap = [&](const std::vector<char>& mask) {
    std::vector<char> renumbered(count, 0);
    for (int v = 0; v < nv; ++v)
      if (newIndex[v] >= 0) renumbered[newIndex[v]] = mask[v];
    return renumbered;
  };
  if (!options.vertexMask.empty()) out.vertexMask = remap(options.vertexMask);
  for (const auto& region : options.forcedRegions) out.forcedRegions.push_back(remap(region));

  // The body scale: the character is scaled about the origin into its units, so mm, cm, m and x100 exports give the
  // same muscles.
  // Roles come from the bone tree and the skin's shape relative to the body, so they do not change with the units.
  out.roles = characterBoneRoles(body, options.roleOverrides);
  out.scale = makeScaleContext(body, out.roles, options.scale, options.planes.spacing);
  const double factor = out.scale.factor;
  auto toBody = [&](const Vec3& p) { return Vec3(p * factor); };
  for (int v = 0; v < count; ++v) body.mesh.vertices.row(v) = toBody(body.mesh.vertices.row(v).transpose()).transpose();
  for (Bone& b : body.skeleton.bones) {
    b.head = toBody(b.head), b.tail = toBody(b.tail);
    b.rest.block<3, 1>(0, 3) = toBody(b.rest.block<3, 1>(0, 3));
  }
  out.scale.defaultSpacing = automaticPlaneSpacing(body.mesh.vertices);
  out.scale.meanEdgeLength = body.mesh.numTriangles() > 0 ? meanEdgeLength(body.mesh.vertices, body.mesh.triangles) : 0.0;
  out.body = std::move(body);
  return out;
}

}  // namespace myoskin::stages
