"""Choosing among objects the words fit equally well, by the room's free floor.

When a text leaves several objects of the room ("sit on the stool" in a room with two
stools) or names none ("wander around for a bit"), the default grounding (``auto``) chooses
by the room's geometry, the way the story planner places a walk's end
(:mod:`jaxmotion.planning.paths`):

- **among several** (:func:`most_reachable`): the one a body reaches most freely, i.e. with
  the most free floor to end an approach on (:func:`approach_areas`: the cells a standing
  body fits on within reach of the object, 0.5–1 m before a sit or lie and 0.3–0.6 m
  otherwise, in front of it when it has a ``front``); the lowest id on a tie;
- **none named** (:func:`wander_target`): a walk to a piece of furniture drawn with the
  seed, each in proportion to that free floor (doors, windows and the like only in a room
  whose furniture has none; walls and floors never).

``grounding="adm"`` leaves both choices to the affordance model's map instead
(:func:`jaxmotion.grounding.region.choose_region`), and a scene without object labels always
does. All of it is NumPy on the scene's points near the candidates: no model runs.
"""

from __future__ import annotations

import numpy as np

from jaxmotion.constants import PASSABLE, STRUCTURE

__all__ = ["approach_areas", "most_reachable", "wander_target"]

#: Tag of the draw in :func:`wander_target` (``np.random.default_rng([seed, WANDER_TAG])``).
WANDER_TAG = 7


def approach_areas(room, objects, action: str | None = None) -> np.ndarray | None:
    """Free floor (m²) a body has to end an approach to each of ``objects`` (rows of the room's
    object table) on, for ``action`` (:func:`jaxmotion.planning.paths.approach_area`, reach
    :data:`~jaxmotion.planning.paths.SIT_REACH` for ``sit`` / ``lie``, else
    :data:`~jaxmotion.planning.paths.WALK_REACH`); ``[len(objects)]``. None when the scene has
    no floor points to measure on."""
    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.planning.paths import (END_RADIUS, SIT_REACH, WALK_REACH, approach_area,
                                          floor_points)

    try:  # the points near each object only, not a clearance grid of the room
        grid = floor_points(room.xyz, room.instance)
    except PlanningError:
        return None
    if len(objects) > 3:  # their windows cover most of the room: measure it once
        grid = grid.measured(END_RADIUS)
    reach = SIT_REACH if action in ("sit", "lie") else WALK_REACH
    areas = []
    for o in objects:
        pts = room.xyz[room.instance == int(o["id"]), :2]
        areas.append(approach_area(grid, pts, reach=reach, front=o.get("front"))
                     if len(pts) else 0.0)
    return np.asarray(areas, np.float64)


def most_reachable(room, candidates, action: str | None = None) -> int | None:
    """The index into ``candidates`` of the object a body reaches most freely
    (:func:`approach_areas`; the lowest object id among equals), or None when the scene has
    no floor to measure on."""
    areas = approach_areas(room, candidates, action)
    if areas is None:
        return None
    ids = np.array([int(o["id"]) for o in candidates])
    order = np.lexsort((ids, -areas))  # most free floor first, then the lowest id
    return int(order[0])


def wander_target(room, objects, seed: int) -> dict | None:
    """The object a walk goes to when the text names none: drawn from ``objects`` (the
    room's object table) with ``seed``, each in proportion to its free floor within reach
    (:func:`approach_areas`, a walk's reach). Furniture is drawn from; openings and things on
    walls or the floor (:data:`~jaxmotion.constants.PASSABLE`: doors, windows, rugs, ...) only
    when no furniture has free floor around it, the room's structure (walls, floor) never.
    None when nothing has free floor around it (or the scene has no floor)."""
    every = [o for o in objects if o["category"] not in STRUCTURE]
    areas = approach_areas(room, every) if every else None  # measured once for both pools
    if areas is None:
        return None
    passable = np.array([o["category"] in PASSABLE for o in every])
    for pool in (~passable, passable):
        a = np.where(pool, areas, 0.0)
        if a.sum() > 0.0:
            rng = np.random.default_rng([int(seed), WANDER_TAG])
            return every[int(rng.choice(len(every), p=a / a.sum()))]
    return None
