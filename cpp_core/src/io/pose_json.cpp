// Pose files ("myoskin.pose"): per-bone local rotations -> posed bone matrices.
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "myoskin/errors.h"
#include "myoskin/pose_io.h"

namespace myoskin {

namespace {

using nlohmann::json;


std::vector<double> numbers(const json& j, size_t count, const std::string& what) {
  if (!j.is_array() || j.size() != count) throw InputError(what + " needs " + std::to_string(count) + " numbers");
  std::vector<double> out;
  for (const json& x : j) {
    if (!x.is_number()) throw InputError(what + " needs " + std::to_string(count) + " numbers");
    out.push_back(x.get<double>());
    if (!std::isfinite(out.back())) throw InputError(what + " has a non-finite value");
  }
  return out;
}

// One frame {"bones": {...}} -> posed matrices.
Pose frameFromJson(const json& frame, const Skeleton& skeleton, const std::string& label) {
  if (!frame.is_object()) throw InputError(label + " must be an object");
  std::vector<Eigen::Quaterniond> rotations(skeleton.bones.size(), Eigen::Quaterniond::Identity());
  if (frame.contains("bones")) {
    const json& bones = frame.at("bones");
    if (!bones.is_object()) throw InputError(label + ": \"bones\" must be an object of bone name -> rotation");
    for (auto it = bones.begin(); it != bones.end(); ++it) {
      const int b = skeleton.find(it.key());
      const std::string what = label + ": bone '" + it.key() + "'";
      if (b < 0) throw InputError(what + " is not in the skeleton");
      if (!it.value().is_object()) throw InputError(what + " must be an object");
      for (auto k = it.value().begin(); k != it.value().end(); ++k) {
        if (k.key() == "rotation_quaternion") {
          const auto q = numbers(k.value(), 4, what + " rotation_quaternion");
          const Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
          if (quat.norm() < 1e-12) throw InputError(what + " rotation_quaternion is zero");
          rotations[b] = quat.normalized() * rotations[b];
        } else if (k.key() == "rotation_axis_angle") {
          const auto a = numbers(k.value(), 4, what + " rotation_axis_angle");
          const Vec3 axis(a[1], a[2], a[3]);
          if (axis.norm() < 1e-12) throw InputError(what + " rotation_axis_angle has a zero axis");
          rotations[b] = Eigen::Quaterniond(Eigen::AngleAxisd(a[0] * kPi / 180.0, axis.normalized())) * rotations[b];
        } else {
          throw InputError(what + " has unknown key '" + k.key() +
                           "' (use rotation_quaternion [w,x,y,z] or rotation_axis_angle [degrees,x,y,z])");
        }
      }
    }
  }
  return poseFromLocalRotations(skeleton, rotations);
}

}  // namespace

PoseSequence posesFromJson(const std::string& text, const Skeleton& skeleton) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(std::string("pose: not valid JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError("pose: the file must hold a JSON object");
  if (j.contains("format") && j.at("format") != "myoskin.pose")
    throw InputError("pose: format is " + j.at("format").dump() + ", expected \"myoskin.pose\"");
  if (j.contains("version") && j.at("version") != 1)
    throw InputError("pose: version " + j.at("version").dump() + " is not supported (expected 1)");
  PoseSequence seq;
  if (j.contains("start_frame")) {
    if (!j.at("start_frame").is_number()) throw InputError("pose: start_frame must be a number");
    seq.startFrame = j.at("start_frame").get<double>();
  }
  if (j.contains("frames")) {
    if (j.contains("bones")) throw InputError("pose: give either \"bones\" (one pose) or \"frames\", not both");
    const json& frames = j.at("frames");
    if (!frames.is_array() || frames.empty()) throw InputError("pose: \"frames\" must be a non-empty list");
    for (size_t f = 0; f < frames.size(); ++f)
      seq.frames.push_back(frameFromJson(frames[f], skeleton, "pose: frame " + std::to_string(f)));
  } else {
    seq.frames.push_back(frameFromJson(j, skeleton, "pose"));
  }
  return seq;
}

PoseSequence readPoseJson(const std::string& path, const Skeleton& skeleton) {
  std::ifstream in(path);
  if (!in) throw InputError("pose: cannot open " + path);
  std::stringstream text;
  text << in.rdbuf();
  return posesFromJson(text.str(), skeleton);
}

}  // namespace myoskin
