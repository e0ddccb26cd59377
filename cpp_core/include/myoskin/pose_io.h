// Pose files (format "myoskin.pose", version 1): skeleton poses as per-bone local rotations, one pose or a
// sequence of frames. Used by `myoskin deform` and the tests.
//   {"format": "myoskin.pose", "version": 1,
//    "bones": {"forearm": {"rotation_quaternion": [w, x, y, z]},
//              "upper_arm": {"rotation_axis_angle": [degrees, x, y, z]}}}
// or, for a sequence (e.g. a .pc2 cache):
//   {"format": "myoskin.pose", "version": 1, "start_frame": 1, "frames": [{"bones": {...}}, ...]}
// A rotation is about the bone's head in its own rest frame (Blender's PoseBone.rotation_quaternion /
// axis-angle mode); bones not listed stay at rest. "format"/"version" may be omitted.
#pragma once
#include <string>
#include <vector>

#include "myoskin/skeleton.h"

namespace myoskin {

struct PoseSequence {
  double startFrame = 1.0;
  std::vector<Pose> frames;  // posed bone matrices (poseFromLocalRotations)
};

// Parses and validates (unknown bones or keys, non-finite or zero quaternions -> InputError naming them).
PoseSequence posesFromJson(const std::string& text, const Skeleton& skeleton);
PoseSequence readPoseJson(const std::string& path, const Skeleton& skeleton);

}  // namespace myoskin
