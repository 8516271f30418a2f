"""BVH files of the SMPL-X 22-joint body skeleton (Blender, MotionBuilder, Maya, ...).

Format
------
``HIERARCHY``: the pelvis is the ``ROOT`` with six channels ``Xposition
Yposition Zposition Zrotation Xrotation Yrotation``; the other 21 body joints
(named as in SMPL-X and its Blender add-on, ``jaxmotion.geometry.SMPLX_JOINT_NAMES``:
``pelvis``, ``left_hip``, …, ``right_wrist``, the bones of ``motion.glb``) have three,
``Zrotation Xrotation
Yrotation``, and are listed depth first (children in SMPL-X index order). The
leaves (feet, head, wrists) end in an ``End Site`` half as long as their bone
(for display only). ``MOTION``: one line per frame, the channels in the order of
the hierarchy. Angles are degrees; a joint's local rotation is the intrinsic
product of its channels in the listed order, ``R = Rz(z) · Rx(x) · Ry(y)``, acting
on column vectors (the usual BVH reading). Angles are unwrapped over time (no
±180° jumps) so that players interpolating them stay smooth.

Other rigs
----------
``skeleton="mixamo"`` / ``"ue5"`` (:func:`rig_bones`) write the same body with the bone names
and hierarchy of Mixamo's rig or Unreal Engine 5's Manny / Quinn, in centimetres; bones those
rigs have and SMPL-X does not (UE5's ``root``, ``spine_02``, ``spine_04``, ``neck_02``) do not
turn, so every SMPL-X joint is where the ``smplx`` file puts it. The rest pose stays the body's
own (SMPL-X's T-pose, its proportions): a character with that rig is driven through its
retargeting tools (Blender's Mixamo add-on, Unreal's IK Retargeter), which match the bones by
name.

Conventions
-----------
- Units: metres (``scale=100`` writes centimetres). Blender imports a metre file
  at its true size with its default scale 1.0.
- Rest pose = SMPL-X's: the offsets are the rest joints shaped by ``betas``
  (``jaxmotion.geometry.rest_joints``), child minus parent, in SMPL-X's canonical
  frame (y up, the body facing +z, T-pose).
- **y up**: BVH tools assume y up (Blender's importer by default), so the file's
  world is jaxmotion's z-up world turned by Rx(−90°), ``(x, y, z) → (x, z, −y)``,
  folded into the root's channels. Blender's default import (forward −Z, up Y)
  turns it back, so the motion lands in its original z-up place in the scene.
- Root: ``OFFSET 0 0 0``; its position channels are the world position of the
  pelvis, ``Rx(−90°) · (rest[0] + transl)`` (SMPL-X turns the body about the rest
  pelvis and adds ``transl`` after), and its rotation is ``Rx(−90°) · global_orient``.
  Other joints carry SMPL-X's local rotations (``body_pose``) unchanged, so the
  file reproduces ``jaxmotion.geometry.smplx_joints`` exactly (up to the printed
  precision: 1e-6 degrees and 1e-6 of the length unit).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.export._common import Z_UP_TO_Y_UP, check_array, check_fps, smplx_motion
from jaxmotion.export.rotations import euler_zxy, rotvec_to_matrix
from jaxmotion.geometry.skeleton import (
    NUM_BETAS,
    NUM_JOINTS,
    PARENTS,
    SMPLX_JOINT_NAMES,
    rest_joints_host,
)

__all__ = ["BVH", "SKELETONS", "check_skeleton", "read_bvh", "rig_bones", "rig_name",
           "write_bvh"]

_EULER = "ZXY"  # intrinsic (euler_zxy) = the order of the rotation channels
_ROT_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")
_POS_CHANNELS = ("Xposition", "Yposition", "Zposition")


class BVH(NamedTuple):
    """A parsed BVH file.

    Attributes:
      names: joint names in file order (End Sites are not joints).
      parents: ``[J]`` parent index of each joint in file order, −1 for the root.
      offsets: ``[J, 3]`` offset of each joint from its parent, file units.
      channels: channel names of each joint, e.g. ``("Zrotation", "Xrotation", "Yrotation")``.
      frames: ``[T, C]`` channel values per frame, joints in file order.
      frame_time: seconds per frame.
      end_sites: ``(parent joint index, (x, y, z) offset)`` of each ``End Site``, file order
        (real skeletons end their chains there: a foot's toe tip, the top of the head).
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    frames: np.ndarray
    frame_time: float
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()


#: The skeletons :func:`write_bvh` writes: SMPL-X's own, and the bone names and hierarchy of
#: the rigs animators use (:func:`rig_bones`).
SKELETONS = ("smplx", "mixamo", "ue5")
_MIXAMO_NAMES = ("Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1",
                 "LeftFoot", "RightFoot", "Spine2", "LeftToeBase", "RightToeBase", "Neck",
                 "LeftShoulder", "RightShoulder", "Head", "LeftArm", "RightArm", "LeftForeArm",
                 "RightForeArm", "LeftHand", "RightHand")
_UE5_NAMES = ("pelvis", "thigh_l", "thigh_r", "spine_01", "calf_l", "calf_r", "spine_03",
              "foot_l", "foot_r", "spine_05", "ball_l", "ball_r", "neck_01", "clavicle_l",
              "clavicle_r", "head", "upperarm_l", "upperarm_r", "lowerarm_l", "lowerarm_r",
              "hand_l", "hand_r")
#: the default length unit (metres per file unit inverted: 100 = centimetres) of each
_SKELETON_SCALE = {"smplx": 1.0, "mixamo": 100.0, "ue5": 100.0}


def check_skeleton(skeleton: str) -> str:
    """``skeleton`` if it is one of :data:`SKELETONS`, else ValueError naming them."""
    if skeleton not in SKELETONS:
        raise ValueError(f"skeleton must be one of {', '.join(SKELETONS)}, got {skeleton!r}")
    return skeleton


def rig_name(smplx_name: str, skeleton: str) -> str:
    """The name a skeleton gives an SMPL-X joint (``SMPLX_JOINT_NAMES``; the 22 body joints
    as :func:`rig_bones`, and the fingers: Mixamo's ``mixamorig:LeftHandIndex1``, UE5's
    ``index_01_l``); a joint the rig has no name for (SMPL-X's jaw and eyes) keeps its own."""
    check_skeleton(skeleton)
    if skeleton == "smplx":
        return smplx_name
    body = list(SMPLX_JOINT_NAMES[:NUM_JOINTS])
    if smplx_name in body:
        j = body.index(smplx_name)
        return f"mixamorig:{_MIXAMO_NAMES[j]}" if skeleton == "mixamo" else _UE5_NAMES[j]
    side, _, finger = smplx_name.partition("_")  # left_index1
    if side in ("left", "right") and finger[:-1] in ("index", "middle", "pinky", "ring",
                                                     "thumb") and finger[-1:].isdigit():
        if skeleton == "mixamo":
            return f"mixamorig:{side.capitalize()}Hand{finger[:-1].capitalize()}{finger[-1]}"
        return f"{finger[:-1]}_0{finger[-1]}_{side[0]}"
    return smplx_name


def rig_bones(skeleton: str = "smplx") -> list[tuple[str, int, int | None, tuple | None]]:
    """The bones of a skeleton in file (depth-first) order: ``(name, parent index in the list
    or -1, the SMPL-X joint it is (or None), (a, b, f) for a bone placed the fraction f of the
    way from SMPL-X joint a to b with no rotation of its own, or "origin")``.

    - ``smplx``: SMPL-X's 22 body joints, named as SMPL-X and its Blender add-on.
    - ``mixamo``: Mixamo's names with its ``mixamorig:`` prefix (``mixamorig:Hips``,
      ``mixamorig:LeftUpLeg``, ..., ``mixamorig:LeftShoulder`` the collar): the same
      hierarchy as SMPL-X's 22, joint for joint (Blender's Mixamo conventions).
    - ``ue5``: Unreal Engine 5's Manny / Quinn names and hierarchy: ``root`` (at the origin,
      not moving) > ``pelvis`` > ``spine_01`` … ``spine_05`` > ``neck_01`` > ``neck_02`` >
      ``head``; ``clavicle_l`` > ``upperarm_l`` > ``lowerarm_l`` > ``hand_l``; ``thigh_l`` >
      ``calf_l`` > ``foot_l`` > ``ball_l``. SMPL-X's spine1–3 are ``spine_01``, ``spine_03``,
      ``spine_05``; ``spine_02``, ``spine_04`` and ``neck_02`` lie half way between their
      neighbours and do not turn.
    """
    check_skeleton(skeleton)
    names = {"smplx": SMPLX_JOINT_NAMES, "ue5": _UE5_NAMES,
             "mixamo": tuple(f"mixamorig:{n}" for n in _MIXAMO_NAMES)}[skeleton]
    inserted = {}  # SMPL-X joint -> bone put between it and its parent
    if skeleton == "ue5":
        inserted = {6: ("spine_02", (3, 6, 0.5)), 9: ("spine_04", (6, 9, 0.5)),
                    15: ("neck_02", (12, 15, 0.5))}
    bones: list[tuple[str, int, int | None, tuple | None]] = []
    if skeleton == "ue5":
        bones.append(("root", -1, None, "origin"))

    def emit(j: int, parent: int) -> None:
        if j in inserted:
            name, at = inserted[j]
            bones.append((name, parent, None, at))
            parent = len(bones) - 1
        bones.append((names[j], parent, j, None))
        me = len(bones) - 1
        for c in range(NUM_JOINTS):
            if PARENTS[c] == j:
                emit(c, me)

    emit(0, len(bones) - 1)
    return bones


def write_bvh(
    path, global_orient, body_pose, transl, betas, fps: float, *, scale: float | None = None,
    skeleton: str = "smplx",
) -> Path:
    """Write one SMPL-X body motion as a BVH file (atomically); see the module docstring.

    Args:
      path: the ``.bvh`` file to write.
      global_orient: ``[T, 3]`` axis-angle, radians; body_pose: ``[T, 21, 3]``;
      transl: ``[T, 3]`` metres, jaxmotion's z-up world.
      betas: ``[B]`` (B ≤ 10) shape coefficients, or None for the neutral body.
      fps: frames per second.
      scale: multiplies every length (1 = metres, 100 = centimetres); None: the skeleton's
        own unit (metres for ``smplx``, centimetres for ``mixamo`` and ``ue5``).
      skeleton: the bone names and hierarchy, :data:`SKELETONS` (:func:`rig_bones`); every
        skeleton poses the same body (the same joint positions read back).
    Returns:
      the path written.
    """
    bones = rig_bones(skeleton)
    if scale is None:
        scale = _SKELETON_SCALE[skeleton]
    go, bp, tr = smplx_motion(global_orient, body_pose, transl)
    if go.shape[0] != 1:
        raise ValueError(
            f"write_bvh writes one motion: global_orient must be [T,3], got {go.shape}"
        )
    go, bp, tr = go[0], bp[0], tr[0]
    fps = check_fps(fps)
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive number, got {scale}")
    if betas is not None:
        betas = check_array("betas", betas, (None,))
        if len(betas) > NUM_BETAS:
            raise ValueError(f"betas has {len(betas)} coefficients; at most {NUM_BETAS}")
    rest = rest_joints_host(betas)
    t = len(go)

    mats = rotvec_to_matrix(np.concatenate([go[:, None], bp], axis=1))  # [T, 22, 3, 3]
    mats[:, 0] = Z_UP_TO_Y_UP @ mats[:, 0]
    euler = euler_zxy(mats, degrees=True)  # the order of the rotation channels (_EULER)
    euler = np.unwrap(euler.reshape(t, NUM_JOINTS, 3), period=360.0, axis=0)
    root_pos = (rest[0] + tr) @ Z_UP_TO_Y_UP.T * scale

    def at(bone):  # a bone's rest position (SMPL-X's canonical frame, metres)
        _, _, j, where = bone
        if j is not None:
            return rest[j]
        if where == "origin":
            return np.zeros(3)
        a, b, f = where
        return rest[a] + f * (rest[b] - rest[a])

    lines = ["HIERARCHY"]
    columns: list[np.ndarray] = []
    zeros = np.zeros((t, 3))

    def emit(i: int, pad: str) -> None:
        name, parent, j, _ = bones[i]
        moves = j == 0  # the pelvis carries the body's place and turn
        offset = np.zeros(3) if parent < 0 or moves else (at(bones[i]) - at(bones[parent])) * scale
        channels = _POS_CHANNELS + _ROT_CHANNELS if moves or parent < 0 else _ROT_CHANNELS
        if moves or parent < 0:
            columns.append(root_pos if moves else zeros)
        columns.append(euler[:, j] if j is not None else zeros)
        lines.extend(
            [
                f"{pad}{'ROOT' if parent < 0 else 'JOINT'} {name}",
                f"{pad}{{",
                f"{pad}  OFFSET {offset[0]:.6f} {offset[1]:.6f} {offset[2]:.6f}",
                f"{pad}  CHANNELS {len(channels)} {' '.join(channels)}",
            ]
        )
        children = [c for c in range(len(bones)) if bones[c][1] == i]
        for c in children:
            emit(c, pad + "  ")
        if not children:
            end = 0.5 * offset
            lines.extend(
                [
                    f"{pad}  End Site",
                    f"{pad}  {{",
                    f"{pad}    OFFSET {end[0]:.6f} {end[1]:.6f} {end[2]:.6f}",
                    f"{pad}  }}",
                ]
            )
        lines.append(f"{pad}}}")

    emit(0, "")
    values = np.concatenate(columns, axis=1)
    lines += ["MOTION", f"Frames: {t}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(row) for row in np.char.mod("%.6f", values)]
    with atomic_open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return Path(path)


def read_bvh(path) -> BVH:
    """Parse a BVH file (any joint names, channel sets and orders; one root).

    Raises ``ValueError`` naming the problem when the file is not a valid BVH.
    """
    tokens = Path(path).read_text().split()
    pos = 0

    def take(expected: str | None = None) -> str:
        nonlocal pos
        if pos >= len(tokens):
            raise ValueError(f"{path}: not a BVH file: it ends early")
        tok = tokens[pos]
        pos += 1
        if expected is not None and tok != expected:
            raise ValueError(f"{path}: not a BVH file: expected {expected!r}, got {tok!r}")
        return tok

    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_sites: list[tuple[int, tuple[float, float, float]]] = []
    take("HIERARCHY")
    stack: list[int] = []  # joint index per open brace, −1 for an End Site
    opening = None
    try:
        while True:
            tok = take()
            if tok in ("ROOT", "JOINT"):
                if (tok == "ROOT") != (not stack):
                    raise ValueError(f"{path}: not a BVH file: {tok} at the wrong level")
                names.append(take())
                parents.append(stack[-1] if stack else -1)
                offsets.append([0.0, 0.0, 0.0])
                channels.append(())
                opening = len(names) - 1
            elif tok == "End":
                take("Site")
                if not stack:
                    raise ValueError(f"{path}: not a BVH file: End Site outside a joint")
                end_sites.append((stack[-1], (0.0, 0.0, 0.0)))
                opening = -1
            elif tok == "{":
                if opening is None:
                    raise ValueError(f"{path}: not a BVH file: '{{' without a joint")
                stack.append(opening)
                opening = None
            elif tok == "}":
                stack.pop()
                if not stack:
                    break
            elif tok == "OFFSET" and stack:
                values = [float(take()) for _ in range(3)]
                if stack[-1] >= 0:
                    offsets[stack[-1]] = values
                else:
                    end_sites[-1] = (end_sites[-1][0], tuple(values))
            elif tok == "CHANNELS" and stack and stack[-1] >= 0:
                channels[stack[-1]] = tuple(take() for _ in range(int(take())))
            else:
                raise ValueError(f"{path}: not a BVH file: unexpected {tok!r} in the hierarchy")
        take("MOTION")
        take("Frames:")
        num_frames = int(take())
        take("Frame")
        take("Time:")
        frame_time = float(take())
        values = np.array(tokens[pos:], np.float64)
    except (IndexError, ValueError) as err:
        if str(err).startswith(str(path)):
            raise
        raise ValueError(f"{path}: not a BVH file: {err}") from err
    width = sum(len(c) for c in channels)
    if values.size != num_frames * width:
        raise ValueError(
            f"{path}: {values.size} motion values, expected {num_frames} frames × {width} channels"
        )
    return BVH(
        names=tuple(names),
        parents=np.array(parents, np.int64),
        offsets=np.array(offsets, np.float64).reshape(-1, 3),
        channels=tuple(channels),
        frames=values.reshape(num_frames, width),
        frame_time=frame_time,
        end_sites=tuple(end_sites),
    )
