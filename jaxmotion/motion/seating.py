"""Where and how the body sits or lies on a piece of furniture.

Furniture is an axis-aligned box (``bbox_min``, ``bbox_max``; world metres) with
``surface_height`` (the seat or mattress top) and, for seats with a backrest, a
``front`` direction. A sitting spot is on one *edge* of the box footprint (the
front for seats with a front; any side otherwise), described by the edge's
outward normal. Geometry of a seated body (all checked, else
:class:`SeatUnreachable`):

- the hips (hip-joint centre) 6.5-9.5 cm over the surface (the pelvis joint then
  15-20 cm), the pelvis 12-20 cm behind the edge and inside the footprint, the
  pelvis tilted back 6-14 deg;
- thighs near horizontal (-3..7 deg preferred); the shins reach the floor 2-22 deg
  from vertical (ankle dorsiflexion), feet flat in front of the edge; a seat too
  high or too low for that tilts the thighs, up to 35 deg up or 45 deg down
  (perching on a bar stool), beyond which the seat does not fit the body;
- the standing spot (hips over the feet) and the feet are on free floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jaxmotion.motion import kinematics as K
from jaxmotion.motion.planner import Grid, MotionError

__all__ = [
    "SeatSpot",
    "SeatUnreachable",
    "UnsupportedTarget",
    "box_edges",
    "find_seat",
    "front_edge",
    "lie_along",
    "lie_pose",
    "seat_spot",
]


class SeatUnreachable(MotionError):
    """No usable sitting spot on the requested object."""


class UnsupportedTarget(MotionError):
    """The target object does not afford the action (e.g. lying on a chair)."""


WIDE = ("sofa", "couch", "bed", "bench")  # seats one may sit on anywhere along the edge
LIE_MIN_LENGTH = 1.3  # shortest furniture one can lie on (legs bent), metres


@dataclass(frozen=True)
class SeatSpot:
    """A sitting spot. Positions are world metres, angles radians.

    Attributes:
      pelvis: ``[3]`` seated pelvis joint. hip: ``[3]`` seated hip centre.
      yaw: facing (the edge's outward normal). pitch: seated pelvis pitch (< 0 reclined).
      spine_flex: seated spine flexion. feet_xy: ``[2,2]`` flat ankle xy; feet_yaw: ``[2]``.
      stand_xy: ``[2]`` hip-centre xy when standing on those feet.
      normal: ``[2]`` outward edge normal. surface: seat height.
    """

    pelvis: np.ndarray
    hip: np.ndarray
    yaw: float
    pitch: float
    spine_flex: float
    feet_xy: np.ndarray
    feet_yaw: np.ndarray
    stand_xy: np.ndarray
    normal: np.ndarray
    surface: float


def box_edges(obj) -> list[dict]:
    """The four footprint edges: outward ``normal`` [2], ``center`` [2], ``length``, ``depth``."""
    lo, hi = np.asarray(obj["bbox_min"], float)[:2], np.asarray(obj["bbox_max"], float)[:2]
    c, size = 0.5 * (lo + hi), hi - lo
    out = []
    for ax in (0, 1):
        for sgn in (1.0, -1.0):
            n = np.zeros(2)
            n[ax] = sgn
            out.append(
                {
                    "normal": n,
                    "center": c + n * 0.5 * size[ax],
                    "length": size[1 - ax],
                    "depth": size[ax],
                }
            )
    return out


def front_edge(obj) -> dict | None:
    """The edge facing ``obj['front']`` (snapped to the nearest axis), or None."""
    if obj.get("front") is None:
        return None
    f = np.asarray(obj["front"], float)[:2]
    return max(box_edges(obj), key=lambda e: float(e["normal"] @ f))


def seat_spot(
    obj,
    edge: dict,
    body: K.Body,
    rng: np.random.Generator,
    grid: Grid,
    along=None,
    wide: bool = False,
) -> SeatSpot:
    """Sample a seated posture on ``edge`` of ``obj``.

    Args:
      along: lateral position along the edge (metres from its centre); default
        random (anywhere on ``wide`` seats such as sofas and beds, centred otherwise).
      grid: floor grid *without* the seat itself, for the free-floor checks.
    Raises:
      SeatUnreachable: the posture does not fit (seat too high or low, feet blocked).
    """
    h = float(obj["surface_height"])
    n = edge["normal"]
    lat = np.array([-n[1], n[0]])  # body's left when facing n
    yaw = float(np.arctan2(n[1], n[0]))
    if along is None:
        half = 0.5 * edge["length"] - 0.32
        along = rng.uniform(-half, half) if (wide and half > 0) else rng.normal(0, 0.015)
    inset = min(rng.uniform(0.12, 0.2), 0.42 * edge["depth"])
    pitch, flex = -rng.uniform(0.1, 0.25), rng.uniform(0.05, 0.2)
    rp = K.upright(yaw) @ K.rx(pitch)
    pel_off = rp @ (body.rest[0] - body.hip_center)
    pelvis_xy = edge["center"] - n * inset + lat * along
    hip = np.array([*(pelvis_xy - pel_off[:2]), h + rng.uniform(0.065, 0.095)])
    pelvis = hip + pel_off
    elev_pref, splay = rng.uniform(-0.05, 0.12), rng.uniform(0.05, 0.2)
    feet_xy, feet_yaw = np.zeros((2, 2)), np.zeros(2)
    for i, side in ((0, 1.0), (1, -1.0)):
        hip_i = hip + rp @ (body.rest[K.HIP[i]] - body.hip_center)
        hdir = n + splay * side * lat
        hdir /= np.linalg.norm(hdir)
        l1, l2, ah = body.thigh[i], body.shin[i], body.ankle_height[i]
        cos_g = (hip_i[2] + l1 * np.sin(elev_pref) - ah) / l2
        cos_g = np.clip(cos_g, np.cos(np.radians(22)), np.cos(np.radians(2)))
        sin_e = (ah + l2 * cos_g - hip_i[2]) / l1
        if not -np.sin(np.radians(45)) <= sin_e <= np.sin(np.radians(35)):
            raise SeatUnreachable(
                f"seat height {h:.2f} m does not fit this body "
                f"(thigh {np.degrees(np.arcsin(np.clip(sin_e, -1, 1))):.0f} deg)"
            )
        knee = hip_i + l1 * np.array([*(np.sqrt(1 - sin_e**2) * hdir), sin_e])
        feet_xy[i] = knee[:2] + l2 * np.sqrt(1 - cos_g**2) * hdir
        feet_yaw[i] = yaw + side * rng.uniform(0.0, 0.15)
    stand_xy = feet_xy.mean(0) + 0.03 * n
    # Feet, toes and the standing spot must be on free floor, clear of other furniture.
    toes = np.stack([feet_xy[i] + K.upright(feet_yaw[i])[:2] @ body.toe_off[i] for i in (0, 1)])
    if np.any(grid.clearance_at(np.concatenate([feet_xy, toes])) < 0.06):
        raise SeatUnreachable("no room for the feet in front of the seat")
    if grid.clearance_at(stand_xy)[0] < 0.16:
        raise SeatUnreachable("no room to stand in front of the seat")
    return SeatSpot(pelvis, hip, yaw, pitch, flex, feet_xy, feet_yaw, stand_xy, n, h)


def find_seat(
    obj, body: K.Body, rng: np.random.Generator, grid_wo: Grid, lie: bool = False
) -> SeatSpot:
    """A sitting spot on ``obj`` for sitting (front edge of seats with a front, any
    side otherwise, never a bed's head end) or, with ``lie``, for lying down later
    (a long side, with the pelvis placed so that head and legs fit along it).

    Args:
      grid_wo: floor grid without ``obj`` (for the free-floor checks).
    Raises:
      UnsupportedTarget: no seat surface, too short to lie on, no usable edge.
      SeatUnreachable: every candidate spot is blocked or does not fit the body.
    """
    cat = str(obj.get("category", "")).lower()
    if obj.get("surface_height") is None:
        raise UnsupportedTarget(
            f"object {obj['id']} ({cat}) has no surface_height to sit or lie on"
        )
    edges = box_edges(obj)
    fe = front_edge(obj)
    if lie:
        size = np.asarray(obj["bbox_max"], float)[:2] - np.asarray(obj["bbox_min"], float)[:2]
        if size.max() < LIE_MIN_LENGTH:
            raise UnsupportedTarget(
                f"object {obj['id']} ({cat}) is too short to lie on ({size.max():.2f} m)"
            )
        long_ax = int(np.argmax(size))
        edges = [e for e in edges if e["normal"][long_ax] == 0]  # sit on a long side
        if fe is not None and cat != "bed":
            edges = [e for e in edges if e["normal"] @ fe["normal"] > 0.5]
    elif fe is not None and cat != "bed":
        edges = [fe]
    elif fe is not None:
        edges = [e for e in edges if e["normal"] @ fe["normal"] > -0.5]
    edges = [edges[k] for k in rng.permutation(len(edges)) if edges[k]["length"] >= 0.3]
    if not edges:
        raise UnsupportedTarget(f"object {obj['id']} ({cat}) has no edge to sit on for this action")
    errors = []
    for e in edges:
        for _ in range(3):
            try:
                along = None
                if lie:
                    along = lie_along(obj, e, body, rng)
                return seat_spot(
                    obj, e, body, rng, grid_wo, along=along, wide=cat in WIDE or e["length"] > 1.0
                )
            except SeatUnreachable as err:
                errors.append(str(err))
    raise SeatUnreachable(
        f"object {obj['id']} ({cat}): no usable sitting spot ({'; '.join(sorted(set(errors)))})"
    )


def lie_along(obj, edge: dict, body: K.Body, rng: np.random.Generator) -> float:
    """Position (m from the edge centre) where the pelvis goes so the head fits at one end
    (a bed's headboard end when its ``front`` is the foot end), legs towards the other."""
    half = 0.5 * edge["length"]
    head = np.linalg.norm(body.rest[15] - body.rest[0]) + rng.uniform(0.15, 0.28)
    if edge["length"] < head + 0.55:  # shorter: the knees bend up (lie_down "room")
        raise UnsupportedTarget(
            f"object {obj['id']} is too short to lie on ({edge['length']:.2f} m)"
        )
    lat = np.array([-edge["normal"][1], edge["normal"][0]])
    f = obj.get("front")
    sign = rng.choice([-1.0, 1.0])  # +1: head towards +lat
    if (
        f is not None
        and abs(np.asarray(f, float)[:2] @ lat) > 0.7
        and str(obj.get("category")) == "bed"
    ):
        sign = -float(
            np.sign(np.asarray(f, float)[:2] @ lat)
        )  # head at the headboard, away from front
    return sign * (half - head)


def lie_pose(obj, spot: SeatSpot, body: K.Body, rng: np.random.Generator):
    """Final lying pose after sitting on ``spot`` (a long edge of ``obj``).

    The pelvis moves in from the edge (a bed: 0.3-0.5 m; a sofa: a third of its
    depth), 9-13 cm above the surface, the body supine along the long axis with the
    legs towards the far end.

    Returns:
      ``(hip [3], yaw, room)``: the hip centre, the heading the legs point to, and the
      free length (m) in front of the hips before the furniture ends.
    """
    cat = str(obj.get("category", "")).lower()
    h, n = spot.surface, spot.normal
    lo, hi = np.asarray(obj["bbox_min"], float)[:2], np.asarray(obj["bbox_max"], float)[:2]
    depth = float(abs((hi - lo) @ n))
    inset = float((hi if n.sum() > 0 else lo) @ n - spot.pelvis[:2] @ n)
    if cat == "bed":
        deep = min(rng.uniform(0.3, 0.5), depth - 0.3)
    else:
        deep = rng.uniform(0.3, 0.42) * depth
    deep = max(deep, inset)
    lat = np.array([-n[1], n[0]])
    legs = -(np.sign((spot.pelvis[:2] - 0.5 * (lo + hi)) @ lat) or -1.0) * lat  # to the far end
    yaw = float(np.arctan2(legs[1], legs[0]))
    pel = np.array([*(spot.pelvis[:2] - n * (deep - inset)), h + rng.uniform(0.09, 0.13)])
    rp = K.upright(yaw) @ K.rx(-np.pi / 2 + 0.04)
    hip = pel - rp @ (body.rest[0] - body.hip_center)
    far = hi if legs.sum() > 0 else lo  # the foot end of the furniture
    return hip, yaw, float(abs((far - hip[:2]) @ legs) - 0.1)
