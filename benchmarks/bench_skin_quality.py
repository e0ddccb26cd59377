"""Skin quality at bent joints, LBS vs DQS vs Myoskin (and Myoskin + Preserve Volume, Myoskin + the volume blend) vs
the anchored skin through the
core (benchmarks/skin_quality.py defines the measures). Prints a table per character and a second one for the
anchored skin (band, bulge, crossings, ms per frame against Equation 3 in the same run), then a bend sweep per joint
(30-150 degrees, human ankles 15-60: where Bind's skin folds more than LBS, which one test angle hides), the Joints Slide
on/off crumples, and the muscle joints' jumps over a 0-150 degree sweep (skin_quality.joint_jumps); never asserts. Joints
(skin_quality.py): elbow, knee, shoulder, hip and ankle plantar flexion (the calf's bulge on the lower leg). Characters:
makehuman_muscular_male, a generated biped (makeSyntheticBody, known muscles), Quaternius' woman soldier (four
meshes, x100) and Quaternius' horse (x100). Usage (./myoskin.sh bench
runs it):

    PYTHONPATH=build/blender_scripts/addons/myoskin python3 benchmarks/bench_skin_quality.py [SHARED_DIR]
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _core as core  # noqa: E402  (the staged compiled module, on PYTHONPATH)
import skin_quality  # noqa: E402

shared = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..", "shared")
Z_FORWARD, Y_BACK = (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)
characters = [
    ("makehuman_muscular_male", "characters/makehuman_muscular_male/makehuman_muscular_male.glb",
     skin_quality.MAKEHUMAN_JOINTS, Z_FORWARD),
    ("generated biped, seed 21", None, skin_quality.SYNTHETIC_BODY_JOINTS, Y_BACK),
    ("quaternius_woman_soldier", "characters/quaternius_woman_soldier/woman_soldier.glb",
     skin_quality.QUATERNIUS_JOINTS, Z_FORWARD),
    ("quaternius_horse", "characters/quaternius_horse/horse.glb", skin_quality.HORSE_JOINTS, Z_FORWARD),
]
anchored_rows = []
sweeps = []
jumps = []
print(f"{'character':24s} {'joint':20s} {'LBS band':>9s} {'DQS band':>9s} {'Blender DQS':>11s} {'Myoskin':>9s} "
      f"{'Myoskin+PV':>10s} {'Myoskin+VB':>10s} {'VB+keys':>8s} {'bulge over LBS':>22s} {'+PV over LBS':>12s} {'+PV over DQS':>12s} "
      f"{'crossings LBS/DQS/Myo/Myo+PV/Myo+VB/VB+keys':>44s} {'(crumples LBS/VB+keys)':>22s}")
for name, relative, joints, facing in characters:
    if relative is None:
        character, _truth = core.make_synthetic_body(seed=21)
    else:
        path = os.path.join(shared, relative)
        if not os.path.exists(path):
            print(f"{name}: skipped, needs {path}")
            continue
        character = core.load_character(path, require_weights=True)
    start = time.perf_counter()
    muscles, report = core.extract_muscles(character)
    bound = skin_quality.bind_skin(core, character, muscles)  # Bind once: the table and the sweep reuse it
    for row in skin_quality.measure(core, character, muscles, joints, facing=facing, anchored=True, bound=bound):
        anchored_rows.append((name, row))
        print(f"{name[:24]:24s} {row['label']:20s} {100 * row['lbs']:+8.1f}% {100 * row['dqs']:+8.1f}% "
              f"{100 * row['blender_dqs']:+10.1f}% {100 * row['myoskin']:+8.1f}% {100 * row['myoskin_pv']:+9.1f}% "
              f"{100 * row['myoskin_vb']:+9.1f}% {100 * row['myoskin_vk']:+7.1f}% "
              f"{1000 * row['bulge']:7.1f} mm ({row['bulge'] / row['limb_radius']:.3f} r) {1000 * row['bulge_pv']:9.1f} mm {1000 * row['bulge_pv_over_dqs']:9.1f} mm "
              f"{row['crossings_lbs']:>15d}/{row['crossings_dqs']}/{row['crossings_myoskin']}/{row['crossings_myoskin_pv']}"
              f"/{row['crossings_myoskin_vb']}/{row['crossings_myoskin_vk']} "
              f"({row['crumples_lbs']}/{row['crumples_myoskin_vk']})")
    print(f"{name}: {len(muscles)} muscles, measured in {time.perf_counter() - start:.1f} s")
    # A human ankle plantar-flexes about 50 degrees at most: its sweep stops at 60 (a horse's hock sweeps to 150).
    ankles = {j[0]: (15, 30, 45, 60) for j in joints if j[0].startswith("ankle")}
    fixed = skin_quality.fold_sweep(core, character, muscles, joints, facing=facing, degrees_by_label=ankles,
                                    rig_options=dict(joints_slide=False))
    free = skin_quality.fold_sweep(core, character, muscles, joints, facing=facing, degrees_by_label=ankles,
                                   bound=skin_quality.bind_skin(core, character, muscles, slide_limit=False))
    sweeps.append((name, skin_quality.fold_sweep(core, character, muscles, joints, facing=facing,
                                                 degrees_by_label=ankles, bound=bound), fixed, free))
    jumps.append((name, skin_quality.joint_jumps(core, character, bound[0], joints, report["limb_radius"],
                                                 facing=facing)))
print()
print(f"{'character':24s} {'joint':20s} {'LBS band':>9s} {'Myoskin+PV':>10s} {'anchored':>9s} {'anchored bulge over LBS':>24s} "
      f"{'crossings LBS/+PV/anchored':>27s} {'anchored ms':>11s} {'Eq.3 ms':>8s} {'ratio':>6s}")
for name, row in anchored_rows:
    print(f"{name[:24]:24s} {row['label']:20s} {100 * row['lbs']:+8.1f}% {100 * row['myoskin_pv']:+9.1f}% "
          f"{100 * row['anchored']:+8.1f}% {1000 * row['bulge_anchored']:9.1f} mm ({row['bulge_anchored'] / row['limb_radius']:+.3f} r) "
          f"{row['crossings_lbs']:>14d}/{row['crossings_myoskin_pv']}/{row['crossings_anchored']} "
          f"{row['ms_anchored']:11.2f} {row['ms_eq3']:8.2f} {row['ms_anchored'] / row['ms_eq3']:6.2f}")


def total(sweep, key):
    return sum(r[key] for joint in sweep for r in joint["rows"])


def over_lbs(sweep):
    return sum(r["crossings_myoskin_vk"] > r["crossings_lbs"] for joint in sweep for r in joint["rows"])


print()
print("Bend sweep (30-150 degrees by 15, ankles 15-60): crossing band triangle pairs, LBS / Myoskin (VB+keys, what Bind gives), "
      "in brackets the crumples among them (new pairs whose triangles' centroids lie within "
      f"{skin_quality.CRUMPLE_RADII} limb radii at rest), '!' where "
      "Myoskin folds more than LBS, and Myoskin's band change")
for name, sweep, _fixed, _free in sweeps:
    for joint in sweep:
        cells = " ".join(f"{r['degrees']}:{r['crossings_lbs']}({r['crumples_lbs']})/{r['crossings_myoskin_vk']}"
                         f"({r['crumples_myoskin_vk']}){'!' if r['crossings_myoskin_vk'] > r['crossings_lbs'] else ''} "
                         f"{100 * r['myoskin_vk']:+.0f}%" for r in joint["rows"])
        worse = over_lbs([joint])
        print(f"{name[:24]:24s} {joint['label']:20s} folds more than LBS at {worse} of {len(joint['rows'])}: {cells}")


print()
print("Joints Slide on (the default, with Bind's slide limits), on without the limits (free: bind_skin(slide_limit=False)) "
      "and off (MuscleRig joints_slide=False), the same sweep: crumples and the (joint, angle) cases folding more than "
      "LBS, summed over each character's joints")
for name, sweep, fixed, free in sweeps:
    print(f"{name[:24]:24s} crumples LBS {total(sweep, 'crumples_lbs')}, on {total(sweep, 'crumples_myoskin_vk')}, free "
          f"{total(free, 'crumples_myoskin_vk')}, off {total(fixed, 'crumples_myoskin_vk')}; cases over LBS on "
          f"{over_lbs(sweep)}, free {over_lbs(free)}, off {over_lbs(fixed)} of {sum(len(joint['rows']) for joint in sweep)}")
print()
print("Muscle joint jumps: each joint bent 0-150 degrees in 0.5-degree steps with 0, 7 and 23 degrees of twist; a jump is a "
      "muscle joint moving over 0.05 limb radii and 8 times its median step (a wrap changing its way round)")
for name, found in jumps:
    worst = max(found, key=lambda j: j[4]) if found else None
    where = sorted({(label, round(degrees)) for label, _t, degrees, _n, _m in found})
    print(f"{name[:24]:24s} {len(found)} jumps" + (f", largest {worst[4]:.2f} r ({worst[3]}, {worst[0]} at "
                                                   f"{worst[2]:g} degrees); at {where[:8]}" if worst else ""))
