"""Trajectory-control metrics, as OmniControl (Xie et al., ICLR 2024) and MotionLCM report them.

For a motion ``joints [T, J, 3]`` whose ``joint`` (the pelvis, 0) was asked to follow
``target [T, D]`` (D = 2: the ground path x, y, as ``jaxmotion generate --trajectory``
controls it; D = 3: positions) in the frames of ``mask [T]`` (the controlled frames), with
``e(t) = || joints[t, joint, :D] − target[t] ||``:

    average error   = mean_t e(t)                             metres
    location error  = mean_t [e(t) > threshold]               the share of controlled frames
                                                              farther than 50 cm
    trajectory error = [max_t e(t) > threshold]               the motion fails if any frame does

Over a batch the trajectory error is the share of failed motions. Pure JAX, jit-able.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmotion.eval._common import as_mask, require_any

__all__ = ["CONTROL_THRESHOLD", "control_errors"]

#: The distance (m) beyond which a controlled frame counts as missed (OmniControl's 50 cm).
CONTROL_THRESHOLD = 0.5


def control_errors(joints, target, mask=None, *, joint: int = 0,
                   threshold: float = CONTROL_THRESHOLD) -> dict:
    """Trajectory, location and average error of one motion (formulas: module docstring).

    Args:
      joints: ``[T, J, 3]`` metres. target: ``[T, 2]`` (x, y) or ``[T, 3]``.
      mask: ``[T]`` the controlled frames (None: all). joint: the controlled joint.
      threshold: metres.
    Returns:
      dict of scalars ``trajectory_error`` (0 or 1), ``location_error`` (in [0, 1]),
      ``average_error`` (m), ``max_error`` (m).
    """
    joints = jnp.asarray(joints, jnp.float32)
    target = jnp.asarray(target, jnp.float32)
    if joints.ndim != 3 or joints.shape[-1] != 3:
        raise ValueError(f"joints must be [T, J, 3], got shape {joints.shape}")
    t = joints.shape[0]
    if target.ndim != 2 or target.shape[0] != t or target.shape[1] not in (2, 3):
        raise ValueError(f"target must be [T, 2] or [T, 3] with T = {t} (the motion's "
                         f"frames), got shape {target.shape}")
    if not 0 <= joint < joints.shape[1]:
        raise ValueError(f"joint {joint} is not one of the motion's {joints.shape[1]} joints")
    mask = as_mask(mask, t, "mask")
    require_any(mask, "mask controls no frame: the errors are undefined")
    return _errors(joints[:, joint, : target.shape[1]], target,
                   jnp.ones(t, bool) if mask is None else mask, jnp.float32(threshold))


@jax.jit
def _errors(pos, target, mask, threshold):
    err = jnp.linalg.norm(pos - target, axis=-1)
    n = jnp.maximum(jnp.sum(mask), 1)
    miss = (err > threshold) & mask
    return {"trajectory_error": jnp.any(miss).astype(jnp.float32),
            "location_error": jnp.sum(miss) / n,
            "average_error": jnp.sum(jnp.where(mask, err, 0.0)) / n,
            "max_error": jnp.max(jnp.where(mask, err, 0.0))}
