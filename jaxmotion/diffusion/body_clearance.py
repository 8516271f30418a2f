"""Body clearance: the completion stage keeps the body's joints off the other furniture.

:mod:`.clearance` keeps the *pelvis* of standing and walking frames away from obstacles, and
:mod:`.seated_turn` points a seated body's legs at free floor; the limbs are the completion
model's. In real rooms, where chairs stand 15 cm apart and a table fills the space in front
of a sofa, they still brush the furniture next to the target: a knee passing the neighbouring
chair as the body lowers onto its seat, a wrist in the next chair's back at a table, a foot in
a coffee table while sitting on a sofa.

This module adds a term to the completion stage's reconstruction guidance (the one foot
guidance uses, :func:`.foot_guidance.make_refiner`): for every valid frame and every joint, how
far the joint is inside :data:`MARGIN` of the nearest obstacle, squared, in units of
:data:`SCALE`, summed over the frames and divided by :data:`FRAMES` (a few frames with a knee
in a chair are not diluted by the many where the body is clear, whose gradient is 0). Only the
body's rotations move; the pelvis stays on the first stage's path.

The obstacles are the room's own points (all of them, not the few thousand of the crop the
models read: between those a joint finds gaps of 10 cm in a chair's back), those of the target
aside, at least :data:`LOW` above the floor (floor noise and rugs: the feet stand on them).
They are read through a **distance field** over the crop (:func:`distance_field`, made on the
host once per request): at the nodes of a grid of :data:`CELL` over the crop square and
:data:`TOP` high, the distance (m) to the nearest obstacle point, exact up to :data:`CLIP`;
a joint's distance is its trilinear interpolation (:func:`field_distance`), differentiable and
as cheap for a dense scan as for a sparse one.

Pure functions of arrays for one motion; ``vmap`` for batches.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.motion.representation import motion_to_joints

__all__ = ["CELL", "CLIP", "FIELD_SHAPE", "FRAMES", "HALF", "LOW", "MARGIN", "SCALE", "TOP",
           "clearance_loss", "distance_field", "empty_field", "field_distance",
           "joints_clearance", "room_field"]

#: Points lower than this (m) above the floor are floor, not obstacles (as :mod:`.clearance`).
LOW = 0.1
#: A joint keeps this distance (m) from the obstacle points: the 4 cm of the real-scan metric
#: and a margin for the limb's own thickness around its joint centre.
MARGIN = 0.07
#: The unit of the term (m): a joint this far inside the margin costs 1.
SCALE = 0.04
#: The term is summed over frames and divided by this many (as the foot guidance's sink term).
FRAMES = 2.0
#: The field's grid: nodes every CELL (m) over x, y in [-HALF, HALF] of the crop frame (the
#: crop square is 4 m; a body at its edge reaches past it) and z in [0, TOP]; distances are
#: exact up to CLIP (m) and CLIP beyond (the term only reads them under MARGIN).
CELL = 0.04
HALF = 2.2
TOP = 2.0
CLIP = 0.12
FIELD_SHAPE = (round(2 * HALF / CELL) + 1,) * 2 + (round(TOP / CELL) + 1,)


def empty_field() -> np.ndarray:
    """The field of a crop without obstacles: ``CLIP`` everywhere, ``float32 FIELD_SHAPE``."""
    return np.full(FIELD_SHAPE, CLIP, np.float32)


def distance_field(points) -> np.ndarray:
    """The distance field (module docstring) of obstacle points ``[P, 3]`` in the crop frame
    (metres, floor at z = 0; the caller chooses which points are obstacles):
    ``float32 FIELD_SHAPE``, node ``(i, j, k)`` at ``(-HALF + i CELL, -HALF + j CELL,
    k CELL)``. Exact nearest-point distances (a k-d tree) at the nodes a coarse distance
    transform puts near a point; ``CLIP`` elsewhere."""
    from scipy import ndimage
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64).reshape(-1, 3)
    lo = np.array([-HALF, -HALF, 0.0])
    hi = np.array([HALF, HALF, TOP])
    pts = pts[np.all((pts >= lo - CLIP) & (pts <= hi + CLIP), axis=1)]
    field = empty_field()
    if len(pts) == 0:
        return field
    # nodes within CLIP (+ a cell's diagonal) of an occupied cell: the only ones to query
    cell = np.clip(np.round((pts - lo) / CELL).astype(np.int64), 0, np.array(FIELD_SHAPE) - 1)
    occupied = np.zeros(FIELD_SHAPE, bool)
    occupied[tuple(cell.T)] = True
    near = ndimage.distance_transform_edt(~occupied, sampling=CELL) <= CLIP + CELL
    nodes = lo + np.argwhere(near) * CELL
    d, _ = cKDTree(pts).query(nodes, distance_upper_bound=CLIP)
    field[near] = np.minimum(d, CLIP)
    return field


def room_field(xyz, obstacle, shift, rot) -> np.ndarray:
    """:func:`distance_field` of a room's points ``xyz [N, 3]`` (scene frame) where
    ``obstacle [N]`` (bool), in the crop frame ``x_crop = rot @ (x - shift)`` of
    :func:`jaxmotion.data.crop.crop_at`; points under :data:`LOW` in that frame are floor."""
    xyz = np.asarray(xyz, np.float32)[np.asarray(obstacle, bool)]
    crop = (xyz - np.asarray(shift, np.float32)) @ np.asarray(rot, np.float32).T
    return distance_field(crop[crop[:, 2] >= LOW])


def field_distance(field, points):
    """The distance field ``field [FIELD_SHAPE]`` at ``points [..., 3]`` (crop frame), by
    trilinear interpolation between its nodes (``CLIP`` outside the grid);
    differentiable in ``points``."""
    shape = jnp.asarray(FIELD_SHAPE)
    u = (points - jnp.asarray([-HALF, -HALF, 0.0], jnp.float32)) / CELL  # node units
    outside = jnp.any((u < 0) | (u > shape - 1), axis=-1)
    u = jnp.clip(u, 0.0, shape - 1.0)
    i0 = jnp.clip(jnp.floor(u).astype(jnp.int32), 0, shape - 2)
    w = u - i0  # [..., 3] in [0, 1]
    value = 0.0
    for corner in range(8):
        bits = jnp.asarray([(corner >> a) & 1 for a in range(3)], jnp.int32)
        idx = i0 + bits
        weight = jnp.prod(jnp.where(bits == 1, w, 1.0 - w), axis=-1)
        value = value + weight * field[idx[..., 0], idx[..., 1], idx[..., 2]]
    return jnp.where(outside, CLIP, value)


def joints_clearance(joints, field, mask):
    """The term (module docstring) of placed joints ``[T, J, 3]`` (crop frame) against
    ``field``, over the frames of ``mask [T]``: a float32 scalar."""
    inside = jax.nn.relu(MARGIN - field_distance(field, joints)) / SCALE  # [T, J]
    return jnp.sum(jnp.asarray(mask, jnp.float32)[:, None] * inside ** 2) / FRAMES


def clearance_loss(features, betas, field, mask):
    """:func:`joints_clearance` of motion ``features [T, 135]`` (metres, crop frame) of a body
    of shape ``betas [10]``."""
    return joints_clearance(motion_to_joints(features, betas), field, mask)
