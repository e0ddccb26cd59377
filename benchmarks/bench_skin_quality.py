"""Skin quality at bent joints, LBS vs DQS vs Myoskin (and Myoskin + Preserve Volume) through the core (benchmarks/skin_quality.py defines the
measures). Prints a table per character; never asserts. Usage (./myoskin.sh bench runs it):

    PYTHONPATH=build/blender_scripts/addons/myoskin python3 benchmarks/bench_skin_quality.py [SHARED_DIR]
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _core as core  # noqa: E402  (the staged compiled module, on PYTHONPATH)
import skin_quality  # noqa: E402

shared = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..", "shared")
characters = [("makehuman_muscular_male", "characters/makehuman_muscular_male/makehuman_muscular_male.glb",
               skin_quality.MAKEHUMAN_JOINTS)]
print(f"{'character':24s} {'joint':20s} {'LBS band':>9s} {'DQS band':>9s} {'Blender DQS':>11s} {'Myoskin':>9s} "
      f"{'Myoskin+PV':>10s} {'bulge over LBS':>22s} {'+PV over LBS':>12s} {'+PV over DQS':>12s} "
      f"{'crossings LBS/DQS/Myo/Myo+PV':>29s}")
for name, relative, joints in characters:
    path = os.path.join(shared, relative)
    if not os.path.exists(path):
        print(f"{name}: skipped, needs {path}")
        continue
    character = core.load_character(path, require_weights=True)
    start = time.perf_counter()
    muscles, _ = core.extract_muscles(character)
    for row in skin_quality.measure(core, character, muscles, joints):
        print(f"{name:24s} {row['label']:20s} {100 * row['lbs']:+8.1f}% {100 * row['dqs']:+8.1f}% "
              f"{100 * row['blender_dqs']:+10.1f}% {100 * row['myoskin']:+8.1f}% {100 * row['myoskin_pv']:+9.1f}% "
              f"{1000 * row['bulge']:7.1f} mm ({row['bulge'] / row['limb_radius']:.3f} r) {1000 * row['bulge_pv']:9.1f} mm {1000 * row['bulge_pv_over_dqs']:9.1f} mm "
              f"{row['crossings_lbs']:>8d}/{row['crossings_dqs']}/{row['crossings_myoskin']}/{row['crossings_myoskin_pv']}")
    print(f"{name}: {len(muscles)} muscles, measured in {time.perf_counter() - start:.1f} s")
