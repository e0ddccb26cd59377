#!/usr/bin/env python3
"""Writes the seed corpora of the libFuzzer targets into tests/fuzz/corpus/<target>/ (small valid inputs the
fuzzers mutate). Run once; the output is committed. Regression inputs (crashes found and fixed) are committed
beside them as crash-<what> by hand and are not touched here.
    python3 tests/fuzz/make_seeds.py
"""
import base64
import json
import math
import os
import random
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "corpus")


def write(target, name, data):
    os.makedirs(os.path.join(CORPUS, target), exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(CORPUS, target, name), "wb") as f:
        f.write(data)


# A skinned box (8 vertices, 12 triangles) on a two-bone chain along +Y: the smallest whole character.
BOX = [(x, y, z) for y in (0.0, 1.0) for z in (-0.1, 0.1) for x in (-0.1, 0.1)]
BOX_FACES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def gltf_character(binary):
    pos = b"".join(struct.pack("<3f", *p) for p in BOX)
    idx = b"".join(struct.pack("<3H", *f) for f in BOX_FACES)
    joints = b"".join(struct.pack("<4B", 0 if p[1] < 0.5 else 1, 0, 0, 0) for p in BOX)
    weights = b"".join(struct.pack("<4f", 1, 0, 0, 0) for _ in BOX)
    # inverse bind matrices (column-major): joint 0 at the origin, joint 1 at y = 0.5
    ibm = struct.pack("<16f", *[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
    ibm += struct.pack("<16f", *[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -0.5, 0, 1])
    blob = b""
    views = []
    for chunk in (pos, idx, joints, weights, ibm):
        while len(blob) % 4:
            blob += b"\0"
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(chunk)})
        blob += chunk
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"name": "root", "children": [2]}, {"name": "Body", "mesh": 0, "skin": 0},
                  {"name": "upper", "translation": [0, 0.5, 0], "children": []}],
        "meshes": [{"name": "Body", "primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3},
                                                    "indices": 1}]}],
        "skins": [{"joints": [0, 2], "inverseBindMatrices": 4}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [-0.1, 0, -0.1], "max": [0.1, 1, 0.1]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5121, "count": 8, "type": "VEC4"},
            {"bufferView": 3, "componentType": 5126, "count": 8, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    if not binary:
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        return json.dumps(doc, separators=(",", ":"))
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def obj_character(quads):
    lines = ["# box"] + ["v %g %g %g" % p for p in BOX]
    if quads:
        lines += ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2/1 6/1 8/1 4/1"]
    else:
        lines += ["f %d %d %d" % (a + 1, b + 1, c + 1) for a, b, c in BOX_FACES]
    skeleton = {"bones": [{"name": "lower", "parent": None, "head": [0, 0, 0], "tail": [0, 0.5, 0]},
                          {"name": "upper", "parent": "lower", "head": [0, 0.5, 0], "tail": [0, 1, 0],
                           "x_axis": [1, 0, 0]}],
                "weights": {"lower": [[i, 1.0] for i in range(4)], "upper": [[i, 1.0] for i in range(4, 8)]}}
    return "\n".join(lines) + "\n#skeleton\n" + json.dumps(skeleton)


def muscles_json():
    def section(u, x):
        return {"u": u, "center": [x, 0.02, 0], "axis_a": [0, 1, 0], "a": 0.02, "b": 0.012, "normal": [1, 0, 0]}
    muscle = {"name": "biceps", "region": "upper_arm.R",
              "origin": {"bone": "upper_arm", "position": [0.05, 0, 0]},
              "insertion": {"bone": "forearm", "position": [0.35, 0, 0]},
              "root_curve": [[0.05 + 0.05 * i, 0.01 * math.sin(i), 0] for i in range(7)],
              "sections": [section(-0.5, 0.12), section(0.0, 0.2), section(0.5, 0.28)],
              "wrap": {"type": "none"}, "bulge": 1.0, "joints": 3, "confidence": 0.9}
    wrapped = dict(muscle, name="brachialis", wrap={"type": "joint", "bone": "forearm", "radius": 0.02, "side": 1})
    return json.dumps({"format": "myoskin.muscles", "version": 1, "muscles": [muscle, wrapped]}, indent=1)


def pose_json():
    one = {"format": "myoskin.pose", "version": 1,
           "bones": {"forearm": {"rotation_axis_angle": [90, 0, 0, 1]},
                     "upper_arm": {"rotation_quaternion": [0.9239, 0, 0.3827, 0]}}}
    frames = {"start_frame": 1, "frames": [{"bones": {"forearm": {"rotation_axis_angle": [a, 0, 0, 1]}}}
                                           for a in (0, 45, 90)]}
    return json.dumps(one), json.dumps(frames)


def pc2(points, frames):
    out = b"POINTCACHE2\0" + struct.pack("<iiffi", 1, points, 1.0, 1.0, frames)
    rng = random.Random(points * 31 + frames)
    for _ in range(points * frames):
        out += struct.pack("<3f", rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1))
    return out


def bumps_polygon(n, lobes, raw):
    """A section with `lobes` muscle bumps: int16 grid points (scale byte 5: 0.1 mm) or raw doubles."""
    header = bytes([1 if raw else 0, 5, 0, n // 2, 255, 0])
    body = b""
    for i in range(n):
        t = 2 * math.pi * i / n
        r = 400 + 60 * max(0.0, math.cos(lobes * t)) ** 3
        x, y = r * math.cos(t), r * math.sin(t)
        body += struct.pack("<dd", x * 1e-4, y * 1e-4) if raw else struct.pack("<hh", int(x), int(y))
    return header + body


def main():
    write("gltf", "box.glb", gltf_character(True))
    write("gltf", "box.gltf", gltf_character(False))
    write("obj", "box_triangles", obj_character(False))
    write("obj", "box_quads", obj_character(True))
    write("muscles_json", "two_muscles.json", muscles_json())
    one, frames = pose_json()
    write("pose_json", "one_pose.json", one)
    write("pose_json", "frames.json", frames)
    write("pc2", "three_points_two_frames.pc2", pc2(3, 2))
    write("pc2", "empty.pc2", pc2(5, 0))
    write("bumps", "two_bumps_grid", bumps_polygon(64, 2, False))
    write("bumps", "three_bumps_grid", bumps_polygon(96, 3, False))
    write("bumps", "two_bumps_raw", bumps_polygon(48, 2, True))
    # extract: edit lists (kind, index16, d xyz); empty = the arm as made.
    write("extract", "unchanged", b"")
    rng = random.Random(5)
    for name, kinds in (("moved_vertices", [0, 1]), ("moved_bones", [2, 3]), ("mixed", list(range(8)))):
        data = b""
        for _ in range(6):
            data += struct.pack("<BH3b", rng.choice(kinds), rng.randrange(65536), *(rng.randrange(-20, 21) for _ in range(3)))
        write("extract", name, data)


if __name__ == "__main__":
    main()
