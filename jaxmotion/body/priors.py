"""Pose priors for body fitting: joint limits and temporal smoothness (pure jax.numpy).

Joint limits
------------
The ranges are the project's own (:data:`jaxmotion.motion.limits.LIMITS`, the
ones the synthetic character obeys), so a fit never fights the motions of the
synthetic world. Each body joint's local rotation (SMPL-X ``body_pose``; rest
frame axes x = the body's left, y = up, z = forward) is described by three
angles named after the axes, in degrees (at the time of writing):

::

    joint      angles, in the order of LIMIT_AXES
    l_hip      x [-125, 30]    z [-35, 45]     y [-45, 45]
    l_knee     x [-8, 150]     z [-20, 20]     y [-25, 25]
    l_ankle    x [-35, 55]     z [-35, 25]     y [-30, 30]
    l_foot     x [-30, 30]     z [-15, 15]     y [-15, 15]
    spine1     x [-25, 50]     z [-25, 25]     y [-30, 30]
    spine2/3   x [-25, 40]     z [-25, 25]     y [-30, 30]
    neck       x [-45, 50]     z [-30, 30]     y [-50, 50]
    head       x [-45, 45]     z [-30, 30]     y [-50, 50]
    l_collar   z [-20, 20]     y [-25, 25]     x [-20, 20]
    l_shoulder z [-95, 60]     y [-100, 60]    x [-80, 80]
    l_elbow    y [-150, 8]     z [-20, 20]     x [-40, 40]
    l_wrist    z [-40, 40]     y [-60, 60]     x [-40, 40]

x > 0 tips the child forward for spine, neck, head and ankle (plantar flexion)
and backward for the knee (flexion > 0); hip flexion is x < 0; shoulder z < 0
lowers the arm, y < 0 swings it forward; elbow flexion is y < 0 on the left.
Right-side joints mirror the left (x → −x in the body frame): the x range is
kept and the y and z ranges are negated and swapped.

How the angles are measured, chosen so that no range meets a singularity:

- legs, spine, neck, head: intrinsic Euler ``XZY`` (x, then z, then y = twist
  about the bone), as in ``motion.limits``;
- collars and wrists: intrinsic Euler ``ZYX`` (z, y, then x = twist), likewise;
- elbows: intrinsic Euler ``YZX`` (the flexion y first, so the middle angle z
  stays small; ``ZYX`` would put the ±90° gimbal lock inside the flexion range),
  as in ``motion.limits``;
- shoulders: swing-twist about the arm bone (x): the swing is the shortest
  rotation carrying x to the arm's direction, and its rotation vector
  ``(0, s_y, s_z)`` gives the y and z angles; the twist about x after it gives x.
  Singular only for an arm pointing through the body (swing 180°); Euler ZYX
  would be singular with the arm pointing straight forward.

The penalty is the squared excess angle (radians) beyond a range, zero inside:
a *soft* limit. :func:`rotation_from_limit_angles` is the inverse map.

Smoothness
----------
Second differences along time, scaled by ``fps²`` to accelerations (m/s² for
joints, 1/s² for rotation-matrix entries) so that one weight suits any frame rate.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxmotion.geometry.rotations import axis_angle_to_matrix
from jaxmotion.geometry.skeleton import JOINT_NAMES
from jaxmotion.motion.limits import LIMITS, ORDERS

__all__ = [
    "JOINT_LIMITS_DEG",
    "LIMIT_AXES",
    "acceleration",
    "joint_limit_excess",
    "limit_angles",
    "rotation_from_limit_angles",
]

_BODY = JOINT_NAMES[1:]
# The axis each of the three limit angles of a joint is about, e.g. "XZY".
LIMIT_AXES: tuple[str, ...] = tuple(ORDERS[n] for n in _BODY)
# [21, 3, 2]: (lo, hi) in degrees of each limit angle.
JOINT_LIMITS_DEG: np.ndarray = np.array([[list(r) for r in LIMITS[n]] for n in _BODY], np.float32)

# How each joint's angles are measured (see the module docstring).
_METHOD = tuple("swing" if "shoulder" in n else ORDERS[n] for n in _BODY)
if not set(LIMIT_AXES) <= {"XZY", "ZYX", "YZX"}:  # pragma: no cover - guards motion.limits
    raise RuntimeError(f"unsupported Euler orders in jaxmotion.motion.limits: {set(LIMIT_AXES)}")
if any(LIMIT_AXES[j] != "ZYX" for j, m in enumerate(_METHOD) if m == "swing"):
    raise RuntimeError("jaxmotion.body.priors expects ZYX-named limits for the shoulders")
_EPS = 1e-12


# Every limit angle is one atan2(Y, X) of entries of the local rotation matrix R (flat
# index 3·row + col); all 63 go through a single batched atan2 (a few dozen ops to
# differentiate instead of hundreds: this prior sits inside the fitting objective).
# Euler angles, per joint and angle: (Y entry, Y sign, X entry, X sign); an X entry of
# -1 marks a middle angle, whose X is sqrt(a² + b²) of the two entries in _MIDDLE_AB.
_EULER = {
    "XZY": (((7, 1), (4, 1)), ((1, -1), (-1, 1)), ((2, 1), (0, 1))),  # Rx Rz Ry: x, z, y
    "ZYX": (((3, 1), (0, 1)), ((6, -1), (-1, 1)), ((7, 1), (8, 1))),  # Rz Ry Rx: z, y, x
    "YZX": (((6, -1), (0, 1)), ((3, 1), (-1, 1)), ((5, -1), (4, 1))),  # Ry Rz Rx: y, z, x
}
_MIDDLE_AB = {"XZY": (0, 2), "ZYX": (7, 8), "YZX": (4, 5)}


def _angle_tables():
    euler = [j for j, m in enumerate(_METHOD) if m != "swing"]
    swing = [j for j, m in enumerate(_METHOD) if m == "swing"]
    ys, ysg, xs, xsg, ma, mb, mid = [], [], [], [], [], [], []
    for j in euler:
        m = _METHOD[j]
        for (yi, ysn), (xi, xsn) in _EULER[m]:
            ys.append(9 * j + yi)
            ysg.append(ysn)
            xs.append(9 * j + max(xi, 0))
            xsg.append(xsn)
            ma.append(9 * j + _MIDDLE_AB[m][0])
            mb.append(9 * j + _MIDDLE_AB[m][1])
            mid.append(xi < 0)
    order = np.argsort(euler + swing)  # back to joint order after [euler..., swing...]
    as_tuple = lambda x: tuple(int(v) for v in x)  # noqa: E731
    return (tuple(map(as_tuple, (ys, ysg, xs, xsg, ma, mb, mid))), tuple(swing),
            as_tuple(order))  # fmt: skip


# Tuples, made fresh numpy arrays per call (see the note in jaxmotion.body.fit).
_EULER_TABLES, _SWING_JOINTS, _JOINT_ORDER = _angle_tables()


def _atan2(y, x):
    """atan2 with a finite gradient at the origin (gimbal lock): x is nudged off 0 there."""
    return jnp.arctan2(y, jnp.where((x == 0) & (y == 0), 1.0, x))


def limit_angles(rot) -> jnp.ndarray:
    """The limit angles (radians) of the 21 body joints' local rotations.

    Args:
      rot: ``[..., 21, 3, 3]`` local rotations (SMPL-X ``body_pose`` as matrices).
    Returns:
      ``[..., 21, 3]`` angles about the axes of :data:`LIMIT_AXES`, in that order.

    Euler joints use the closed forms of their order (middle angle as
    ``atan2(s, sqrt(a² + b²))``). Shoulders (swing-twist about x): with the bone
    direction ``d = R e_x``, the swing angle is ``θ = atan2(|d_yz|, d_x)`` and its
    rotation vector ``θ/|d_yz| · (0, −d_z, d_y)``; the twist is
    ``2 atan2(R21 − R12, 1 + tr R)`` (twice the angle of the quaternion's (w, x)
    part, whose entries are proportional to these, for rotations below 180°).
    """
    flat = rot.reshape(*rot.shape[:-3], -1)  # [..., 21 * 9]
    ys, ysg, xs, xsg, ma, mb, mid = (np.array(t) for t in _EULER_TABLES)
    y = flat[..., ys] * ysg
    x_mid = jnp.sqrt(jnp.maximum(flat[..., ma] ** 2 + flat[..., mb] ** 2, _EPS))
    x = jnp.where(mid, x_mid, flat[..., xs] * xsg)
    sw = np.array(_SWING_JOINTS) * 9
    r = lambda i, j: flat[..., sw + 3 * i + j]  # noqa: E731
    sin_t = jnp.sqrt(jnp.maximum(r(1, 0) ** 2 + r(2, 0) ** 2, _EPS))
    trace1 = 1.0 + r(0, 0) + r(1, 1) + r(2, 2)
    y = jnp.concatenate([y, sin_t, r(2, 1) - r(1, 2)], -1)
    x = jnp.concatenate([x, r(0, 0), trace1], -1)
    ang = _atan2(y, x)
    n_euler, n_swing = len(ys), len(_SWING_JOINTS)
    euler = ang[..., :n_euler].reshape(*ang.shape[:-1], n_euler // 3, 3)
    scale = ang[..., n_euler : n_euler + n_swing] / sin_t  # θ / sinθ, -> 1 at θ = 0
    twist = 2.0 * ang[..., n_euler + n_swing :]
    swing = jnp.stack([r(1, 0) * scale, -r(2, 0) * scale, twist], -1)  # (z, y, x)
    return jnp.concatenate([euler, swing], -2)[..., np.array(_JOINT_ORDER), :]


def _axis_rotation(axis: str, angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, i = jnp.zeros_like(c), jnp.ones_like(c)
    rows = {
        "X": ((i, o, o), (o, c, -s), (o, s, c)),
        "Y": ((c, o, s), (o, i, o), (-s, o, c)),
        "Z": ((c, -s, o), (s, c, o), (o, o, i)),
    }[axis]
    return jnp.stack([jnp.stack(row, -1) for row in rows], -2)


def rotation_from_limit_angles(angles) -> jnp.ndarray:
    """Inverse of :func:`limit_angles`: ``[..., 21, 3]`` radians → ``[..., 21, 3, 3]``."""
    angles = jnp.asarray(angles)
    mats = []
    for j, method in enumerate(_METHOD):
        a = angles[..., j, :]
        if method == "swing":  # (z, y, x): swing rotation vector (0, y, z), then twist x
            zero = jnp.zeros_like(a[..., 0])
            swing = axis_angle_to_matrix(jnp.stack([zero, a[..., 1], a[..., 0]], -1))
            mats.append(swing @ _axis_rotation("X", a[..., 2]))
            continue
        m = _axis_rotation(method[0], a[..., 0])
        for ax, v in zip(method[1:], (a[..., 1], a[..., 2]), strict=True):
            m = m @ _axis_rotation(ax, v)
        mats.append(m)
    return jnp.stack(mats, -3)


def joint_limit_excess(rot) -> jnp.ndarray:
    """Angle (radians) by which each limit angle leaves its range: ``[..., 21, 3]``, ≥ 0."""
    ang = limit_angles(rot)
    lim = jnp.asarray(np.radians(JOINT_LIMITS_DEG), ang.dtype)
    return jnp.maximum(lim[:, :, 0] - ang, 0.0) + jnp.maximum(ang - lim[:, :, 1], 0.0)


def acceleration(x, fps: float) -> jnp.ndarray:
    """Second difference along axis 0 times ``fps²``: ``[T, ...] -> [T-2, ...]``."""
    return (x[2:] - 2.0 * x[1:-1] + x[:-2]) * (fps * fps)
