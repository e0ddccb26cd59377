# SPDX-License-Identifier: GPL-3.0-or-later
"""Myoskin in batch (background) mode: extract, bind, bake and export without the UI.

    blender -b character.blend --python-exit-code 1 -P addon/myoskin/batch.py -- \\
        extract --bind --bake 1-120 -o out.blend
    blender -b --python-exit-code 1 -P addon/myoskin/batch.py -- \\
        --input character.glb extract --bind --bake 1-120 --gltf out.glb --pc2 skin.pc2 -o out.blend

Steps run in this order, each optional: import (--input .glb/.gltf/.blend), extract, --bind, --bake A-B
(muscle joints keyed into the armature's Action), --pc2 FILE (the skin over the bake range, computed by the
core; a character of several meshes gets one file per mesh, FILE_<mesh>.pc2), --gltf FILE (skin + armature
+ helper bones + Actions), -o FILE.blend. A farm splits a bake into chunks run by separate processes: each `--bake A-B --pc2
FILE_A.pc2 [--jiggle] [--skin-solve] [--jiggle-start F] --state-in PREV.json --state-out NEXT.json` continues the
simulation from the state file the chunk before wrote, and the chunks' frames equal one bake's bit for bit (the
jiggled Action's keys too: its state goes to NEXT.action.json beside the PC2's, read back from PREV.action.json).
The add-on must be findable
(BLENDER_USER_SCRIPTS=<build>/blender_scripts, or installed); it is enabled here when it is not. Errors
print one line "myoskin batch: error: ..." and exit with status 1 (with --python-exit-code 1 for Python
exceptions too).

The character is the scene's armature and every mesh it deforms (several skinned meshes, e.g. Body, Feet,
Head, Legs, are analysed as one surface and all bound); `--object MESH` uses that mesh alone, `--object
ARMATURE` picks one character when the scene holds several. Meshes of the armature without weights of its
bones are skipped, and the log says so, as it names the skin components left out of the analysis (eyes,
hair, helmets: small or rigidly bound to one bone) per mesh. `--roles ROLES.json` ({"bone": "role"}) sets the
bone role overrides extraction uses (stored in the saved file). When nothing can be analysed (no limb chain
recognised, every section skipped) batch exits 1 with "myoskin batch: error: nothing could be analysed: <why>";
when sections were analysed but no muscle stands out, it goes on and logs "found no muscles: <why>".
"""
import argparse
import importlib
import json
import os
import sys
import time

import bpy


def expert_options(args):
    """--options FILE.json, then each --expert KEY=VALUE (a number, true or false): {key: value}."""
    options = {}
    if args.options:
        try:
            with open(args.options) as f:
                options = json.load(f)
        except (OSError, ValueError) as e:
            fail(f"--options {args.options}: {e}")
        if not isinstance(options, dict):
            fail(f"--options {args.options}: an options file is an object {{\"key\": value}}")
    for item in args.expert:
        key, eq, text = item.partition("=")
        if not eq or not key:
            fail(f"--expert needs KEY=VALUE, got '{item}'")
        if text in ("true", "false"):
            options[key] = text == "true"
        else:
            try:
                options[key] = float(text)
            except ValueError:
                fail(f"--expert {key} needs a number or true/false, got '{text}'")
    return options


def parse_args(argv):
    p = argparse.ArgumentParser(prog="batch.py", description="Myoskin batch: extract, bind, bake, export")
    p.add_argument("command", nargs="?", choices=("extract", "none"), default="none",
                   help="extract: (re-)extract the muscles; none: use the muscles already in the file")
    p.add_argument("--input", "-i", help="a .blend, .glb or .gltf to open first (default: the open file)")
    p.add_argument("--object", help="a skinned mesh to use alone, or an armature (default: the scene's one armature "
                                    "with every mesh it deforms: the whole character)")
    p.add_argument("--spacing", type=float, default=-1.0,
                   help="section spacing in limb radii (the body's median limb radius; 0 = automatic, default: the "
                        "add-on's preferences)")
    p.add_argument("--min-confidence", type=float, default=-1.0, help="in [0, 1]; default: the add-on's preferences")
    p.add_argument("--min-sections", type=int, default=-1, help="significant sections a muscle needs (default: the "
                                                                 "add-on's preferences)")
    p.add_argument("--max-per-region", type=int, default=0, help="keep the most confident per region (0 = all)")
    p.add_argument("--joint-wrap", type=float, default=0.3,
                   help="a muscle crossing a joint wraps round it on a sphere of this times its thickness (0 = off)")
    p.add_argument("--options", metavar="EXPERT.json",
                   help="expert extraction tuning: a JSON object {key: value} (the CLI's --options; keys: Python "
                        "_core.extraction_options())")
    p.add_argument("--expert", action="append", default=[], metavar="KEY=VALUE",
                   help="one expert extraction option, after --options (repeatable; the CLI's --expert)")
    p.add_argument("--roles", metavar="ROLES.json",
                   help="bone role overrides for extract, {\"bone\": \"role\"} (roles: ignore, limb, shoulder, neck, "
                        "spine, pelvis; the CLI's format); they replace the overrides stored in the file")
    p.add_argument("--bind", action="store_true", help="bind the muscles to the armature")
    p.add_argument("--deformer", choices=("joints", "anchored"), default=None,
                   help="with --bind: muscle joints (Equation 3, the default) or the anchored skin")
    p.add_argument("--volume-blend", choices=("on", "off"), default=None,
                   help="with --bind: the volume blend (linear and dual-quaternion skin mixed per vertex so joints "
                        "keep their volume; default: the rig's setting, on)")
    p.add_argument("--joints-slide", choices=("on", "off"), default=None,
                   help="with --bind: muscle joints ride their action paths along the limb (on, the paper; default: "
                        "the rig's setting, on) or move along their bones as the bones do (off: on some bodies less "
                        "skin folding on itself under the volume blend; less crease in linear and Preserve Volume)")
    p.add_argument("--max-influences", type=int, default=0, metavar="N",
                   help="bones and muscle joints per vertex after --bind (default: the rig's setting, 8; 4 for game engines)")
    p.add_argument("--bake", metavar="A-B", help="bake the muscle joints to keyframes over frames A-B")
    p.add_argument("--jiggle", action="store_true",
                   help="with --bake: simulate the muscles' jiggle into the baked keys (the rig's Jiggle settings)")
    p.add_argument("--jiggle-start", type=int, default=None, metavar="F",
                   help="with --jiggle: the frame the simulation starts from (a farm chunk --bake A-B of a longer "
                        "bake from F: keyed over A-B, simulated from F, so chunks join exactly; with --pc2 too)")
    p.add_argument("--pc2", metavar="FILE", help="bake the skin to a PC2 cache (needs --bind and --bake)")
    p.add_argument("--skin-solve", action="store_true",
                   help="with --pc2: solve the skin against the posed muscles every frame (it slides over them)")
    p.add_argument("--filter", action="store_true",
                   help="with --pc2 --skin-solve: the temporal filter on what the solve adds")
    p.add_argument("--state-in", metavar="S.json",
                   help="with --pc2 or --jiggle: a farm chunk continues the simulation (the PC2's and the jiggled "
                        "Action's) from the state file the chunk before it wrote (--state-out), instead of replaying "
                        "from --jiggle-start (default: the state's start); it may be the --state-out file")
    p.add_argument("--state-out", metavar="S.json",
                   help="with --pc2 or --jiggle: write the simulation state of frame B - 1 of --bake A-B, for the next "
                        "chunk's --state-in (chunks then stitch bit for bit to one bake)")
    p.add_argument("--gltf", metavar="FILE", help="export skin + armature + helper bones to glTF")
    p.add_argument("-o", "--output", metavar="FILE.blend", help="save the result")
    return p.parse_args(argv)


def fail(message):
    print(f"myoskin batch: error: {message}", file=sys.stderr, flush=True)
    sys.exit(1)


def log(message, start=[time.perf_counter()]):  # noqa: B006 (process start)
    print(f"[myoskin batch {time.perf_counter() - start[0]:6.1f} s] {message}", flush=True)


def _is_myoskin(name):
    return name == "myoskin" or name.endswith(".myoskin")


def addon_package():
    """The add-on's package name, never assumed: "myoskin" (a user-scripts folder or the legacy zip) or
    "bl_ext.<repository>.myoskin" (an extension). Prefers an enabled one, then the one holding this file."""
    enabled = sorted(n for n in bpy.context.preferences.addons.keys() if _is_myoskin(n))
    if enabled:
        return enabled[0]
    import addon_utils
    here = os.path.dirname(os.path.abspath(__file__))
    found = sorted((m.__name__, os.path.dirname(os.path.abspath(m.__file__)))
                   for m in addon_utils.modules() if _is_myoskin(m.__name__))
    beside = [name for name, folder in found if folder == here]
    return (beside or [name for name, _ in found] or ["myoskin"])[0]


def addon(submodule):
    """A submodule of the enabled add-on (e.g. addon("core_loader"))."""
    return importlib.import_module(f"{addon_package()}.{submodule}")


def ensure_addon():
    import addon_utils
    package = addon_package()
    if package not in bpy.context.preferences.addons:
        try:
            addon_utils.enable(package, default_set=True, handle_error=lambda e: (_ for _ in ()).throw(e))
        except Exception as e:  # noqa: BLE001
            fail(f"cannot enable the myoskin add-on ({e}): install the extension, or set "
                 f"BLENDER_USER_SCRIPTS=<build>/blender_scripts")
    core_loader = addon("core_loader")
    if not core_loader.available():
        fail(core_loader.status().message)


def open_input(path):
    path = os.path.abspath(path)
    if not os.path.isfile(path):
        fail(f"no such file: {path}")
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".blend", ".glb", ".gltf"):
        fail(f"unsupported input {path}: give a .blend, .glb or .gltf")
    try:  # a damaged file: Blender's reader or glTF importer raises RuntimeError("Error: <why>")
        if ext == ".blend":
            bpy.ops.wm.open_mainfile(filepath=path)
        else:
            addon("gltf_io").check_gltf_file(path)  # an unreadable container: our message, not a traceback
            bpy.ops.wm.read_homefile(use_empty=True)
            addon("gltf_io").import_gltf(path)
    except Exception as e:  # noqa: BLE001  (the importer's own failures are not all RuntimeError)
        lines = [ln.strip() for ln in str(e).splitlines() if ln.strip() and not ln.startswith((" ", "Traceback"))]
        lines = [ln for ln in lines if not ln.startswith(("Error: Python:", "Location:"))]
        why = lines[0] if lines else type(e).__name__
        why = why[len("Error: "):] if why.startswith("Error: ") else why
        fail(f"cannot read {path} (damaged or not a {ext[1:]} file?): {why}")
    log(f"opened {path}")


def find_character(name):
    """The object to make active: --object NAME (a skinned mesh alone, or an armature and all its meshes),
    else the one armature of the scene that deforms meshes (the whole character)."""
    blender_io = addon("blender_io")
    if name:
        obj = bpy.data.objects.get(name)
        if obj is None:
            fail(f"no object '{name}'")
        if obj.type not in ('MESH', 'ARMATURE'):
            fail(f"--object '{name}' is a {obj.type.lower()}: give a skinned mesh or an armature")
        return obj
    skins = [o for o in bpy.context.scene.objects if o.type == 'MESH' and o.get("myoskin_muscle") is None
             and blender_io.find_armature(o) is not None]
    if not skins:
        fail("0 skinned meshes in the scene: nothing to extract (give a file with a mesh deformed by an armature)")
    armatures = []
    for o in skins:
        arm = blender_io.find_armature(o)
        if arm not in armatures:
            armatures.append(arm)
    if len(armatures) != 1:
        fail(f"{len(armatures)} armatures deform meshes in the scene ({', '.join(a.name for a in armatures)}): "
             f"pick one with --object")
    return armatures[0]


def run_op(op, **kwargs):
    """Call an operator; its ERROR report becomes a batch failure."""
    try:
        result = op(**kwargs)
    except RuntimeError as e:
        text = str(e).replace("Error: ", "").strip()
        if text.startswith("Nothing could be analysed"):
            text = "n" + text[1:]  # myoskin batch: error: nothing could be analysed: <why>
        fail(text)
    if result != {'FINISHED'}:
        fail(f"{op.idname()} returned {result}")


def writable_target(path):
    """None when `path` can be written, else why not."""
    folder = os.path.dirname(path) or "."
    if not os.path.isdir(folder):
        return f"folder {folder} does not exist"
    if not os.access(folder, os.W_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        return "permission denied"
    return None


def save(path):
    problem = writable_target(path)
    if problem:
        fail(f"cannot save {path}: {problem}")
    try:
        bpy.ops.wm.save_as_mainfile(filepath=path)
    except RuntimeError as e:
        fail(f"cannot save {path}: {str(e).replace('Error: ', '').strip()}")


def read_roles(path):
    """{bone: role} from a role file ({"bone": "role"}, or {"roles": {...}} as `myoskin roles -o` may write)."""
    import json
    path = os.path.abspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except OSError as e:
        fail(f"--roles {path}: cannot read it ({e.strerror or e})")
    except ValueError as e:
        fail(f"--roles {path}: not valid JSON ({e})")
    if isinstance(data, dict) and isinstance(data.get("roles"), dict):
        data = data["roles"]
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        fail(f"--roles {path}: a role file is an object {{\"bone\": \"role\"}}")
    return data


def parse_range(text):
    try:
        a, b = (int(x) for x in text.split("-"))
    except ValueError:
        fail(f"--bake wants A-B (e.g. 1-120), got {text!r}")
    if b < a:
        fail(f"--bake range {text} is empty")
    return a, b


def action_state(path, beside):
    """The jiggled Action's state file: `path` itself, or (beside a PC2's) <path without .json>.action.json."""
    if not path or not beside:
        return path
    root, ext = os.path.splitext(path)
    return f"{root}.action{ext or '.json'}"


def chunk_states(state_in, state_out):
    """The state_in / state_out keywords of a chunk's bake: state_in is copied first to a file of its own (read
    before the bake writes state_out, which may be the same file)."""
    chunk = {}
    if state_in:
        path = os.path.abspath(state_in)
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except OSError as e:
            fail(f"--state-in {path}: cannot read it ({e.strerror or e})")
        import tempfile
        handle, copy = tempfile.mkstemp(prefix="myoskin_state_", suffix=".json")
        with os.fdopen(handle, "w", encoding="utf-8") as f:
            f.write(text)
        chunk["state_in"] = copy
    if state_out:
        chunk["state_out"] = os.path.abspath(state_out)
    return chunk


def main(argv):
    args = parse_args(argv)
    for flag, value in (("--deformer", args.deformer), ("--volume-blend", args.volume_blend),
                        ("--joints-slide", args.joints_slide), ("--max-influences", args.max_influences)):
        if value and not args.bind:
            fail(f"{flag} needs --bind (a setting of the bind)")
    for target in (args.output, args.pc2, args.gltf):
        if target and writable_target(os.path.abspath(target)):
            fail(f"cannot save {os.path.abspath(target)}: {writable_target(os.path.abspath(target))}")
    ensure_addon()
    if args.input:
        open_input(args.input)
    target = find_character(args.object)
    bpy.context.view_layer.objects.active = target
    blender_io = addon("blender_io")
    arm = blender_io.find_armature(target)
    if arm is None:
        fail(f"'{target.name}' has no armature: add an Armature modifier or parent it to an armature")
    state = arm.myoskin
    if args.roles:
        if args.command != "extract":
            fail("--roles needs the extract command (the roles are what extraction uses)")
        roles = read_roles(args.roles)
        missing = sorted(b for b in roles if b not in arm.data.bones)
        if missing:
            fail(f"--roles {os.path.abspath(args.roles)}: '{arm.name}' has no bone {', '.join(repr(b) for b in missing)}")
        try:
            addon("state").set_role_overrides(arm, roles)
        except ValueError as e:
            fail(f"--roles {os.path.abspath(args.roles)}: {e}")
        log(f"bone roles: {len(roles)} override(s) from {args.roles}")
    if args.command == "extract":
        if state.bound:
            run_op(bpy.ops.myoskin.unbind)
        if args.joint_wrap < 0 or args.max_per_region < 0:  # the operator's properties would clamp them
            fail("--joint-wrap and --max-per-region must be >= 0")
        run_op(bpy.ops.myoskin.extract_muscles, spacing=args.spacing, min_confidence=args.min_confidence,
               min_sections=args.min_sections, max_per_region=args.max_per_region, joint_wrap=args.joint_wrap,
               expert=json.dumps(expert_options(args)))
        skins = [s.object.name for s in state.skins if s.object is not None]
        log(f"extracted {len(state.muscles)} muscles from {arm.name if target == arm else target.name} "
            f"({len(skins)} mesh(es): {', '.join(skins)})")
        if target == arm:
            for obj, why in blender_io.character_meshes(arm)[1]:
                log(f"skipped mesh {obj.name}: {why}")
        done = addon("operators.muscles").last_extraction.get(arm.name, {})
        for line in done.get("left_out", []):
            log(f"left out {line}")
        if not len(state.muscles):
            log(f"found no muscles: {done.get('diagnosis') or 'no significant relief'}")
        if done.get("scale_note"):
            log(f"note: {done['scale_note']}")
    if args.bind:
        if args.deformer:
            state.deformer = args.deformer.upper()
        if args.volume_blend:
            state.volume_blend = args.volume_blend == "on"
        if args.joints_slide:
            if state.deformer == 'ANCHORED':
                fail("--joints-slide is for the muscle joints deformer (the anchored skin does not use the joints)")
            state.joints_slide = args.joints_slide == "on"
        if args.max_influences:
            if not 1 <= args.max_influences <= 16:
                fail(f"--max-influences must be in 1..16, got {args.max_influences}")
            state.max_influences = args.max_influences
        run_op(bpy.ops.myoskin.bind)
        log(f"bound: {len(state.muscles)} muscles to {', '.join(s.object.name for s in state.skins if s.object)}")
    frames = parse_range(args.bake) if args.bake else None
    if args.jiggle and not frames:
        fail("--jiggle needs --bake A-B")
    jiggled = bool(args.jiggle or state.jiggle)
    if (args.state_in or args.state_out) and not (args.pc2 or (frames and jiggled)):
        fail("--state-in / --state-out need --pc2 or --jiggle (they stitch the chunks of a bake)")
    # The jiggled Action's state goes to a file of its own beside the PC2's when both are baked (the Action's joints
    # take the painted jiggle map per joint, the PC2 per vertex, so their springs' goals can differ).
    both = bool(args.pc2 and jiggled)
    pc2_chunk = chunk_states(args.state_in, args.state_out)
    action_chunk = chunk_states(action_state(args.state_in, both), action_state(args.state_out, both))
    if frames:
        if args.jiggle:
            state.jiggle = True
        extra = {"jiggle_start": args.jiggle_start} if args.jiggle_start is not None else {}
        if state.jiggle:  # a chunk's Action continues the jiggle from the state too
            extra.update(action_chunk)
        run_op(bpy.ops.myoskin.bake_action, frame_start=frames[0], frame_end=frames[1], jiggle=bool(state.jiggle),
               **extra)
        log(f"baked muscle joints{' with jiggle' if state.jiggle else ''} over frames {frames[0]}-{frames[1]}")
    if args.pc2:
        if not frames:
            fail("--pc2 needs --bake A-B for its frame range")
        if args.jiggle_start is not None:
            pc2_chunk["simulation_start"] = args.jiggle_start
        run_op(bpy.ops.myoskin.bake_pc2, filepath=os.path.abspath(args.pc2), frame_start=frames[0],
               frame_end=frames[1], skin_solve=args.skin_solve, jiggle=bool(state.jiggle),
               temporal_filter=args.filter, **pc2_chunk)
        written = addon("operators.rig").pc2_paths(os.path.abspath(args.pc2), addon("binding").bound_skins(arm))
        log(f"wrote {', '.join(written)}")
    if args.gltf:
        run_op(bpy.ops.myoskin.export_gltf, filepath=os.path.abspath(args.gltf))
        log(f"wrote {args.gltf}")
    if args.output:
        save(os.path.abspath(args.output))
        log(f"saved {args.output}")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
