"""A geometric action judge: did the motion do the action the text asks for, on the target?

No network: the body pose at the anchor frame of HUMANISE (the last valid
frame; the first for "stand up", :func:`jaxmotion.eval.body_metrics.anchor_index`)
is compared with the target object's axis-aligned box and, optionally, its
points. Per action:

- **sit** (pose at the last frame) and **stand_up** (at the first frame) —
  *seated*: the pelvis over the box footprint (xy, within
  :data:`FOOTPRINT_TOLERANCE`), the pelvis joint :data:`SEAT_HEIGHT_BAND` above the
  seat surface, the torso (pelvis→neck) within :data:`UPRIGHT_MAX_TILT` of
  vertical, and the knees bent (pelvis height over the ankles below
  :data:`KNEES_BENT_MAX_RATIO` leg lengths, thighs above
  :data:`SEATED_MIN_THIGH_ELEVATION`);
- **lie** — *lying*: the torso within :data:`LIE_MAX_TILT` of horizontal, the pelvis
  over the footprint, the pelvis :data:`LIE_HEIGHT_BAND` above the surface;
- **walk** — *standing near*: the torso upright, the pelvis at standing height
  over the ankles (at least :data:`STANDING_MIN_RATIO` leg lengths), the lowest
  foot joint on the floor (:data:`FEET_FLOOR_TOLERANCE`), and the pelvis within
  :data:`NEAR_DISTANCE` (xy) of the box.

Surface height (seat top, mattress top): ``surface_height`` when given (not
NaN); else, with target points, the highest target point within
:data:`SURFACE_SEARCH_RADIUS` (xy) of the pelvis and below it (NaN — a failed
check — when there is none: nothing of the target is under the pelvis); else the
top of the box, which is right for stools, tables and mattresses but not for
seats with a backrest: pass points or the surface height for those. With points,
the seat-height lower bound holds by construction (the surface is searched below
the pelvis): sinking into a seat is for the penetration metrics, not this judge.

Thresholds come from the procedural character of the synthetic world
(:mod:`jaxmotion.motion.seating`, :mod:`jaxmotion.motion.segments`,
:mod:`jaxmotion.motion.actions`) and from its motions measured at the anchor frame
(200 ground-truth samples of ``sample_room`` / ``sample_task`` / ``synthesize``, 50 per
action; seats: chair, armchair, sofa, bed, stool, toilet): seated pelvis 0.16–0.20 m
over the seat surface (as low as 0.004 m over the point estimate where a pillow is
beside the pelvis), torso 5–17° from vertical, pelvis over the ankles 0.60–0.97 leg
lengths, thighs 42° below to 5° above horizontal; lying torso within 4° of horizontal,
pelvis 0.09–0.13 m over the mattress; standing 1.09–1.12 leg lengths, thighs 77–81°
down, pelvis 0.10–0.19 m from the box. Each constant's comment says why.

Pure jax.numpy for one motion (``jit``-compatible; ``action`` strings are static),
lifted with ``vmap`` in :func:`judge_actions` (per-motion actions, boxes, points).
Metres and degrees; masks ``[T]`` bool, True = valid.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS, FOOT_JOINTS
from jaxmotion.geometry.skeleton import NUM_JOINTS

__all__ = [
    "ACTIONS",
    "FEET_FLOOR_TOLERANCE",
    "FOOTPRINT_TOLERANCE",
    "KNEES_BENT_MAX_RATIO",
    "LIE_HEIGHT_BAND",
    "LIE_MAX_TILT",
    "NEAR_DISTANCE",
    "SEATED_MIN_THIGH_ELEVATION",
    "SEAT_HEIGHT_BAND",
    "STANDING_MIN_RATIO",
    "SURFACE_SEARCH_RADIUS",
    "UPRIGHT_MAX_TILT",
    "action_id",
    "action_report",
    "judge_action",
    "judge_actions",
    "judge_on_object",
]

ACTIONS: tuple[str, ...] = ("walk", "sit", "stand_up", "lie")

# Seated pelvis is 12-20 cm inside the seat's edge (seating.seat_spot); 10 cm more lets a
# body perch on the very edge, anything farther out is not over the seat.
FOOTPRINT_TOLERANCE = 0.10
# Pelvis joint over the seat surface, m: the hips sit 6.5-9.5 cm over it and the SMPL-X
# pelvis joint ~9 cm above the hips (measured 0.16-0.20 m); above 0.35 m it hovers.
SEAT_HEIGHT_BAND = (0.0, 0.35)
# Torso (pelvis -> neck) tilt from vertical, degrees: seated 5-17 deg (pelvis reclined
# 6-14 deg, spine flexed 3-11 deg), walking lean <= 7 deg; 35 deg is a marked slouch.
UPRIGHT_MAX_TILT = 35.0
# (pelvis z - mean ankle z) / leg length (hip->knee + knee->ankle, measured on the pose).
# Standing: 1.09-1.12 (straight legs, the pelvis joint ~0.1 leg above the hips); seated
# 0.60-0.97 (up to 45 deg sloping thighs on high seats). 1.03 ~ 45 deg of knee flexion.
KNEES_BENT_MAX_RATIO = 1.03
STANDING_MIN_RATIO = 1.03
# Thigh (hip -> knee) elevation above horizontal, degrees: seated -45..+7 (seating.py),
# standing about -80; a seated body has thighs nearer horizontal than vertical.
SEATED_MIN_THIGH_ELEVATION = -60.0
# Torso tilt from horizontal when lying, degrees: the character lies at 2.3 deg
# (measured within 4 deg); 30 deg still reads as lying back, not sitting.
LIE_MAX_TILT = 30.0
# Pelvis over the lying surface, m: 9-13 cm in the synthetic world (seating.lie_pose);
# down to 10 cm below it (a soft mattress, a coarse estimate), up to 35 cm above it.
LIE_HEIGHT_BAND = (-0.10, 0.35)
# Walk: the pelvis stops 0.125-0.215 m (+~2 cm) in front of the box (actions._walk);
# 0.6 m is "at the object" (within reach), not across the room.
NEAR_DISTANCE = 0.6
# Lowest foot joint minus its flat-foot height (skating.FOOT_FLOOR_OFFSETS), m: 0 for a
# planted foot; within 5 cm (the foot-contact height of the skating metric).
FEET_FLOOR_TOLERANCE = 0.05
# Where the surface under the pelvis is searched among the target points (xy radius, m):
# the buttocks' width; narrow enough to miss armrests (>= 0.25 m from a centred pelvis).
SURFACE_SEARCH_RADIUS = 0.2

_PELVIS, _NECK = 0, 12
_FRAME_BUCKET, _POINT_BUCKET = 32, 256  # single-motion inputs are padded to these sizes
_HIPS, _KNEES, _ANKLES = (1, 2), (4, 5), (7, 8)


def action_id(action) -> int:
    """Index in :data:`ACTIONS` of ``"walk"``, ``"sit"``, ``"stand_up"`` / ``"stand up"``,
    ``"lie"`` (case-insensitive), or of an int id (checked)."""
    if isinstance(action, (int, np.integer)) and not isinstance(action, bool):
        if not 0 <= action < len(ACTIONS):
            raise ValueError(f"action id must be in [0, {len(ACTIONS)}), got {action}")
        return int(action)
    name = str(action).strip().lower().replace(" ", "_")
    if name not in ACTIONS:
        raise ValueError(f"unknown action {action!r}; expected one of {ACTIONS} (or 'stand up')")
    return ACTIONS.index(name)


def _elevation(v):
    """Angle (deg) of vectors ``[..., 3]`` above the horizontal plane."""
    return jnp.degrees(jnp.arctan2(v[..., 2], jnp.linalg.norm(v[..., :2], axis=-1)))


def _pose_report(pose, action, bbox_min, bbox_max, points, point_mask, surface_height):
    """Measures and checks of one pose ``[22, 3]`` for the action id ``action`` (traced)."""
    pelvis = pose[_PELVIS]
    lo, hi = bbox_min.astype(jnp.float32), bbox_max.astype(jnp.float32)
    gap = jnp.maximum(jnp.maximum(lo[:2] - pelvis[:2], pelvis[:2] - hi[:2]), 0.0)
    box_xy = jnp.linalg.norm(gap)

    if points is None:
        fallback = hi[2]
    else:
        near = jnp.linalg.norm(points[:, :2] - pelvis[:2], axis=-1) <= SURFACE_SEARCH_RADIUS
        under = near & (points[:, 2] <= pelvis[2])
        if point_mask is not None:
            under = under & point_mask
        highest = jnp.max(jnp.where(under, points[:, 2], -jnp.inf))
        fallback = jnp.where(jnp.any(under), highest, jnp.nan)
    surface = jnp.where(jnp.isnan(surface_height), fallback, surface_height)
    above = pelvis[2] - surface

    torso = _elevation(pose[_NECK] - pelvis)
    hips, knees, ankles = pose[jnp.array(_HIPS)], pose[jnp.array(_KNEES)], pose[jnp.array(_ANKLES)]
    thighs = jnp.mean(_elevation(knees - hips))
    leg = jnp.mean(
        jnp.linalg.norm(knees - hips, axis=-1) + jnp.linalg.norm(ankles - knees, axis=-1)
    )
    ratio = (pelvis[2] - jnp.mean(ankles[:, 2])) / jnp.maximum(leg, 1e-6)
    feet = jnp.min(pose[jnp.array(FOOT_JOINTS), 2] - jnp.asarray(FOOT_FLOOR_OFFSETS, jnp.float32))

    over = box_xy <= FOOTPRINT_TOLERANCE
    seat_ok = (above >= SEAT_HEIGHT_BAND[0]) & (above <= SEAT_HEIGHT_BAND[1])
    lie_ok = (above >= LIE_HEIGHT_BAND[0]) & (above <= LIE_HEIGHT_BAND[1])
    upright = torso >= 90.0 - UPRIGHT_MAX_TILT
    horizontal = jnp.abs(torso) <= LIE_MAX_TILT
    knees = (ratio < KNEES_BENT_MAX_RATIO) & (thighs >= SEATED_MIN_THIGH_ELEVATION)
    standing = ratio >= STANDING_MIN_RATIO
    on_floor = jnp.abs(feet) <= FEET_FLOOR_TOLERANCE
    near_box = box_xy <= NEAR_DISTANCE

    seated = over & seat_ok & upright & knees
    lying = horizontal & over & lie_ok
    standing_near = upright & standing & on_floor & near_box
    success = jnp.stack([standing_near, seated, seated, lying])[action]
    return {
        "success": success,
        "seated": seated,
        "lying": lying,
        "standing_near": standing_near,
        "over_footprint": over,
        "seat_height_ok": seat_ok,
        "lie_height_ok": lie_ok,
        "torso_upright": upright,
        "torso_horizontal": horizontal,
        "knees_bent": knees,
        "standing_height": standing,
        "feet_on_floor": on_floor,
        "near_box": near_box,
        "pelvis_box_xy_distance": box_xy,
        "surface_height": surface,
        "pelvis_above_surface": above,
        "pelvis_height": pelvis[2],
        "torso_elevation": torso,
        "thigh_elevation": thighs,
        "leg_length": leg,
        "pelvis_height_ratio": ratio,
        "feet_height": feet,
    }


def _report_one(joints, mask, action, bbox_min, bbox_max, points, point_mask, surface_height):
    """One motion: the anchor frame (first valid for stand_up, else last valid), then its pose."""
    first = jnp.argmax(mask)
    last = mask.shape[0] - 1 - jnp.argmax(mask[::-1])
    anchor = jnp.where(action == ACTIONS.index("stand_up"), first, last).astype(jnp.int32)
    out = _pose_report(
        joints[anchor], action, bbox_min, bbox_max, points, point_mask, surface_height
    )
    out["anchor"] = anchor
    out["success"] = out["success"] & jnp.any(mask)
    return out


_report_jit = jax.jit(_report_one)
_report_batch = jax.jit(jax.vmap(_report_one))


def _check(joints, mask, batched: bool):
    joints = jnp.asarray(joints, jnp.float32)
    want = "[B, T, 22, 3]" if batched else "[T, 22, 3]"
    if joints.ndim != 3 + batched or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be {want}, got shape {joints.shape}")
    if joints.shape[-3] == 0:
        raise ValueError("joints has no frames")
    shape = joints.shape[:-2]
    mask = jnp.ones(shape, bool) if mask is None else jnp.asarray(mask).astype(bool)
    if mask.shape != shape:
        raise ValueError(f"mask must have shape {shape}, got {mask.shape}")
    return joints, mask


def _check_points(points, point_mask, lead: tuple):
    if points is None:
        if point_mask is not None:
            raise ValueError("point_mask given without points")
        return None, None
    points = jnp.asarray(points, jnp.float32)
    if points.ndim != len(lead) + 2 or points.shape[:-2] != lead or points.shape[-1] != 3:
        raise ValueError(f"points must be [{'B, ' if lead else ''}N, 3], got {points.shape}")
    if point_mask is not None:
        point_mask = jnp.asarray(point_mask).astype(bool)
        if point_mask.shape != points.shape[:-1]:
            raise ValueError(
                f"point_mask must have shape {points.shape[:-1]}, got {point_mask.shape}"
            )
    return points, point_mask


def _pad_axis(x, size, axis, value):
    """Pad axis ``axis`` of ``x`` up to ``size`` with ``value``."""
    widths = [(0, 0)] * x.ndim
    widths[axis] = (0, size - x.shape[axis])
    return jnp.pad(x, widths, constant_values=value)


def _bucket(n: int, step: int) -> int:
    """The size ``n`` is padded to: a multiple of ``step``."""
    return max(step, -(-n // step) * step)


def action_report(
    joints,
    mask,
    action,
    bbox_min,
    bbox_max,
    points=None,
    *,
    point_mask=None,
    surface_height=None,
) -> dict[str, jax.Array]:
    """Measures and checks of one motion at its anchor frame (criteria: module docstring).

    Args:
      joints: ``[T, 22, 3]`` z-up, metres. mask: ``[T]`` valid frames, or None.
      action: "walk", "sit", "stand_up" (or "stand up"), "lie", or its index in
        :data:`ACTIONS`; static.
      bbox_min, bbox_max: ``[3]`` the target object's axis-aligned box, metres.
      points: optional ``[N, 3]`` target-object points (for the surface height);
        point_mask: ``[N]`` valid points (padding), or None.
      surface_height: known surface height (m), or None / NaN to estimate it.
    Returns:
      dict of scalars: ``success`` (bool: the action's verdict), the per-action verdicts
      ``seated`` / ``lying`` / ``standing_near``, each check (bool: ``over_footprint``,
      ``seat_height_ok``, ``lie_height_ok``, ``torso_upright``, ``torso_horizontal``,
      ``knees_bent``, ``standing_height``, ``feet_on_floor``, ``near_box``), the measures
      (``pelvis_box_xy_distance``, ``surface_height``, ``pelvis_above_surface``,
      ``pelvis_height``, ``leg_length``, ``feet_height`` in m; ``torso_elevation``,
      ``thigh_elevation`` in degrees above horizontal; ``pelvis_height_ratio`` in leg
      lengths) and ``anchor`` (int32 frame). ``success`` is False without a valid frame.
    """
    joints, mask = _check(joints, mask, False)
    points, point_mask = _check_points(points, point_mask, ())
    # Pad frames and points to a few sizes, so motions and objects of varying sizes reuse
    # a few compiled programs (the padding is masked out).
    t = _bucket(joints.shape[0], _FRAME_BUCKET)
    joints, mask = _pad_axis(joints, t, 0, 0.0), _pad_axis(mask, t, 0, False)
    if points is not None:
        n = max(_POINT_BUCKET, 1 << max(points.shape[0] - 1, 0).bit_length())
        if point_mask is None:
            point_mask = jnp.ones(points.shape[0], bool)
        points, point_mask = _pad_axis(points, n, 0, 0.0), _pad_axis(point_mask, n, 0, False)
    sh = jnp.asarray(jnp.nan if surface_height is None else surface_height, jnp.float32)
    return _report_jit(
        joints, mask, jnp.int32(action_id(action)), jnp.asarray(bbox_min, jnp.float32),
        jnp.asarray(bbox_max, jnp.float32), points, point_mask, sh,
    )  # fmt: skip


def judge_action(joints, mask, action, bbox_min, bbox_max, points=None, **kw) -> jax.Array:
    """Whether one motion did ``action`` on the target: bool scalar (see :func:`action_report`)."""
    return action_report(joints, mask, action, bbox_min, bbox_max, points, **kw)["success"]


def judge_actions(
    joints,
    mask,
    actions,
    bbox_min,
    bbox_max,
    points=None,
    *,
    point_mask=None,
    surface_height=None,
) -> dict[str, jax.Array]:
    """:func:`action_report` for a batch, each motion with its own action and target.

    Args:
      joints: ``[B, T, 22, 3]``; mask: ``[B, T]`` or None.
      actions: ``B`` action names / ids (a sequence), or an int array ``[B]`` of ids.
      bbox_min, bbox_max: ``[B, 3]``. points: optional ``[B, N, 3]`` (pad with
        ``point_mask [B, N]``). surface_height: optional ``[B]`` (NaN = estimate).
    Returns:
      the dict of :func:`action_report` with ``[B]`` arrays.
    """
    joints, mask = _check(joints, mask, True)
    b = joints.shape[0]
    if hasattr(actions, "dtype") and np.issubdtype(actions.dtype, np.integer):
        ids = jnp.asarray(actions, jnp.int32)  # ids, possibly traced
    else:
        ids = jnp.asarray([action_id(a) for a in actions], jnp.int32)
    if ids.shape != (b,):
        raise ValueError(f"actions must have {b} entries, got shape {ids.shape}")
    lo, hi = jnp.asarray(bbox_min, jnp.float32), jnp.asarray(bbox_max, jnp.float32)
    if lo.shape != (b, 3) or hi.shape != (b, 3):
        raise ValueError(f"bbox_min / bbox_max must be [{b}, 3], got {lo.shape}, {hi.shape}")
    points, point_mask = _check_points(points, point_mask, (b,))
    if surface_height is None:
        sh = jnp.full((b,), jnp.nan, jnp.float32)
    else:
        sh = jnp.broadcast_to(jnp.asarray(surface_height, jnp.float32), (b,))
    return _report_batch(joints, mask, ids, lo, hi, points, point_mask, sh)


def judge_on_object(joints, mask, action, bbox_min, bbox_max, points,
                    surface_height=None) -> dict[str, np.ndarray]:
    """:func:`judge_actions` for the K motions ``joints [K, T, 22, 3]`` that all do ``action``
    on one object: its box ``bbox_min``, ``bbox_max`` ``[3]``, its points ``[N, 3]`` (none: the
    box's low corner stands in) and its surface height (None or NaN: estimated); ``mask``
    ``[K, T]`` or None. Returns numpy ``[K]`` arrays."""
    k = joints.shape[0]
    pts = np.asarray(points, np.float32).reshape(-1, 3)
    if not len(pts):
        pts = np.asarray(bbox_min, np.float32)[None]
    surface = np.nan if surface_height is None else float(surface_height)
    rep = judge_actions(joints, mask, [action] * k, np.tile(bbox_min, (k, 1)),
                        np.tile(bbox_max, (k, 1)), np.broadcast_to(pts, (k, *pts.shape)),
                        surface_height=np.full(k, surface, np.float32))
    return {key: np.asarray(v) for key, v in jax.device_get(rep).items()}
