# SPDX-License-Identifier: GPL-3.0-or-later
"""Child script of tests/cross_version.py: writes (make) or reads a .blend with Myoskin state and prints
its state as one JSON line "state: {...}" (muscles and every stored setting, bind record, joint bones,
vertex groups, locators), then re-saves it (resave) so the next Blender reads this one's file.

    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python blend_state.py -- \\
        make|resave FILE.blend [OUT.blend]
"""
import json
import sys

import bpy

mode, path = sys.argv[sys.argv.index("--") + 1:][:2]
if mode == "make":
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=2) == {'FINISHED'}
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    arm = bpy.context.view_layer.objects.active.parent
    state = arm.myoskin
    state.muscles[0].enabled = False
    state.muscles[1].bulge, state.muscles[1].joints = 2.5, 6
    state.muscles[1].wrap_type = 'none'
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    state.live = False
    bpy.ops.wm.save_as_mainfile(filepath=path)
else:
    bpy.ops.wm.open_mainfile(filepath=path)

arms = [o for o in bpy.data.objects if o.type == 'ARMATURE' and len(o.myoskin.muscles)]
assert len(arms) == 1, f"{len(arms)} armatures with muscles after opening {path}"
arm = arms[0]
state = arm.myoskin
rig_io = next(m for n, m in sorted(sys.modules.items()) if n == "myoskin.rig_io" or n.endswith(".myoskin.rig_io"))
summary = {
    "muscles": [{k: (list(getattr(m, k)) if k.endswith("_rest") else getattr(m, k))
                 for k in ("name", "enabled", "region", "confidence", "data", "bulge", "joints", "wrap_type",
                           "wrap_bone", "wrap_radius", "wrap_side", "origin_rest", "insertion_rest",
                           "origin_bone", "insertion_bone")}
                | {"locators": [getattr(m, k).name if getattr(m, k) else None
                                for k in ("origin_locator", "insertion_locator", "surface")]}
                for m in state.muscles],
    "skin": state.skin.name if state.skin else None, "bound": state.bound, "dirty": state.dirty,
    "live": state.live, "auto_rebind": state.auto_rebind, "active_index": state.active_index,
    "muscles_text": state.muscles_text.as_string() if state.muscles_text else None,
    "bind_text": state.bind_text.as_string() if state.bind_text else None,
    "joint_bones": sorted(rig_io.muscle_bone_names(arm)),
    "vertex_groups": sorted(g.name for g in state.skin.vertex_groups) if state.skin else [],
}
print("state: " + json.dumps(summary, sort_keys=True))
if mode == "resave":
    bpy.ops.wm.save_as_mainfile(filepath=sys.argv[sys.argv.index("--") + 3])
