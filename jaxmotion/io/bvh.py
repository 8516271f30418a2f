"""BVH motion files (any skeleton) read as the 22 SMPL-X body joints.

Reading
-------
The file is parsed fully (:func:`jaxmotion.export.read_bvh`: any number of joints, any
channel set and order per joint, ``End Site`` leaves), then posed by forward kinematics
in NumPy, the usual BVH reading:

- a joint's local rotation is the product of its rotation channels **in the listed
  order**, ``Zrotation Xrotation Yrotation`` → ``R = Rz(z) · Rx(x) · Ry(y)`` (degrees,
  column vectors; intrinsic);
- its local translation is its ``OFFSET``, except that position channels **replace** the
  matching offset components (the root's ``Xposition Yposition Zposition`` are its position
  in the file's world; on other joints they are their position in the parent's frame, as
  files with 6 channels on every joint write them);
- ``world = world(parent) · [R | t]``; joints are at the origin of their frame.
- an ``End Site`` is a point of its parent joint's frame at its ``OFFSET``; it is named
  ``<parent>_End`` (``LeftAnkle_End``), so a joint map can name it like a joint (skeletons
  such as MocapBank's end the leg at the ankle, the toe tip being an End Site).

Mapping to SMPL-X
-----------------
A joint map ``{smplx_joint_name: bvh_joint_name}`` picks the BVH joint whose position is
each SMPL-X joint (``joint_map``: ``"auto"``, ``"cmu"``, ``"mixamo"``, ``"mocapbank"``,
``"cc"``, ``"smplx"``, a dict, or a JSON file holding the dict). Names match exactly, else
ignoring case and any namespace prefix up to the last ``:`` (``mixamorig:Hips`` = ``Hips``).
``"auto"`` takes the first built-in map (smplx, jaxmotion, mixamo, cmu, mocapbank, cc) whose
every name is in the file (a built-in map may list alternatives for a joint, the first in the
file is used, and mark a joint as optional, it is then filled in as below).

- ``cmu`` (the CMU/cgspeed 31-joint skeleton): pelvis Hips; hips LeftUpLeg/RightUpLeg;
  knees LeftLeg/RightLeg; ankles LeftFoot/RightFoot; feet LeftToeBase/RightToeBase;
  spine1 Spine; spine2 Spine1; neck Neck1 (cgspeed's Neck sits on Spine1, at the chest);
  head Head; shoulders LeftArm/RightArm; elbows LeftForeArm/RightForeArm; wrists
  LeftHand/RightHand. spine3 and the collars have no CMU joint.
- ``mixamo``: Hips, LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase, Spine, Spine1, Spine2
  (spine3), Neck, Head, LeftShoulder (collar), LeftArm, LeftForeArm, LeftHand, and the
  Right ones, with or without the ``mixamorig:`` prefix.
- ``mocapbank`` (MocapBank's skeleton; joints named after the anatomical joint): pelvis
  Hips; spine1 Chest; spine2 Chest2 (filled in when the file has none); neck Neck; head
  Head; hips, knees, ankles LeftHip/LeftKnee/LeftAnkle; feet LeftToe, else the ankle's End
  Site ``LeftAnkle_End`` (the toe tip); shoulders, elbows, wrists LeftShoulder/LeftElbow/
  LeftWrist; and the Right ones. spine3 and the collars are filled in: MocapBank's
  LeftCollar sits on the neck's point, SMPL-X's collar 8 cm lower and 4.5 cm to the side.
- ``cc`` (Reallusion Character Creator 3+ / iClone exports, ``CC_Base_`` names, with or
  without the ``RL_BoneRoot`` root; e.g. the CMU takes retargeted in iClone): pelvis
  CC_Base_Hip; spine1 CC_Base_Spine01; spine2 CC_Base_Spine02; neck CC_Base_NeckTwist01;
  head CC_Base_Head; hips, knees, ankles, feet CC_Base_L_Thigh/L_Calf/L_Foot/L_ToeBase;
  collars, shoulders, elbows, wrists CC_Base_L_Clavicle/L_Upperarm/L_Forearm/L_Hand; and the
  R_ ones. spine3 is filled in (CC_Base_Waist, 8 cm above the hip, is not used). The twist,
  share, finger, toe and face bones are ignored.
- ``smplx``: SMPL-X's own joint names (``SMPLX_JOINT_NAMES``: ``pelvis``, ``left_hip``,
  …; the SMPL-X Blender add-on's bones), as jaxmotion's BVH export
  (:func:`jaxmotion.export.write_bvh`) writes them.
- ``jaxmotion``: the short names of ``JOINT_NAMES`` (``l_hip``, …), as jaxmotion's BVH
  export wrote them before it took SMPL-X's names.

**Joints without a counterpart** (a map may leave out any SMPL-X joint but the pelvis
and the five chain ends: feet, head, wrists) are placed on the straight line from their
parent (mapped, or placed before them: joints are filled in SMPL-X index order) to the
first mapped joint further down their chain (spine → neck → head, collar → shoulder →
elbow → wrist, hip → knee → ankle → foot), at the fraction of the way that the neutral
SMPL-X rest skeleton's bone lengths give (spine3 with spine2 and neck mapped: 27 % of the
way from spine2 to the neck; a collar: 42 % of the way from spine3 to the shoulder).

Units and axes
--------------
``up="y"`` (BVH's usual frame) is turned z-up by ``(x, y, z) → (x, −z, y)`` (+90° about x:
a body facing +z in the file faces −y); ``up="z"`` keeps the axes (Vicon / Shogun and other
z-up exports). ``up="auto"`` (the default) takes ``"z"`` when the head is above the pelvis
along the file's z axis by more than along its y and x axes both in most frames and in the
rest pose (every rotation zero: the ``OFFSET`` chain), else ``"y"``. Both must agree so that
neither a y-up capture lying along its z axis nor a y-up file whose root turns a z-up rig
upright (Character Creator's ``RL_BoneRoot``) is taken for z-up; a z-up capture lying in every
frame is read y-up: pass ``up="z"`` for it.
``unit`` is metres per file unit, or ``"auto"``: the ankle–knee–hip–pelvis–spine–neck–head
chain of the first frame (bone lengths, so the pose does not matter) is compared with the
neutral SMPL-X body's (1.54 m) for metres, CMU units (0.056444 m), inches, centimetres and
millimetres, and the closest within a factor of two wins; otherwise pass ``unit``.
``fps`` resamples (linear interpolation of joint positions); default: the file's rate,
``1 / Frame Time``, rounded to a whole number when within 0.05 % of one (0.008333 s: 120).

A leading rest pose
-------------------
Some releases put the skeleton's rest pose (a T-pose) before the capture as frame 0 (CMU
conversions that prepend it for retargeting: every rotation channel a whole number of
degrees, 0, ±21, ..., the root where the capture starts). Read as motion, it is a jump of
up to a metre into the first captured pose, and its straight legs reach below the captured
feet, so putting the lowest foot on the floor lifts the whole capture off it.
``first_frame="auto"`` (default) drops frame 0 when it is such a pose: all of its rotation
channels are whole numbers while frame 1's are not, the file has at least 3 frames, and
some joint moves farther from frame 0 to 1 than 5 times the most any joint moves from frame
1 to 2 plus 3 % of the body's extent. ``info["rest_frame_dropped"]`` says whether it was;
``first_frame="keep"`` keeps every frame.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from jaxmotion.export.bvh import BVH, read_bvh
from jaxmotion.geometry.skeleton import (
    JOINT_NAMES,
    NUM_JOINTS,
    PARENTS,
    SMPLX_JOINT_NAMES,
    rest_joints_host,
)
from jaxmotion.io.motion import Motion, MotionFormatError, y_up_to_z_up

__all__ = [
    "JOINT_MAPS",
    "REQUIRED_JOINTS",
    "UNITS",
    "bvh_world_positions",
    "detect_unit",
    "end_site_names",
    "fill_missing_joints",
    "load_bvh",
    "resolve_joint_map",
]

_SIDES = (("l_", "Left"), ("r_", "Right"))
_LIMB = {"hip": "UpLeg", "knee": "Leg", "ankle": "Foot", "foot": "ToeBase",
         "shoulder": "Arm", "elbow": "ForeArm", "wrist": "Hand"}
_CMU = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "neck": "Neck1", "head": "Head"}
_MIXAMO = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2",
           "neck": "Neck", "head": "Head", "l_collar": "LeftShoulder",
           "r_collar": "RightShoulder"}
_MOCAPBANK: dict[str, str | tuple[str | None, ...]] = {
    "pelvis": "Hips", "spine1": "Chest", "spine2": ("Chest2", None), "neck": "Neck",
    "head": "Head"}
_CC: dict[str, str | tuple[str | None, ...]] = {
    "pelvis": "CC_Base_Hip", "spine1": "CC_Base_Spine01", "spine2": "CC_Base_Spine02",
    "neck": "CC_Base_NeckTwist01", "head": "CC_Base_Head"}
_CC_LIMB = {"hip": "Thigh", "knee": "Calf", "ankle": "Foot", "foot": "ToeBase",
            "collar": "Clavicle", "shoulder": "Upperarm", "elbow": "Forearm", "wrist": "Hand"}
for _p, _side in _SIDES:
    for _k, _v in _CC_LIMB.items():
        _CC[_p + _k] = f"CC_Base_{_side[0]}_{_v}"
    for _k, _v in _LIMB.items():
        _CMU[_p + _k] = _MIXAMO[_p + _k] = _side + _v
    for _k in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist"):
        _MOCAPBANK[_p + _k] = _side + _k.capitalize()
    _MOCAPBANK[_p + "foot"] = (_side + "Toe", _side + "Ankle_End")

# A value is the BVH joint's name, or a tuple of alternatives (the first in the file is
# used; None: the joint may be absent, it is then filled in).
JOINT_MAPS: dict[str, dict[str, str | tuple[str | None, ...]]] = {
    "smplx": dict(zip(JOINT_NAMES, SMPLX_JOINT_NAMES)),
    "jaxmotion": {n: n for n in JOINT_NAMES},
    "mixamo": _MIXAMO,
    "cmu": _CMU,
    "mocapbank": _MOCAPBANK,
    "cc": _CC,
}
REQUIRED_JOINTS = ("pelvis", "l_foot", "r_foot", "head", "l_wrist", "r_wrist")
UNITS = {"metres": 1.0, "cmu": 0.056444, "inches": 0.0254, "centimetres": 0.01,
         "millimetres": 0.001}
# The next joint down each limb (the chain a joint without a counterpart is placed on).
_CHAIN_CHILD = {1: 4, 2: 5, 3: 6, 4: 7, 5: 8, 6: 9, 7: 10, 8: 11, 9: 12, 12: 15, 13: 16,
                14: 17, 16: 18, 17: 19, 18: 20, 19: 21}
_HEIGHT_CHAIN = (7, 4, 1, 0, 3, 6, 9, 12, 15)  # l_ankle ... head: unit detection
FIRST_FRAME_MODES = ("auto", "keep")
UP_AXES = ("auto", "y", "z")


def _rotation_columns(bvh: BVH) -> np.ndarray:
    """Indices of the rotation channels in a frame row."""
    cols, col = [], 0
    for chans in bvh.channels:
        cols += [col + c for c, ch in enumerate(chans) if ch[1:].lower() == "rotation"]
        col += len(chans)
    return np.asarray(cols, dtype=int)


def _leading_rest_frame(bvh: BVH, world: np.ndarray) -> bool:
    """Whether frame 0 is a rest pose put before the capture (module docstring): whole-number
    rotations in frame 0 only, and a jump from it far larger than frame 1 -> 2's."""
    if bvh.frames.shape[0] < 3:
        return False
    rot = bvh.frames[:2, _rotation_columns(bvh)]
    whole = np.all(np.abs(rot - np.round(rot)) < 1e-6, axis=1)
    if rot.shape[1] == 0 or not whole[0] or whole[1]:
        return False
    jump = float(np.linalg.norm(world[1] - world[0], axis=-1).max())
    step = float(np.linalg.norm(world[2] - world[1], axis=-1).max())
    extent = float(np.ptp(world[1], axis=0).max())  # the body's size, file units
    return jump > 5.0 * step + 0.03 * extent


def _matcher(names: tuple[str, ...]):
    """name -> index in ``names``: exact (the first such name), else case-insensitive without
    namespace prefix when that is unique."""
    exact: dict[str, int] = {}
    loose: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        exact.setdefault(n, i)
        loose.setdefault(n.rpartition(":")[2].lower(), []).append(i)

    def find(name: str) -> int | None:
        if name in exact:
            return exact[name]
        hits = loose.get(name.rpartition(":")[2].lower(), [])
        return hits[0] if len(hits) == 1 else None

    return find


def _builtin_index(mapping: dict, find) -> np.ndarray | None:
    """[22] BVH index per SMPL-X joint (−1: filled in) for a built-in map, or None when a
    joint it needs is not in the file."""
    index = np.full(NUM_JOINTS, -1)
    for j, n in enumerate(JOINT_NAMES):
        if n not in mapping:
            continue
        options = mapping[n] if isinstance(mapping[n], tuple) else (mapping[n],)
        hit = next((find(o) for o in options if o is not None and find(o) is not None), None)
        if hit is None and None not in options:
            return None
        index[j] = -1 if hit is None else hit
    return index


def _user_map(joint_map, where: str) -> tuple[str, dict]:
    if isinstance(joint_map, Mapping):
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in joint_map.items()):
            raise MotionFormatError(f"{where}: a joint map maps SMPL-X joint names to BVH joint "
                                    "names, both strings")
        return "custom", dict(joint_map)
    path = Path(joint_map)
    if not path.is_file():
        raise MotionFormatError(
            f"{where}: joint_map={joint_map!r} is neither a built-in map ({', '.join(JOINT_MAPS)}"
            ", 'auto') nor an existing JSON file; give a JSON file "
            '{"pelvis": "Hips", "l_hip": "LeftUpLeg", ...}')
    try:
        mapping = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise MotionFormatError(f"{path}: not a readable JSON joint map ({e}); write it as "
                                '{"pelvis": "Hips", "l_hip": "LeftUpLeg", ...}') from e
    if not isinstance(mapping, dict) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in mapping.items()):
        raise MotionFormatError(f"{path}: a joint map is a JSON object of SMPL-X joint name -> "
                                "BVH joint name strings")
    return str(path), mapping


def resolve_joint_map(names, joint_map="auto", *, where: str = "BVH", parents=None,
                      positions=None, report: dict | None = None) -> tuple[str, np.ndarray]:
    """Index of the BVH joint for each SMPL-X joint (−1: no counterpart) and the map's name.

    Args:
      names: the BVH joint names, file order.
      joint_map: ``"auto"``, a built-in name (:data:`JOINT_MAPS`), a dict or a JSON file path.
      where: the file, for error messages.
      parents, positions: ``[J]`` parent indices and ``[J, 3]`` positions of one pose: with
        them, ``"auto"`` maps a skeleton that no built-in map names by its names' words and
        its shape (:func:`jaxmotion.io.skeleton_map.auto_joint_map`; the map is then
        ``"automatic"``).
      report: a dict to fill with ``confidence`` (1 for a built-in or given map) and
        ``notes`` of the mapping.
    Returns:
      ``(map name, [22] int array)``.
    Raises MotionFormatError when a name is unknown, missing from the file, or a required
    joint (:data:`REQUIRED_JOINTS`) is left out, or an automatic mapping is unsure.
    """
    names = tuple(names)
    find = _matcher(names)
    if report is not None:
        report.update(confidence=1.0, notes=[])
    if joint_map in (None, "auto"):
        for key, mapping in JOINT_MAPS.items():
            if (index := _builtin_index(mapping, find)) is not None:
                return key, index
        if parents is not None and positions is not None:
            from jaxmotion.io.skeleton_map import MappingError, auto_joint_map

            try:
                index, confidence, notes = auto_joint_map(names, parents, positions,
                                                          where=where)
            except MappingError as e:
                raise MotionFormatError(f"{e}. No built-in map ({', '.join(JOINT_MAPS)}) "
                                        "names it either") from e
            if report is not None:
                report.update(confidence=confidence, notes=notes)
            return "automatic", index
        raise MotionFormatError(
            f"{where}: the skeleton matches no built-in joint map ({', '.join(JOINT_MAPS)}); its "
            f"joints are {list(names)}. Pass joint_map= a JSON file or dict "
            '{"pelvis": "<BVH joint>", "l_hip": ..., ...} naming the BVH joint of each SMPL-X '
            f"joint ({', '.join(JOINT_NAMES)}; at least {', '.join(REQUIRED_JOINTS)}).")
    if isinstance(joint_map, str) and joint_map in JOINT_MAPS:
        index = _builtin_index(JOINT_MAPS[joint_map], find)
        if index is None:
            want = {k: v for k, v in JOINT_MAPS[joint_map].items()
                    if _builtin_index({k: v}, find) is None}
            raise MotionFormatError(
                f"{where}: the built-in joint map {joint_map!r} names BVH joints not in the file "
                f"(or not unique): {want}; the file has {list(names)}. Use joint_map='auto' or "
                "a JSON file naming this skeleton's joints")
        return joint_map, index
    key, mapping = _user_map(joint_map, where)
    if unknown := sorted(set(mapping) - set(JOINT_NAMES)):
        raise MotionFormatError(f"{where}: joint map {key!r} has keys {unknown} that are not "
                                f"SMPL-X body joints; use {', '.join(JOINT_NAMES)}")
    if missing := [n for n in REQUIRED_JOINTS if n not in mapping]:
        raise MotionFormatError(f"{where}: joint map {key!r} leaves out {missing}; these chain "
                                "ends (and the pelvis) need a BVH joint")
    if absent := {k: v for k, v in mapping.items() if find(v) is None}:
        raise MotionFormatError(f"{where}: joint map {key!r} names BVH joints not in the file "
                                f"(or not unique): {absent}; the file has {list(names)}")
    return key, np.array([find(mapping[n]) if n in mapping else -1 for n in JOINT_NAMES])


def end_site_names(bvh: BVH) -> tuple[str, ...]:
    """The names :func:`load_bvh` gives the file's ``End Site`` points: ``<parent>_End``
    (``LeftAnkle_End``, ``mixamorig:HeadTop_End_End``), file order."""
    return tuple(f"{bvh.names[p]}_End" for p, _ in bvh.end_sites)


def bvh_world_positions(bvh: BVH, *, where: str = "BVH", end_sites: bool = False) -> np.ndarray:
    """World position of every BVH joint in every frame: ``[T, J, 3]``, file units and axes.

    With ``end_sites=True`` the ``End Site`` points follow, in file order (``[T, J + E, 3]``;
    each is its parent joint's frame moved by its ``OFFSET``). See the module docstring for
    the kinematics. Raises MotionFormatError for unknown channel names or a joint listed
    before its parent.
    """
    t, n = bvh.frames.shape[0], len(bvh.names)
    rot = np.empty((t, n, 3, 3))
    pos = np.empty((t, n, 3))
    col = 0
    for j in range(n):
        chans = bvh.channels[j]
        vals = bvh.frames[:, col:col + len(chans)]
        col += len(chans)
        local_t = np.broadcast_to(bvh.offsets[j], (t, 3)).copy()
        axes, angles = [], []
        for c, ch in enumerate(chans):
            kind = ch[1:].lower()
            if ch[:1].upper() not in "XYZ" or kind not in ("position", "rotation"):
                raise MotionFormatError(
                    f"{where}: joint {bvh.names[j]!r} has an unknown channel {ch!r}; BVH "
                    "channels are X/Y/Z followed by 'position' or 'rotation'")
            if kind == "position":
                local_t[:, "XYZ".index(ch[0].upper())] = vals[:, c]
            else:
                axes.append(ch[0].upper())
                angles.append(vals[:, c])
        local_r = np.broadcast_to(np.eye(3), (t, 3, 3))
        # scipy takes at most 3 axes per sequence; each group is intrinsic (upper case).
        for k in range(0, len(axes), 3):
            group = np.stack(angles[k:k + 3], axis=1)
            local_r = local_r @ Rotation.from_euler("".join(axes[k:k + 3]), group,
                                                    degrees=True).as_matrix()
        p = int(bvh.parents[j])
        if p < 0:
            rot[:, j], pos[:, j] = local_r, local_t
        elif p >= j:
            raise MotionFormatError(f"{where}: joint {bvh.names[j]!r} comes before its parent")
        else:
            rot[:, j] = rot[:, p] @ local_r
            pos[:, j] = pos[:, p] + np.einsum("tab,tb->ta", rot[:, p], local_t)
    if not end_sites or not bvh.end_sites:
        return pos
    ends = [pos[:, p] + rot[:, p] @ np.asarray(off, np.float64) for p, off in bvh.end_sites]
    return np.concatenate([pos, np.stack(ends, axis=1)], axis=1)


def fill_missing_joints(joints: np.ndarray, index: np.ndarray) -> np.ndarray:
    """[T, 22, 3] with the unmapped joints placed on their chain (module docstring)."""
    rest = rest_joints_host()
    bone = np.r_[0.0, np.linalg.norm(rest[1:] - rest[list(PARENTS[1:])], axis=1)]
    out = joints.copy()
    for j in range(1, NUM_JOINTS):
        if index[j] >= 0:
            continue
        chain, d = [j], j
        while index[d] < 0:
            d = _CHAIN_CHILD[d]  # required chain ends are always mapped, so this stops
            chain.append(d)
        frac = bone[j] / sum(bone[c] for c in chain)
        a = out[:, PARENTS[j]]
        out[:, j] = a + frac * (out[:, d] - a)
    return out


def _rest_positions(bvh: BVH) -> np.ndarray:
    """Every joint and End Site (file order, as :func:`bvh_world_positions` with
    ``end_sites=True``) in the rest pose: the sums of the ``OFFSET``s, file units and axes."""
    rest = np.zeros((len(bvh.names), 3))
    for j, p in enumerate(bvh.parents):
        rest[j] = np.asarray(bvh.offsets[j], np.float64) + (rest[p] if p >= 0 else 0.0)
    ends = [rest[p] + np.asarray(off, np.float64) for p, off in bvh.end_sites]
    return np.concatenate([rest, np.reshape(ends, (-1, 3))], axis=0)


def _mapping_pose(bvh: BVH, first: np.ndarray) -> np.ndarray:
    """The pose an automatic joint mapping reads the body's shape from: the rest pose (a
    first frame can be any pose), or the first frame when every ``OFFSET`` is zero."""
    rest = _rest_positions(bvh)
    return rest if np.abs(rest).max(initial=0.0) > 0 else np.asarray(first, np.float64)


def _z_above(d: np.ndarray) -> bool:
    return bool(d[2] > 0 and d[2] > abs(d[1]) and d[2] > abs(d[0]))


def _detect_up(bvh: BVH, world: np.ndarray, index: np.ndarray) -> str:
    """``"z"`` when the head is above the pelvis along the file's z axis (more than along y
    and x) in most frames and in the rest pose; else ``"y"`` (module docstring)."""
    head, pelvis = int(index[15]), int(index[0])
    posed = np.median(world[:, head] - world[:, pelvis], axis=0)
    rest = _rest_positions(bvh)
    return "z" if _z_above(posed) and _z_above(rest[head] - rest[pelvis]) else "y"


def detect_unit(joints0: np.ndarray, where: str) -> float:
    """Metres per file unit from the first frame's ankle-to-head chain (module docstring)."""
    rest = rest_joints_host()
    chain = list(_HEIGHT_CHAIN)

    def length(x):
        return float(np.linalg.norm(np.diff(x[chain], axis=0), axis=1).sum())

    ref, got = length(rest), length(joints0)
    if not got > 0:
        raise MotionFormatError(f"{where}: the skeleton has zero size in the first frame; "
                                "check the OFFSETs, or pass unit=")
    unit = min(UNITS.values(), key=lambda u: abs(np.log(got * u / ref)))
    if abs(np.log(got * unit / ref)) > np.log(2.0):
        raise MotionFormatError(
            f"{where}: cannot tell the length unit: the ankle-to-head chain is {got:.4g} file "
            f"units, which is no person's size in {', '.join(UNITS)}; pass unit=<metres per "
            "file unit> (e.g. unit=0.01 for centimetres)")
    return unit


def load_bvh(path, *, up: str = "auto", unit="auto", fps: float | None = None,
             joint_map="auto", first_frame: str = "auto") -> Motion:
    """Read a BVH file as a :class:`~jaxmotion.io.Motion` of the 22 SMPL-X body joints.

    Args:
      path: the ``.bvh`` file.
      up: ``"auto"`` (default: detected from the head's side of the pelvis), ``"y"`` or
        ``"z"``, the file's up axis (see the module docstring).
      unit: metres per file unit, or ``"auto"`` (detected from the skeleton's size).
      fps: resample to this rate (linear interpolation), or None for the file's rate.
      joint_map: ``"auto"``, a built-in map (``"cmu"``, ``"mixamo"``, ``"mocapbank"``,
        ``"cc"``, ``"smplx"``, ``"jaxmotion"``), a dict ``{smplx_joint: bvh_joint}`` or a JSON
        file of one (End Sites are named ``<parent>_End``).
      first_frame: ``"auto"`` (default) drops a leading rest pose (T-pose) frame, ``"keep"``
        keeps every frame (see the module docstring).
    Returns:
      joints ``[T, 22, 3]`` metres, z-up; no SMPL-X parameters, no texts. ``info`` records
      the joint map, the unit, the up axis used (``"y"`` or ``"z"``, also when detected)
      and whether a rest frame was dropped.
    Raises MotionFormatError naming the file and the fix.
    """
    path = Path(path)
    where = str(path)
    if up not in UP_AXES:
        raise MotionFormatError(f"{where}: up must be 'auto', 'y' or 'z', got {up!r}")
    if first_frame not in FIRST_FRAME_MODES:
        raise MotionFormatError(f"{where}: first_frame must be 'auto' (drop a leading rest "
                                f"pose) or 'keep' (keep every frame), got {first_frame!r}")
    if not path.is_file():
        raise MotionFormatError(f"{where}: no such file")
    try:
        bvh = read_bvh(path)
    except UnicodeDecodeError as e:
        raise MotionFormatError(f"{where}: not a BVH file (not text: {e}); give a .bvh "
                                "motion capture file") from e
    except ValueError as e:
        raise MotionFormatError(f"{e}; check that the file is a complete BVH (HIERARCHY, "
                                "MOTION, Frames:, Frame Time:, one line per frame)") from e
    if bvh.frames.shape[0] < 1:
        raise MotionFormatError(f"{where}: the BVH has no frames (Frames: 0)")
    if not (np.isfinite(bvh.frame_time) and bvh.frame_time > 0):
        raise MotionFormatError(f"{where}: Frame Time must be a positive number of seconds, "
                                f"got {bvh.frame_time}")
    if not np.isfinite(bvh.frames).all() or not np.isfinite(bvh.offsets).all():
        raise MotionFormatError(f"{where}: the file has NaN or inf values")
    names = bvh.names + end_site_names(bvh)
    world = bvh_world_positions(bvh, where=where, end_sites=True)
    parents = np.concatenate([np.asarray(bvh.parents, int),
                              np.asarray([p for p, _ in bvh.end_sites], int)])
    mapped: dict = {}
    map_name, index = resolve_joint_map(names, joint_map, where=where, parents=parents,
                                        positions=_mapping_pose(bvh, world[0]),
                                        report=mapped)
    rest_dropped = first_frame == "auto" and _leading_rest_frame(bvh, world)
    if rest_dropped:
        world = world[1:]
    joints = np.zeros((world.shape[0], NUM_JOINTS, 3))
    joints[:, index >= 0] = world[:, index[index >= 0]]
    joints = fill_missing_joints(joints, index)
    if up == "auto":
        up = _detect_up(bvh, world, index)
    if unit == "auto":
        scale = detect_unit(joints[0], where)
    else:
        try:
            scale = float(unit)
        except (TypeError, ValueError):
            scale = float("nan")
        if not (np.isfinite(scale) and scale > 0):
            raise MotionFormatError(f"{where}: unit must be 'auto' or metres per file unit "
                                    f"(> 0), got {unit!r}")
    joints = joints * scale
    if up == "y":
        joints = y_up_to_z_up(joints)
    rate = 1.0 / bvh.frame_time
    if abs(rate - round(rate)) < 5e-4 * rate:  # "Frame Time: 0.008333" means 120 fps
        rate = float(round(rate))
    motion = Motion(joints=joints, fps=rate, source=where,
                    info={"format": "bvh", "joint_map": map_name, "unit": scale, "up": up,
                          "rest_frame_dropped": bool(rest_dropped),
                          "joint_map_confidence": mapped["confidence"],
                          "joints_from": {n: (names[i] if i >= 0 else None)
                                          for n, i in zip(JOINT_NAMES, index)}})
    return motion if fps is None else motion.resampled(fps)
