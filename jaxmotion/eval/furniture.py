"""Bodies inside furniture: the share of frames in which some joint lies inside the box of an
object of the room, as a person looking at the motion sees it (a walk through a table, knees
through a desk, a hand through a cabinet).

The body measure of non-collision (:mod:`jaxmotion.eval.body_metrics`) reads the scene's
points and normals, and misses a body inside an object's empty volume (the legroom under a
table top, between its legs). Here each object is its axis-aligned box (the object table's
``bbox_min`` / ``bbox_max``, z-up, metres) shrunk by ``margin`` on every side, so that a
joint brushing a surface does not count. Objects a body may pass (doors, windows, pictures,
curtains, rugs: :data:`jaxmotion.constants.PASSABLE`) and floors, walls and ceilings are left
out, and so are the ids in ``exclude`` (the seat a sit ends on). Host-side numpy.

A real scan's boxes are loose (an L-shaped sofa's box holds the table it wraps, a segment
spanning the room holds everything): :func:`contact_frames` reads the objects' own points
instead, a frame counting when a joint is within a few centimetres of another object's
surface (against it, or passing through it).
"""

from __future__ import annotations

import numpy as np

from jaxmotion.constants import PASSABLE, STRUCTURE

__all__ = ["IGNORED", "contact_frames", "furniture_frames"]

#: Categories never counted: passable objects and the room's own surfaces.
IGNORED = (*PASSABLE, *STRUCTURE)


def furniture_frames(joints, objects, exclude=(), mask=None, margin: float = 0.05) -> np.ndarray:
    """The share of valid frames in which a joint is inside some object's shrunk box.

    Args:
      joints: ``[..., T, J, 3]`` in the room's frame (metres, z-up).
      objects: the room's object table (dicts with ``id``, ``category``, ``bbox_min``,
        ``bbox_max``).
      exclude: object ids not counted (e.g. the target a sit or lie ends on).
      mask: ``[..., T]`` bool, True = valid frame (default all).
      margin: metres each box is shrunk by on every side.
    Returns:
      ``[...]`` fractions in [0, 1] (0 for a motion with no valid frame).
    """
    joints, mask = _joints_and_mask(joints, mask)
    inside = np.zeros(joints.shape[:-2], bool)
    for o in _counted(objects, exclude):
        lo = np.asarray(o["bbox_min"], np.float64) + margin
        hi = np.asarray(o["bbox_max"], np.float64) - margin
        if np.any(lo >= hi):  # thinner than twice the margin: nothing inside counts
            continue
        inside |= np.all((joints > lo) & (joints < hi), axis=-1).any(-1)
    return _share(inside, mask)


def contact_frames(joints, xyz, instance, objects, exclude=(), mask=None,
                   radius: float = 0.04) -> np.ndarray:
    """The share of valid frames in which a joint is within ``radius`` of the points of an
    object other than those in ``exclude`` (passable objects and structure left out, as in
    :func:`furniture_frames`).

    Args:
      joints: ``[..., T, J, 3]`` in the room's frame (metres, z-up).
      xyz: ``[N, 3]`` the room's points; instance: ``[N]`` their object ids.
      objects: the room's object table (dicts with ``id`` and ``category``).
      exclude: object ids not counted (the target of a sit or lie; a walk's target too when
        touching it is fine).
      mask: ``[..., T]`` bool, True = valid frame (default all).
      radius: metres from a point within which a joint counts as against the object.
    Returns:
      ``[...]`` fractions in [0, 1] (0 for a motion with no valid frame, or a room with no
      counted point).
    """
    from scipy.spatial import cKDTree

    joints, mask = _joints_and_mask(joints, mask)
    xyz, instance = np.asarray(xyz, np.float64), np.asarray(instance)
    if xyz.shape != (len(instance), 3):
        raise ValueError(f"xyz must be [N, 3] with one instance id per point, got {xyz.shape} "
                         f"and {instance.shape}")
    near = np.zeros(joints.shape[:-2], bool)
    pts = xyz[np.isin(instance, [int(o["id"]) for o in _counted(objects, exclude)])]
    if len(pts):
        d, _ = cKDTree(pts).query(joints.reshape(-1, 3), distance_upper_bound=radius)
        near = (d.reshape(joints.shape[:-1]) < radius).any(-1)
    return _share(near, mask)


def _joints_and_mask(joints, mask):
    """``joints`` as float64 ``[..., T, J, 3]`` (checked) and ``mask`` as bool ``[..., T]``."""
    joints = np.asarray(joints, np.float64)
    if joints.ndim < 3 or joints.shape[-1] != 3:
        raise ValueError(f"joints must be [..., T, J, 3], got {joints.shape}")
    mask = (np.ones(joints.shape[:-2], bool) if mask is None
            else np.broadcast_to(np.asarray(mask, bool), joints.shape[:-2]))
    return joints, mask


def _counted(objects, exclude):
    """The objects a body must keep out of: not in ``exclude``, not passable, not structure."""
    skip = {int(i) for i in exclude}
    return [o for o in objects if int(o["id"]) not in skip and o["category"] not in IGNORED]


def _share(hit, mask):
    """The share of the valid frames that ``hit`` ``[..., T]`` (0 where none is valid)."""
    n = mask.sum(-1)
    return np.where(n > 0, (hit & mask).sum(-1) / np.maximum(n, 1), 0.0)
