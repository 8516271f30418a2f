"""Plausibility of raw joint motions: speeds, teleports, jerk, floor, foot skating, bones.

The checks a person makes before any benchmark number (``DESIGN.md``, "What
counts as a good motion"), for motions ``joints[T, 22, 3]`` (z-up, metres, floor
at z = 0) at ``fps`` frames per second with a frame mask ``[T]``. Per motion:

- ``pelvis_speed_max``: top horizontal (xy) pelvis speed, m/s;
- ``joint_speed_max``: top 3-D speed of any joint, m/s;
- ``teleport``: any joint faster than :data:`TELEPORT_JOINT_SPEED` (9 m/s, i.e.
  0.3 m per frame at 30 fps) or the pelvis (3-D) faster than
  :data:`TELEPORT_PELVIS_SPEED` (3 m/s; people walk indoors at 1.0–1.4 m/s);
- ``jerk_mean``: mean over joints and 4-frame windows of
  ``|| x[t+3] − 3 x[t+2] + 3 x[t+1] − x[t] || · fps³``, m/s³;
- ``floor_penetration``: ``max(0, −min z)`` over every joint of the valid
  frames, m (raw joint heights: a flat foot's toe joint sits 2.5 cm above the
  sole, so this only flags joints really below the floor);
- ``skate_ratio``: :func:`jaxmotion.eval.skating.foot_skating` (fraction of
  valid frame pairs with a foot sliding while on the floor);
- ``bone_length_spread``: for each bone (joint, parent) the max minus the min
  of its length over the valid frames, then the max over the 21 bones, m
  (0 for exact forward kinematics; large for raw generated joints that drift);
- ``valid_frames``: the number of valid frames (int32).

Masks: a frame pair (t, t+1) counts only when both frames are valid, a jerk
window only when its four frames are; padded frames are zeroed before anything
is computed, so NaN or huge garbage in them never leaks in. A motion with fewer
than two valid frames has no pair: its speeds, jerk and skate ratio are 0 and
``teleport`` is False (its ``floor_penetration`` still looks at its one valid
frame; with no valid frame everything is 0). :func:`summarize_plausibility`
leaves such motions out of its statistics.

Pure jax.numpy, written for one motion and lifted with ``vmap``; ``jit`` is
applied in :func:`plausibility` (``fps`` and the thresholds are traced, so
changing them does not recompile). float32 throughout.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.eval._common import safe_norm
from jaxmotion.eval.skating import foot_skating
from jaxmotion.geometry.skeleton import NUM_JOINTS, PARENTS

__all__ = [
    "PLAUSIBILITY_KEYS",
    "TELEPORT_JOINT_SPEED",
    "TELEPORT_PELVIS_SPEED",
    "plausibility",
    "summarize_plausibility",
    "teleports",
]

#: Any joint faster than this (m/s) is a teleport: 0.3 m in one frame at 30 fps. Fast
#: hand and foot motions of everyday movement stay well below it.
TELEPORT_JOINT_SPEED = 9.0
#: The pelvis faster than this (m/s, 3-D) is a teleport: over twice indoor walking speed.
TELEPORT_PELVIS_SPEED = 3.0

#: Keys of the per-motion dict returned by :func:`plausibility`.
PLAUSIBILITY_KEYS: tuple[str, ...] = (
    "pelvis_speed_max",
    "joint_speed_max",
    "teleport",
    "jerk_mean",
    "floor_penetration",
    "skate_ratio",
    "bone_length_spread",
    "valid_frames",
)

_FRAME_BUCKET = 16  # frames are padded (masked out) to a multiple of this


def plausibility(
    joints,
    mask=None,
    *,
    fps: float = 30.0,
    teleport_joint_speed: float = TELEPORT_JOINT_SPEED,
    teleport_pelvis_speed: float = TELEPORT_PELVIS_SPEED,
) -> dict[str, jax.Array]:
    """Plausibility measures of a batch of motions (definitions: module docstring).

    Args:
      joints: ``[B, T, 22, 3]`` joint positions (z-up, metres), or one motion ``[T, 22, 3]``.
      mask: ``[B, T]`` (``[T]`` for one motion) valid frames, or None (all valid).
      fps: frame rate (30 scene data, 20 HumanML3D).
      teleport_joint_speed: joint speed (m/s) above which a motion teleports.
      teleport_pelvis_speed: 3-D pelvis speed (m/s) above which a motion teleports.
    Returns:
      dict with the keys :data:`PLAUSIBILITY_KEYS`: float32 arrays ``[B]`` (``teleport``
      bool, ``valid_frames`` int32), scalars for one motion. Speeds m/s, jerk m/s³,
      lengths m.
    """
    joints, mask, single = _prepared(joints, mask)
    out = _plausibility_batch(
        joints,
        mask,
        jnp.float32(fps),
        jnp.float32(teleport_joint_speed),
        jnp.float32(teleport_pelvis_speed),
    )
    return {k: v[0] for k, v in out.items()} if single else out


def teleports(
    joints,
    mask=None,
    *,
    fps: float = 30.0,
    teleport_joint_speed: float = TELEPORT_JOINT_SPEED,
    teleport_pelvis_speed: float = TELEPORT_PELVIS_SPEED,
) -> jax.Array:
    """The ``teleport`` flag of :func:`plausibility` alone (same arguments; bool ``[B]``, or a
    scalar for one motion), without the other measures: for a caller on a hot path, such as
    the choice among motion candidates in ``generate``."""
    joints, mask, single = _prepared(joints, mask)
    out = _teleport_batch(joints, mask, jnp.float32(fps), jnp.float32(teleport_joint_speed),
                          jnp.float32(teleport_pelvis_speed))
    return out[0] if single else out


def _prepared(joints, mask):
    """Checked ``joints [B, T', 22, 3]`` and ``mask [B, T']`` padded in frames (masked out) to a
    multiple of ``_FRAME_BUCKET``, and whether one motion was given."""
    joints = jnp.asarray(joints, jnp.float32)
    single = joints.ndim == 3
    if single:
        joints = joints[None]
    if joints.ndim != 4 or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(
            f"joints must be [B, T, {NUM_JOINTS}, 3] or [T, {NUM_JOINTS}, 3], got shape "
            f"{joints.shape if not single else joints.shape[1:]}"
        )
    b, t = joints.shape[:2]
    if mask is None:
        mask = jnp.ones((b, t), bool)
    else:
        mask = jnp.asarray(mask).astype(bool)
        if single:
            mask = mask[None]
        if mask.shape != (b, t):
            want = f"[{t}]" if single else f"[{b}, {t}]"
            raise ValueError(
                f"mask must have shape {want}, got {mask.shape[1:] if single else mask.shape}"
            )
    # Pad frames (masked out) to a multiple of _FRAME_BUCKET: no empty axes for short
    # motions, and motions of varying lengths reuse a few compiled programs.
    size = max(_FRAME_BUCKET, -(-t // _FRAME_BUCKET) * _FRAME_BUCKET)
    if size != t:
        joints = jnp.pad(joints, ((0, 0), (0, size - t), (0, 0), (0, 0)))
        mask = jnp.pad(mask, ((0, 0), (0, size - t)))
    return joints, mask, single


def _speeds(joints, mask, fps, joint_limit, pelvis_limit):
    """One motion's padded-safe frames ``x``, frame pairs, steps, joint speeds ``[T-1, J]``,
    horizontal pelvis speeds ``[T-1]`` and teleport flag."""
    x = jnp.where(mask[:, None, None], joints, 0.0)  # garbage in padded frames never leaks in
    pair = mask[1:] & mask[:-1]  # [T-1]
    step = x[1:] - x[:-1]  # [T-1, J, 3]
    speed = jnp.where(pair[:, None], safe_norm(step) * fps, 0.0)  # [T-1, J]
    pelvis_xy = jnp.where(pair, safe_norm(step[:, 0, :2]) * fps, 0.0)  # [T-1]
    teleport = ((jnp.max(speed) > joint_limit) | (jnp.max(speed[:, 0]) > pelvis_limit)) & (
        jnp.any(pair))
    return x, pair, step, speed, pelvis_xy, teleport


def _plausibility_one(joints, mask, fps, joint_limit, pelvis_limit):
    """One motion: ``joints [T, 22, 3]``, ``mask [T]`` -> dict of scalars."""
    x, pair, step, speed, pelvis_xy, teleport = _speeds(joints, mask, fps, joint_limit,
                                                        pelvis_limit)
    any_pair = jnp.any(pair)
    joint_max = jnp.max(speed)

    window = mask[3:] & mask[2:-1] & mask[1:-2] & mask[:-3]  # [T-3]
    second = step[1:] - step[:-1]  # nested differences: exact 0 for still frames in float32
    third = second[1:] - second[:-1]  # [T-3, J, 3] = x[t+3] - 3 x[t+2] + 3 x[t+1] - x[t]
    jerk = jnp.where(window[:, None], safe_norm(third) * fps**3, 0.0)
    count = jnp.sum(window) * x.shape[1]
    jerk_mean = jnp.sum(jerk) / jnp.maximum(count, 1)

    z_min = jnp.min(jnp.where(mask[:, None], x[..., 2], jnp.inf))
    floor = jnp.maximum(-z_min, 0.0)  # 0 when no frame is valid (min = +inf)

    skate = foot_skating(x, mask, fps=fps)["skate_ratio"]  # NaN without a valid pair
    skate = jnp.where(any_pair, skate, 0.0)

    parents = jnp.asarray(PARENTS[1:])
    bones = safe_norm(x[:, 1:] - x[:, parents])  # [T, 21]
    longest = jnp.max(jnp.where(mask[:, None], bones, -jnp.inf), axis=0)
    shortest = jnp.min(jnp.where(mask[:, None], bones, jnp.inf), axis=0)
    spread = jnp.where(jnp.any(mask), jnp.max(longest - shortest), 0.0)

    return {
        "pelvis_speed_max": jnp.max(pelvis_xy),
        "joint_speed_max": joint_max,
        "teleport": teleport,
        "jerk_mean": jerk_mean,
        "floor_penetration": floor,
        "skate_ratio": skate.astype(jnp.float32),
        "bone_length_spread": spread,
        "valid_frames": jnp.sum(mask).astype(jnp.int32),
    }


_plausibility_batch = jax.jit(jax.vmap(_plausibility_one, in_axes=(0, 0, None, None, None)))
_teleport_batch = jax.jit(jax.vmap(lambda *a: _speeds(*a)[-1], in_axes=(0, 0, None, None, None)))


def summarize_plausibility(per_motion: dict, *, percentiles=(50, 99)) -> dict[str, float]:
    """Table numbers from the per-motion output of :func:`plausibility` (host-side numpy).

    Motions with fewer than two valid frames (``valid_frames < 2``, when that key is
    present) are left out. Returns floats:

    - ``motions``: motions counted; ``teleport_rate``: fraction that teleport;
    - ``pelvis_speed_p{p}`` and ``joint_speed_p{p}`` for each ``p`` in ``percentiles``
      (of the per-motion top speeds, m/s), and ``pelvis_speed_max``;
    - ``jerk_mean`` (m/s³), ``skate_ratio_mean``, ``floor_penetration_mean`` and
      ``floor_penetration_max`` (m), ``bone_length_spread_mean`` / ``_max`` (m): over
      motions.

    Every statistic is NaN when no motion is counted.
    """
    arrays = {k: np.atleast_1d(np.asarray(v)) for k, v in per_motion.items()}
    missing = [k for k in PLAUSIBILITY_KEYS if k != "valid_frames" and k not in arrays]
    if missing:
        raise KeyError(f"per_motion lacks {missing}: pass the output of plausibility()")
    n = len(arrays["teleport"])
    keep = arrays["valid_frames"] >= 2 if "valid_frames" in arrays else np.ones(n, bool)
    a = {k: v[keep].astype(np.float64) for k, v in arrays.items()}
    counted = int(keep.sum())

    def stat(fn, values, *args):
        return float(fn(values, *args)) if counted else float("nan")

    out = {"motions": float(counted), "teleport_rate": stat(np.mean, a["teleport"])}
    for p in percentiles:
        out[f"pelvis_speed_p{p:g}"] = stat(np.percentile, a["pelvis_speed_max"], p)
        out[f"joint_speed_p{p:g}"] = stat(np.percentile, a["joint_speed_max"], p)
    out["pelvis_speed_max"] = stat(np.max, a["pelvis_speed_max"])
    out["jerk_mean"] = stat(np.mean, a["jerk_mean"])
    out["skate_ratio_mean"] = stat(np.mean, a["skate_ratio"])
    out["floor_penetration_mean"] = stat(np.mean, a["floor_penetration"])
    out["floor_penetration_max"] = stat(np.max, a["floor_penetration"])
    out["bone_length_spread_mean"] = stat(np.mean, a["bone_length_spread"])
    out["bone_length_spread_max"] = stat(np.max, a["bone_length_spread"])
    return out
