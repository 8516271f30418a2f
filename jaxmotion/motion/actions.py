"""The four HUMANISE actions in a room: walk to, sit on, stand up from, lie on an object.

:func:`synthesize` is the entry point. The world is given as plain data:

- ``floor_rects``: (xmin, ymin, xmax, ymax) rectangles whose union is the floor;
- ``objects``: dicts with ``id``, ``category``, ``bbox_min`` [3], ``bbox_max`` [3],
  optional ``surface_height`` (top of the seat or mattress) and ``front`` (unit xy
  direction a seat faces; its backrest is on the opposite side).

Every random choice comes from the given ``numpy.random.Generator``: body shape
(10 betas ~ N(0,1) clipped to ±2), posture style, gait (speed 0.8-1.5 m/s, step
length, cadence, width, foot clearance), start position, timing. Clips are 30 fps
and 30-120 frames. The anchor frame (HUMANISE) is the last frame for walk, sit
and lie, the first for stand_up. A request that cannot be met raises a
:class:`~jaxmotion.motion.planner.MotionError` (no path, seat unreachable,
unsupported target), so a dataset builder can resample.
"""

from __future__ import annotations

import numpy as np

from jaxmotion.motion import kinematics as K
from jaxmotion.motion.character import FPS, Controls, Motion, make_motion
from jaxmotion.motion.gait import locomote, sample_gait
from jaxmotion.motion.planner import MotionError, PlanningError, build_grid, plan_path
from jaxmotion.motion.quality import furniture_penetration_np
from jaxmotion.motion.seating import UnsupportedTarget, box_edges, find_seat, front_edge, lie_pose
from jaxmotion.motion.segments import (
    Style,
    from_locomotion,
    lie_down,
    sample_style,
    seated,
    sit_down,
    stand_up,
    standing,
)

__all__ = [
    "ACTIONS",
    "MAX_FRAMES",
    "MIN_FRAMES",
    "RADIUS",
    "UnsupportedTarget",
    "sample_betas",
    "synthesize",
]

ACTIONS = ("walk", "sit", "stand_up", "lie")
MIN_FRAMES, MAX_FRAMES = 30, 120
RADIUS = 0.25  # body clearance while walking, metres
ATTEMPTS = 4  # draws of style, gait and start before giving up
MAX_PENETRATION = 0.04  # joints may sink this far into furniture (soft surfaces, hands), metres


def sample_betas(rng: np.random.Generator) -> np.ndarray:
    """Body shape ``[10]``: N(0, 1) clipped to ±2."""
    return np.clip(rng.normal(size=10), -2.0, 2.0)


def _sample_free(grid, rng, center, dmin, dmax, radius, halfplane=None):
    """A random free point (clearance ≥ radius) at ``dmin..dmax`` from ``center``."""
    nx, ny = grid.clearance.shape
    ij = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"), -1).reshape(-1, 2)
    xy = grid.centers(ij)
    d = np.linalg.norm(xy - center, axis=1)
    ok = (grid.clearance.ravel() >= radius + 0.02) & (d >= dmin) & (d <= dmax)
    if halfplane is not None:
        ok &= (xy - center) @ halfplane > 0.3 * d
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        raise PlanningError(f"no free floor {dmin}-{dmax} m from {np.round(center, 2).tolist()}")
    return xy[rng.choice(idx)] + rng.uniform(-0.02, 0.02, 2)


def _arc_len(path):
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])


def _cut(path, keep, from_end=True):
    """Keep ``keep`` metres of a path: its end part (``from_end``) or its start."""
    s = _arc_len(path)
    if keep >= s[-1]:
        return path
    return path[s >= s[-1] - keep] if from_end else path[s <= keep]


def _heading_of(path, at_end=False):
    d = (path[-1] - path[-2]) if at_end else (path[min(5, len(path) - 1)] - path[0])
    return float(np.arctan2(d[1], d[0])) if np.linalg.norm(d) > 1e-6 else None


def _walk_in(
    body, style, g, rng, path, budget, heading_end, final_feet=None, width_end=None, heading0=None
):
    """Stand at the start of ``path``, walk it, turn to ``heading_end``; fit in ``budget`` frames.

    The start of the path is dropped (the person starts closer) until it fits. With
    ``final_feet`` (a seat's stance) the walk ends on them and flows into what follows.
    """
    h_path = _heading_of(path)
    h0 = (
        (h_path if h_path is not None else heading_end) + rng.normal(0, 0.25)
        if heading0 is None
        else heading0
    )
    delay = rng.uniform(0.0, 0.25)
    for _ in range(10):
        start = path[0]
        lat = np.array([-np.sin(h0), np.cos(h0)]) * (g.width + 0.015)
        feet = np.stack([start + lat, start - lat])
        lo = locomote(
            path,
            g,
            feet,
            [h0, h0],
            h0,
            heading_end,
            delay=delay,
            settle=rng.uniform(0.15, 0.4) if final_feet is None else rng.uniform(0.0, 0.1),
            fps=FPS,
            width_end=width_end,
            final_feet=final_feet,
        )
        if lo.n <= budget:
            st = standing(body, style, start, h0, feet, [h0, h0], 1)
            return from_locomotion(lo, body, g, style, st)
        length = _arc_len(path)[-1]
        if length > 0.05:
            path = _cut(path, max(0.0, length - (lo.n - budget) / FPS * g.speed * 0.8 - 0.1))
            h_new = _heading_of(path)
            h0 = h_new if h_new is not None else h0
        elif final_feet is not None and abs(np.angle(np.exp(1j * (heading_end - h0)))) < 0.3:
            break  # no time to step at all: start in the final stance
        else:  # no walking left: start already partly turned
            path, h0 = path[-1:], h0 + 0.5 * np.angle(np.exp(1j * (heading_end - h0)))
        delay = 0.0
    if final_feet is None:
        raise MotionError("could not fit the walk into the clip length")
    return standing(
        body, style, path[-1], heading_end, final_feet[0], final_feet[1], max(1, min(budget, 10))
    )


def _walk(world, obj, body, style, g, rng):
    rects, objects = world
    grid = build_grid(rects, objects)
    grid_wo = build_grid(rects, objects, exclude=(obj["id"],))
    edges = box_edges(obj)
    fe = front_edge(obj)
    order = list(rng.permutation(len(edges)))
    if fe is not None and rng.random() < 0.8:
        order.sort(key=lambda k: -float(edges[k]["normal"] @ fe["normal"]))
    for k in order:
        e = edges[k]
        for _ in range(4):
            along = rng.uniform(-0.35, 0.35) * max(e["length"] - 0.3, 0.0)
            lat = np.array([-e["normal"][1], e["normal"][0]])
            # The pelvis joint is ~2 cm ahead of the hip centre we plan for.
            goal = e["center"] + lat * along + e["normal"] * rng.uniform(0.125, 0.215)
            pre = goal + 0.35 * e["normal"]
            if grid_wo.clearance_at(goal)[0] < 0.12 or grid.clearance_at(pre)[0] < RADIUS:
                continue
            start = _sample_free(grid, rng, goal, 1.0, 5.0, RADIUS)
            try:
                path = plan_path(
                    grid, start, pre, RADIUS, end_radius=0.08, end_zone=0.45, final=goal
                )
            except PlanningError:
                continue
            facing = float(np.arctan2(-e["normal"][1], -e["normal"][0]))
            c = _walk_in(body, style, g, rng, path, MAX_FRAMES, facing)
            return c, c.n - 1
    raise PlanningError(f"no reachable approach point in front of object {obj['id']}")


def _approach_seat(world, obj, spot, body, style, g, rng, budget, dmin=1.0, dmax=2.5):
    """Walk from a random start to stand on the seat's feet, facing away from it."""
    rects, objects = world
    grid = build_grid(rects, objects)
    end_r = max(0.05, min(0.14, grid.clearance_at(spot.stand_xy)[0] - 0.005))
    try:
        start = _sample_free(grid, rng, spot.stand_xy, dmin, dmax, RADIUS)
        path = plan_path(grid, start, spot.stand_xy, RADIUS, end_radius=end_r, end_zone=0.6)
    except PlanningError:  # cramped: start right there, facing the seat
        path = spot.stand_xy[None]
    h0 = None if len(path) > 1 else spot.yaw + np.pi + rng.normal(0, 0.4)
    return _walk_in(
        body,
        style,
        g,
        rng,
        path,
        budget,
        spot.yaw,
        final_feet=(spot.feet_xy, spot.feet_yaw),
        heading0=h0,
    )


def _sit(world, obj, body, style, g, rng):
    grid_wo = build_grid(world[0], world[1], exclude=(obj["id"],))
    spot = find_seat(obj, body, rng, grid_wo)
    _, pose = seated(spot, body, style, rng)
    n_sit, n_hold = int(rng.uniform(1.0, 1.5) * FPS), int(rng.uniform(0.1, 0.3) * FPS)
    walk = _approach_seat(world, obj, spot, body, style, g, rng, MAX_FRAMES - n_sit - n_hold)
    down = sit_down(walk.last(), pose, n_sit / FPS, rng.uniform(0.35, 0.6))
    c = Controls.cat([walk, down, down.hold(n_hold)])
    return c, c.n - 1


def _stand_up(world, obj, body, style, g, rng):
    rects, objects = world
    grid = build_grid(rects, objects)
    spot = find_seat(obj, body, rng, build_grid(rects, objects, exclude=(obj["id"],)))
    start, _ = seated(spot, body, style, rng)
    hold = start.hold(int(rng.uniform(0.15, 0.6) * FPS))
    up = stand_up(
        start,
        np.array([*spot.stand_xy, body.stand_height]),
        rng.uniform(1.2, 1.7),
        rng.uniform(0.4, 0.65),
        style,
    )
    budget = MAX_FRAMES - hold.n - up.n
    parts = [hold, up]
    try:
        goal = _sample_free(grid, rng, spot.stand_xy, 1.0, 3.0, RADIUS, halfplane=spot.normal)
        end_r = max(0.05, min(0.14, grid.clearance_at(spot.stand_xy)[0] - 0.005))
        path = plan_path(grid, spot.stand_xy, goal, RADIUS, end_radius=end_r, end_zone=0.6)
        path = _cut(path, max(0.3, (budget / FPS - 1.4) * g.speed), from_end=False)
        for _ in range(8):
            lo = locomote(
                path,
                g,
                spot.feet_xy,
                spot.feet_yaw,
                spot.yaw,
                None,
                delay=rng.uniform(0, 0.15),
                settle=rng.uniform(0.1, 0.3),
                fps=FPS,
            )
            if lo.n <= budget:
                parts.append(from_locomotion(lo, body, g, style, up.last()))
                break
            path = _cut(
                path,
                max(0.0, _arc_len(path)[-1] - (lo.n - budget) / FPS * g.speed - 0.1),
                from_end=False,
            )
    except PlanningError:
        pass  # nowhere to go: the clip ends standing in front of the seat
    c = Controls.cat(parts)
    return c, 0


def _lie(world, obj, body, style, g, rng):
    grid_wo = build_grid(world[0], world[1], exclude=(obj["id"],))
    spot = find_seat(obj, body, rng, grid_wo, lie=True)
    _, pose = seated(spot, body, style, rng)
    hip_lie, yaw_lie, room = lie_pose(obj, spot, body, rng)
    n_sit, n_pause = int(rng.uniform(1.0, 1.3) * FPS), int(rng.uniform(0.0, 0.15) * FPS)
    n_lie, n_hold = int(rng.uniform(1.2, 1.6) * FPS), int(rng.uniform(0.1, 0.25) * FPS)
    walk = _approach_seat(
        world,
        obj,
        spot,
        body,
        style,
        g,
        rng,
        MAX_FRAMES - n_sit - n_pause - n_lie - n_hold,
        0.4,
        1.5,
    )
    down = sit_down(walk.last(), pose, n_sit / FPS, rng.uniform(0.3, 0.5))
    parts = [walk, down] + ([down.hold(n_pause)] if n_pause else [])
    lie = lie_down(
        parts[-1].last(),
        body,
        hip_lie,
        yaw_lie,
        spot.surface,
        n_lie / FPS,
        rng.uniform(0.1, 0.3),
        rng,
        room,
    )
    c = Controls.cat(parts + [lie, lie.hold(n_hold)])
    return c, c.n - 1


_PROGRAMS = {"walk": _walk, "sit": _sit, "stand_up": _stand_up, "lie": _lie}


def synthesize(action: str, floor_rects, objects, target_id, rng: np.random.Generator) -> Motion:
    """Synthesize one motion of ``action`` towards object ``target_id``.

    Args:
      action: one of :data:`ACTIONS`.
      floor_rects: ``[R,4]`` floor rectangles (xmin, ymin, xmax, ymax), metres.
      objects: list of object dicts (see the module docstring).
      target_id: ``id`` of the target object.
      rng: the only source of randomness (same seed -> identical output).
    Returns:
      :class:`~jaxmotion.motion.character.Motion` with 30..120 frames at 30 fps.
    Raises:
      MotionError (PlanningError, SeatUnreachable, UnsupportedTarget): cannot be done
      here. A draw that puts a joint more than :data:`MAX_PENETRATION` inside
      furniture (rare: arms in a tight turn, legs swung over a neighbour) is drawn
      again, up to :data:`ATTEMPTS` times, before giving up with MotionError.
    """
    if action not in _PROGRAMS:
        raise ValueError(f"unknown action {action!r}; expected one of {ACTIONS}")
    by_id = {o["id"]: o for o in objects}
    if target_id not in by_id:
        raise UnsupportedTarget(f"no object with id {target_id!r} in the room")
    body = K.make_body(sample_betas(rng))
    world = (np.asarray(floor_rects, float).reshape(-1, 4), list(objects))
    last = None
    for _ in range(ATTEMPTS):  # a rare clash with furniture: draw the motion again
        style: Style = sample_style(rng)
        g = sample_gait(rng, float(body.leg.mean()))
        c, anchor = _PROGRAMS[action](world, by_id[target_id], body, style, g, rng)
        if c.n < MIN_FRAMES:  # pad with stillness (before the motion; after it for stand_up)
            k = MIN_FRAMES - c.n
            if action == "stand_up":
                c = Controls.cat([c, c.hold(k)])
            else:
                first = Controls(**{name: v[:1] for name, v in vars(c).items()})
                c, anchor = Controls.cat([first.hold(k), c]), anchor + k
        if c.n > MAX_FRAMES:
            raise MotionError(f"{action} needs {c.n} frames (> {MAX_FRAMES})")
        m = make_motion(c, body, action, target_id, anchor)
        last = furniture_penetration_np(m.joints, objects, target_id, action)
        if last <= MAX_PENETRATION:
            return m
    raise MotionError(f"{action}: every attempt put a joint {last:.3f} m inside furniture")
