"""Joints-only body metrics for fast validation during training.

The body is approximated by spheres around the 22 SMPL-X joints
(:data:`JOINT_RADII`), whose signed distance is, positive inside,

    s(p) = max_j (r_j − || p − c_j ||)

(exact outside the union of spheres, the deepest penetration inside). On it,
non-collision, contact and goal distance are computed exactly as for the mesh
(:mod:`jaxmotion.eval.body_metrics`). Coarse: a check of trends during
training, not a substitute for the mesh metrics in reported tables.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmotion.eval._common import safe_norm
from jaxmotion.eval.body_metrics import (
    CONTACT_THRESHOLD,
    anchor_index,
    check_target,
    contact,
    min_penetration_gap,
    non_collision,
)
from jaxmotion.geometry.skeleton import JOINT_NAMES

__all__ = [
    "JOINT_RADII",
    "joint_sphere_sdf",
    "joint_sphere_sdf_frames",
    "joints_goal_distance",
    "joints_physical_metrics",
]

# Sphere radii (m) of the joints-only body, SMPL-X joint order. Chosen so the union of
# spheres roughly fills a neutral adult body: torso 0.11-0.12, hips 0.09, head 0.10,
# limbs 0.04-0.07. The foot (toe) joint sits ~2.5 cm and the ankle ~7 cm above the
# floor with the foot flat, so their radii (0.02, 0.05) keep a standing body from
# colliding with floor points while still counting as contact (|s| < 5 cm).
_RADII = {
    "pelvis": 0.12, "l_hip": 0.09, "r_hip": 0.09, "spine1": 0.11, "l_knee": 0.06,
    "r_knee": 0.06, "spine2": 0.11, "l_ankle": 0.05, "r_ankle": 0.05, "spine3": 0.12,
    "l_foot": 0.02, "r_foot": 0.02, "neck": 0.06, "l_collar": 0.07, "r_collar": 0.07,
    "head": 0.10, "l_shoulder": 0.06, "r_shoulder": 0.06, "l_elbow": 0.05, "r_elbow": 0.05,
    "l_wrist": 0.04, "r_wrist": 0.04,
}  # fmt: skip
#: ``[22]`` sphere radius per SMPL-X body joint, metres (see the comment above).
JOINT_RADII: tuple[float, ...] = tuple(_RADII[n] for n in JOINT_NAMES)


def _radii(radii, j):
    r = jnp.asarray(JOINT_RADII if radii is None else radii, jnp.float32)
    if r.shape != (j,):
        raise ValueError(f"radii must be [{j}] (one per joint), got shape {r.shape}")
    return r


def joint_sphere_sdf(points, joints, radii=None):
    """Signed distance to a body made of spheres at the joints, positive inside: ``[N,3] -> [N]``.

    ``s(p) = max_j (r_j − || p − c_j ||)``: exact outside the union of spheres
    (minus the distance to the nearest sphere), the deepest penetration inside.
    Same sign convention as :func:`signed_distance_to_body`.

    Args:
      points: ``[N, 3]``; joints: ``[J, 3]`` sphere centres, metres.
      radii: ``[J]`` metres; default :data:`JOINT_RADII` (J = 22).
    """
    points = jnp.asarray(points, jnp.float32)
    joints = jnp.asarray(joints, jnp.float32)
    if joints.ndim != 2 or joints.shape[-1] != 3 or joints.shape[0] == 0:
        raise ValueError(f"joints must be [J, 3] with J >= 1, got shape {joints.shape}")
    if points.ndim != 2 or points.shape[-1] != 3:
        raise ValueError(f"points must be [N, 3], got shape {points.shape}")
    return _sphere_sdf(points, joints, _radii(radii, joints.shape[0]))


@jax.jit
def _sphere_sdf(points, joints, radii):
    d = safe_norm(points[:, None, :] - joints[None, :, :])  # [N, J]; J is small
    return jnp.max(radii[None, :] - d, axis=1)


def joint_sphere_sdf_frames(points, joints, radii=None):
    """:func:`joint_sphere_sdf` per frame (sequential): ``[N,3], [T,J,3] -> [T, N]``."""
    joints = jnp.asarray(joints, jnp.float32)
    if joints.ndim != 3:
        raise ValueError(f"joints must be [T, J, 3], got shape {joints.shape}")
    return jax.lax.map(lambda jt: joint_sphere_sdf(points, jt, radii), joints)


def joints_goal_distance(target_points, joints, radii=None, *, target_mask=None):
    """:func:`goal_distance` with the sphere body of one frame: ``[M,3], [J,3] -> ()``."""
    target_points, target_mask = check_target(target_points, target_mask)
    return min_penetration_gap(joint_sphere_sdf(target_points, joints, radii), target_mask)


def joints_physical_metrics(
    points,
    joints,
    target_points=None,
    mask=None,
    action: str = "",
    *,
    radii=None,
    threshold: float = CONTACT_THRESHOLD,
    point_mask=None,
    target_mask=None,
):
    """Fast validation metrics from joints only (body ≈ spheres at the joints).

    Args:
      points: ``[N, 3]`` scene points; joints: ``[T, J, 3]``; mask: ``[T]`` frames.
      target_points: ``[M, 3]`` target-object points, or None (no goal distance).
      action: action label or text (static), picks the anchor frame.
    Returns:
      dict with ``non_collision``, ``contact`` and, with a target, ``goal_distance``
      (same definitions as the vertex versions, on :func:`joint_sphere_sdf`).
    """
    joints = jnp.asarray(joints, jnp.float32)
    sdf = joint_sphere_sdf_frames(points, joints, radii)
    out = {
        "non_collision": non_collision(sdf, mask, point_mask=point_mask),
        "contact": contact(sdf, threshold, mask, point_mask=point_mask),
    }
    if target_points is not None:
        a = anchor_index(jnp.ones(joints.shape[0], bool) if mask is None else mask, action)
        out["goal_distance"] = joints_goal_distance(
            target_points, joints[a], radii, target_mask=target_mask
        )
    return out
