"""Walking paths on the floor: occupancy grid with body clearance, A*, smoothing.

The world is a union of floor rectangles (metres, world xy) and axis-aligned
furniture boxes. Only what is below :data:`BODY_TOP` can touch a walking body,
so boxes whose bottom lies above it (wall shelves) are ignored.

The grid stores, per 5 cm cell, the **clearance**: the horizontal distance from
the cell centre to the nearest obstacle footprint or wall (≤ 0 off the floor).
A body of radius ``r`` may stand where clearance ≥ r. Near the two ends of a
path a smaller ``end_radius`` is allowed inside ``end_zone``, because walk
targets and seats are approached closer than the cruising clearance.

Paths: 8-connected A* on cells → greedy line-of-sight shortcutting (tries a
larger clearance first, so that rounding corners keeps a margin) → corners
blended with quadratic Bézier arcs (G1-continuous spline) that are checked
against the exact clearance → resampled by arc length.
"""

from __future__ import annotations

import functools
import heapq
import itertools
from dataclasses import dataclass

import numpy as np

__all__ = [
    "BODY_TOP",
    "CELL",
    "Grid",
    "GridCells",
    "MotionError",
    "PlanningError",
    "build_grid",
    "obstacle_boxes",
    "plan_path",
    "resample",
    "wall_distance",
]

CELL = 0.05  # grid cell, metres
BODY_TOP = 1.9  # obstacles above this height cannot touch a standing body, metres


class MotionError(RuntimeError):
    """The requested motion cannot be made in this room (the caller may resample)."""


class PlanningError(MotionError):
    """No collision-free path (or free position) exists for the request."""


def obstacle_boxes(objects, exclude=()) -> np.ndarray:
    """xy footprints ``[K,4]`` (xmin, ymin, xmax, ymax) of objects reaching below BODY_TOP."""
    out = [
        (o["bbox_min"][0], o["bbox_min"][1], o["bbox_max"][0], o["bbox_max"][1])
        for o in objects
        if o["bbox_min"][2] < BODY_TOP and o["id"] not in exclude
    ]
    return np.asarray(out, float).reshape(-1, 4)


def _rect_dist(p: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """Signed xy distance (< 0 inside) of points ``[N,2]`` to rectangles ``[K,4]``: ``[N,K]``."""
    c = 0.5 * (rects[:, :2] + rects[:, 2:])
    h = 0.5 * (rects[:, 2:] - rects[:, :2])
    q = np.abs(p[:, None, :] - c[None]) - h[None]
    out = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    return out + np.minimum(q.max(-1), 0.0)


@functools.lru_cache(maxsize=64)
def _exposed_edges(rects: tuple) -> np.ndarray:
    """Boundary segments ``[S,2,2]`` of the union of floor rectangles."""
    r = np.asarray(rects, float).reshape(-1, 4)
    segs = []
    for x0, y0, x1, y1 in r:
        for a, b in (
            ((x0, y0), (x1, y0)),
            ((x1, y0), (x1, y1)),
            ((x1, y1), (x0, y1)),
            ((x0, y1), (x0, y0)),
        ):
            a, b = np.array(a), np.array(b)
            # Split the edge where other rectangles start or stop, keep exposed pieces.
            ts = {0.0, 1.0}
            ax = 0 if abs(b[0] - a[0]) > 0 else 1
            for v in np.concatenate([r[:, ax], r[:, ax + 2]]):
                t = (v - a[ax]) / (b[ax] - a[ax])
                if 0 < t < 1:
                    ts.add(float(t))
            ts = sorted(ts)
            normal = np.array([b[1] - a[1], a[0] - b[0]])
            normal /= np.linalg.norm(normal)  # outward for counter-clockwise edges
            for t0, t1 in itertools.pairwise(ts):
                m = a + (b - a) * 0.5 * (t0 + t1) + 1e-4 * normal
                if not np.any(_rect_dist(m[None], r)[0] < 0):
                    segs.append((a + (b - a) * t0, a + (b - a) * t1))
    return np.asarray(segs, float).reshape(-1, 2, 2)


def wall_distance(p: np.ndarray, floor_rects) -> np.ndarray:
    """Distance ``[N]`` from points ``[N,2]`` to the floor boundary; negative off the floor."""
    rects = tuple(map(tuple, np.asarray(floor_rects, float).reshape(-1, 4)))
    segs = _exposed_edges(rects)
    a, b = segs[:, 0], segs[:, 1]
    ab = b - a
    t = np.clip(np.einsum("nsk,sk->ns", p[:, None] - a[None], ab) / np.sum(ab * ab, -1), 0, 1)
    d = np.linalg.norm(p[:, None] - (a[None] + t[..., None] * ab[None]), axis=-1).min(1)
    inside = np.any(_rect_dist(p, np.asarray(rects)) <= 0, axis=1)
    return np.where(inside, d, -d)


class GridCells:
    """The cells of a floor grid of :data:`CELL` squares: ``origin`` (``[2]`` xy of cell
    (0, 0)'s centre) and ``shape`` ``(NX, NY)``, from the class that mixes it in."""

    def centers(self, ij) -> np.ndarray:
        """Cell indices ``[N,2]`` -> xy ``[N,2]``."""
        return self.origin + CELL * np.asarray(ij, float)

    def index(self, xy) -> np.ndarray:
        """xy ``[N,2]`` -> nearest cell indices ``[N,2]`` (clipped to the grid)."""
        ij = np.rint((np.asarray(xy, float) - self.origin) / CELL).astype(int)
        return np.clip(ij, 0, np.array(self.shape) - 1)


@dataclass(frozen=True)
class Grid(GridCells):
    """Floor occupancy grid.

    Attributes:
      origin: ``[2]`` xy of the centre of cell (0, 0), metres.
      clearance: ``[NX, NY]`` clearance of each cell centre, metres (≤ 0 off the floor).
      floor_rects: ``[R,4]``; boxes: ``[K,4]`` obstacle footprints used.
    """

    origin: np.ndarray
    clearance: np.ndarray
    floor_rects: np.ndarray
    boxes: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """The grid's cells ``(NX, NY)``."""
        return self.clearance.shape

    def clearance_at(self, xy: np.ndarray) -> np.ndarray:
        """Exact clearance ``[N]`` at arbitrary points ``[N,2]`` (not the grid lookup)."""
        xy = np.atleast_2d(np.asarray(xy, float))
        d = wall_distance(xy, self.floor_rects)
        if len(self.boxes):
            d = np.minimum(d, _rect_dist(xy, self.boxes).min(1))
        return d


def build_grid(floor_rects, objects, exclude=()) -> Grid:
    """Occupancy grid of a room (cached per room; ``exclude`` lists object ids to ignore)."""
    rects = tuple(map(tuple, np.asarray(floor_rects, float).reshape(-1, 4).round(6)))
    boxes = tuple(map(tuple, obstacle_boxes(objects, exclude).round(6)))
    return _build(rects, boxes)


@functools.lru_cache(maxsize=32)
def _build(rects: tuple, boxes: tuple) -> Grid:
    r = np.asarray(rects, float)
    lo, hi = r[:, :2].min(0), r[:, 2:].max(0)
    n = np.floor((hi - lo) / CELL).astype(int) + 1
    origin = lo + 0.5 * ((hi - lo) - CELL * (n - 1))
    ij = np.stack(np.meshgrid(np.arange(n[0]), np.arange(n[1]), indexing="ij"), -1).reshape(-1, 2)
    g = Grid(origin, np.zeros(n), r, np.asarray(boxes, float).reshape(-1, 4))
    clr = g.clearance_at(g.centers(ij)).reshape(n)
    clr.flags.writeable = False
    return Grid(origin, clr, r, g.boxes)


def _required(grid: Grid, xy, ends, radius, end_radius, end_zone) -> np.ndarray:
    """Clearance a body needs at points ``[N,2]``: ``end_radius`` near the path ends."""
    xy = np.atleast_2d(xy)
    near = np.zeros(len(xy), bool)
    for e in ends:
        near |= np.linalg.norm(xy - e, axis=1) < end_zone
    return np.where(near, end_radius, radius)


def _segment_ok(grid, a, b, need_fn, margin=0.0, step=0.025) -> bool:
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
    pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
    return bool(np.all(grid.clearance_at(pts) >= need_fn(pts) + margin))


def _astar(passable: np.ndarray, start: tuple, goal: tuple) -> list:
    nx, ny = passable.shape
    free = passable.ravel().tolist()
    s, g = start[0] * ny + start[1], goal[0] * ny + goal[1]
    gx, gy = goal
    moves = [
        (dx, dy, dx * ny + dy, 1.4142135623730951 if dx and dy else 1.0)
        for dx in (-1, 0, 1)
        for dy in (-1, 0, 1)
        if dx or dy
    ]
    best = {s: 0.0}
    came = {}
    heap = [(0.0, 0.0, s)]
    while heap:
        _, cost, c = heapq.heappop(heap)
        if c == g:
            path = [c]
            while c in came:
                c = came[c]
                path.append(c)
            return [(p // ny, p % ny) for p in reversed(path)]
        if cost > best.get(c, np.inf):
            continue
        cx, cy = divmod(c, ny)
        for dx, dy, dn, w in moves:
            x, y = cx + dx, cy + dy
            if not (0 <= x < nx and 0 <= y < ny):
                continue
            nb = c + dn
            if not free[nb] or (dx and dy and not (free[c + dx * ny] and free[c + dy])):
                continue  # no corner cutting between blocked cells
            nc = cost + w
            if nc < best.get(nb, np.inf):
                best[nb] = nc
                came[nb] = c
                ax, ay = abs(x - gx), abs(y - gy)
                h = max(ax, ay) + 0.4142135623730951 * min(ax, ay)  # octile distance
                heapq.heappush(heap, (nc + h, nc, nb))
    raise PlanningError(f"no collision-free path from {start} to {goal} on the floor grid")


def resample(poly: np.ndarray, step: float = 0.02) -> np.ndarray:
    """Resample a polyline ``[N,2]`` at (nearly) uniform arc length ``step``: ``[M,2]``."""
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    poly = poly[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=1))])
    if s[-1] < 1e-9:
        return poly[:1].copy()
    m = max(2, int(np.ceil(s[-1] / step)) + 1)
    u = np.linspace(0, s[-1], m)
    return np.stack([np.interp(u, s, poly[:, 0]), np.interp(u, s, poly[:, 1])], 1)


def _round_corners(grid, pts, need_fn, rho_max=0.6) -> np.ndarray:
    """Replace each interior corner by the widest quadratic Bézier arc that stays clear."""
    out = [pts[0]]
    for i in range(1, len(pts) - 1):
        p, a, b = pts[i], pts[i - 1], pts[i + 1]
        lin, lout = np.linalg.norm(p - a), np.linalg.norm(b - p)
        ui, uo = (p - a) / lin, (b - p) / lout
        rho = min(rho_max, 0.45 * lin, 0.45 * lout)
        curve = None
        while rho > 0.02:
            s = np.linspace(0, 1, max(5, int(rho / 0.01)))[:, None]
            p0, p2 = p - rho * ui, p + rho * uo
            c = (1 - s) ** 2 * p0 + 2 * s * (1 - s) * p + s**2 * p2
            if np.all(grid.clearance_at(c) >= need_fn(c) - 0.005):
                curve = c
                break
            rho *= 0.6
        out.extend([p] if curve is None else list(curve))
    out.append(pts[-1])
    return np.asarray(out)


def plan_path(
    grid: Grid,
    start,
    goal,
    radius: float = 0.22,
    end_radius: float | None = None,
    end_zone: float = 0.6,
    step: float = 0.02,
    final=None,
) -> np.ndarray:
    """Smooth collision-free walking path from ``start`` to ``goal`` (xy, metres).

    Args:
      grid: from :func:`build_grid`. radius: body clearance along the path.
      end_radius: smaller clearance allowed within ``end_zone`` of either end
        (default: ``radius``).
      final: optional xy after ``goal``: the path continues straight from ``goal`` to
        it (an approach segment checked at ``end_radius``), the corner at ``goal``
        rounded like the others.
    Returns:
      ``[M,2]`` points spaced ``step`` apart along the path, first = start, last = goal.
    Raises:
      PlanningError: an end is not free or the two are not connected.
    """
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    end_radius = radius if end_radius is None else end_radius
    ends = (start, goal) if final is None else (start, goal, np.asarray(final, float))

    def need(xy):  # the smaller clearance is allowed near the start and the very end only
        return _required(grid, xy, (ends[0], ends[-1]), radius, end_radius, end_zone)

    for name, p in (("start", start), ("goal", goal)):
        if grid.clearance_at(p)[0] < need(p[None])[0] - 1e-9:
            raise PlanningError(
                f"{name} {p.round(3).tolist()} is not free (clearance < {end_radius} m)"
            )
    tail = []
    if final is not None:
        if not _segment_ok(grid, goal, ends[2], need):
            raise PlanningError("the final approach segment is blocked")
        tail = [ends[2]]
    if _segment_ok(grid, start, goal, need, margin=0.05):
        return resample(_round_corners(grid, np.asarray([start, goal] + tail), need), step)
    nx, ny = grid.clearance.shape
    ij = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"), -1).reshape(-1, 2)
    req = need(grid.centers(ij)).reshape(nx, ny)
    si, gi = (tuple(int(v) for v in grid.index(p[None])[0]) for p in ends[:2])
    try:  # a small margin first: the segments between cell centres then stay clear too
        passable = grid.clearance >= req + 0.5 * CELL
        passable[si] = passable[gi] = True
        cells = _astar(passable, si, gi)
    except PlanningError:
        passable = grid.clearance >= req
        passable[si] = passable[gi] = True
        cells = _astar(passable, si, gi)
    cells = grid.centers(np.asarray(cells))
    cells[0], cells[-1] = start, goal
    # Keep only the turning points of the cell path, then shortcut between them.
    d = np.diff(cells, axis=0)
    turn = np.abs(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]) > 1e-9
    cells = np.concatenate([cells[:1], cells[1:-1][turn], cells[-1:]])
    # Greedy shortcutting: farthest visible vertex, preferring a 5 cm safety margin.
    pts, i = [cells[0]], 0
    while i < len(cells) - 1:
        j = len(cells) - 1
        while j > i + 1 and not _segment_ok(grid, cells[i], cells[j], need, margin=0.05):
            j -= 1
        if j == i + 1:
            j = len(cells) - 1
            while j > i + 1 and not _segment_ok(grid, cells[i], cells[j], need):
                j -= 1
        pts.append(cells[j])
        i = j
    return resample(_round_corners(grid, np.asarray(pts + tail), need), step)
