// Muscles JSON (format "myoskin.muscles", version 1): serialisation with validation.
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "myoskin/errors.h"
#include "myoskin/io.h"

namespace myoskin {

using nlohmann::json;

namespace {

// ============================================================================
// Writing
// ============================================================================

json vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

json attachment(const MuscleAttachment& a) { return {{"bone", a.bone}, {"position", vec(a.position)}}; }

json muscleToJson(const Muscle& m) {
  json j;
  j["name"] = m.name;
  j["region"] = m.region;
  j["origin"] = attachment(m.origin);
  j["insertion"] = attachment(m.insertion);
  j["root_curve"] = json::array();
  for (const Vec3& p : m.rootCurve) j["root_curve"].push_back(vec(p));
  j["sections"] = json::array();
  for (const MuscleSection& s : m.sections)
    j["sections"].push_back({{"u", s.u}, {"center", vec(s.center)}, {"axis_a", vec(s.axisA)}, {"a", s.a},
                             {"b", s.b}, {"normal", vec(s.normal)}});
  json wrap = {{"type", wrapTypeName(m.wrap.type)}};
  if (m.wrap.type != WrapType::None) {
    wrap["bone"] = m.wrap.bone;
    wrap["radius"] = m.wrap.radius;
    wrap["side"] = m.wrap.side;
  }
  j["wrap"] = wrap;
  j["bulge"] = m.bulge;
  j["joints"] = m.joints;
  j["confidence"] = m.confidence;
  return j;
}

// ============================================================================
// Reading
// ============================================================================

// Field access with a message that says which muscle and field is wrong.
const json& field(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError("muscles JSON: " + where + " lacks \"" + key + "\"");
  return j.at(key);
}

double number(const json& j, const std::string& where) {
  if (!j.is_number()) throw InputError("muscles JSON: " + where + " must be a number");
  return j.get<double>();
}

Vec3 readVec(const json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 3) throw InputError("muscles JSON: " + where + " must be [x, y, z]");
  return Vec3(number(j[0], where), number(j[1], where), number(j[2], where));
}

MuscleAttachment readAttachment(const json& j, const std::string& where) {
  MuscleAttachment a;
  const json& bone = field(j, "bone", where);
  if (!bone.is_string()) throw InputError("muscles JSON: " + where + ".bone must be a string");
  a.bone = bone.get<std::string>();
  a.position = readVec(field(j, "position", where), where + ".position");
  return a;
}

Muscle readMuscle(const json& j, size_t index) {
  std::string where = "muscles[" + std::to_string(index) + "]";
  Muscle m;
  const json& name = field(j, "name", where);
  if (!name.is_string()) throw InputError("muscles JSON: " + where + ".name must be a string");
  m.name = name.get<std::string>();
  where += " '" + m.name + "'";
  if (j.contains("region") && j["region"].is_string()) m.region = j["region"].get<std::string>();
  m.origin = readAttachment(field(j, "origin", where), where + ".origin");
  m.insertion = readAttachment(field(j, "insertion", where), where + ".insertion");
  const json& curve = field(j, "root_curve", where);
  if (!curve.is_array()) throw InputError("muscles JSON: " + where + ".root_curve must be an array");
  for (const json& p : curve) m.rootCurve.push_back(readVec(p, where + ".root_curve"));
  const json& sections = field(j, "sections", where);
  if (!sections.is_array()) throw InputError("muscles JSON: " + where + ".sections must be an array");
  for (const json& s : sections) {
    MuscleSection sec;
    sec.u = number(field(s, "u", where), where + ".u");
    sec.center = readVec(field(s, "center", where), where + ".center");
    sec.axisA = readVec(field(s, "axis_a", where), where + ".axis_a");
    sec.a = number(field(s, "a", where), where + ".a");
    sec.b = number(field(s, "b", where), where + ".b");
    sec.normal = readVec(field(s, "normal", where), where + ".normal");
    m.sections.push_back(sec);
  }
  const json& wrap = field(j, "wrap", where);
  const json& type = field(wrap, "type", where + ".wrap");
  if (!type.is_string()) throw InputError("muscles JSON: " + where + ".wrap.type must be a string");
  m.wrap.type = wrapTypeFromName(type.get<std::string>());
  if (m.wrap.type != WrapType::None) {
    const json& bone = field(wrap, "bone", where + ".wrap");
    if (!bone.is_string()) throw InputError("muscles JSON: " + where + ".wrap.bone must be a string");
    m.wrap.bone = bone.get<std::string>();
    m.wrap.radius = number(field(wrap, "radius", where + ".wrap"), where + ".wrap.radius");
    if (wrap.contains("side")) m.wrap.side = number(wrap["side"], where + ".wrap.side") < 0 ? -1 : 1;
  }
  m.bulge = number(field(j, "bulge", where), where + ".bulge");
  const json& joints = field(j, "joints", where);
  if (!joints.is_number_integer() || joints.get<int64_t>() < 1 || joints.get<int64_t>() > 100000)
    throw InputError("muscles JSON: " + where + ".joints must be an integer from 1 to 100000");
  m.joints = joints.get<int>();
  if (j.contains("confidence")) m.confidence = number(j["confidence"], where + ".confidence");
  return m;
}

}  // namespace

std::string musclesToJson(const std::vector<Muscle>& muscles, int indent) {
  json doc = {{"format", "myoskin.muscles"}, {"version", 1}, {"muscles", json::array()}};
  for (const Muscle& m : muscles) doc["muscles"].push_back(muscleToJson(m));
  return doc.dump(indent);
}

std::vector<Muscle> musclesFromJson(const std::string& text) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(std::string("muscles JSON: not valid JSON (") + e.what() + ")");
  }
  if (!doc.is_object() || !doc.contains("format") || !doc["format"].is_string() ||
      doc["format"].get<std::string>() != "myoskin.muscles")
    throw InputError("muscles JSON: \"format\" must be \"myoskin.muscles\"");
  if (!doc.contains("version") || !doc["version"].is_number_integer() || doc["version"].get<int64_t>() != 1)
    throw InputError("muscles JSON: unsupported \"version\" (this build reads version 1)");
  const json& list = field(doc, "muscles", "document");
  if (!list.is_array()) throw InputError("muscles JSON: \"muscles\" must be an array");
  std::vector<Muscle> muscles;
  for (size_t i = 0; i < list.size(); ++i) muscles.push_back(readMuscle(list[i], i));
  validateMuscles(muscles);
  return muscles;
}

void writeMusclesJson(const std::string& path, const std::vector<Muscle>& muscles) {
  std::ofstream out(path);
  if (!out) throw InputError("cannot write " + path);
  out << musclesToJson(muscles) << "\n";
  if (!out) throw InputError("failed writing " + path);
}

std::vector<Muscle> readMusclesJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot open " + path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  try {
    return musclesFromJson(buffer.str());
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

}  // namespace myoskin
