"""Limits: time and peak memory of extraction, bind (the hybrid weights) and one frame (rig evaluation +
Equation 3 skinning) at about a million skin vertices and with 500 muscles. Each case runs in its own process,
so its peak resident memory is its own. Prints a table; never asserts. Usage (./myoskin.sh bench runs it):

    PYTHONPATH=build/blender_scripts/addons/myoskin python3 benchmarks/bench_limits.py

The characters are generated (makeSyntheticBody at a finer skin cell: ~1M vertices), so nothing is needed
beside the build. 500 muscles: the body's extracted muscles repeated round their limbs (each copy turned about
its bone's axis), which gives the rig and the weights 500 real muscles to evaluate.
"""
import json
import os
import resource
import subprocess
import sys
import time

CASES = {
    "body-110k": dict(cell=0.0, muscles=0),
    "body-1M": dict(cell=0.0027, muscles=0),
    "body-110k-500-muscles": dict(cell=0.0, muscles=500),
}


def many_muscles(core, character, muscles, count):
    """`count` muscles: copies of `muscles` turned about the bone each one's origin lies on (names made unique)."""
    import numpy as np
    names = list(character.bone_names)
    heads, tails = np.asarray(character.bone_heads), np.asarray(character.bone_tails)
    doc = json.loads(core.muscles_to_json(muscles))
    if not doc["muscles"]:
        raise SystemExit("bench_limits: the body gave no muscles to repeat")
    rounds = -(-count // len(doc["muscles"]))  # ceil: each round turned by 2 pi / rounds
    out = []
    for k in range(count):
        m = json.loads(json.dumps(doc["muscles"][k % len(doc["muscles"])]))
        b = names.index(m["origin"]["bone"])
        axis = tails[b] - heads[b]
        axis /= np.linalg.norm(axis)
        angle = 2 * np.pi * (k // len(doc["muscles"])) / rounds
        kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rot = np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx

        def turn(p):
            return (rot @ (np.asarray(p) - heads[b]) + heads[b]).tolist()

        m["name"] = f"{m['name']}_copy{k}"
        m["origin"]["position"] = turn(m["origin"]["position"])
        m["insertion"]["position"] = turn(m["insertion"]["position"])
        m["root_curve"] = [turn(p) for p in m["root_curve"]]
        for s in m["sections"]:
            s["center"] = turn(s["center"])
            s["axis_a"] = (rot @ np.asarray(s["axis_a"])).tolist()
            s["normal"] = (rot @ np.asarray(s["normal"])).tolist()
        m.pop("surface", None)
        out.append(m)
    doc["muscles"] = out
    return core.muscles_from_json(json.dumps(doc))


def run_case(name):
    import _core as core
    import numpy as np
    import skin_quality  # beside this script
    case = CASES[name]
    t = time.perf_counter()
    character, _ = core.make_synthetic_body(seed=1, cell_size=case["cell"])
    made = time.perf_counter() - t
    t = time.perf_counter()
    muscles, report = core.extract_muscles(character)
    extract = time.perf_counter() - t
    if case["muscles"]:
        muscles = many_muscles(core, character, muscles, case["muscles"])
    t = time.perf_counter()
    rig, joints, weights = skin_quality.bound_rig(core, character, muscles)  # as Bind: with the slide limits
    bind = time.perf_counter() - t
    skinner = core.Skinner(character.vertices, joints, weights, character.num_bones + rig.num_joints)
    rest = np.asarray(character.bone_rest)
    pose = rest.copy()
    t = time.perf_counter()
    state = rig.evaluate(pose)
    transforms = core.skinning_transforms(character, pose, rig, state["joint_matrices"])
    skinner.deform(transforms)
    frame = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # MiB (Linux: KiB)
    print(json.dumps(dict(case=name, vertices=character.num_vertices, muscles=len(muscles), joints=rig.num_joints,
                          generate=made, extract=extract, bind=bind, frame=frame, peak_mib=peak)), flush=True)


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--case":
        run_case(sys.argv[2])
        return
    print(f"{'case':24s} {'vertices':>9s} {'muscles':>7s} {'joints':>6s} {'extract':>8s} {'bind':>8s} "
          f"{'frame':>8s} {'peak memory':>11s}")
    for name in CASES:
        done = subprocess.run([sys.executable, os.path.abspath(__file__), "--case", name], capture_output=True,
                              text=True)
        if done.returncode != 0:
            print(f"{name:24s} failed ({done.returncode}): {done.stderr.strip().splitlines()[-1:]}")
            continue
        r = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"{r['case']:24s} {r['vertices']:9d} {r['muscles']:7d} {r['joints']:6d} {r['extract']:7.2f}s "
              f"{r['bind']:7.2f}s {1000 * r['frame']:6.1f}ms {r['peak_mib']:8.0f} MiB")


if __name__ == "__main__":
    main()
