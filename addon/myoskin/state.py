# SPDX-License-Identifier: GPL-3.0-or-later
"""Where muscles live in the .blend (decision; see README "Muscle state in the .blend").

Everything is stored on the character's ARMATURE OBJECT, so it is saved with the file, survives reload and
undo, and is readable without the add-on (ID properties and a Text datablock need no registered classes):

    armature_obj.myoskin                  MyoskinRigState (PointerProperty on bpy.types.Object)
        .skin                             the (first) skinned mesh object the muscles belong to
        .skins[i].object                  every mesh of the character the muscles belong to (Extract with
                                          the armature active: all the meshes it deforms; with a mesh
                                          active: that mesh); Bind, Unbind and the bakes act on all of them
        .collection                       the "Muscles" collection holding the muscle surface objects
        .muscles_text                     Text datablock "<armature>.muscles.json": the whole muscles.json
                                          (format myoskin.muscles v1), rewritten after every change
        .muscles[i]                       MyoskinMuscle, one per muscle, in muscles.json order:
            name, enabled, region, confidence
            data                          this muscle's full geometry as a one-muscle muscles.json document
                                          (root curve, sections, origin/insertion, wrap, bulge, joints)
            bulge, joints                 bulge factor k, muscle-joint count (win over `data`)
            wrap_type/bone/radius/side    action-path wrap (win over `data`)
            origin_bone, insertion_bone   attachment bones (win over `data`)
            origin_locator, insertion_locator, wrap_locator   empties (positions win over `data`)
            origin_rest, insertion_rest   the attachment positions last built (a locator moved elsewhere
                                          re-attaches the muscle)
            surface                       the muscle's mesh object
        .active_index                     the UI list's selection
        .bound, .dirty                    muscle joints are bound to the rig / edited since the bind (a
                                          bulge change is applied to the bound rig at once)
        .live                             live update on (off: the baked Action plays)
        .preserve_volume                  Bind sets the Armature modifiers' use_deform_preserve_volume to it
        .volume_blend                     Bind adds the volume blend (share group myoskin_dqs_share, a second
                                          Armature modifier with Preserve Volume + Multi Modifier after the first,
                                          which stays linear over the group myoskin_linear); a bound rig follows
                                          a switch at once; Unbind removes all of it
        .joints_slide                     Bind builds the MuscleRig with joints_slide (the bind record keeps it,
                                          and with it on the joints' slide limits Bind computes from the weights;
                                          a switch on a bound rig binds again with Auto Rebind, else marks it
                                          edited)
        .bind_text                        Text datablock "<armature>.bind.json", the bind record: skeleton
                                          (names, parents, heads, tails, rest), the bound muscles' json,
                                          joint names, surface object names (live update rebuilds from it)
        .bone_roles[i]                    MyoskinBoneRole, one per bone, as Detect (or Extract) last saw them:
            name                          the bone
            detected                      the role the core gave it from the bone tree ('' = not detected)
            role                          the role Extract uses; an OVERRIDE where it differs from `detected`
                                          (role_overrides; passed to the core as bone_roles=)
    skin_obj["myoskin_original_weights"]  ID property on every bound mesh: its vertex groups before Bind
                                          (Unbind restores them exactly)
    skin_obj["myoskin_added_groups"]      the skeleton bones' vertex groups Bind created (bones the mesh had
                                          no group of); Unbind removes them again
        .jiggle, .skin_solve, .temporal_filter, .jiggle_frequency/damping/amount   the Dynamics panel's settings
    skin_obj vertex group "myoskin_jiggle"  the painted jiggle map (dynamics.py)
    skin_obj["myoskin_sculpt"] + mesh attributes myoskin_sculpt_delta / myoskin_sculpt_framed   sculpt deltas
                                          (dynamics.py: JSON description + the core's local deltas per vertex)

Converting this to and from core Muscle lists is muscle_io's job; no core call here (only property
definitions and their update callbacks, which hand the work to the layers above through runtime.dispatch;
handlers.register connects them). Layer: core data. Imports only runtime.
"""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty,
                       PointerProperty, StringProperty)

from . import runtime

WRAP_TYPES = (
    ('none', "None", "Straight action path from origin to insertion"),
    ('joint', "Joint", "Wrap around a sphere at the head of the wrap bone (the joint)"),
    ('bone', "Bone", "Wrap around a cylinder around the wrap bone"),
)
WRAP_SIDES = (
    ('1', "+", "Wrap one way round the cylinder"),
    ('-1', "-", "Wrap the other way round"),
)


def _dispatching(event, failure):
    """A property update callback: runtime.dispatch(event, armature, item) (the handlers' work), and on an error the
    message `failure` (formatted with item= the item's name, rig= the armature's) where the user sees it: an update
    callback must never raise into the UI."""
    def update(self, context):
        arm_obj = self.id_data
        try:
            runtime.dispatch(event, arm_obj, self)
        except Exception as e:  # noqa: BLE001
            runtime.report_error(arm_obj, f"{failure.format(item=getattr(self, 'name', ''), rig=arm_obj.name)}: {e}")
    return update


# A muscle setting changed: its wrap display and the muscles.json text follow (handlers.on_settings_changed).
_settings_changed = _dispatching("settings_changed", "could not apply the change to '{item}'")
_name_changed = _dispatching("renamed", "could not rename '{item}'")
_preserve_volume_changed = _dispatching("preserve_volume_changed", "could not switch Preserve Volume of '{rig}'")
_volume_blend_changed = _dispatching("volume_blend_changed", "could not switch Volume Blend of '{rig}'")
_live_changed = _dispatching("live_changed", "could not switch live update of '{rig}'")
_joints_slide_changed = _dispatching("joints_slide_changed", "could not switch Joints Slide of '{rig}'")


class MyoskinMuscle(bpy.types.PropertyGroup):
    name: StringProperty(name="Name", description="Muscle name (its joints become <name>.j<k>)",
                         update=_name_changed)
    previous_name: StringProperty(options={'HIDDEN'})
    enabled: BoolProperty(name="Enabled", description="Use this muscle when binding (disabled muscles keep "
                                                      "their data but get no joints)", default=True,
                          update=_settings_changed)
    region: StringProperty(name="Region", description="Skin region the muscle was extracted from")
    confidence: FloatProperty(name="Confidence", min=0.0, max=1.0)
    data: StringProperty(name="Data", description="Full muscle geometry (muscles.json, one muscle)",
                         options={'HIDDEN'})
    bulge: FloatProperty(name="Bulge", description="Bulge factor k: how much of the thickening goes to the "
                                                   "belly (0 = uniform; volume is constant for every k)",
                         default=1.0, min=0.0, soft_max=4.0, update=_settings_changed)
    joints: IntProperty(name="Joints", description="Muscle joints (deform bones) along the action path",
                        default=4, min=1, soft_max=16, update=_settings_changed)
    wrap_type: EnumProperty(name="Wrap", items=WRAP_TYPES, default='none', update=_settings_changed)
    wrap_bone: StringProperty(name="Wrap Bone", description="Joint wrap: sphere at this bone's head; bone "
                                                            "wrap: cylinder around this bone",
                              update=_settings_changed)
    wrap_radius: FloatProperty(name="Wrap Radius", default=0.03, min=0.0, soft_max=0.3, subtype='DISTANCE',
                               unit='LENGTH', update=_settings_changed)
    wrap_side: EnumProperty(name="Wrap Side", items=WRAP_SIDES, default='1', update=_settings_changed)
    origin_rest: FloatVectorProperty(size=3, options={'HIDDEN'}, description="Stored origin (armature space)")
    insertion_rest: FloatVectorProperty(size=3, options={'HIDDEN'}, description="Stored insertion")
    origin_bone: StringProperty(name="Origin Bone")
    insertion_bone: StringProperty(name="Insertion Bone")
    origin_locator: PointerProperty(name="Origin Locator", type=bpy.types.Object)
    insertion_locator: PointerProperty(name="Insertion Locator", type=bpy.types.Object)
    wrap_locator: PointerProperty(name="Wrap Display", type=bpy.types.Object)
    surface: PointerProperty(name="Surface", type=bpy.types.Object)
    jiggle_frequency: FloatProperty(
        name="Jiggle Frequency", default=0.0, min=0.0, soft_max=20.0, unit='NONE',
        description="This muscle's natural frequency in Hz when jiggling (0 = the rig's, scaled by muscle size)")
    jiggle_damping: FloatProperty(
        name="Jiggle Damping", default=-1.0, min=-1.0, max=4.0,
        description="This muscle's damping as a fraction of critical (-1 = the rig's)")


BONE_ROLES = (
    ('ignore', "Ignore", "No cutting planes around this bone"),
    ('limb', "Limb", "A limb segment: planes across the bone (arm, leg, tail)"),
    ('shoulder', "Shoulder", "A shoulder or hip girdle: planes around the joint"),
    ('neck', "Neck", "The neck: planes across it"),
    ('spine', "Spine", "The trunk: horizontal planes over the abdomen and chest"),
    ('pelvis', "Pelvis", "The pelvis / hips (the root of the legs)"),
)
ROLE_NAMES = tuple(r[0] for r in BONE_ROLES)


class MyoskinBoneRole(bpy.types.PropertyGroup):
    name: StringProperty(name="Bone", description="The bone")
    detected: StringProperty(name="Detected Role", description="The role the core detected from the bone tree "
                                                               "('' = not detected)", options={'HIDDEN'})
    role: EnumProperty(name="Role", items=BONE_ROLES, default='ignore',
                       description="The role Extract gives this bone (an override where it differs from the "
                                   "detected role)")

    @property
    def overridden(self):
        return self.role != self.detected


class MyoskinSkin(bpy.types.PropertyGroup):
    object: PointerProperty(name="Mesh", type=bpy.types.Object, description="A mesh of the character")


class MyoskinRigState(bpy.types.PropertyGroup):
    skin: PointerProperty(name="Skin", type=bpy.types.Object, description="The (first) skinned mesh of the muscles")
    skins: CollectionProperty(type=MyoskinSkin, name="Skins",
                              description="Every mesh of the character the muscles belong to")
    collection: PointerProperty(name="Muscles Collection", type=bpy.types.Collection)
    muscles_text: PointerProperty(name="muscles.json", type=bpy.types.Text)
    muscles: CollectionProperty(type=MyoskinMuscle)
    active_index: IntProperty(name="Active Muscle", default=0, min=0)
    bound: BoolProperty(name="Bound", description="Muscle joints are deform bones of this armature")
    dirty: BoolProperty(name="Edited Since Bind", description="Muscles changed after the bind: bind again")
    live: BoolProperty(name="Live Update", default=True, update=_live_changed,
                       description="Move muscle joints (and the muscle surfaces) whenever the skeleton moves; "
                                   "off: the baked Action plays (also without the add-on)")
    auto_rebind: BoolProperty(name="Auto Rebind", default=True,
                              description="When a locator of a bound muscle moves, bind again once it is still, "
                                          "so the muscle joints follow (Object Mode)")
    preserve_volume: BoolProperty(
        name="Preserve Volume", default=True, update=_preserve_volume_changed,
        description="Skin with the Armature modifier's Preserve Volume (dual quaternions) on the skeleton and "
                    "the muscle joints together, so bent joints keep their volume; Bind sets it on the "
                    "character's Armature modifiers (at once when bound) and Bake PC2 computes the same mode "
                    "in the core. Off: linear blending, as the paper")
    volume_blend: BoolProperty(
        name="Volume Blend", default=True, update=_volume_blend_changed,
        description="Mix the linear and the dual-quaternion skin per vertex so bent joints keep their volume: "
                    "Preserve Volume's dual quaternions where they keep it (elbows, shoulders), less where they "
                    "over-inflate (hips, some knees). Bind writes the share as the vertex group "
                    "'myoskin_dqs_share' and adds a second Armature modifier (Preserve Volume, Multi Modifier) "
                    "after the first, which turns linear; Unbind removes both. Overrides Preserve Volume; a bound "
                    "rig follows at once (one bound with it off binds again first; Muscle Joints deformer)")
    joints_slide: BoolProperty(
        name="Joints Slide", default=True, update=_joints_slide_changed,
        description="Muscle joints ride their stations of the action path, so a shortening muscle carries the skin "
                    "over its belly along the limb (the paper), each no further along its bone than the skin it "
                    "carries follows without folding (Bind measures that from the weights, where they fade). Off: "
                    "along its bone a joint moves as the bone does; "
                    "the muscle still lifts, turns and bulges it. On some bodies off folds the skin on itself less "
                    "at mid-angle elbows under the Volume Blend, but linear and Preserve Volume skinning lose the "
                    "elbow's crease. A bound rig binds again (Auto Rebind; else Bind again)")
    deformer: EnumProperty(
        name="Deformer", default='JOINTS',
        items=(('JOINTS', "Muscle Joints", "The paper's Equation 3: the muscle joints are deform bones blended with "
                "the skeleton's weights by the Armature modifier (plays without the add-on once baked)"),
               ('ANCHORED', "Anchored Skin", "Each skin vertex anchored to the nearest muscle ellipsoid, bone "
                "capsule or joint sphere (Schneider & Wilhelms; Arabaci), computed by the core every frame and "
                "shown through a Geometry Nodes modifier; the Armature modifier is switched off while bound. "
                "Needs the add-on to play; Bake PC2 for farms")),
        description="How Bind deforms the skin (takes effect at the next Bind)")
    jiggle: BoolProperty(name="Jiggle", default=False,
                         description="Bake Muscle Action simulates jiggle: each muscle's mass on a damped spring "
                                     "behind its bones (Gray & Hutchinson), baked into the muscle joints' keys")
    skin_solve: BoolProperty(name="Skin Solve", default=False,
                             description="Bake PC2 relaxes the skin every frame and pushes it out of the posed muscles "
                                         "so it slides over them (Gray & Hutchinson's skin solve)")
    temporal_filter: BoolProperty(name="Temporal Filter", default=True,
                                  description="With Skin Solve: Bake PC2 pulls back what the solve adds where it "
                                              "jitters from frame to frame (smooth motion passes unchanged)")
    jiggle_frequency: FloatProperty(name="Frequency", default=5.0, min=0.05, soft_max=20.0,
                                    description="Natural frequency in Hz of a muscle of the median size (smaller "
                                                "muscles are stiffer)")
    jiggle_damping: FloatProperty(name="Damping", default=0.3, min=0.0, max=4.0,
                                  description="Damping as a fraction of critical (1 = no overshoot)")
    jiggle_amount: FloatProperty(name="Amount", default=1.0, min=0.0, soft_max=3.0,
                                 description="Multiplies every muscle's jiggle (0 = none)")
    max_influences: IntProperty(name="Max Influences", default=8, min=1, max=16,
                                description="Bones and muscle joints per skin vertex after Bind (the largest "
                                            "are kept and renormalised; 4 is what game engines take)")
    bind_text: PointerProperty(name="Bind Record", type=bpy.types.Text,
                               description="<armature>.bind.json: what Bind built (live update rebuilds from it)")
    bone_roles: CollectionProperty(type=MyoskinBoneRole, name="Bone Roles",
                                   description="Per bone: the detected role and the one Extract uses")
    bone_role_index: IntProperty(name="Active Bone Role", default=0, min=0, options={'HIDDEN'})


def rig_skins(arm_obj):
    """The meshes of the character an armature's muscles belong to (those still in the file), in order;
    files from before several meshes were stored give [skin]."""
    state = rig_state(arm_obj)
    if state is None:
        return []
    skins = [s.object for s in state.skins if s.object is not None and s.object.name in bpy.data.objects]
    if not skins and state.skin is not None and state.skin.name in bpy.data.objects:
        skins = [state.skin]
    return skins


def set_rig_skins(arm_obj, skins):
    """Record the meshes of the character (state.skin = the first)."""
    state = rig_state(arm_obj)
    state.skins.clear()
    for obj in skins:
        state.skins.add().object = obj
    state.skin = skins[0] if skins else None


def role_overrides(arm_obj):
    """{bone: role} the user set against the detected roles (what Extract passes as bone_roles=)."""
    state = rig_state(arm_obj)
    if state is None:
        return {}
    return {item.name: item.role for item in state.bone_roles if item.role != item.detected}


def missing_role_bones(arm_obj):
    """Bones named by a role override that the armature no longer has (renamed or deleted), sorted."""
    bones = arm_obj.data.bones
    return sorted(b for b in role_overrides(arm_obj) if b not in bones)


def set_role_overrides(arm_obj, overrides):
    """Replace the overrides by `overrides` ({bone: role}); ValueError naming an unknown role. Bones without an
    item get one (detected '' until the next Detect)."""
    bad = {b: r for b, r in overrides.items() if r not in ROLE_NAMES}
    if bad:
        bone, role = next(iter(sorted(bad.items())))
        raise ValueError(f"bone '{bone}': unknown role '{role}' ({', '.join(ROLE_NAMES)})")
    state = rig_state(arm_obj)
    for item in state.bone_roles:
        if item.name not in overrides:
            if item.detected:
                item.role = item.detected
    stale = [i for i, item in enumerate(state.bone_roles) if not item.detected and item.name not in overrides]
    for i in reversed(stale):
        state.bone_roles.remove(i)
    items = {item.name: item for item in state.bone_roles}
    for bone, role in overrides.items():
        item = items.get(bone)
        if item is None:
            item = state.bone_roles.add()
            item.name = bone
        item.role = role


def set_detected_roles(arm_obj, detected):
    """Store the detected roles ({bone: role}, in bone order) and keep the overrides of bones still there.
    Returns the overrides dropped because their bone is gone ({bone: role})."""
    state = rig_state(arm_obj)
    overrides = role_overrides(arm_obj)
    state.bone_roles.clear()
    for bone, role in detected.items():
        item = state.bone_roles.add()
        item.name, item.detected = bone, role
        item.role = overrides.get(bone, role)
    return {b: r for b, r in overrides.items() if b not in detected}


def clear_role_overrides(arm_obj):
    """Every bone back to its detected role; items of bones never detected are removed. Returns how many
    overrides were cleared."""
    state = rig_state(arm_obj)
    cleared = len(role_overrides(arm_obj))
    for i in reversed(range(len(state.bone_roles))):
        item = state.bone_roles[i]
        if item.detected:
            item.role = item.detected
        else:
            state.bone_roles.remove(i)
    return cleared


def role_chains(arm_obj):
    """The bones with a role other than ignore grouped into chains for display: [(role, [item, ...])], each a
    run of bones of one role from parent to child (a bone whose parent has another role, or none, starts a
    chain; it continues through the first child of the same role). Ordered by the chains' first bones."""
    state = rig_state(arm_obj)
    if state is None:
        return []
    items = {item.name: item for item in state.bone_roles}
    bones = arm_obj.data.bones
    chains = []
    for item in state.bone_roles:
        if item.role == 'ignore':
            continue
        bone = bones.get(item.name)
        parent = bone.parent if bone is not None else None
        parent_item = items.get(parent.name) if parent is not None else None
        if parent_item is not None and parent_item.role == item.role and \
                _first_child_of_role(bones.get(parent.name), items, item.role) == item.name:
            continue  # continues its parent's chain
        chain = [item]
        while bone is not None:
            child = _first_child_of_role(bone, items, item.role)
            if child is None:
                break
            chain.append(items[child])
            bone = bones.get(child)
        chains.append((item.role, chain))
    return chains


def _first_child_of_role(bone, items, role):
    if bone is None:
        return None
    for child in bone.children:
        item = items.get(child.name)
        if item is not None and item.role == role:
            return child.name
    return None


def rig_state(arm_obj):
    """The MyoskinRigState of an armature object (None for anything else)."""
    if arm_obj is None or arm_obj.type != 'ARMATURE':
        return None
    return arm_obj.myoskin


LIMITS = (
    ('ALL', "Whole Skin", "Extract everywhere"),
    ('SELECTED', "Selected Vertices", "Extract only where vertices are selected"),
    ('GROUP', "Vertex Group", "Extract only inside a vertex group"),
)


class MyoskinSceneSettings(bpy.types.PropertyGroup):
    """The sidebar's tool settings (what the buttons pass to the operators)."""
    # Named for its unit: a .blend saved when the spacing was in metres keeps that value under the old name, unused.
    spacing_radii: FloatProperty(name="Section Spacing", description="Distance between cutting planes in limb radii "
                           "(the body's median limb radius; 0 = automatic: 1/80 of the character's extent)",
                           default=0.0, min=0.0, soft_max=4.0)
    min_confidence: FloatProperty(name="Min Confidence", description="Drop muscles less significant than this",
                                  default=0.5, min=0.0, max=1.0)
    joint_wrap: FloatProperty(name="Joint Wrap", description="A muscle crossing a joint wraps round it on a "
                              "sphere of this times its thickness, so it bends with the skeleton (0 = straight)",
                              default=0.3, min=0.0, soft_max=1.0)
    max_per_region: IntProperty(name="Max per Region", description="Keep at most this many muscles (the most "
                                "confident) per region (0 = all)", default=0, min=0, soft_max=10)
    expert: StringProperty(name="Expert", description="Expert tuning, not for everyday use: a JSON object "
                           "{key: value} of the core's extraction options (e.g. {\"filters.minEvidence\": 7})",
                           default="")
    limit: EnumProperty(name="Limit To", items=LIMITS, default='ALL')
    vertex_group: StringProperty(name="Vertex Group", description="Region for Limit To / Add Muscle")
    region_source: EnumProperty(name="Region", items=(
        ('FACES', "Selected Faces", "The faces selected on the skin"),
        ('GROUP', "Vertex Group", "The vertices of the vertex group above")), default='FACES')
    show_ignored: BoolProperty(name="Ignored Bones", default=False,
                               description="List the bones Extract ignores (to give one of them a role)")
    frame_start: IntProperty(name="Start", default=1)
    frame_end: IntProperty(name="End", default=120)
    export_path: StringProperty(name="glTF", subtype='FILE_PATH', default="//character.glb")
    pc2_path: StringProperty(name="PC2", subtype='FILE_PATH', default="//skin.pc2")


classes = (MyoskinMuscle, MyoskinBoneRole, MyoskinSkin, MyoskinRigState, MyoskinSceneSettings)


def register():
    bpy.types.Object.myoskin = PointerProperty(type=MyoskinRigState)
    bpy.types.Scene.myoskin_ui = PointerProperty(type=MyoskinSceneSettings)


def unregister():
    for owner, attr in ((bpy.types.Scene, "myoskin_ui"), (bpy.types.Object, "myoskin")):
        if hasattr(owner, attr):
            delattr(owner, attr)
