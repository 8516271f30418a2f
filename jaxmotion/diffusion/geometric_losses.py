"""Geometric losses on the predicted clean motion, beside the x0 loss (as MDM's).

An x0 loss on absolute joint positions alone cannot tell a smooth path from one that holds
still and then jumps: with ~12 cm of position error per frame, 15–20 cm stairs cost no more
than a smooth walk, and a model trained on it writes its own fine timing as holds and jumps
(docs/results.md in the git history, "Why the motions teleport"). These terms compare the
*motion* instead: per-frame joint velocities and accelerations of the prediction against the
data's, in physical units, over valid frames only.

Both take the motions in metres, ``[B, T, J, 3]`` (de-normalise the model's features first:
for z-scored absolute positions, ``x * std`` — the mean cancels in differences), the frame
mask ``[B, T]`` and ``fps``; a velocity counts when both of its frames are valid, an
acceleration when all three are.

For models that write joint rotations (the object-centric completion model), the motions are
the forward kinematics of the prediction: :func:`joint_position_loss` compares the joints
themselves (a floating or sunken foot is a position error a rotation loss weighs lightly), and
:func:`foot_contact_loss` is MDM's foot-contact term: where the data's foot stands still, the
prediction's foot must too (a sliding planted foot is foot skating).
"""

from __future__ import annotations

import jax.numpy as jnp

from jaxmotion.constants import FOOT_JOINTS

__all__ = ["acceleration_loss", "foot_contact_loss", "joint_position_loss", "velocity_loss"]


def _pairs(mask, lag: int):
    m = jnp.asarray(mask, bool)
    out = m[:, lag:]
    for i in range(lag):
        out = out & m[:, i:m.shape[1] - lag + i]
    return out.astype(jnp.float32)


def _masked_mse(err, valid, weights=None):
    """Mean of ``‖err‖²`` over joints of the valid frames: ``err [B,T',J,3]``, ``valid [B,T']``;
    ``weights [B]`` scale each example's terms (the mean stays over the valid entries)."""
    sq = jnp.sum(err * err, axis=-1)  # [B, T', J]
    w = valid[..., None] * jnp.ones_like(sq)
    scale = 1.0 if weights is None else jnp.asarray(weights, sq.dtype)[:, None, None]
    return jnp.sum(sq * w * scale) / jnp.maximum(jnp.sum(w), 1.0)


def velocity_loss(pred, target, mask, fps: float, weights=None):
    """Mean squared error of joint velocities (m/s)², ``pred``, ``target`` ``[B,T,J,3]`` in
    metres, ``mask [B,T]``; velocities between consecutive valid frames. ``weights [B]``:
    per-example factors (e.g. the signal level ᾱ_t of each example's diffusion step)."""
    v_p = (pred[:, 1:] - pred[:, :-1]) * fps
    v_t = (target[:, 1:] - target[:, :-1]) * fps
    return _masked_mse(v_p - v_t, _pairs(mask, 1), weights)


def acceleration_loss(pred, target, mask, fps: float, weights=None):
    """Mean squared error of joint accelerations (m/s²)², as :func:`velocity_loss` over
    three consecutive valid frames."""
    def acc(x):
        return (x[:, 2:] - 2.0 * x[:, 1:-1] + x[:, :-2]) * fps * fps
    return _masked_mse(acc(pred) - acc(target), _pairs(mask, 2), weights)


def joint_position_loss(pred, target, mask, weights=None):
    """Mean squared joint position error (m²) over the valid frames, ``pred``, ``target``
    ``[B,T,J,3]`` in metres, ``mask [B,T]``, ``weights [B]`` as :func:`velocity_loss`."""
    return _masked_mse(pred - target, jnp.asarray(mask, jnp.float32), weights)


def foot_contact_loss(pred, target, mask, fps: float, weights=None, *,
                      foot_joints=FOOT_JOINTS, still_speed: float = 0.2):
    """MDM's foot-contact term: mean squared speed (m/s)² of the prediction's foot joints over
    the frame pairs where the target's foot joint is still (speed below ``still_speed`` m/s,
    both frames valid). The mean is over the still (foot, pair) entries; none gives 0.

    ``pred``, ``target`` ``[B,T,J,3]`` in metres, ``mask [B,T]``; ``weights [B]`` as
    :func:`velocity_loss`."""
    idx = jnp.asarray(foot_joints, jnp.int32)
    p, t = pred[:, :, idx], target[:, :, idx]
    v_p = (p[:, 1:] - p[:, :-1]) * fps  # [B, T-1, F, 3]
    v_t = (t[:, 1:] - t[:, :-1]) * fps
    still = (jnp.linalg.norm(v_t, axis=-1) < still_speed) * _pairs(mask, 1)[..., None]
    scale = 1.0 if weights is None else jnp.asarray(weights, p.dtype)[:, None, None]
    sq = jnp.sum(v_p * v_p, axis=-1)
    return jnp.sum(sq * still * scale) / jnp.maximum(jnp.sum(still), 1.0)
