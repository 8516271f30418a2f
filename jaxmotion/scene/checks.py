"""Checks that a loaded scene follows the conventions the models were trained on.

jaxmotion's scenes are z-up, in metres, with the floor at z = 0 (ScanNet / HUMANISE). A scan
exported y-up, or with its floor elsewhere, still loads, but the models then see a room on its
side or floating: :func:`scene_warnings` says so, and how to convert it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_POINTS", "check_room", "scene_warnings"]

#: The fewest points a room must have to be grounded in and sampled around.
MIN_POINTS = 500

#: How far (m) the floor (the 2nd percentile of z) may sit from z = 0 before a warning.
FLOOR_TOLERANCE = 0.15
_CONVERT = "jaxmotion scene convert --up y SRC DST.npz"


def scene_warnings(scene) -> list[str]:
    """Messages for a scene that does not look z-up with its floor at z ≈ 0 (empty when it
    does). Y-up is suspected when more surfaces face +y than −y by far more than +z over −z
    (with normals), or, without normals, when the scene is much taller (z) than deep (y)."""
    xyz = np.asarray(scene.xyz, np.float64)
    if len(xyz) < 10:
        return []
    out = []
    normal = np.asarray(scene.normal, np.float64)
    has_normals = len(normal) == len(xyz) and bool((np.abs(normal).sum(1) > 0.5).any())
    extent = np.percentile(xyz, 98, axis=0) - np.percentile(xyz, 2, axis=0)
    if has_normals:
        # the up axis is the one whose surfaces face mostly one way (floor, seats and table
        # tops face up; a scan sees few undersides), the horizontal ones face both ways (walls)
        up = (normal > 0.9).mean(0)
        down = (normal < -0.9).mean(0)
        lean = up - down
        y_up = lean[1] > 2.0 * max(lean[2], 0.0) and lean[1] > 0.1
    else:
        y_up = extent[2] > 2.0 * max(extent[1], 1e-6) and extent[2] > 3.5
    if y_up:
        out.append(f"the scene looks y-up (its floor faces +y): jaxmotion expects z-up; convert "
                   f"it with `{_CONVERT}` (or load it with up='y')")
    floor = float(np.percentile(xyz[:, 2], 2))
    if not y_up and abs(floor) > FLOOR_TOLERANCE:
        out.append(f"the scene's floor is at z = {floor:.2f} m, not 0: the models expect the "
                   "floor at z = 0; shift the scene, or if it is y-up convert it with "
                   f"`{_CONVERT}`")
    return out


def check_room(room, pipeline: str = "auto") -> None:
    """Refuse, before any model runs, a room that cannot serve an instruction:
    :class:`~jaxmotion.errors.GenerateError` for an empty or near-empty scan (fewer than
    :data:`MIN_POINTS` points) and, unless the affordance pipeline is asked for, a room in
    which no object was found (a floor-only scan): the object-centric pipeline needs one, and
    the affordance pipeline's guess is no longer taken silently."""
    from jaxmotion.errors import GenerateError

    if room.num_points < MIN_POINTS:
        raise GenerateError(f"the scene has {room.num_points} point(s): too few to be a room "
                            f"(at least {MIN_POINTS}); check the file, or scan more of the room")
    if not room.objects and pipeline in ("auto", "object-centric"):
        raise GenerateError("no object was found in this room (a floor or walls only?), so "
                            "there is nothing to sit on or walk to; scan the furniture too, or "
                            "pass --pipeline affordance to let the affordance model choose a "
                            "place on its own")
