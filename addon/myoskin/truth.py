# SPDX-License-Identifier: GPL-3.0-or-later
"""Ground-truth muscles of the procedural characters as core Muscle objects (no bpy).

make_synthetic_arm returns its known muscles as centre lines with a radius per point; the demo and
tests turn them into Muscle objects (the same type extraction returns) so they can be written as
muscles.json and drawn like extracted muscles.
"""
import numpy as np

from . import core_loader


def arc_length_u(points):
    """u in [-1, 1] by arc length along a polyline (#N by 3), -1 at the first point, +1 at the last."""
    points = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    return -1.0 + 2.0 * s / s[-1] if s[-1] > 0.0 else np.linspace(-1.0, 1.0, len(points))


def nearest_bone(point, heads, tails):
    """Index of the bone segment (head -> tail) nearest to `point`."""
    d = tails - heads
    t = np.clip(np.einsum("ij,ij->i", point - heads, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-30), 0, 1)
    closest = heads + t[:, None] * d
    return int(np.argmin(np.linalg.norm(closest - point, axis=1)))


def _perpendicular(tangent, reference=(0.0, 0.0, 1.0)):
    """Unit vector perpendicular to `tangent`, as close to `reference` as possible."""
    ref = np.asarray(reference, dtype=np.float64)
    v = ref - tangent * np.dot(ref, tangent)
    if np.linalg.norm(v) < 1e-6:
        ref = np.array([0.0, 1.0, 0.0])
        v = ref - tangent * np.dot(ref, tangent)
    return v / np.linalg.norm(v)


def muscles_from_truth(truth, character, joints=4, bulge=1.0, min_radius=1e-5):
    """Muscle objects from ground-truth dicts (name, bone, center_line, radius): root curve = centre
    line, circular sections (a = b = radius, normal = tangent) at every centre-line point whose radius
    exceeds min_radius, u by arc length, origin/insertion at the line's ends on the nearest bones."""
    core = core_loader.core()
    heads = np.asarray(character.bone_heads, dtype=np.float64)
    tails = np.asarray(character.bone_tails, dtype=np.float64)
    names = list(character.bone_names)
    muscles = []
    for t in truth:
        line = np.asarray(t["center_line"], dtype=np.float64)
        radius = np.asarray(t["radius"], dtype=np.float64)
        u = arc_length_u(line)
        tangents = np.gradient(line, axis=0)
        tangents /= np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-30)
        m = core.Muscle()
        m.name = t["name"]
        m.region = t.get("bone", "")
        m.root_curve = line
        m.origin = line[0]
        m.origin_bone = names[nearest_bone(line[0], heads, tails)]
        m.insertion = line[-1]
        m.insertion_bone = names[nearest_bone(line[-1], heads, tails)]
        for i in range(len(line)):
            if radius[i] > min_radius:
                m.add_section(float(u[i]), line[i], _perpendicular(tangents[i]), float(radius[i]),
                              float(radius[i]), tangents[i])
        m.joints = int(joints)
        m.bulge = float(bulge)
        m.confidence = 1.0
        muscles.append(m)
    return muscles


def truth_to_json_dict(truth):
    """The ground truth as plain JSON-able data (for truth.json)."""
    return {
        "format": "myoskin.truth",
        "version": 1,
        "muscles": [{
            "name": t["name"],
            "bone": t["bone"],
            "peak_radius": float(t["peak_radius"]),
            "center_line": np.asarray(t["center_line"], dtype=float).tolist(),
            "radius": np.asarray(t["radius"], dtype=float).tolist(),
            "relief": np.asarray(t.get("relief", []), dtype=float).tolist(),
        } for t in truth],
    }
