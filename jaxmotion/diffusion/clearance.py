"""Path clearance: the trajectory stage's standing and walking frames kept out of furniture.

The object-centric trajectory model reads the room through coarse voxel sensors and was
trained on synthetic rooms whose furniture stands apart. In real rooms, where chairs stand
15 cm from each other and a table fills the space in front of a sofa, its paths pass
through the furniture next to the target: on real ScanNet rooms a sit started with the
pelvis over the target's own seat and stood for 40 frames inside the neighbouring chair
before sitting. Anchor guidance (:mod:`.anchor_guidance`) makes it worse where it moves the
whole path by one offset to put the seated pelvis on the seat: the start moves with it.

This module moves the sampled path (the final prediction, once) so that the pelvis of every
frame a body stands or walks in keeps a horizontal distance from the room's obstacle points:

- obstacles: the crop's points between :data:`LOW` and :data:`~jaxmotion.motion.planner.
  BODY_TOP` above the floor (furniture, walls, doors), kept at :data:`RADIUS`; the target's
  own points at :data:`TARGET_RADIUS` in the frames whose pelvis is at standing height (a walk
  stops in front of a table and a sit's approach stands at the seat's edge, but nobody stands
  over a seat; a body sitting on a bed's edge before it lies down is on its target);
- frames: for sit, stand up and lie, not those around the anchor, where the pelvis is on the
  target (the :data:`~.anchor_guidance.HOLD` frames nearest it, then a linear taper over
  :data:`~.anchor_guidance.TAPER`); a walk's end too, when anchor guidance stopped it in
  other furniture (it moves to the nearest free place, which stays within reach of its
  target unless the furniture fills all of it); frames held by inpainting (a prefix joined
  to the previous motion) never move;
- how: :data:`ITERATIONS` rounds of "move each frame's pelvis that overlaps an obstacle
  :data:`STEP` of the way to the nearest free place (:func:`free_places`: a grid of
  :data:`CELL` over the crop, clear and on the floor), then smooth the displacement over
  time" (a Gaussian of :data:`SMOOTH_FRAMES` frames), so the path bends around the obstacle
  instead of jumping, and its frames stay in order; the displacement is capped at
  :data:`MAX_MOVE`, and scaled down (:data:`SHARES`) where the moved path would be faster than
  :data:`SPEED_LIMIT` and the model's own (frames pushed towards exits on two sides of an
  object: a path over a bed's middle, anchor guidance's offset for a lie, has none near).

Heights and orientations are not touched. Where no free place exists (a gap narrower than a
body) the pushes from both sides cancel to the middle of the gap. Pure functions of arrays for
one motion; ``vmap`` for batches.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from jaxmotion.constants import SCENE_FPS
from jaxmotion.diffusion.anchor_guidance import TAPER, anchor_frame, guided_actions, hold_weights
from jaxmotion.motion.planner import BODY_TOP

__all__ = ["CELL", "FLOOR_GAP", "GRID", "ITERATIONS", "LOW", "MAX_MOVE", "RADIUS", "SHARES",
           "SMOOTH_FRAMES", "SPEED_LIMIT", "STANDING_SLACK", "STEP", "TARGET_RADIUS", "clear_path",
           "free_frames", "free_places", "path_overlap"]

#: Points lower than this (m) are floor (its noise, rugs), not obstacles.
LOW = 0.1
#: Horizontal distance (m) a standing or walking pelvis keeps from furniture and walls: half a
#: body's width at the shoulders, the arms swinging beside it.
RADIUS = 0.25
#: ... and from its own target (a sit's approach stands at the seat's front edge).
TARGET_RADIUS = 0.15
#: A pelvis less than this (m) under the body's standing height is not standing: its target
#: is not an obstacle then.
STANDING_SLACK = 0.2
#: Rounds of push-and-smooth, the share of the overlap pushed each round.
ITERATIONS, STEP = 40, 0.7
#: Standard deviation (frames) of the Gaussian the displacement is smoothed with.
SMOOTH_FRAMES = 5.0
#: No frame moves further than this (m): a path that would need more keeps its shape.
MAX_MOVE = 0.6
#: The grid of places a pushed pelvis goes to: cells of this side (m), this many a side
#: (4.8 m: the 4 m crop and its margin).
CELL, GRID = 0.05, 96
#: A place is on the floor when a floor point lies this close (m).
FLOOR_GAP = 0.15
#: A moved path's pelvis is no faster (m/s, horizontal) than this or the model's own path:
#: the largest of SHARES of the move that keeps to it is taken.
SPEED_LIMIT = 2.0
SHARES = (1.0, 0.75, 0.5, 0.25)


def free_frames(mask, action, given=None) -> jnp.ndarray:
    """``[T]`` weights in [0, 1]: how freely each frame's pelvis may move. 0 outside ``mask
    [T]``, on frames ``given [T]`` (held: a prefix; the next :data:`~.anchor_guidance.TAPER` frames
    rise linearly to 1), and, for sit / stand up / lie (``action``, an index
    of :data:`~jaxmotion.constants.ACTION_CLASSES`), on the anchor's hold; 1 elsewhere."""
    mask = jnp.asarray(mask, bool)
    frame = anchor_frame(mask, action)
    on_target = hold_weights(mask, frame)
    w = jnp.where(guided_actions(action), 1.0 - on_target, 1.0) * mask
    if given is not None:  # a prefix: held, then free again over TAPER frames
        n_given = jnp.sum(jnp.asarray(given, jnp.int32))
        w = w * jnp.clip((jnp.arange(mask.shape[0]) - n_given + 1) / TAPER, 0.0, 1.0)
    return w


def _radii(points, target_mask, action) -> jnp.ndarray:
    """``[N]``: the distance each crop point keeps a pelvis at (0: not an obstacle)."""
    z = points[:, 2]
    obstacle = (z > LOW) & (z < BODY_TOP)
    own = jnp.where(guided_actions(action), TARGET_RADIUS, RADIUS)
    return jnp.where(obstacle, jnp.where(jnp.asarray(target_mask, bool), own, RADIUS), 0.0)


def _overlap(xy, points_xy, radii):
    """``[M]``: how deep each place ``xy [M, 2]`` is inside the obstacle points' discs."""
    d = jnp.sqrt(jnp.sum((xy[:, None, :] - points_xy[None]) ** 2, -1) + 1e-12)
    return jnp.max(jnp.where(radii[None] > 0, radii[None] - d, -jnp.inf), axis=1)


def free_places(points, radii):
    """The :data:`CELL` grid over the crop (:data:`GRID` cells a side, centred on its points,
    each point counted at its cell's centre): ``(origin [2], overlap [G, G], goal [G, G, 2])``:
    the centre of cell (0, 0); how deep each cell centre lies inside the obstacles' discs (0:
    clear); and the nearest *free* cell centre to each (clear, and with a floor point under
    :data:`LOW` within :data:`FLOOR_GAP`, so that nothing is pushed beyond a wall or into a hole
    of the scan; itself when free; found by jump flooding, nearest up to a cell or two)."""
    xy = points[:, :2]
    origin = 0.5 * (jnp.min(xy, 0) + jnp.max(xy, 0)) - (GRID - 1) / 2 * CELL
    u = jnp.round((xy - origin) / CELL).astype(jnp.int32)
    ok = jnp.all((u >= 0) & (u < GRID), axis=1)
    u = jnp.clip(u, 0, GRID - 1)
    rad = jnp.zeros((GRID, GRID)).at[u[:, 0], u[:, 1]].max(jnp.where(ok, radii, 0.0))
    on_floor = jnp.zeros((GRID, GRID)).at[u[:, 0], u[:, 1]].max(
        (ok & (points[:, 2] < LOW)).astype(jnp.float32))
    cells = jnp.arange(GRID)
    # the overlap: every cell's largest (radius + half a cell - distance) over the occupied
    # cells within reach, in one gather over the offsets (half a cell wider: a point counts at
    # its cell's centre, up to that far from itself)
    k = math.ceil((RADIUS + CELL / 2) / CELL - 1e-6)
    off = jnp.stack(jnp.meshgrid(jnp.arange(-k, k + 1), jnp.arange(-k, k + 1),
                                 indexing="ij"), -1).reshape(-1, 2)
    padded = jnp.pad(rad, k)
    near = padded[cells[None, :, None] + k + off[:, 0, None, None],
                  cells[None, None, :] + k + off[:, 1, None, None]]  # [K, G, G]
    reach = CELL * jnp.linalg.norm(off.astype(jnp.float32), axis=-1)[:, None, None]
    over = jnp.max(jnp.where(near > 0, near + CELL / 2 - reach, 0.0), axis=0)
    over = jnp.maximum(over, 0.0)
    f = int(FLOOR_GAP / CELL)
    floor = jax.lax.reduce_window(on_floor, 0.0, jax.lax.max, (2 * f + 1, 2 * f + 1), (1, 1),
                                  "SAME") > 0
    centres = origin + CELL * jnp.stack(jnp.meshgrid(cells, cells, indexing="ij"),
                                        -1).astype(jnp.float32)
    free = (over <= 0) & floor
    goal = jnp.where(free[..., None], centres, jnp.inf)
    nbr = jnp.stack(jnp.meshgrid(jnp.arange(-1, 2), jnp.arange(-1, 2), indexing="ij"),
                    -1).reshape(-1, 2)
    rounds = (GRID - 1).bit_length()

    def flood(r, goal):  # jump flooding: each cell takes the nearest seed its neighbours know
        step = jnp.right_shift(1 << (rounds - 1), r)
        i = cells[None, :, None] + step * nbr[:, 0, None, None]
        j = cells[None, None, :] + step * nbr[:, 1, None, None]
        inside = (i >= 0) & (i < GRID) & (j >= 0) & (j < GRID)
        cand = goal[jnp.clip(i, 0, GRID - 1), jnp.clip(j, 0, GRID - 1)]  # [9, G, G, 2]
        d = jnp.where(inside, jnp.sum((cand - centres[None]) ** 2, -1), jnp.inf)
        best = jnp.argmin(d, axis=0)
        return jnp.take_along_axis(cand, best[None, ..., None], axis=0)[0]

    goal = jax.lax.fori_loop(0, rounds, flood, goal)
    goal = jnp.where(jnp.isfinite(goal), goal, centres)  # no free place: nowhere to go
    return origin, over, goal


def _bilinear(grid, u):
    """``grid [G, G]`` at fractional cell coordinates ``u [M, 2]`` (clamped to the grid)."""
    u = jnp.clip(u, 0.0, GRID - 1.0)
    i0 = jnp.minimum(jnp.floor(u).astype(jnp.int32), GRID - 2)
    f = u - i0
    a, b = i0[:, 0], i0[:, 1]
    return ((1 - f[:, 0]) * (1 - f[:, 1]) * grid[a, b] + f[:, 0] * (1 - f[:, 1]) * grid[a + 1, b]
            + (1 - f[:, 0]) * f[:, 1] * grid[a, b + 1] + f[:, 0] * f[:, 1] * grid[a + 1, b + 1])


def _smooth(x, sigma: float):
    """``x [T, D]`` convolved over frames with a normalised Gaussian (edges renormalised)."""
    half = int(3 * sigma)
    taps = jnp.exp(-0.5 * (jnp.arange(-half, half + 1) / sigma) ** 2)
    conv = jax.vmap(lambda c: jnp.convolve(c, taps, mode="same"), in_axes=1, out_axes=1)
    norm = jnp.convolve(jnp.ones(x.shape[0]), taps, mode="same")
    return conv(x) / norm[:, None]


def path_overlap(xy, points, target_mask, action, weight, standing=None) -> jnp.ndarray:
    """``[T]``: how far (m) each weighted frame's pelvis ``xy [T, 2]`` is inside the
    clearance of the crop's obstacles (0: clear); ``weight [T]`` from :func:`free_frames`;
    ``standing [T]`` bool: the frames the target is an obstacle in (None: all)."""
    radii = _radii(points, target_mask, action)
    over = _overlap(xy, points[:, :2], radii)
    if standing is not None:
        other = jnp.where(jnp.asarray(target_mask, bool), 0.0, radii)
        over = jnp.where(jnp.asarray(standing, bool), over, _overlap(xy, points[:, :2], other))
    return jnp.maximum(over, 0.0) * (weight > 0)


def clear_path(xy, points, target_mask, action, weight, standing=None) -> jnp.ndarray:
    """The pelvis path ``xy [T, 2]`` (metres, crop frame) moved out of the obstacles of the
    crop ``points [N, 3]`` (``target_mask [N]`` the target's; ``action`` an action index;
    ``weight [T]`` from :func:`free_frames`; ``standing [T]`` bool: the frames in which the
    target is an obstacle too, those of a pelvis at standing height (None: all): a body
    sitting on the edge of a bed before it lies down is not pushed off it): ``[T, 2]``. See
    the module docstring."""
    radii = _radii(points, target_mask, action)
    weight = jnp.asarray(weight, jnp.float32)
    if standing is None:
        origin, over, goal = free_places(points, radii)
    else:  # and the grids without the target, for the other frames: one program for both
        other = jnp.where(jnp.asarray(target_mask, bool), 0.0, radii)
        origin, overs, goals = jax.vmap(free_places, in_axes=(None, 0))(
            points, jnp.stack([radii, other]))
        origin, over, goal, over_o, goal_o = origin[0], overs[0], goals[0], overs[1], goals[1]
        standing = jnp.asarray(standing, bool)

    def round_(delta, _):
        p = xy + delta
        u = (p - origin) / CELL
        cell = jnp.clip(jnp.round(u).astype(jnp.int32), 0, GRID - 1)
        deep = _bilinear(over, u)
        to = goal[cell[:, 0], cell[:, 1]]
        if standing is not None:
            deep = jnp.where(standing, deep, _bilinear(over_o, u))
            to = jnp.where(standing[:, None], to, goal_o[cell[:, 0], cell[:, 1]])
        push = jnp.where((deep > 0)[:, None], to - p, 0.0)
        delta = delta + STEP * weight[:, None] * push
        delta = _smooth(delta, SMOOTH_FRAMES) * weight[:, None]
        size = jnp.linalg.norm(delta, axis=-1, keepdims=True)
        return delta * jnp.minimum(1.0, MAX_MOVE / jnp.maximum(size, 1e-9)), None

    delta, _ = jax.lax.scan(round_, jnp.zeros_like(xy), None, length=ITERATIONS)
    # never faster than the model's own path or SPEED_LIMIT, whichever is higher: the largest
    # share of the move that keeps to it (frames pushed to exits on two sides of an object
    # would otherwise cross between them)
    def top_speed(path):
        step = jnp.linalg.norm(jnp.diff(path, axis=0), axis=-1) * SCENE_FPS
        return jnp.max(jnp.where(weight[1:] + weight[:-1] > 0, step, 0.0))

    limit = jnp.maximum(top_speed(xy), SPEED_LIMIT)
    shares = jnp.asarray(SHARES, jnp.float32)
    ok = jax.vmap(lambda a: top_speed(xy + a * delta) <= limit)(shares)
    share = jnp.max(jnp.where(ok, shares, 0.0))
    return xy + share * delta
