"""The object-centric pipeline's motion representation: a root trajectory and body rotations.

Two feature vectors per frame (pure JAX, any leading batch axes, z-up, metres):

- **trajectory** ``[..., T, 9]`` (:data:`TRAJECTORY_DIM`): the pelvis position (3) and the
  6D form of the global orientation (6; the first two rows of the rotation matrix,
  :func:`~jaxmotion.geometry.matrix_to_rotation_6d`);
- **motion** ``[..., T, 135]`` (:data:`MOTION_DIM`): the trajectory followed by the 21 body
  joints' rotations relative to their parents, 6D each (SMPL-X ``body_pose``).

Cen et al. use SMPL-X's ``transl`` as the translation; here it is the pelvis itself (``transl``
plus the rest pelvis of the body's shape), so that the trajectory is the path the body
actually takes whatever its shape, and a crop's rigid transform moves it as it moves any
point. Joints come back by forward kinematics (:func:`motion_to_joints`): bone lengths are
those of the body's shape in every frame, whatever the network writes.
"""

from __future__ import annotations

import jax.numpy as jnp

from jaxmotion.geometry.rotations import (
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    matrix_to_rotation_6d,
    rotation_6d_to_matrix,
)
from jaxmotion.geometry.skeleton import forward_kinematics, rest_joints

__all__ = [
    "MOTION_DIM",
    "TRAJECTORY_DIM",
    "motion_features",
    "motion_to_joints",
    "motion_to_smplx",
    "trajectory_frames",
]

TRAJECTORY_DIM = 9
MOTION_DIM = TRAJECTORY_DIM + 21 * 6


def motion_features(pelvis, global_rot, body_pose):
    """Features from SMPL-X parameters.

    Args:
      pelvis: ``[..., T, 3]`` pelvis positions (joint 0), metres.
      global_rot: ``[..., T, 3, 3]`` global orientation matrices.
      body_pose: ``[..., T, 21, 3]`` axis-angle body pose (SMPL-X ``body_pose``).
    Returns:
      ``[..., T, 135]``; its first :data:`TRAJECTORY_DIM` entries are the trajectory.
    """
    pelvis = jnp.asarray(pelvis, jnp.float32)
    body = matrix_to_rotation_6d(axis_angle_to_matrix(jnp.asarray(body_pose, jnp.float32)))
    body = body.reshape(*body.shape[:-2], 21 * 6)
    return jnp.concatenate([pelvis, matrix_to_rotation_6d(jnp.asarray(global_rot)), body], -1)


def trajectory_frames(features):
    """``(pelvis [..., T, 3], rotation [..., T, 3, 3])`` of trajectory (or motion) features."""
    features = jnp.asarray(features, jnp.float32)
    if features.shape[-1] < TRAJECTORY_DIM:
        raise ValueError(f"features must have at least {TRAJECTORY_DIM} entries per frame, "
                         f"got {features.shape}")
    return features[..., :3], rotation_6d_to_matrix(features[..., 3:TRAJECTORY_DIM])


def motion_to_smplx(features, betas=None) -> dict:
    """SMPL-X parameters of motion features ``[..., T, 135]``: ``global_orient [..., T, 3]``,
    ``body_pose [..., T, 21, 3]`` (axis-angle), ``transl [..., T, 3]`` (so that SMPL-X's
    pelvis lands on the features' pelvis for a body of shape ``betas [..., B]``)."""
    features = jnp.asarray(features, jnp.float32)
    if features.shape[-1] != MOTION_DIM:
        raise ValueError(f"motion features must be [..., T, {MOTION_DIM}], got {features.shape}")
    pelvis, g = trajectory_frames(features)
    body = rotation_6d_to_matrix(features[..., TRAJECTORY_DIM:].reshape(
        *features.shape[:-1], 21, 6))
    rest = rest_joints(betas)
    return {"global_orient": matrix_to_axis_angle(g), "body_pose": matrix_to_axis_angle(body),
            "transl": pelvis - rest[..., None, 0, :]}


def motion_to_joints(features, betas=None):
    """Joints ``[..., T, 22, 3]`` of motion features ``[..., T, 135]`` by forward kinematics
    of a body of shape ``betas [..., B]`` (default: the neutral body)."""
    features = jnp.asarray(features, jnp.float32)
    if features.shape[-1] != MOTION_DIM:
        raise ValueError(f"motion features must be [..., T, {MOTION_DIM}], got {features.shape}")
    pelvis, g = trajectory_frames(features)
    body = rotation_6d_to_matrix(features[..., TRAJECTORY_DIM:].reshape(
        *features.shape[:-1], 21, 6))
    local = jnp.concatenate([g[..., None, :, :], body], axis=-3)
    rest = rest_joints(betas)[..., None, :, :]  # [..., 1, 22, 3]: the same body every frame
    return forward_kinematics(local, pelvis - rest[..., 0, :], rest)
