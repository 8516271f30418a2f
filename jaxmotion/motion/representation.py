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
import numpy as np

from jaxmotion.constants import NUM_JOINTS
from jaxmotion.geometry.rotations import (
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    matrix_to_rotation_6d,
    rotation_6d_to_matrix,
)
from jaxmotion.geometry.skeleton import (
    forward_kinematics_with_rotations,
    kinematic_chain,
    rest_joints,
)

__all__ = [
    "MOTION_DIM",
    "TRAJECTORY_DIM",
    "VELOCITY_DIM",
    "motion_features",
    "motion_to_joints",
    "motion_to_smplx",
    "trajectory_frames",
    "trajectory_velocity",
]

TRAJECTORY_DIM = 9
MOTION_DIM = TRAJECTORY_DIM + 21 * 6
#: Entries per frame of :func:`trajectory_velocity`.
VELOCITY_DIM = 4


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


def motion_to_joints(features, betas=None, joints=None):
    """Joints ``[..., T, 22, 3]`` of motion features ``[..., T, 135]`` by forward kinematics
    of a body of shape ``betas [..., B]`` (default: the neutral body).

    ``joints``: None, or joint indices: then only those are placed, ``[..., T, len(joints),
    3]``, and only the rotations of their :func:`~jaxmotion.geometry.kinematic_chain` are
    read (the feet: 8 of the 21 body rotations; under a gradient, as foot guidance takes
    one, about a third of the whole body's work)."""
    features = jnp.asarray(features, jnp.float32)
    if features.shape[-1] != MOTION_DIM:
        raise ValueError(f"motion features must be [..., T, {MOTION_DIM}], got {features.shape}")
    pelvis, g = trajectory_frames(features)
    rest = rest_joints(betas)[..., None, :, :]  # [..., 1, 22, 3]: the same body every frame
    chain = tuple(range(NUM_JOINTS)) if joints is None else kinematic_chain(joints)
    six = features[..., TRAJECTORY_DIM:]
    if joints is not None:  # the chain's body rotations only (their columns: XLA's fastest)
        six = features[..., np.asarray([TRAJECTORY_DIM + 6 * (j - 1) + c for j in chain[1:]
                                        for c in range(6)])]
    six = six.reshape(*features.shape[:-1], len(chain) - 1, 6)
    local = jnp.concatenate([g[..., None, :, :], rotation_6d_to_matrix(six)], axis=-3)
    placed, _ = forward_kinematics_with_rotations(local, pelvis - rest[..., 0, :], rest, chain)
    return placed if joints is None else placed[..., np.asarray([chain.index(int(j))
                                                                  for j in joints]), :]


def trajectory_velocity(features, mask=None, fps: float = 30.0):
    """How the root moves, in the body's own heading frame: ``[..., T, 4]`` = the pelvis's
    forward and leftward speed along the ground (m/s, forward being the body's z axis
    projected on the floor), its vertical speed (m/s) and the turning rate of the heading
    (rad/s divided by π), by central differences over the valid frames (one-sided at the
    ends of ``mask``; 0 on padded frames and for a motion of one frame).

    A walk's step rhythm (speed rising and falling twice a cycle, the pelvis's bob and sway)
    reads plainly here, where the absolute trajectory features only move by a small fraction
    of their spread between two frames.

    Args:
      features: ``[..., T, >=9]`` trajectory (or motion) features, metres (not normalised).
      mask: ``[..., T]`` bool, True = valid frame (default all).
    """
    pelvis, rot = trajectory_frames(features)
    mask = (jnp.ones(pelvis.shape[:-1], bool) if mask is None
            else jnp.broadcast_to(jnp.asarray(mask, bool), pelvis.shape[:-1]))
    fwd = rot[..., :, 2]
    yaw = jnp.arctan2(fwd[..., 1], fwd[..., 0])
    x = jnp.concatenate([pelvis, yaw[..., None]], -1)  # [..., T, 4]
    pad = jnp.zeros(mask.shape[:-1] + (1,), bool)
    m_next = jnp.concatenate([mask[..., 1:], pad], -1) & mask
    m_prev = jnp.concatenate([pad, mask[..., :-1]], -1) & mask
    nxt = jnp.concatenate([x[..., 1:, :], x[..., -1:, :]], -2)  # the next frame (last: itself)
    prv = jnp.concatenate([x[..., :1, :], x[..., :-1, :]], -2)
    d = jnp.where(m_next[..., None], nxt, x) - jnp.where(m_prev[..., None], prv, x)
    d = d.at[..., 3].set((d[..., 3] + jnp.pi) % (2 * jnp.pi) - jnp.pi)  # wrap the turn
    steps = (m_next.astype(jnp.float32) + m_prev.astype(jnp.float32))[..., None]
    v = d / jnp.maximum(steps, 1.0) * fps
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    out = jnp.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1],
                     v[..., 2], v[..., 3] / jnp.pi], -1)
    return jnp.where(mask[..., None], out, 0.0)
