"""Physical-plausibility measurements of a synthesized motion (the acceptance criteria).

Every function takes a :class:`~jaxmotion.motion.character.Motion` (and the room
where needed) and returns plain floats, so tests, benchmarks and a dataset
builder can use the same numbers. Units: metres, degrees, m/s.
"""

from __future__ import annotations

import numpy as np

from jaxmotion.geometry import PARENTS, bone_lengths, box_signed_distance, rest_joints
from jaxmotion.motion.character import Motion
from jaxmotion.motion.limits import ANKLE_ALLOWANCE, FOOT_ALLOWANCE, limit_violations

__all__ = [
    "anchor_on_surface",
    "bone_error",
    "floor_penetration",
    "foot_skate",
    "furniture_penetration",
    "furniture_penetration_np",
    "planted_drift",
    "report",
    "root_speed",
    "thigh_elevation",
    "torso_elevation",
]

ANKLES, FEET = (7, 8), (10, 11)


def floor_penetration(m: Motion) -> float:
    """Deepest foot below the floor (m, > 0 = below), after the foot-height allowances."""
    a = FOOT_ALLOWANCE - m.joints[:, FEET, 2]
    b = ANKLE_ALLOWANCE - m.joints[:, ANKLES, 2]
    return float(max(a.max(), b.max()))


def _runs(mask):
    """(start, stop) of each run of True in a 1-D bool array."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def planted_drift(m: Motion) -> float:
    """Largest displacement (m) of a toe joint within one planted (contact) run."""
    worst = 0.0
    for i, j in enumerate(FEET):
        for a, b in _runs(m.contacts[:, i]):
            p = m.joints[a:b, j]
            worst = max(worst, float(np.linalg.norm(p - p[0], axis=1).max()))
    return worst


def foot_skate(m: Motion, height: float = 0.01) -> float:
    """Label-free check: the fastest horizontal speed (m/s) of a toe joint while it
    and its ankle are both within ``height`` of their flat-foot heights."""
    worst = 0.0
    for a, f in zip(ANKLES, FEET):
        flat = (m.joints[:, f, 2] < m.joints[:, f, 2].min() + height) & (
            m.joints[:, a, 2] < m.joints[:, a, 2].min() + height
        )
        both = flat[1:] & flat[:-1]
        v = np.linalg.norm(np.diff(m.joints[:, f, :2], axis=0), axis=1) * m.fps
        if both.any():
            worst = max(worst, float(v[both].max()))
    return worst


def _furniture_boxes(objects, target_id, action):
    lo, hi = [], []
    for o in objects:
        bmin, bmax = np.array(o["bbox_min"], float), np.array(o["bbox_max"], float)
        if o["id"] == target_id and action != "walk" and o.get("surface_height") is not None:
            bmax[2] = min(bmax[2], float(o["surface_height"]))
        lo.append(bmin)
        hi.append(bmax)
    return np.asarray(lo, float).reshape(-1, 3), np.asarray(hi, float).reshape(-1, 3)


def furniture_penetration(m: Motion, objects, target_id) -> float:
    """Deepest joint inside a piece of furniture (m, > 0 = inside), with the foundation's
    :func:`~jaxmotion.geometry.box_signed_distance`.

    For the target of sit / stand_up / lie only the part below its surface counts
    (the body rests on it; backrests and headboards are not modelled as boxes).
    """
    lo, hi = _furniture_boxes(objects, target_id, m.action)
    if not len(lo):
        return 0.0
    # Fixed shapes (120 frames, boxes in blocks of 16) so the kernel compiles once.
    pts = m.joints.reshape(-1, 3)
    pts = (
        np.concatenate([pts, np.repeat(pts[:1], 120 * 22 - len(pts), 0)])
        if len(pts) < 120 * 22
        else pts
    )
    k = -len(lo) % 16
    far = np.full((k, 3), 1e4)
    d = np.asarray(
        box_signed_distance(pts, np.concatenate([lo, far]), np.concatenate([hi, far + 1]))
    )
    return float(max(0.0, -d.min()))


def furniture_penetration_np(joints: np.ndarray, objects, target_id, action: str) -> float:
    """:func:`furniture_penetration` in plain numpy for joints ``[T,22,3]`` (no compilation)."""
    lo, hi = _furniture_boxes(objects, target_id, action)
    if not len(lo):
        return 0.0
    p = joints.reshape(-1, 1, 3)
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    q = np.abs(p - c) - h
    d = np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)
    return float(max(0.0, -d.min()))


def anchor_on_surface(m: Motion, obj) -> tuple[float, float]:
    """(xy distance of the anchor pelvis to the object's footprint, its height over the surface)."""
    p = m.joints[m.anchor_frame, 0]
    lo, hi = np.array(obj["bbox_min"], float)[:2], np.array(obj["bbox_max"], float)[:2]
    d = float(np.linalg.norm(np.maximum(np.maximum(lo - p[:2], p[:2] - hi), 0.0)))
    return d, float(p[2] - float(obj["surface_height"]))


def root_speed(m: Motion) -> float:
    """Maximum pelvis speed (m/s)."""
    return (
        float(np.linalg.norm(np.diff(m.joints[:, 0], axis=0), axis=1).max() * m.fps)
        if m.num_frames > 1
        else 0.0
    )


def torso_elevation(m: Motion, frame: int) -> float:
    """Angle (deg) of the pelvis -> neck vector above the horizontal plane at ``frame``."""
    v = m.joints[frame, 12] - m.joints[frame, 0]
    return float(np.degrees(np.arcsin(v[2] / np.linalg.norm(v))))


def thigh_elevation(m: Motion, frame: int) -> float:
    """Mean angle (deg) of the two hip -> knee vectors above the horizontal at ``frame``."""
    v = m.joints[frame, [4, 5]] - m.joints[frame, [1, 2]]
    return float(np.degrees(np.arcsin(v[:, 2] / np.linalg.norm(v, axis=1))).mean())


def bone_error(m: Motion) -> float:
    """Largest deviation (m) of any bone length from the body's rest skeleton."""
    rest = np.asarray(bone_lengths(rest_joints(m.betas)), np.float64)
    par = np.asarray(PARENTS[1:])
    lengths = np.linalg.norm(m.joints[:, 1:].astype(np.float64) - m.joints[:, par], axis=-1)
    return float(np.abs(lengths - rest).max())


def report(m: Motion, objects, target_id) -> dict:
    """All measurements of one motion as a dict of floats (and the limit violations)."""
    obj = {o["id"]: o for o in objects}[target_id]
    out = {
        "frames": m.num_frames,
        "joints": m.joints.shape[1],
        "floor_penetration": floor_penetration(m),
        "planted_drift": planted_drift(m),
        "foot_skate": foot_skate(m),
        "bone_error": bone_error(m),
        "furniture_penetration": furniture_penetration(m, objects, target_id),
        "root_speed": root_speed(m),
        "limit_violations": limit_violations(m.body_pose),
    }
    if m.action in ("sit", "stand_up", "lie"):
        out["anchor_xy_dist"], out["anchor_height"] = anchor_on_surface(m, obj)
    if m.action in ("sit", "stand_up"):
        out["anchor_thigh_elevation"] = thigh_elevation(m, m.anchor_frame)
    if m.action == "lie":
        out["anchor_torso_elevation"] = torso_elevation(m, m.anchor_frame)
    if m.action == "walk":
        lo, hi = np.array(obj["bbox_min"], float)[:2], np.array(obj["bbox_max"], float)[:2]
        p = m.joints[m.anchor_frame, 0, :2]
        out["anchor_distance"] = float(np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0)))
        left = m.joints[m.anchor_frame, 1] - m.joints[m.anchor_frame, 2]  # left hip - right hip
        face = np.array([left[1], -left[0]])  # the left axis turned clockwise
        to_obj = np.clip(p, lo, hi) - p
        cosang = face @ to_obj / (np.linalg.norm(face) * np.linalg.norm(to_obj) + 1e-9)
        out["anchor_facing_error"] = float(np.degrees(np.arccos(np.clip(cosang, -1, 1))))
    return out
