"""Put a library clip (:mod:`jaxmotion.data.motion_library`) into a room for one instruction.

:func:`place_clip` tries clips of the requested action in an order drawn from the
sample's generator and returns the first that fits, transformed by a rotation about z
and a horizontal shift (never scaled, never moved vertically: the feet stay on the floor):

- ``walk``: the last pelvis 15-30 cm in front of an edge of the target's footprint (the
  front edge first when it has one), the body facing it (±0.15 rad);
- ``sit`` / ``stand_up``: the seated frame (last / first) on a sitting spot of
  :func:`jaxmotion.motion.seating.find_seat` for a body of the clip's shape, facing out;
  the clip's seated pelvis must be within :data:`SEAT_TOLERANCE` of that spot's height
  (the seat height the clip was captured on must match this seat's);
- ``lie``: the last frame's pelvis where :func:`~jaxmotion.motion.seating.lie_pose` puts
  it, the legs pointing along the bed or sofa the same way, the pelvis within
  :data:`LIE_TOLERANCE` of that height, pelvis, neck and head over the furniture.

A placement fits the room when, as for the procedural character
(:func:`jaxmotion.motion.synthesize`), no joint is more than ``MAX_PENETRATION`` (4 cm)
inside furniture (for sit / stand_up / lie only the part of the target below its surface
counts), every joint stays on the floor plan (inside the walls), the pelvis keeps
:data:`CLEARANCE` from other furniture and walls (:data:`END_CLEARANCE` within 0.6 m of
the anchor pelvis, where the body meets the object), and a standing body never has its
pelvis over the target. Otherwise the next clip is tried; None when none fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from jaxmotion.geometry.skeleton import rest_joints_host
from jaxmotion.motion import kinematics as K
from jaxmotion.motion.actions import MAX_PENETRATION
from jaxmotion.motion.planner import MotionError, build_grid, wall_distance
from jaxmotion.motion.quality import furniture_penetration_np
from jaxmotion.motion.seating import UnsupportedTarget, box_edges, find_seat, front_edge, lie_pose

__all__ = ["CLEARANCE", "END_CLEARANCE", "LIE_TOLERANCE", "SEAT_TOLERANCE", "Placed",
           "heading", "place_clip", "transform_clip"]

SEAT_TOLERANCE = 0.06  # seated pelvis height vs the seat's, metres
LIE_TOLERANCE = 0.08  # lying pelvis height vs the bed's, metres
CLEARANCE = 0.2  # pelvis to furniture and walls while walking, metres
END_CLEARANCE = 0.05  # ... near the object (within 0.6 m of the anchor pelvis)
TRIES = 8  # clips tried per sample
_PELVIS_OVER_SURFACE = {"sit": (0.15 - SEAT_TOLERANCE, 0.2 + SEAT_TOLERANCE),
                        "stand_up": (0.15 - SEAT_TOLERANCE, 0.2 + SEAT_TOLERANCE),
                        "lie": (0.09 - LIE_TOLERANCE, 0.13 + LIE_TOLERANCE)}


@dataclass(frozen=True)
class Placed:
    """A clip in the room: ``angle`` (rad, about z through the origin), then ``shift`` [3]
    (z = 0); the arrays are the clip's after the transform (float32)."""

    clip: object
    angle: float
    shift: np.ndarray
    joints: np.ndarray
    transl: np.ndarray
    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray


def heading(frame: np.ndarray) -> float:
    """Facing (rad, about z) of one pose ``[22,3]``: perpendicular to the hips, forwards."""
    left = frame[1] - frame[2]
    f = np.cross(left, [0.0, 0.0, 1.0])
    return float(np.arctan2(f[1], f[0]))


def transform_clip(clip, angle: float, shift) -> Placed:
    """The clip rotated by ``angle`` about z, then moved by ``shift`` (joints and SMPL-X:
    ``global_orient`` turned, ``transl`` moved so the rest pelvis follows the joints)."""
    rz = K.rz(angle)
    shift = np.asarray(shift, np.float64)
    joints = np.asarray(clip.joints, np.float64) @ rz.T + shift
    r0 = rest_joints_host(np.asarray(clip.betas, np.float64))[0]
    transl = (np.asarray(clip.transl, np.float64) + r0) @ rz.T + shift - r0
    go = (Rotation.from_matrix(rz) * Rotation.from_rotvec(clip.global_orient)).as_rotvec()
    f32 = (lambda x: np.asarray(x, np.float32))
    return Placed(clip, float(angle), shift, f32(joints), f32(transl), f32(go),
                  f32(clip.body_pose), f32(clip.betas))


def _place_at(clip, frame: int, yaw: float, xy) -> Placed:
    angle = yaw - heading(clip.joints[frame])
    p = K.rz(angle)[:2, :2] @ np.asarray(clip.joints[frame, 0, :2], np.float64)
    return transform_clip(clip, angle, [*(np.asarray(xy, float) - p), 0.0])


def _fits(p: Placed, action, world, target, grid) -> bool:
    rects, objects = world
    j = p.joints.astype(np.float64)
    if furniture_penetration_np(j, objects, target["id"], action) > MAX_PENETRATION:
        return False
    if wall_distance(j[::2, :, :2].reshape(-1, 2), rects).min() < 0.0:
        return False
    pelvis = j[:, 0]
    near = np.linalg.norm(pelvis[:, :2] - pelvis[p.clip.anchor, :2], axis=1) < 0.6
    if np.any(grid.clearance_at(pelvis[:, :2]) < np.where(near, END_CLEARANCE, CLEARANCE)):
        return False
    if action != "walk":  # a standing body never has its pelvis over the target
        lo, hi = np.asarray(target["bbox_min"], float), np.asarray(target["bbox_max"], float)
        high = pelvis[:, 2] > float(target["surface_height"]) + 0.4
        inside = np.all((pelvis[:, :2] > lo[:2] - 0.05) & (pelvis[:, :2] < hi[:2] + 0.05), 1)
        if np.any(high & inside):
            return False
    return True


def _walk(clip, world, target, rng, grid):
    edges = box_edges(target)
    fe = front_edge(target)
    order = list(rng.permutation(len(edges)))
    if fe is not None:
        order.sort(key=lambda k: -float(edges[k]["normal"] @ fe["normal"]))
    for k in order[:2]:
        e = edges[k]
        lat = np.array([-e["normal"][1], e["normal"][0]])
        along = rng.uniform(-0.35, 0.35) * max(e["length"] - 0.3, 0.0)
        goal = e["center"] + lat * along + e["normal"] * rng.uniform(0.15, 0.3)
        yaw = float(np.arctan2(-e["normal"][1], -e["normal"][0])) + rng.uniform(-0.15, 0.15)
        p = _place_at(clip, clip.anchor, yaw, goal)
        if _fits(p, "walk", world, target, grid):
            return p
    return None


def _seat(clip, action, world, target, rng, grid_wo):
    body = K.make_body(clip.betas)
    try:
        spot = find_seat(target, body, rng, grid_wo)
    except UnsupportedTarget:
        raise
    except MotionError:
        return None
    a = clip.anchor
    if abs(float(clip.joints[a, 0, 2]) - float(spot.pelvis[2])) > SEAT_TOLERANCE:
        return None
    p = _place_at(clip, a, spot.yaw, spot.pelvis[:2])
    return p if _fits(p, action, world, target, grid_wo) else None


def _lie(clip, world, target, rng, grid_wo):
    body = K.make_body(clip.betas)
    try:
        spot = find_seat(target, body, rng, grid_wo, lie=True)
    except UnsupportedTarget:
        raise
    except MotionError:
        return None
    hip, legs_yaw, _ = lie_pose(target, spot, body, rng)
    pelvis = hip + K.upright(legs_yaw) @ K.rx(-np.pi / 2 + 0.04) @ (body.rest[0] - body.hip_center)
    a = clip.anchor
    if abs(float(clip.joints[a, 0, 2]) - float(pelvis[2])) > LIE_TOLERANCE:
        return None
    legs = clip.joints[a, 0, :2] - clip.joints[a, 12, :2]
    angle = legs_yaw - float(np.arctan2(legs[1], legs[0]))
    shift = pelvis[:2] - K.rz(angle)[:2, :2] @ clip.joints[a, 0, :2]
    p = transform_clip(clip, angle, [*shift, 0.0])
    lo, hi = np.asarray(target["bbox_min"], float), np.asarray(target["bbox_max"], float)
    on = p.joints[a, [0, 12, 15], :2]
    if not np.all((on > lo[:2]) & (on < hi[:2])):
        return None
    return p if _fits(p, "lie", world, target, grid_wo) else None


def place_clip(clips, action: str, floor_rects, objects, target_id,
               rng: np.random.Generator, *, tries: int = TRIES) -> Placed | None:
    """The first of up to ``tries`` clips of ``action`` (in an order drawn from ``rng``) that
    fits the room for ``target_id``, placed (see the module docstring); None if none fits
    or the target does not afford the action. For sit / stand_up / lie only clips whose
    anchor pelvis is a plausible height over the target's surface are drawn."""
    by_id = {o["id"]: o for o in objects}
    if target_id not in by_id:
        return None
    target = by_id[target_id]
    clips = [c for c in clips if c.action == action]
    if action != "walk" and target.get("surface_height") is not None:
        # only clips whose seated / lying pelvis could be on this surface (a seated pelvis is
        # 15-20 cm over the seat, a lying one 9-13 cm): a large library keeps its hit rate
        lo, hi = _PELVIS_OVER_SURFACE[action]
        h = float(target["surface_height"])
        clips = [c for c in clips if lo <= float(c.joints[c.anchor, 0, 2]) - h <= hi]
    if not clips:
        return None
    world = (np.asarray(floor_rects, float).reshape(-1, 4), list(objects))
    grid = build_grid(world[0], world[1])
    grid_wo = build_grid(world[0], world[1], exclude=(target_id,))
    for k in rng.permutation(len(clips))[:tries]:
        clip = clips[int(k)]
        try:
            if action == "walk":
                p = _walk(clip, world, target, rng, grid)
            elif action == "lie":
                p = _lie(clip, world, target, rng, grid_wo)
            else:
                p = _seat(clip, action, world, target, rng, grid_wo)
        except UnsupportedTarget:
            return None
        if p is not None:
            return p
    return None
