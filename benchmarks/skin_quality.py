"""Skin quality at bent joints through the core: band volume change and muscle bulge for plain linear blend
skinning (LBS), dual quaternions (DQS), Myoskin (Equation 3 with the extracted muscles), Myoskin with
Preserve Volume (the core's preserve-volume skinner, Blender's dual quaternion blend, on the same hybrid
weights and transforms, muscle joints included) and the anchored skin (issue 17: the skin anchored to muscle
ellipsoids, bone capsules and joint spheres, with relaxation), with the time per frame of the anchored skin and of
Equation 3 (rig + transforms + skinner).

- band: the skin within 1.5 limb radii of the joint; its volume is the cone volume of its triangles from the
  joint's posed position (rigid motion of either side keeps it), reported as the change from rest;
- bulge: the largest outward move of the upper segment's skin over the LBS skin, along the LBS normals;
- crossings: pairs of band triangles that pass through each other (the skin folding through itself), counted
  by the core (CGAL); at rest the count is subtracted.

Used by benchmarks/bench_skin_quality.py (the table) and the Python tests (the targets).
"""
import numpy as np

# New crossing triangle pairs whose centroids lie closer than this many limb radii at rest are crumples (`crumples`):
# well inside one side of a crease, which is about two limb radii across.
CRUMPLE_RADII = 0.5

# Joints to bend, per rig naming: (label, moving bone, hinge bone, upper-segment bones, direction, degrees). The
# moving bone and its subtree turn about its head by `degrees`, about the axis perpendicular to the hinge bone and
# to `direction`: "forward"/"backward" along the character's facing (bent_pose's `facing`, +Z for MakeHuman), or
# "outward" (about the facing axis, swinging away from the body's mirror plane X = 0). Plantar flexion turns the foot
# "backward" about the same axis as the knee's flexion: the toes go down and the calf shortens (its bulge is
# measured on the lower leg's skin, the "upper segment" of the ankle).
MAKEHUMAN_JOINTS = [
    ("elbow flexion", "lowerarm01.L", "upperarm02.L", ("upperarm01.L", "upperarm02.L"), "forward", 120.0),
    ("knee flexion", "lowerleg01.L", "upperleg02.L", ("upperleg01.L", "upperleg02.L"), "backward", 120.0),
    ("shoulder abduction", "upperarm01.L", "upperarm01.L", ("shoulder01.L", "clavicle.L"), "outward", 120.0),
    ("hip flexion", "upperleg01.L", "upperleg02.L", ("pelvis.L",), "forward", 90.0),
    ("ankle plantar flexion", "foot.L", "lowerleg02.L", ("lowerleg01.L", "lowerleg02.L"), "backward", 45.0),
]
# The generator's bodies (makeSyntheticBody: Z up, facing -Y, A-pose) and Quaternius' rigs (Y up, facing +Z, T-pose).
SYNTHETIC_BODY_JOINTS = [
    ("elbow flexion", "forearm.L", "upper_arm.L", ("upper_arm.L",), "forward", 120.0),
    ("knee flexion", "shin.L", "thigh.L", ("thigh.L",), "backward", 120.0),
    ("shoulder abduction", "upper_arm.L", "upper_arm.L", ("shoulder.L",), "outward", 90.0),
    ("hip flexion", "thigh.L", "thigh.L", ("hips",), "forward", 90.0),
    ("ankle plantar flexion", "foot.L", "shin.L", ("shin.L",), "backward", 45.0),
]
# Quaternius' horse (Y up, facing +Z, x100 in its file): the front knee and the hind hock bend backward, the hind
# leg's upper segment swings forward.
HORSE_JOINTS = [
    ("front knee", "FrontLowerLeg.L", "FrontUpperLeg.L", ("FrontUpperLeg.L",), "backward", 90.0),
    ("hind hock", "BackLowerLeg.L", "BackUpperLeg.L", ("BackUpperLeg.L",), "forward", 60.0),
    ("hind stifle", "BackUpperLeg.L", "BackLeg.L", ("BackLeg.L",), "backward", 45.0),
]
QUATERNIUS_JOINTS = [
    ("elbow flexion", "LowerArm.L", "UpperArm.L", ("UpperArm.L",), "forward", 120.0),
    ("knee flexion", "LowerLeg.L", "UpperLeg.L", ("UpperLeg.L",), "backward", 120.0),
    ("shoulder abduction", "UpperArm.L", "UpperArm.L", ("Shoulder.L",), "outward", 60.0),
    ("hip flexion", "UpperLeg.L", "UpperLeg.L", ("Hips",), "forward", 90.0),
    ("ankle plantar flexion", "Foot.L", "LowerLeg.L", ("LowerLeg.L",), "backward", 45.0),
]


def _rotation(axis, degrees):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def _turned_subtree(character, pose, b, rot, centre):
    """`pose` (#B by 4 by 4) with bone index `b` and its subtree turned by the 3 by 3 `rot` about the point `centre`."""
    parents = np.asarray(character.bone_parents)
    moved = np.zeros(len(parents), bool)
    for i in range(len(parents)):  # parents come first
        moved[i] = i == b or (parents[i] >= 0 and moved[parents[i]])
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = centre - rot @ centre
    out = np.array(pose, copy=True)
    out[moved] = m @ out[moved]
    return out


def bent_pose(character, bone, hinge, direction, degrees, facing=(0.0, 0.0, 1.0)):
    """#B by 4 by 4 posed matrices: `bone` and its subtree turned about its head by `degrees`, about the axis
    perpendicular to the `hinge` bone and to `direction` (a world-space rotation; every other bone at rest)."""
    core_names = list(character.bone_names)
    heads, tails = np.asarray(character.bone_heads), np.asarray(character.bone_tails)
    rest = np.asarray(character.bone_rest)
    b = core_names.index(bone)
    h = core_names.index(hinge)
    d = tails[h] - heads[h]
    d = d / np.linalg.norm(d)
    facing = np.asarray(facing, float)
    if direction in ("forward", "backward"):
        axis = np.cross(d, facing if direction == "forward" else -facing)
    else:  # outward: about the facing axis, the tail swinging away from the mirror plane
        axis = facing if heads[b][0] > 0 else -facing
    return _turned_subtree(character, rest, b, _rotation(axis, degrees), heads[b])


def dqs(rest_vertices, joints, weights, transforms):
    """Dual quaternion skinning (rigid part of each transform), #V by 3."""
    def quat(r):
        w = np.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
        if w > 1e-6:
            return np.array([w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)])
        i = np.argmax(np.diag(r))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = np.sqrt(max(0.0, 1 + r[i, i] - r[j, j] - r[k, k])) * 2
        q = np.zeros(4)
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i], q[1 + j], q[1 + k] = s / 4, (r[j, i] + r[i, j]) / s, (r[k, i] + r[i, k]) / s
        return q

    def qmul(a, b):
        return np.stack([a[..., 0] * b[..., 0] - (a[..., 1:] * b[..., 1:]).sum(-1),
                         *(a[..., 0:1] * b[..., 1:] + b[..., 0:1] * a[..., 1:] + np.cross(a[..., 1:], b[..., 1:])).T], -1) \
            if a.ndim > 1 else np.concatenate([[a[0] * b[0] - a[1:] @ b[1:]], a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:])])

    real = np.array([quat(t[:3, :3]) for t in transforms])
    dual = np.array([0.5 * qmul(np.concatenate([[0.0], t[:3, 3]]), q) for t, q in zip(transforms, real)])
    jj = np.where(joints < 0, 0, joints)
    w = np.where(joints < 0, 0.0, weights)
    w = w / np.maximum(w.sum(1, keepdims=True), 1e-12)
    pivot = real[jj[:, 0]]
    sign = np.sign((real[jj] * pivot[:, None, :]).sum(-1))
    sign[sign == 0] = 1
    b0 = (w[..., None] * sign[..., None] * real[jj]).sum(1)
    be = (w[..., None] * sign[..., None] * dual[jj]).sum(1)
    norm = np.linalg.norm(b0, axis=1, keepdims=True)
    b0, be = b0 / norm, be / norm
    v = np.asarray(rest_vertices, float)
    # p' = p + 2 r x (r x p + w p) + 2 (w t - w0 r + r x re), with b0 = (w, r), be = (w0, re)
    w0, r = b0[:, :1], b0[:, 1:]
    we, re = be[:, :1], be[:, 1:]
    out = v + 2 * np.cross(r, np.cross(r, v) + w0 * v)
    out += 2 * (w0 * re - we * r + np.cross(r, re))
    return out


def band_volume_change(rest, posed, triangles, joint_rest, joint_posed, radius):
    """Relative volume change of the skin within `radius` of the joint (cone volume from the joint)."""
    inside = np.linalg.norm(rest - joint_rest, axis=1) <= radius
    tris = triangles[inside[triangles].all(1)]
    if len(tris) == 0:
        raise ValueError("no skin within the band")

    def cone(v, apex):
        a, b, c = v[tris[:, 0]] - apex, v[tris[:, 1]] - apex, v[tris[:, 2]] - apex
        return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0

    v0 = cone(rest, joint_rest)
    return (cone(posed, joint_posed) - v0) / abs(v0)


def band_triangles(rest, triangles, joint_rest, radius):
    """#F bools: the triangles whose three vertices lie within `radius` of the joint at rest."""
    inside = np.linalg.norm(rest - joint_rest, axis=1) <= radius
    return inside[triangles].all(1)


def with_volume_keys(core, character, rest, keys, pose):
    """#V by 3: the rest skin plus each volume key (compute_volume_keys) at its weight for `pose` (what Blender's shape
    keys give the Armature modifier)."""
    out = np.array(rest, dtype=np.float64)
    weights = core.volume_key_weights(keys, np.asarray(core.bone_local_rotations(character, pose)))
    for key, weight in zip(keys, weights):
        out[np.asarray(key["vertices"])] += weight * np.asarray(key["offsets"])
    return out


def _best_time(f, repeats=5):
    import time
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - start)
    return best


def bound_rig(core, character, muscles, hybrid_options=None, rig_options=None, slide_limit=True):
    """The rig and hybrid weights Bind (and the CLI's deform / simulate) skin with: (core.MuscleRig(character, muscles,
    **rig_options), with sliding joints and `slide_limit` rebuilt with the slide limits core.slide_limits gives its
    skin weights; hybrid weight joints; their values)."""
    rig = core.MuscleRig(character, muscles, **(rig_options or {}))
    hj, hw = core.hybrid_weights(character, rig, **(hybrid_options or {}))
    if slide_limit and rig.joints_slide:
        limits = core.slide_limits(character, rig, hj, hw)
        rig = core.MuscleRig(character, muscles, **dict(rig_options or {}, slide_limits=limits))
    return rig, hj, hw


def bind_skin(core, character, muscles, hybrid_options=None, share_options=None, rig_options=None, slide_limit=True):
    """What the default Bind gives the skin, through the core: (bound_rig's rig, hybrid weight joints and values, the
    volume blend's shares (compute_dqs_share(character, **share_options)), the volume keys fitted on that skin)."""
    rig, hj, hw = bound_rig(core, character, muscles, hybrid_options, rig_options, slide_limit)
    share = np.asarray(core.compute_dqs_share(character, **(share_options or {})))
    keys = core.compute_volume_keys(character, share, rig=rig, weight_joints=hj, weight_values=hw)
    return rig, hj, hw, share, keys


def binds_skin_at(core, character, rest, pose, rig, hj, hw, share, keys, combined_rest):
    """#V by 3: what Bind gives the skin at `pose` (bind_skin's rig, hybrid weights, shares and volume keys: the keyed
    rest skinned with the muscle joints, (1 - s) linear + s dual quaternions)."""
    state = rig.evaluate(pose)
    full = core.skinning_transforms(character, pose, rig, state["joint_matrices"])
    return np.asarray(core.skin(with_volume_keys(core, character, rest, keys, pose), hj, hw, full, dqs_share=share,
                                rest_matrices=combined_rest), float)


def skin_arrays(core, character):
    """What measure and fold_sweep read of a character: rest #V by 3, triangles, skeleton weight joints and values,
    bone names, bone heads, and the body's limb radius (extract_muscles' report)."""
    _, report = core.extract_muscles(character, build_surfaces=False)
    return (np.asarray(character.vertices), np.asarray(character.triangles), np.asarray(character.weight_joints),
            np.asarray(character.weight_values), list(character.bone_names), np.asarray(character.bone_heads),
            report["limb_radius"])


def crumples(pairs, rest_pairs, rest, triangles, limb_radius):
    """Crumples among a skin's crossing triangle pairs (`pairs`, #P by 2 from self_intersecting_pairs): the pairs not
    crossing at rest (`rest_pairs`) whose triangles' centroids lie within CRUMPLE_RADII limb radii of each other at
    rest, the skin folding on itself (an artifact of the deformation), not skin meeting skin across a crease."""
    crossing_at_rest = {tuple(p) for p in np.asarray(rest_pairs).tolist()}
    new = np.array([p for p in np.asarray(pairs).tolist() if tuple(p) not in crossing_at_rest], dtype=int).reshape(-1, 2)
    centres = rest[triangles[new.ravel()]].mean(1).reshape(-1, 2, 3)
    return int((np.linalg.norm(centres[:, 0] - centres[:, 1], axis=1) < CRUMPLE_RADII * limb_radius).sum())


def fold_sweep(core, character, muscles, joints, facing=(0.0, 0.0, 1.0), degrees=tuple(range(30, 151, 15)),
               degrees_by_label=None, rig_options=None, bound=None):
    """Per joint of `joints` (measure's table; the table's angle replaced by each of `degrees`, or of
    degrees_by_label[label] where given): dict(label, rows, crossings_at_rest: the band's pairs at rest), rows one dict
    per angle (degrees, crossings_lbs, crossings_myoskin_vk: self-intersecting band triangle pairs over rest,
    crumples_lbs, crumples_myoskin_vk: the crumples among them (`crumples`), lbs, myoskin_vk: band volume changes).
    Bind is done once for all joints (the rig made with rig_options), or given as `bound` (bind_skin's result, reused;
    then without rig_options);
    a joint whose bone is missing, or with no skin in its band (printed), is left out."""
    if bound and rig_options:
        raise ValueError("fold_sweep: give rig_options or bound (a Bind made with its own options), not both")
    rig, hj, hw, share, keys = bound or bind_skin(core, character, muscles, rig_options=rig_options)
    rest, tris, sj, sw, names, heads, limb_radius = skin_arrays(core, character)
    radius = 1.5 * limb_radius
    combined_rest = core.combined_rest_matrices(character, rig)
    out = []
    for label, bone, hinge, _upper, direction, _degrees in joints:
        if bone not in names:
            continue
        b = names.index(bone)
        mask = band_triangles(rest, tris, heads[b], radius)
        if not mask.any():  # a joint deep inside the body (a hip inside a wide pelvis)
            print(f"{label}: no skin within 1.5 limb radii of the joint, not swept")
            continue
        rest_pairs = core.self_intersecting_pairs(rest, tris, mask)
        rows = []
        for deg in (degrees_by_label or {}).get(label, degrees):
            pose = bent_pose(character, bone, hinge, direction, deg, facing)
            lbs = np.asarray(core.skin(rest, sj, sw, core.skeleton_transforms(character, pose)), float)
            vk = binds_skin_at(core, character, rest, pose, rig, hj, hw, share, keys, combined_rest)
            lbs_pairs, vk_pairs = (core.self_intersecting_pairs(x, tris, mask) for x in (lbs, vk))
            rows.append(dict(degrees=deg,
                             crossings_lbs=len(lbs_pairs) - len(rest_pairs),
                             crossings_myoskin_vk=len(vk_pairs) - len(rest_pairs),
                             crumples_lbs=crumples(lbs_pairs, rest_pairs, rest, tris, limb_radius),
                             crumples_myoskin_vk=crumples(vk_pairs, rest_pairs, rest, tris, limb_radius),
                             lbs=band_volume_change(rest, lbs, tris, heads[b], pose[b][:3, 3], radius),
                             myoskin_vk=band_volume_change(rest, vk, tris, heads[b], pose[b][:3, 3], radius)))
        out.append(dict(label=label, rows=rows, crossings_at_rest=len(rest_pairs)))
    return out


def twisted_pose(character, pose, bone, degrees):
    """`pose` (#B by 4 by 4) with `bone` and its subtree turned by `degrees` about the bone's posed Y axis (a twist)."""
    b = list(character.bone_names).index(bone)
    return _turned_subtree(character, pose, b, _rotation(pose[b][:3, 1], degrees), pose[b][:3, 3])


def joint_jumps(core, character, rig, joints, limb_radius, facing=(0.0, 0.0, 1.0), twists=(0.0, 7.0, 23.0),
                step=0.5, last=150.0):
    """Where the muscle joints jump: each joint of `joints` (measure's rows) bent from 0 to `last` degrees in `step`s,
    its bone also twisted by each of `twists` degrees; a jump is a muscle joint moving more than 0.05 limb radii and 8
    times its median step over that sweep (a muscle's path changing its way round a wrap, not a fast distal joint).
    Returns [(label, twist, degrees, joint name, move in limb radii)], in sweep order."""
    names = list(character.bone_names)
    joint_names = list(rig.joint_names)
    out = []
    for label, bone, hinge, _upper, direction, _degrees in joints:
        if bone not in names:
            continue
        for twist in twists:
            previous, steps, angles = None, [], []
            for degrees in np.arange(0.0, last + 1e-9, step):
                pose = bent_pose(character, bone, hinge, direction, degrees, facing)
                if twist:
                    pose = twisted_pose(character, pose, bone, twist)
                at = np.asarray(rig.evaluate(pose, with_surfaces=False)["joint_matrices"])[:, :3, 3]
                if previous is not None:
                    steps.append(np.linalg.norm(at - previous, axis=1))
                    angles.append(degrees)
                previous = at
            moves = np.array(steps)
            jumps = moves > np.maximum(0.05 * limb_radius, 8.0 * np.median(moves, axis=0))[None, :]
            out += [(label, twist, angles[i], joint_names[k], float(moves[i, k] / limb_radius))
                    for i, k in zip(*np.nonzero(jumps))]
    return out


def measure(core, character, muscles, joints, hybrid_options=None, facing=(0.0, 0.0, 1.0), anchored=False,
            share_options=None, rig_options=None, bound=None):
    """Per joint: dict(label, lbs, dqs, blender_dqs, myoskin, myoskin_pv, myoskin_vb, myoskin_vk band changes, bulge,
    bulge_pv, bulge_vb, bulge_vk (m, over LBS), bulge_pv_over_dqs (m, over blender_dqs), limb_radius). myoskin_vb is the
    volume blend (the hybrid weights skinned (1 - s) linear + s dual quaternions, s = compute_dqs_share(character,
    **share_options)); myoskin_vk the same with its volume keys (compute_volume_keys: what Bind gives). blender_dqs is the core's preserve-volume skinner on the skeleton weights
    (Blender's DQS, a cross-check of the numpy dqs); myoskin_pv the same skinner on the hybrid weights. With
    `anchored`: also anchored (band change), bulge_anchored (m, over LBS), crossings_anchored, and the best time per
    frame of the anchored skin (ms_anchored) and of Equation 3 (ms_eq3: rig, transforms and the skinner, built once).
    rig_options: core.MuscleRig's keyword options (joints_slide, ...), for the rig every Myoskin skin is made with;
    `bound`: bind_skin's result, reused instead (the three options are then not read). Also crumples_lbs and
    crumples_myoskin_vk: the crumples (`crumples`) among the crossing pairs."""
    if bound and (hybrid_options or share_options or rig_options):
        raise ValueError("measure: give the options or bound (a Bind made with its own options), not both")
    rig, hj, hw, share, keys = bound or bind_skin(core, character, muscles, hybrid_options, share_options, rig_options)
    anchored_skin = core.AnchoredSkin(character, muscles) if anchored else None
    rest, tris, sj, sw, names, heads, limb_radius = skin_arrays(core, character)
    bone_rest = np.asarray(character.bone_rest)
    combined_rest = core.combined_rest_matrices(character, rig)
    rows = []
    for label, bone, hinge, upper, direction, degrees in joints:
        if bone not in names:
            continue
        pose = bent_pose(character, bone, hinge, direction, degrees, facing)
        skel = core.skeleton_transforms(character, pose)
        lbs = np.asarray(core.skin(rest, sj, sw, skel), float)
        dq = dqs(rest, sj, sw, skel)
        state = rig.evaluate(pose)
        full = core.skinning_transforms(character, pose, rig, state["joint_matrices"])
        myo = np.asarray(core.skin(rest, hj, hw, full), float)
        blender_dq = np.asarray(core.skin(rest, sj, sw, skel, preserve_volume=True, rest_matrices=bone_rest), float)
        myo_pv = np.asarray(core.skin(rest, hj, hw, full, preserve_volume=True, rest_matrices=combined_rest), float)
        myo_vb = np.asarray(core.skin(rest, hj, hw, full, dqs_share=share, rest_matrices=combined_rest), float)
        myo_vk = binds_skin_at(core, character, rest, pose, rig, hj, hw, share, keys, combined_rest)
        methods = [("lbs", lbs), ("dqs", dq), ("blender_dqs", blender_dq), ("myoskin", myo), ("myoskin_pv", myo_pv),
                   ("myoskin_vb", myo_vb), ("myoskin_vk", myo_vk)]
        timing = {}
        if anchored_skin is not None:
            anch = anchored_skin.evaluate(pose)
            methods.append(("anchored", anch))
            skinner = core.Skinner(rest, hj, hw, len(full))

            def eq3():
                st = rig.evaluate(pose, with_surfaces=False)
                skinner.deform(core.skinning_transforms(character, pose, rig, st["joint_matrices"]))
            timing = dict(ms_anchored=1e3 * _best_time(lambda: anchored_skin.evaluate(pose)), ms_eq3=1e3 * _best_time(eq3))
        b = names.index(bone)
        joint_rest = heads[b]
        joint_posed = pose[b][:3, 3]
        try:
            band = {k: band_volume_change(rest, v, tris, joint_rest, joint_posed, 1.5 * limb_radius)
                    for k, v in methods}
        except ValueError:  # a joint deep inside the body (a hip inside a wide pelvis): no band to measure
            print(f"{label}: no skin within 1.5 limb radii of the joint, not measured")
            continue
        mask = band_triangles(rest, tris, joint_rest, 1.5 * limb_radius)
        rest_pairs = core.self_intersecting_pairs(rest, tris, mask)
        pairs = {k: core.self_intersecting_pairs(v, tris, mask)
                 for k, v in (("lbs", lbs), ("dqs", blender_dq), ("myoskin", myo), ("myoskin_pv", myo_pv),
                              ("myoskin_vb", myo_vb), ("myoskin_vk", myo_vk))
                 + ((("anchored", anch),) if anchored_skin is not None else ())}
        crossings = {"crossings_" + k: len(p) - len(rest_pairs) for k, p in pairs.items()}
        crossings.update({"crumples_" + k: crumples(pairs[k], rest_pairs, rest, tris, limb_radius)
                          for k in ("lbs", "myoskin_vk")})
        upper_ids = [names.index(u) for u in upper if u in names]
        dominant = sj[np.arange(len(sj)), np.argmax(sw, axis=1)]
        on_upper = np.isin(dominant, upper_ids)
        normals = np.asarray(core.vertex_normals(lbs, tris))
        def bulge_of(skin, base=lbs, base_normals=normals):
            return float(((skin - base) * base_normals).sum(1)[on_upper].max()) if on_upper.any() else float("nan")

        # With preserve volume the skin moves off LBS without muscles too (the DQS blend): the muscles' own
        # bulge in that mode is measured over the skeleton-only DQS skin.
        dq_normals = np.asarray(core.vertex_normals(blender_dq, tris))
        extra = dict(bulge_anchored=bulge_of(anch)) if anchored_skin is not None else {}
        rows.append(dict(label=label, bulge=bulge_of(myo), bulge_pv=bulge_of(myo_pv), bulge_vb=bulge_of(myo_vb),
                         bulge_vk=bulge_of(myo_vk),
                         bulge_pv_over_dqs=bulge_of(myo_pv, blender_dq, dq_normals), limb_radius=limb_radius, **band,
                         **crossings, **extra, **timing))
    return rows
