// Ground-truth muscles of the synthetic characters as JSON (format "myoskin.true_muscles", version 1).
#include <cmath>
#include <nlohmann/json.hpp>

#include "myoskin/errors.h"
#include "myoskin/synthetic_character.h"

namespace myoskin {

using nlohmann::json;

namespace {

constexpr const char* kFormat = "myoskin.true_muscles";
constexpr int kVersion = 1;

// ============================================================================
// Reading helpers
// ============================================================================

// The member `key` of object j; throws naming `where` when absent.
const json& member(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError("true muscles JSON: " + where + " lacks \"" + key + "\"");
  return j.at(key);
}

// A finite number.
double finiteNumber(const json& j, const std::string& where) {
  if (!j.is_number()) throw InputError("true muscles JSON: " + where + " must be a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) throw InputError("true muscles JSON: " + where + " is not finite");
  return v;
}

// A non-empty string.
std::string nonEmptyString(const json& j, const std::string& where) {
  if (!j.is_string() || j.get<std::string>().empty())
    throw InputError("true muscles JSON: " + where + " must be a non-empty string");
  return j.get<std::string>();
}

// One muscle object, validated.
TrueMuscle muscleFromJson(const json& j, size_t index) {
  std::string where = "muscle " + std::to_string(index);
  TrueMuscle m;
  m.name = nonEmptyString(member(j, "name", where), where + " name");
  where = "muscle '" + m.name + "'";
  m.bone = nonEmptyString(member(j, "bone", where), where + " bone");
  const json& line = member(j, "center_line", where);
  const json& radius = member(j, "radius", where);
  if (!line.is_array() || line.size() < 2)
    throw InputError("true muscles JSON: " + where + " center_line needs at least 2 points");
  if (!radius.is_array() || radius.size() != line.size())
    throw InputError("true muscles JSON: " + where + " radius must have one value per center_line point");
  for (size_t k = 0; k < line.size(); ++k) {
    const std::string at = where + " center_line[" + std::to_string(k) + "]";
    if (!line[k].is_array() || line[k].size() != 3) throw InputError("true muscles JSON: " + at + " must be [x,y,z]");
    m.centerLine.emplace_back(finiteNumber(line[k][0], at), finiteNumber(line[k][1], at),
                              finiteNumber(line[k][2], at));
    const double r = finiteNumber(radius[k], where + " radius[" + std::to_string(k) + "]");
    if (r < 0.0) throw InputError("true muscles JSON: " + where + " has a negative radius");
    m.radius.push_back(r);
  }
  m.peakRadius = finiteNumber(member(j, "peak_radius", where), where + " peak_radius");
  if (m.peakRadius < 0.0) throw InputError("true muscles JSON: " + where + " has a negative peak_radius");
  if (j.contains("relief") && !(j.at("relief").is_array() && j.at("relief").empty())) {  // optional: absent or empty
    const json& relief = j.at("relief");
    if (!relief.is_array() || relief.size() != line.size())
      throw InputError("true muscles JSON: " + where + " relief must have one value per center_line point");
    for (size_t k = 0; k < relief.size(); ++k) {
      const double r = finiteNumber(relief[k], where + " relief[" + std::to_string(k) + "]");
      if (r < 0.0) throw InputError("true muscles JSON: " + where + " has a negative relief");
      m.relief.push_back(r);
    }
  }
  return m;
}

}  // namespace

// ============================================================================
// Public entry points
// ============================================================================

// Serialises the ground truth (one muscle object per TrueMuscle).
std::string trueMusclesToJson(const std::vector<TrueMuscle>& muscles) {
  json out = {{"format", kFormat}, {"version", kVersion}, {"muscles", json::array()}};
  for (const TrueMuscle& m : muscles) {
    json line = json::array();
    for (const Vec3& p : m.centerLine) line.push_back({p.x(), p.y(), p.z()});
    out["muscles"].push_back({{"name", m.name},
                              {"bone", m.bone},
                              {"center_line", line},
                              {"radius", m.radius},
                              {"peak_radius", m.peakRadius},
                              {"relief", m.relief}});
  }
  return out.dump(1);
}

// Parses and validates; every problem is an InputError naming the muscle and field.
std::vector<TrueMuscle> trueMusclesFromJson(const std::string& text) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(std::string("true muscles JSON: not valid JSON (") + e.what() + ")");
  }
  const json& format = member(j, "format", "document");
  if (!format.is_string() || format.get<std::string>() != kFormat)
    throw InputError(std::string("true muscles JSON: format must be \"") + kFormat + "\"");
  const json& version = member(j, "version", "document");
  if (!version.is_number_integer() || version.get<int64_t>() != kVersion)
    throw InputError("true muscles JSON: unsupported version (expected 1)");
  const json& list = member(j, "muscles", "document");
  if (!list.is_array()) throw InputError("true muscles JSON: \"muscles\" must be an array");
  std::vector<TrueMuscle> muscles;
  for (size_t i = 0; i < list.size(); ++i) muscles.push_back(muscleFromJson(list[i], i));
  return muscles;
}

}  // namespace myoskin
