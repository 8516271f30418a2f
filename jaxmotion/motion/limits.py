"""Joint-angle limits of the procedural character, and foot-height allowances.

Each body joint's local rotation (SMPL-X ``body_pose``, relative to its parent,
axes of the rest frame: x = the body's left, y = up, z = forward) is split into
three intrinsic Euler angles in an order chosen per joint so that the middle
angle stays well away from gimbal lock:

- legs and spine ``XZY``: flexion about x, then ab/adduction or side bend about
  z, then twist about the bone (y);
- collars, shoulders and wrists ``ZYX``: raise/lower about z (arms rest
  horizontally in SMPL-X's T-pose), swing forward about y, then twist about the
  arm bone (x);
- elbows ``YZX``: flexion about y **first** (it reaches 150°, beyond the ±90°
  a middle Tait–Bryan angle can express), then carrying angle about z, then
  twist about the forearm (x).

Signs (rest frame): x-rotation > 0 tips the child **forward** for spine, neck,
head and ankle (plantar flexion) and **backward** for the knee (flexion > 0);
hip flexion is therefore x < 0. Ranges below are in degrees: generous
anatomical ranges (Kapandji; AMASS pose statistics), symmetric where the two
sides mirror. They catch broken poses (hyper-extended knees, backwards-bent
elbows, heads turned through the back), not subtle ones.
"""

from __future__ import annotations

import numpy as np

from jaxmotion.geometry.skeleton import JOINT_NAMES

__all__ = [
    "ANKLE_ALLOWANCE",
    "FOOT_ALLOWANCE",
    "LIMITS",
    "ORDERS",
    "joint_angles",
    "limit_violations",
]

# Height of the joint above the sole of a flat foot, subtracted before testing
# "below the floor": SMPL-X's foot (toe) joint sits ~2.5 cm above the sole, its
# ankle joint 7-9 cm (the character uses the body's own value, at least 7 cm).
FOOT_ALLOWANCE = 0.025
ANKLE_ALLOWANCE = 0.07

_LEG, _ARM, _ELBOW = "XZY", "ZYX", "YZX"
ORDERS = {
    name: (_ELBOW if "elbow" in name else
           _ARM if any(k in name for k in ("collar", "shoulder", "wrist")) else _LEG)
    for name in JOINT_NAMES[1:]
}

# name: ((first lo, hi), (second lo, hi), (third lo, hi)) in degrees, in the joint's Euler
# order; "L/R" pairs mirror the y and z angles (negated and swapped for the right side).
_HALF = {
    "hip": ((-125, 30), (-35, 45), (-45, 45)),
    "knee": ((-8, 150), (-20, 20), (-25, 25)),
    "ankle": ((-35, 55), (-35, 25), (-30, 30)),  # z < 0: inversion (left)
    "foot": ((-30, 30), (-15, 15), (-15, 15)),
    "collar": ((-20, 20), (-25, 25), (-20, 20)),
    "shoulder": ((-95, 60), (-100, 60), (-80, 80)),
    "elbow": ((-150, 8), (-20, 20), (-40, 40)),  # YZX: flexion is y < 0 on the left
    "wrist": ((-40, 40), (-60, 60), (-40, 40)),
}
_MID = {
    "spine1": ((-25, 50), (-25, 25), (-30, 30)),
    "spine2": ((-25, 40), (-25, 25), (-30, 30)),
    "spine3": ((-25, 40), (-25, 25), (-30, 30)),
    "neck": ((-45, 50), (-30, 30), (-50, 50)),
    "head": ((-45, 45), (-30, 30), (-50, 50)),
}


def _mirror(lims, order):
    """Right-side limits from left-side ones: mirroring x -> -x flips rotations about y and z."""
    out = []
    for axis, (lo, hi) in zip(order, lims):
        out.append((lo, hi) if axis == "X" else (-hi, -lo))
    return tuple(out)


LIMITS: dict[str, tuple] = {}
for _name in JOINT_NAMES[1:]:
    if _name in _MID:
        LIMITS[_name] = _MID[_name]
    else:
        _lims = _HALF[_name[2:]]
        LIMITS[_name] = _lims if _name.startswith("l_") else _mirror(_lims, ORDERS[_name])


def joint_angles(body_pose: np.ndarray) -> np.ndarray:
    """Euler angles (deg) ``[T,21,3]`` of an axis-angle ``body_pose`` ``[T,21,3]``."""
    from scipy.spatial.transform import Rotation  # here: ~0.2 s to import in every generate

    bp = np.asarray(body_pose, np.float64)
    out = np.zeros(bp.shape)
    for j, name in enumerate(JOINT_NAMES[1:]):
        out[:, j] = Rotation.from_rotvec(bp[:, j]).as_euler(ORDERS[name], degrees=True)
    return out


def limit_violations(
    body_pose: np.ndarray, tol: float = 0.5
) -> list[tuple[str, int, float, float]]:
    """Every (joint, Euler index, worst angle, bound) beyond its range by more than ``tol`` deg."""
    ang = joint_angles(body_pose)
    bad = []
    for j, name in enumerate(JOINT_NAMES[1:]):
        for k, (lo, hi) in enumerate(LIMITS[name]):
            a = ang[:, j, k]
            if a.min() < lo - tol:
                bad.append((name, k, float(a.min()), float(lo)))
            if a.max() > hi + tol:
                bad.append((name, k, float(a.max()), float(hi)))
    return bad
