// Anatomical muscle names from where a muscle lies on the body (internal to extraction's naming stage).
#pragma once
#include <string>
#include <vector>

#include "myoskin/muscle.h"
#include "myoskin/sections.h"
#include "myoskin/skeleton.h"

namespace myoskin::detail {

// The body's axes and its limbs, from the skeleton's roles: legs are the limb chains that hang from the trunk's
// root end (the pelvis), arms (a quadruped's front legs) those further along the trunk.
// up: from the legs' ends to their roots; forward: the feet's direction across up (or, when the feet point
// down as hooves do, the neck's); left = up x forward, then, with two limbs or more, turned onto the limbs' own
// left-right axis (each limb root's offset from the centre, counted towards its side: the mirror normal of a symmetric
// rig, whose neck or feet may turn) and forward = left x up. valid is false when there are no legs or no forward.
struct BodyFrame {
  bool valid = false;
  bool sided = false;          // two limbs or more: the centre is the mirror plane, so .L / .R mean something
  Vec3 up = Vec3::Zero(), forward = Vec3::Zero(), left = Vec3::Zero();
  Vec3 centre = Vec3::Zero();  // the midpoint of the limb roots (on the mirror plane of a symmetric rig)
  std::vector<int> limb;       // #B: 0 none, 1 arm, 2 leg
  std::vector<int> segment;    // #B: segment index from the limb's root (0 = upper arm / thigh), -1 none
};

BodyFrame bodyFrame(const Skeleton& skeleton, const std::vector<BoneRole>& roles, const std::vector<char>& twist);

// "biceps.L", "quadriceps.R", "pectoral.L", ... for a muscle whose place identifies it (its middle section's
// side of the bone its chain was cut along, `bone`, and the plane family); "" otherwise (the caller names it by
// region). Front / back: within 60 degrees of the body's forward axis around the bone.
std::string anatomicalName(const Muscle& muscle, int bone, const std::string& family, const Skeleton& skeleton,
                           const BodyFrame& frame);

// "forearm_front.L", "shin_outer.R", "neck_back", "flank.L", ...: the region a muscle lies in (limb segment, neck or
// trunk) and its side of the bone (front / back / outer / inner, or top / bottom where the bone runs forward), for a
// muscle anatomicalName cannot name; "" without a body frame (the caller names it by bone and bone axis).
std::string regionName(const Muscle& muscle, int bone, const std::string& family, const Skeleton& skeleton,
                       const BodyFrame& frame);

// p mirrored across the body's mirror plane (through frame.centre, normal frame.left).
Vec3 mirrored(const Vec3& p, const BodyFrame& frame);

// Mirror twins: twin[i] = j when muscles i and j (#M, `family` per muscle) share a family, their mean section centres
// lie on opposite sides of the mirror plane, and each is the other's nearest mirror image within the larger of their
// mean semi-axes a; -1 otherwise (and for every muscle without a sided body frame).
std::vector<int> mirrorTwins(const std::vector<const Muscle*>& muscles, const std::vector<std::string>& family,
                             const BodyFrame& frame);

// `muscle` with its middle section centre (the one the names look at) averaged with the mirror image of its twin's,
// so that a twin pair is named from one place, not from each side's own (a name decided by a threshold would
// otherwise differ between the sides of a symmetric body by round-off).
Muscle symmetrisedForNaming(const Muscle& muscle, const Muscle& twin, const BodyFrame& frame);

}  // namespace myoskin::detail
