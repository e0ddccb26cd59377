// Muscle enums and validation.
#include "myoskin/muscle.h"

#include <cmath>

#include "myoskin/errors.h"

namespace myoskin {

const char* wrapTypeName(WrapType type) {
  switch (type) {
    case WrapType::Joint: return "joint";
    case WrapType::Bone: return "bone";
    default: return "none";
  }
}

WrapType wrapTypeFromName(const std::string& name) {
  if (name == "none") return WrapType::None;
  if (name == "joint") return WrapType::Joint;
  if (name == "bone") return WrapType::Bone;
  throw InputError("muscles: unknown wrap type '" + name + "' (expected none, joint or bone)");
}

void validateMuscles(const std::vector<Muscle>& muscles) {
  for (size_t m = 0; m < muscles.size(); ++m) {
    const Muscle& mu = muscles[m];
    const std::string label = "muscle " + std::to_string(m) + " '" + mu.name + "'";
    if (mu.name.empty()) throw InputError("muscle " + std::to_string(m) + " has an empty name");
    if (mu.rootCurve.size() < 2) throw InputError(label + ": root curve needs at least 2 points");
    for (const Vec3& p : mu.rootCurve)
      if (!p.allFinite()) throw InputError(label + ": root curve has a NaN point");
    if (!mu.origin.position.allFinite() || !mu.insertion.position.allFinite())
      throw InputError(label + ": origin or insertion is NaN");
    double previous = -2.0;
    for (size_t s = 0; s < mu.sections.size(); ++s) {
      const MuscleSection& sec = mu.sections[s];
      const std::string sl = label + " section " + std::to_string(s);
      if (!std::isfinite(sec.u) || sec.u < -1.0 || sec.u > 1.0) throw InputError(sl + ": u outside [-1, 1]");
      if (sec.u <= previous) throw InputError(sl + ": u must increase along the muscle");
      previous = sec.u;
      if (!sec.center.allFinite() || !sec.axisA.allFinite() || !sec.normal.allFinite())
        throw InputError(sl + ": NaN in centre or axes");
      if (!(sec.a > 0.0) || !(sec.b > 0.0)) throw InputError(sl + ": semi-axes must be positive");
    }
    if (mu.joints < 1) throw InputError(label + ": needs at least 1 joint");
    if (!std::isfinite(mu.bulge) || mu.bulge < 0.0) throw InputError(label + ": bulge factor must be >= 0");
    if (mu.wrap.type != WrapType::None && !(mu.wrap.radius > 0.0))
      throw InputError(label + ": wrap radius must be positive");
  }
}

}  // namespace myoskin
