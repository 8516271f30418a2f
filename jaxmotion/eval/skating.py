"""Foot skating: feet sliding horizontally while they touch the floor.

Follows the skating ratio of GMD (Karunratanakul et al. 2023) and OmniControl
(Xie et al. 2024) — "the proportion of frames in which a foot skids more than
2.5 cm while in contact with the ground (foot height < 5 cm)" at HumanML3D's
20 fps, i.e. a horizontal speed above 0.5 m/s — adapted to the z-up scene frame
with the floor at z = 0. For a motion ``joints[T, 22, 3]`` at ``fps``, each foot
joint f and each pair of consecutive valid frames (t, t+1)::

    h_f(t)       = z_f(t) − o_f                      height above its flat-foot height
    contact_f(t) = h_f(t) < H  and  h_f(t+1) < H      (touching the floor in both frames)
    v_f(t)       = || xy_f(t+1) − xy_f(t) || · fps    horizontal speed, m/s
    skate(t)     = any_f [contact_f(t) and v_f(t) > V]

    skate_ratio    = mean_t skate(t)                               over valid pairs, in [0, 1]
    skate_velocity = mean of v_f(t) over the pairs (f, t) in contact, m/s (0 if none)

Foot joints (common practice; HumanML3D's foot-contact labels use the same four):
left/right ankle 7, 8 and left/right foot (toe base) 10, 11. GMD uses only
10, 11 — pass ``foot_joints=(10, 11)`` for that. The offsets ``o_f`` are the
joints' heights above the sole with the foot flat (SMPL-X: toe joint ≈ 2.5 cm,
ankle ≈ 7 cm, :mod:`jaxmotion.motion.limits`), so the same H works for both;
pass zeros to threshold raw heights as HumanML3D code does (its floor is at the
lowest joint). No temporal smoothing of the speed (GMD averages 5 frames).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmotion.constants import FOOT_JOINTS  # l_ankle, r_ankle, l_foot, r_foot (SMPL-X)
from jaxmotion.eval._common import as_mask, masked_mean, require_any, safe_norm

__all__ = ["FOOT_FLOOR_OFFSETS", "FOOT_JOINTS", "foot_faults", "foot_skating"]

#: Height (m) of each of :data:`FOOT_JOINTS` above the floor when the foot is flat.
FOOT_FLOOR_OFFSETS: tuple[float, ...] = (0.07, 0.07, 0.025, 0.025)


def foot_skating(
    joints,
    mask=None,
    *,
    fps: float = 30.0,
    foot_joints=FOOT_JOINTS,
    floor_offsets=FOOT_FLOOR_OFFSETS,
    height_threshold: float = 0.05,
    velocity_threshold: float = 0.5,
):
    """Foot-skating ratio and mean sliding speed of one motion (formulas: module docstring).

    Args:
      joints: ``[T, J, 3]`` joint positions, z-up, floor at z = 0, metres.
      mask: ``[T]`` valid frames, or None; a pair (t, t+1) counts only if both are valid.
      fps: frame rate (30 scene data, 20 HumanML3D).
      foot_joints: joint indices tested; floor_offsets: their flat-foot heights (m),
        same length.
      height_threshold: H, metres above the flat-foot height (5 cm).
      velocity_threshold: V, horizontal speed in m/s (0.5 m/s = 2.5 cm per frame at
        20 fps = 1.67 cm per frame at 30 fps).
    Returns:
      dict ``skate_ratio`` (fraction of valid frame pairs with a skating foot) and
      ``skate_velocity`` (m/s). Fewer than two valid frames: ``ValueError``
      eagerly, NaN ratio under ``jit``.
    """
    joints = jnp.asarray(joints, jnp.float32)
    if joints.ndim != 3 or joints.shape[-1] != 3:
        raise ValueError(f"joints must be [T, J, 3], got shape {joints.shape}")
    t = joints.shape[0]
    if t < 2:
        raise ValueError(f"foot skating needs at least 2 frames, got {t}")
    idx = tuple(int(i) for i in foot_joints)
    offsets = jnp.asarray(floor_offsets, jnp.float32)
    if offsets.shape != (len(idx),):
        raise ValueError(f"floor_offsets must have one value per foot joint ({len(idx)})")
    mask = as_mask(mask, t, "mask")
    pair_ok = None if mask is None else mask[1:] & mask[:-1]  # [T-1]
    require_any(pair_ok, "mask has no two consecutive valid frames: skating is undefined")

    return _skating(
        joints[:, idx, :],
        offsets,
        pair_ok,
        jnp.float32(fps),
        jnp.float32(height_threshold),
        jnp.float32(velocity_threshold),
    )


def _sliding(feet, offsets, fps, height_threshold, velocity_threshold):
    """Of ``feet [T, F, 3]``: ``(height [T, F]`` above the flat-foot height, ``in_contact
    [T-1, F]``, ``speed [T-1, F]`` horizontal m/s, ``skating [T-1]`` any foot sliding) as the
    module docstring defines them."""
    height = feet[..., 2] - offsets[None]
    low = height < height_threshold  # [T, F]
    in_contact = low[1:] & low[:-1]  # [T-1, F]
    speed = safe_norm(feet[1:, :, :2] - feet[:-1, :, :2]) * fps  # [T-1, F]
    skating = jnp.any(in_contact & (speed > velocity_threshold), axis=1)  # [T-1]
    return height, in_contact, speed, skating


@jax.jit
def _skating(feet, offsets, pair_ok, fps, height_threshold, velocity_threshold):
    """``feet [T, F, 3]`` -> dict (formulas: module docstring)."""
    _, in_contact, speed, skating = _sliding(feet, offsets, fps, height_threshold,
                                             velocity_threshold)

    ratio = masked_mean(skating.astype(jnp.float32), pair_ok)
    counted = in_contact if pair_ok is None else in_contact & pair_ok[:, None]
    n = jnp.sum(counted)
    velocity = jnp.sum(jnp.where(counted, speed, 0.0)) / jnp.maximum(n, 1)
    return {"skate_ratio": ratio, "skate_velocity": velocity}


def foot_faults(joints, mask=None, *, fps: float = 30.0, height_threshold: float = 0.05,
                velocity_threshold: float = 0.5, sink: float = 0.03):
    """The share of frame pairs in which the feet are not planted the way a person's are.

    A pair (t, t+1) of valid frames is at fault when, in it, a foot **slides** (it skates,
    as :func:`foot_skating` counts it: a foot joint under ``height_threshold`` above its
    flat-foot height in both frames moving faster than ``velocity_threshold`` m/s), or at
    frame t+1 the lowest foot joint **hovers** more than ``height_threshold`` above its
    flat-foot height (no foot reaches the floor), or **sinks** more than ``sink`` metres
    under it (the floor at z = 0). Skating alone rewards feet in the air (a foot above
    5 cm never skates); with the other two a motion scores well only with its feet on the
    floor and still while they are. A lying or seated body's feet may be off the floor:
    compare motions of the same action (the best of M does), not across actions.

    Pure JAX (jit / vmap it): ``joints [T, 22, 3]`` (z-up, metres), ``mask [T]`` or None.
    Returns a float32 scalar in [0, 1] (NaN without two consecutive valid frames).
    """
    feet = jnp.asarray(joints, jnp.float32)[:, jnp.asarray(FOOT_JOINTS), :]  # [T, F, 3]
    height, _, _, slides = _sliding(feet, jnp.asarray(FOOT_FLOOR_OFFSETS, jnp.float32), fps,
                                    height_threshold, velocity_threshold)
    lowest = jnp.min(height[1:], axis=1)
    fault = slides | (lowest > height_threshold) | (lowest < -sink)  # [T-1]
    mask = None if mask is None else jnp.asarray(mask, bool)
    return masked_mean(fault, None if mask is None else mask[1:] & mask[:-1])
