"""Host-side kinematics for the procedural character: rotations, body geometry, FK, IK.

The animation is computed in float64 numpy (per clip, vectorised over frames) and
handed to the foundation's jax forward kinematics only at the end, so that the
exported SMPL-X parameters reproduce the joints exactly. :func:`fk_numpy` is the
same tree walk as :func:`jaxmotion.geometry.forward_kinematics`; the tests check
the two agree.

Frames: the rest skeleton is SMPL-X's (y up, body faces +z, its left is +x);
the world is z-up. ``upright(h)`` is the global rotation standing the rest body
up facing heading ``h`` (radians from +x, counter-clockwise).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial.transform import Rotation

from jaxmotion.geometry.skeleton import NUM_JOINTS, PARENTS, rest_joints, smplx_joints

__all__ = [
    "Body",
    "fk_numpy",
    "jax_joints",
    "local_from_global",
    "make_body",
    "rot_axis",
    "rotvec",
    "rx",
    "ry",
    "rz",
    "slerp",
    "two_bone",
    "upright",
]

MAX_FRAMES = 120  # the jitted FK is compiled once for this padded length

# Hip, knee, ankle, foot joints per side (left, right).
HIP, KNEE, ANKLE, FOOT = (1, 2), (4, 5), (7, 8), (10, 11)
SHOULDER, ELBOW, WRIST = (16, 17), (18, 19), (20, 21)
TOE_HEIGHT = 0.025  # foot (toe) joint above the floor when the foot is flat, metres


def normalize(v: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """Unit vectors along the last axis (zero vectors stay zero)."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps)


def rot_axis(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues rotation ``[...,3] axis (unit), [...] angle -> [...,3,3]``."""
    axis, angle = np.broadcast_arrays(np.asarray(axis, float), np.asarray(angle, float)[..., None])
    angle = angle[..., 0]
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    o = np.zeros_like(x)
    k = np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def rx(a):
    """Rotation about x by ``a`` radians: ``[...] -> [...,3,3]``."""
    return rot_axis(np.array([1.0, 0.0, 0.0]), a)


def ry(a):
    """Rotation about y by ``a`` radians: ``[...] -> [...,3,3]``."""
    return rot_axis(np.array([0.0, 1.0, 0.0]), a)


def rz(a):
    """Rotation about z by ``a`` radians: ``[...] -> [...,3,3]``."""
    return rot_axis(np.array([0.0, 0.0, 1.0]), a)


_STAND = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # Rx(90°): y-up -> z-up


def upright(heading) -> np.ndarray:
    """Global rotation ``[...,3,3]`` standing the rest body up facing ``heading`` (rad).

    Same as :func:`jaxmotion.geometry.upright_orientation`, in float64 numpy.
    """
    return rz(np.asarray(heading, float) + np.pi / 2) @ _STAND


def rotvec(m: np.ndarray) -> np.ndarray:
    """Axis-angle ``[...,3]`` of rotation matrices ``[...,3,3]``."""
    shp = m.shape[:-2]
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_rotvec().reshape(*shp, 3)


def from_rotvec(v: np.ndarray) -> np.ndarray:
    """Rotation matrices ``[...,3,3]`` from axis-angle ``[...,3]``."""
    shp = v.shape[:-1]
    return Rotation.from_rotvec(v.reshape(-1, 3)).as_matrix().reshape(*shp, 3, 3)


def slerp(r0: np.ndarray, r1: np.ndarray, w) -> np.ndarray:
    """Geodesic blend of rotations: ``r0 exp(w log(r0ᵀ r1))``; ``w`` broadcasts over ``[...]``."""
    rel = rotvec(np.swapaxes(r0, -1, -2) @ r1)
    return r0 @ from_rotvec(rel * np.asarray(w, float)[..., None])


def local_from_global(g: np.ndarray) -> np.ndarray:
    """Local joint rotations ``[...,22,3,3]`` from global ones (joint 0 stays global)."""
    loc = g.copy()
    par = np.asarray(PARENTS[1:])
    loc[..., 1:, :, :] = np.swapaxes(g[..., par, :, :], -1, -2) @ g[..., 1:, :, :]
    return loc


def fk_numpy(local: np.ndarray, transl: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Forward kinematics in numpy, SMPL-X convention: ``[T,22,3,3], [T,3], [22,3] -> [T,22,3]``."""
    g = [local[:, 0]]
    pos = [rest[0] + transl]
    for j in range(1, NUM_JOINTS):
        p = PARENTS[j]
        pos.append(pos[p] + np.einsum("tij,j->ti", g[p], rest[j] - rest[p]))
        g.append(g[p] @ local[:, j])
    return np.stack(pos, 1)


def frame(u: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Orthonormal frame, columns ``[u, m'×u, m']`` with ``m'`` = ``m`` made orthogonal to ``u``."""
    u = normalize(u)
    m = normalize(m - np.sum(m * u, -1, keepdims=True) * u)
    return np.stack([u, np.cross(m, u), m], -1)


@dataclass(frozen=True)
class Body:
    """Rest geometry of one body shape (float64, SMPL-X frame unless noted).

    Attributes:
      betas: ``[10]`` shape coefficients. rest: ``[22,3]`` rest joints, metres.
      thigh, shin, upper_arm, forearm: ``[2]`` bone lengths (left, right), metres.
      hip_center: ``[3]`` midpoint of the rest hips (the root we animate).
      toe_off: ``[2,3]`` rest vector ankle -> foot joint.
      ankle_height: ``[2]`` ankle joint above the floor with the foot flat, metres.
      stand_height: hip-centre height of a relaxed upright stance, metres (world z).
    """

    betas: np.ndarray
    rest: np.ndarray
    thigh: np.ndarray
    shin: np.ndarray
    upper_arm: np.ndarray
    forearm: np.ndarray
    hip_center: np.ndarray
    toe_off: np.ndarray
    ankle_height: np.ndarray
    stand_height: float

    @property
    def leg(self) -> np.ndarray:
        """Hip-to-ankle reach of a straight leg ``[2]``."""
        return self.thigh + self.shin


def _len(rest, a, b):
    return np.array([np.linalg.norm(rest[a[i]] - rest[b[i]]) for i in range(2)])


def make_body(betas: np.ndarray) -> Body:
    """Body geometry for shape coefficients ``betas`` ``[10]``."""
    betas = np.asarray(betas, np.float64)
    rest = np.asarray(rest_joints(jnp.asarray(betas, jnp.float32)), np.float64)
    toe_off = np.stack([rest[FOOT[i]] - rest[ANKLE[i]] for i in range(2)])
    ankle_h = TOE_HEIGHT - toe_off[:, 1]  # the flat foot is the rest foot, stood up
    thigh, shin = _len(rest, KNEE, HIP), _len(rest, ANKLE, KNEE)
    hc = 0.5 * (rest[1] + rest[2])
    # Relaxed stance: ankles under the hips, knees just off straight (~9 deg).
    lat = np.array([abs(rest[ANKLE[i], 0] - rest[HIP[i], 0]) for i in range(2)])
    reach = 0.997 * (thigh + shin)
    stand = float(np.min(ankle_h + np.sqrt(reach**2 - lat**2) + (rest[HIP, 1] - hc[1])))
    return Body(
        betas=betas,
        rest=rest,
        thigh=thigh,
        shin=shin,
        upper_arm=_len(rest, ELBOW, SHOULDER),
        forearm=_len(rest, WRIST, ELBOW),
        hip_center=hc,
        toe_off=toe_off,
        ankle_height=ankle_h,
        stand_height=stand,
    )


def two_bone(root, target, pole, l1, l2, rest_u1, rest_u2, rest_m, max_reach=0.9995, soft=0.01):
    """Analytic two-bone IK with exact bone lengths, vectorised over ``[T]``.

    Args:
      root, target, pole: ``[T,3]`` world root joint, wanted end position and the
        direction the middle joint should bend towards.
      l1, l2: bone lengths (metres). rest_u1, rest_u2: ``[3]`` rest bone directions.
      rest_m: ``[3]`` rest bend-plane normal (the hinge axis of the middle joint).
      max_reach: the end stops at this fraction of ``l1 + l2`` (no hyper-extension).
      soft: "soft IK": beyond ``(1 - soft)(l1 + l2)`` the reach approaches its limit
        exponentially instead of linearly, so the middle joint does not snap when
        the limb straightens (the end may fall short there by a few millimetres).
    Returns:
      ``(g1 [T,3,3], g2 [T,3,3], mid [T,3], end [T,3])``: global rotations of the
      root and middle joints (each maps its rest bone onto the solved bone) and
      the solved joint positions. ``end == target`` within ``(1 - soft)(l1 + l2)``.
    """
    d = target - root
    dist = np.linalg.norm(d, axis=-1)
    dhat = normalize(d)
    total = l1 + l2
    if soft > 0:
        ds = (1.0 - soft) * total
        span = (max_reach - 1.0 + soft) * total
        dist = np.where(dist > ds, ds + span * (1.0 - np.exp(-(dist - ds) / span)), dist)
    reach = np.clip(dist, abs(l1 - l2) + 1e-4, max_reach * total)
    n = pole - np.sum(pole * dhat, -1, keepdims=True) * dhat
    # Degenerate pole (parallel to the limb): fall back to any perpendicular.
    alt = np.cross(dhat, np.array([0.0, 0.0, 1.0]))
    alt = np.where(np.linalg.norm(alt, axis=-1, keepdims=True) < 1e-6, [1.0, 0, 0], alt)
    n = np.where(np.linalg.norm(n, axis=-1, keepdims=True) < 1e-6, alt, n)
    n = normalize(n)
    cos_a = np.clip((l1**2 + reach**2 - l2**2) / (2 * l1 * reach), -1.0, 1.0)
    a = np.arccos(cos_a)[:, None]
    u1 = np.cos(a) * dhat + np.sin(a) * n
    mid = root + l1 * u1
    end = root + reach[:, None] * dhat
    u2 = normalize(end - mid)
    m = normalize(np.cross(dhat, n))
    g1 = frame(u1, m) @ frame(rest_u1, rest_m).T
    g2 = frame(u2, m) @ frame(rest_u2, rest_m).T
    return g1, g2, mid, end


@functools.lru_cache(maxsize=1)
def _jit_joints():
    return jax.jit(smplx_joints)


def jax_joints(global_orient, body_pose, transl, betas) -> np.ndarray:
    """Joints ``[T,22,3]`` (float32) through the foundation's jitted SMPL-X FK.

    Inputs are padded to :data:`MAX_FRAMES` so the function compiles once.
    """
    t = len(transl)
    if t > MAX_FRAMES:
        raise ValueError(f"at most {MAX_FRAMES} frames, got {t}")
    pad = ((0, MAX_FRAMES - t),)

    def p(x):
        return np.pad(np.asarray(x, np.float32), pad + ((0, 0),) * (x.ndim - 1))

    out = _jit_joints()(p(global_orient), p(body_pose), p(transl), np.asarray(betas, np.float32))
    return np.asarray(out)[:t]
