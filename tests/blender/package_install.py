# SPDX-License-Identifier: GPL-3.0-or-later
"""Child script of test_package.py, run in a Blender with empty user folders: installs the package as a
user does (Get Extensions > Install from Disk on 4.2+, Preferences > Add-ons > Install on 3.4), then
uses it: synthetic arm, Extract, Bind, Bake, saved to OUT.blend. Prints "package: NAME" and
"python: X.Y" for the test to check.

    blender -b --factory-startup --python-exit-code 1 --python package_install.py -- ZIP OUT.blend
"""
import importlib
import sys

import addon_utils
import bpy

zip_path, out = sys.argv[sys.argv.index("--") + 1:][:2]
if bpy.app.version >= (4, 2, 0):
    assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                    enable_on_install=True) == {'FINISHED'}
    package = "bl_ext.user_default.myoskin"
else:
    assert bpy.ops.preferences.addon_install(filepath=zip_path) == {'FINISHED'}
    package = "myoskin"
    addon_utils.enable(package, default_set=True)
assert package in bpy.context.preferences.addons, list(bpy.context.preferences.addons.keys())
loader = importlib.import_module(f"{package}.core_loader")
assert loader.available(), loader.status().message
prefs = importlib.import_module(f"{package}.preferences")
assert prefs.ADDON_PACKAGE == package and prefs.get_preferences().joints_per_muscle == 4
print(f"package: {package}")
print(f"python: {loader.core().build_info()['python_version']}")
bpy.ops.wm.read_homefile(use_empty=True)
assert bpy.ops.myoskin.add_synthetic_arm(seed=1) == {'FINISHED'}
assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
assert bpy.ops.myoskin.bind() == {'FINISHED'}
assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=3) == {'FINISHED'}
bpy.ops.wm.save_as_mainfile(filepath=out)
print("package_install: done")
