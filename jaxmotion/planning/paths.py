"""Walking paths in any scene: a clearance grid from the scene's points, A*, smoothing.

The synthetic world plans on its exact geometry (floor rectangles and furniture boxes,
:mod:`jaxmotion.motion.planner`). A scan, a mesh or a point cloud has neither, only points, so
:class:`PointGrid` measures the same thing from them and plugs into the same planner
(:func:`jaxmotion.motion.planner.plan_path`: 8-connected A* on 5 cm cells, line-of-sight
shortcuts, corners rounded into arcs, resampled by arc length):

- *obstacles*: every point between ``low`` (0.1 m, above the floor's noise and rugs) and
  :data:`~jaxmotion.motion.planner.BODY_TOP` (1.9 m), seen from above; objects the path may
  touch (the seat the person gets up from, the target) can be left out by instance id;
- *floor*: where a point below ``floor_height`` (5 cm) lies within ``floor_gap`` (0.15 m):
  outside it (beyond the walls of a scan, a hole in its floor) nobody walks;
- *clearance* of a place: its horizontal distance to the nearest obstacle point, negative off
  the floor. A body of radius ``r`` stands where the clearance is at least ``r``.

:func:`approach_point` picks where a walk to an object ends: the free place within reach of
the object nearest to the start along a path. :func:`approach_area` measures the free floor
within reach of an object, on a :class:`PointGrid` or on :class:`FloorPoints` (the same cells,
measured only near the object from the points there: the free floor's choice among a room's
objects builds no grid of the whole room and imports no SciPy). Errors are
:class:`~jaxmotion.motion.planner.PlanningError` with the reason (an end inside furniture, a
room whose free space is not connected between the two).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from jaxmotion.motion.planner import BODY_TOP, CELL, GridCells, PlanningError, plan_path

if TYPE_CHECKING:  # SciPy is imported where a tree is built (the free floor's choice needs none)
    from scipy.spatial import cKDTree

__all__ = ["SIT_REACH", "WALK_REACH", "WALK_WIDER", "FloorPoints", "PointGrid", "approach_area",
           "approach_point", "floor_points", "free_graph", "point_grid", "scene_path"]

#: Body radius a walking path keeps from obstacles (m); the ends may come closer.
WALK_RADIUS = 0.30
#: Clearance allowed within ``END_ZONE`` of a path's ends (an approach to a seat).
END_RADIUS = 0.12
END_ZONE = 0.6
#: How far from its object (m) a walk before a sit or lie ends.
SIT_REACH = (0.5, 1.0)
#: How far from its object a walk ends (m).
WALK_REACH = (0.3, 0.6)
#: How far out (m) a walk's end may move when nothing within WALK_REACH is free or reachable.
WALK_WIDER = (1.0, 1.5)


@dataclass(frozen=True)
class PointGrid(GridCells):
    """Clearance grid of a point cloud, with the interface of
    :class:`jaxmotion.motion.planner.Grid` (``origin``, ``clearance``, ``centers``,
    ``index``, ``clearance_at``).

    Attributes:
      origin: ``[2]`` xy of the centre of cell (0, 0), metres.
      clearance: ``[NX, NY]`` clearance of each cell centre, metres (negative off the floor).
      obstacles: the obstacle points' tree (xy); floor: the floor points' tree (xy).
      floor_gap: how far from a floor point a place still counts as floor (m).
    """

    origin: np.ndarray
    clearance: np.ndarray
    obstacles: cKDTree
    floor: cKDTree
    floor_gap: float

    @property
    def shape(self) -> tuple[int, int]:
        """The grid's cells ``(NX, NY)``."""
        return self.clearance.shape

    def free(self, i0: int, i1: int, j0: int, j1: int, radius: float) -> np.ndarray:
        """``[i1 - i0, j1 - j0]`` bool: the cells of the window where a body of ``radius``
        stands (clearance ≥ ``radius``)."""
        return self.clearance[i0:i1, j0:j1] >= radius

    def clearance_at(self, xy) -> np.ndarray:
        """Clearance ``[N]`` at points ``[N,2]``: the distance to the nearest obstacle point,
        -1 off the floor."""
        xy = np.atleast_2d(np.asarray(xy, float))
        d_obs = (self.obstacles.query(xy)[0] if self.obstacles.n
                 else np.full(len(xy), np.inf))
        on_floor = self.floor.query(xy, distance_upper_bound=self.floor_gap)[0] <= self.floor_gap
        return np.where(on_floor, np.minimum(d_obs, 10.0), -1.0)


def point_grid(xyz, instance=None, *, exclude=(), low: float = 0.1, high: float = BODY_TOP,
               floor_height: float = 0.05, floor_gap: float = 0.15) -> PointGrid:
    """The :class:`PointGrid` of a scene's points ``xyz [N,3]`` (z-up, floor at 0, metres);
    ``instance [N]`` with ``exclude`` (instance ids) leaves those objects out of the
    obstacles. Raises :class:`PlanningError` for a scene without floor points."""
    from scipy.spatial import cKDTree

    pts = floor_points(xyz, instance, exclude=exclude, low=low, high=high,
                       floor_height=floor_height, floor_gap=floor_gap)
    origin, n = pts.origin, np.asarray(pts.shape)
    grid = PointGrid(origin, np.zeros(n), cKDTree(pts.obstacles), cKDTree(pts.floor),
                     float(floor_gap))
    ij = np.stack(np.meshgrid(np.arange(n[0]), np.arange(n[1]), indexing="ij"), -1)
    clr = grid.clearance_at(grid.centers(ij.reshape(-1, 2))).reshape(n)
    clr.flags.writeable = False
    return PointGrid(origin, clr, grid.obstacles, grid.floor, grid.floor_gap)


@dataclass(frozen=True)
class FloorPoints(GridCells):
    """A scene's floor and obstacle points (xy) on :class:`PointGrid`'s cells, without its
    clearance over the whole room: :meth:`free` answers for a window of cells from the points
    near it (the same cells as :meth:`PointGrid.free`), so measuring the free floor around a
    few objects (:func:`approach_area`) needs no grid of the room and no tree.

    Attributes:
      origin: ``[2]`` xy of cell (0, 0)'s centre; shape: the cells ``(NX, NY)``.
      obstacles: ``[K, 2]`` the obstacle points; floor: ``[F, 2]`` the floor points.
      floor_gap: how far from a floor point a place still counts as floor (m).
      known: ``(radius, [NX, NY] bool)``: the free cells of the whole grid for that radius,
        measured once (:meth:`measured`), or None.
    """

    origin: np.ndarray
    shape: tuple[int, int]
    obstacles: np.ndarray
    floor: np.ndarray
    floor_gap: float
    known: tuple | None = None

    def measured(self, radius: float) -> FloorPoints:
        """These points with the whole grid's free cells for ``radius`` measured at once
        (cheaper than many windows when they cover most of the room)."""
        return dataclasses.replace(self, known=(radius, self.free(0, self.shape[0], 0,
                                                                  self.shape[1], radius)))

    def free(self, i0: int, i1: int, j0: int, j1: int, radius: float) -> np.ndarray:
        """``[i1 - i0, j1 - j0]`` bool: the cells of the window on the floor (a floor point
        nearer than ``floor_gap``) with no obstacle point nearer than ``radius`` (> 0)."""
        if self.known is not None and self.known[0] == radius:
            return self.known[1][i0:i1, j0:j1].copy()
        window = (i0, i1, j0, j1)
        return self._near(window, self.floor, self.floor_gap) & ~self._near(
            window, self.obstacles, radius)

    def _near(self, window, points, r: float) -> np.ndarray:
        """``[i1 - i0, j1 - j0]`` bool: the window's cells with one of ``points`` nearer to
        their centre than ``r`` (the distance as :func:`nearest_distances` computes it). A
        cell is sure when a point lies in a nearby cell's square that is wholly nearer than
        ``r``; the others are measured against the points near them."""
        i0, i1, j0, j1 = window
        k = int(np.ceil(r / CELL + 0.5))  # a point nearer than r lies within k cells
        lo, hi = self.centers([[i0, j0]])[0] - r, self.centers([[i1 - 1, j1 - 1]])[0] + r
        points = points[np.all((points >= lo) & (points <= hi), axis=1)]
        hit = np.zeros((i1 - i0, j1 - j0), bool)
        if not len(points):
            return hit
        pad = np.zeros((i1 - i0 + 2 * k, j1 - j0 + 2 * k), bool)  # the window and k around
        b = np.clip(np.rint((points - self.origin) / CELL).astype(int) - (i0 - k, j0 - k), 0,
                    np.array(pad.shape) - 1)
        pad[b[:, 0], b[:, 1]] = True
        w, h = hit.shape
        for di in range(-k, k + 1):
            for dj in range(-k, k + 1):
                if ((abs(di) + 0.5) ** 2 + (abs(dj) + 0.5) ** 2) * CELL * CELL < r * r * 0.999:
                    hit |= pad[k + di:k + di + w, k + dj:k + dj + h]
        todo = np.zeros_like(pad)
        todo[k:k + w, k:k + h] = ~hit
        # the points within k cells of a cell still to measure (a box sum over the pad)
        box = np.pad(todo, k).cumsum(0).cumsum(1)
        box = np.pad(box, ((1, 0), (1, 0)))
        n = 2 * k + 1
        near = (box[n:, n:] - box[:-n, n:] - box[n:, :-n] + box[:-n, :-n]) > 0
        points = points[near[b[:, 0], b[:, 1]]]
        if not len(points):
            return hit
        offsets = np.stack(np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1),
                                       indexing="ij"), -1).reshape(-1, 2)
        base = np.rint((points - self.origin) / CELL).astype(int)
        step = max(1, (1 << 18) // len(offsets))  # points at a time
        for s in range(0, len(points), step):
            q = points[s:s + step, None]
            ij = base[s:s + step, None] + offsets[None]
            c = self.centers(ij)
            d = np.sqrt((c[..., 0] - q[..., 0]) ** 2 + (c[..., 1] - q[..., 1]) ** 2)
            ok = ((d < r) & (ij[..., 0] >= i0) & (ij[..., 0] < i1) & (ij[..., 1] >= j0)
                  & (ij[..., 1] < j1))
            hit[ij[ok][:, 0] - i0, ij[ok][:, 1] - j0] = True
        return hit


def floor_points(xyz, instance=None, *, exclude=(), low: float = 0.1, high: float = BODY_TOP,
                 floor_height: float = 0.05, floor_gap: float = 0.15) -> FloorPoints:
    """The :class:`FloorPoints` of a scene's points (the arguments of :func:`point_grid`,
    which builds its grid from them). Raises :class:`PlanningError` for a scene without floor
    points."""
    xyz = np.asarray(xyz, float)
    if xyz.ndim != 2 or xyz.shape[1] != 3 or not len(xyz):
        raise PlanningError(f"scene points must be [N, 3] with N > 0, got {xyz.shape}")
    z = xyz[:, 2]
    floor = xyz[z < floor_height, :2]
    if len(floor) < 10:
        raise PlanningError(
            f"the scene has {len(floor)} points below {floor_height} m: no floor to walk on "
            "(is it z-up with the floor at z = 0?)")
    keep = (z >= low) & (z <= high)
    if instance is not None and len(exclude):
        keep &= ~np.isin(np.asarray(instance), np.asarray(list(exclude)))
    lo, hi = floor.min(0), floor.max(0)
    n = np.floor((hi - lo) / CELL).astype(int) + 1
    origin = lo + 0.5 * ((hi - lo) - CELL * (n - 1))
    return FloorPoints(origin, (int(n[0]), int(n[1])), xyz[keep, :2], floor, float(floor_gap))


def nearest_distances(queries, points, within: float) -> np.ndarray:
    """``[Q]``: each of ``queries [Q, 2]``'s distance to the nearest of ``points [P, 2]``, or
    inf when none is nearer than ``within`` (those farther may come back as their distance or
    inf): the points outside the queries' box widened by ``within`` are left out, the rest
    compared with all queries in blocks."""
    queries, points = np.asarray(queries, float), np.asarray(points, float)
    out = np.full(len(queries), np.inf)
    if not len(queries) or not len(points):
        return out
    lo, hi = queries.min(0) - within, queries.max(0) + within
    points = points[np.all((points >= lo) & (points <= hi), axis=1)]
    if not len(points):
        return out
    step = max(1, (1 << 20) // len(points))  # about a million distances at a time
    for i in range(0, len(queries), step):
        q = queries[i:i + step]
        d2 = (q[:, None, 0] - points[None, :, 0]) ** 2 + (q[:, None, 1] - points[None, :, 1]) ** 2
        out[i:i + step] = np.sqrt(d2.min(1))
    return out


def _approach_cells(grid: PointGrid | FloorPoints, target_xy, reach, radius: float, front):
    """The cells a body may end an approach to the object with points ``target_xy [M,2]`` on:
    ``(goal [NX,NY] bool: free and within reach, ahead [NX,NY] bool or None: in front of the
    object's front face)`` (see :func:`approach_point`); both are computed only within reach
    of the object's box, False beyond it."""
    target_xy = np.asarray(target_xy, float).reshape(-1, 2)
    if not len(target_xy):
        raise PlanningError("the target has no points")
    # only the cells within reach of the object's box can be goals
    (i0, j0), (i1, j1) = (grid.index(target_xy.min(0)[None] - reach[1] - CELL)[0],
                          grid.index(target_xy.max(0)[None] + reach[1] + CELL)[0] + 1)
    ij = np.stack(np.meshgrid(np.arange(i0, i1), np.arange(j0, j1), indexing="ij"), -1)
    centres = grid.centers(ij.reshape(-1, 2))
    near = grid.free(i0, i1, j0, j1, radius).flatten()  # a copy: narrowed below
    d_tgt = nearest_distances(centres[near], target_xy, reach[1])  # of the free cells only
    near[near] = (d_tgt >= reach[0]) & (d_tgt <= reach[1])
    goal = np.zeros(grid.shape, bool)
    goal[i0:i1, j0:j1] = near.reshape(i1 - i0, j1 - j0)
    ahead = None
    if front is not None and np.linalg.norm(np.asarray(front, float)[:2]) > 1e-6:
        f = np.asarray(front, float)[:2] / np.linalg.norm(np.asarray(front, float)[:2])
        ahead = np.zeros(grid.shape, bool)  # no goal lies outside the window
        ahead[i0:i1, j0:j1] = (((centres - target_xy.mean(0)) @ f) > (
            (target_xy - target_xy.mean(0)) @ f).max()).reshape(i1 - i0, j1 - j0)
    return goal, ahead


def approach_area(grid: PointGrid | FloorPoints, target_xy, *,
                  reach: tuple[float, float] = WALK_REACH,
                  radius: float = END_RADIUS, front=None) -> float:
    """How much free floor (m²) a body has to end an approach to the object with points
    ``target_xy [M,2]`` on: the free cells (clearance ≥ ``radius``) within ``reach`` of it,
    those in front of its ``front`` face when there are any (as :func:`approach_point` takes
    them, without a start); 0 for an object hemmed in on every side."""
    goal, ahead = _approach_cells(grid, target_xy, reach, radius, front)
    if ahead is not None and (goal & ahead).any():
        goal &= ahead
    return float(goal.sum()) * CELL * CELL


def approach_point(grid: PointGrid, target_xy, start, *, reach: tuple[float, float] = WALK_REACH,
                   radius: float = END_RADIUS, front=None) -> np.ndarray:
    """Where a walk from ``start`` (xy) to the object with points ``target_xy [M,2]`` ends:
    among the free cells (clearance ≥ ``radius``) whose distance to the object is within
    ``reach``, the one nearest ``start`` by walking distance (Dijkstra over the free cells).
    ``front`` (the object's facing, a 2-D or 3-D vector, e.g. a chair's): only cells in front
    of the object's front face count, while one of them can be reached. Raises
    :class:`PlanningError` when none is free or none is reachable."""
    goal, ahead = _approach_cells(grid, target_xy, reach, radius, front)
    if not goal.any():
        raise PlanningError(f"no free place within {reach[1]} m of the target for a body of "
                            f"radius {radius} m (is the object against walls on every side?)")
    from scipy.sparse.csgraph import dijkstra

    free = grid.clearance >= radius
    graph, cell_of = free_graph(free)
    s = start_cell(free, graph, cell_of, grid.index(np.asarray(start, float)[None])[0])
    dist = dijkstra(graph, indices=cell_of[s])
    reach_cost = np.full(free.shape, np.inf)
    reach_cost[free] = dist
    reach_cost[~goal] = np.inf
    if ahead is not None and np.isfinite(reach_cost[ahead]).any():
        reach_cost[~ahead] = np.inf
    best = np.unravel_index(np.argmin(reach_cost), free.shape)
    if not np.isfinite(reach_cost[best]):
        raise PlanningError("no free place near the target can be reached from the start: the "
                            "room's free space is not connected between them")
    return grid.centers(np.asarray(best)[None])[0]


#: Free floor (m²) a walk's start must be connected to: a start inside furniture, or on a
#: pocket of free cells that touches the rest of the floor only at a corner, moves to the
#: nearest free cell of an area at least this large (or of the largest there is).
START_AREA = 1.0


def start_cell(free: np.ndarray, graph, cell_of: np.ndarray, cell,
               within: float | None = None) -> tuple[int, int]:
    """Where a walk from grid cell ``cell`` starts: the cell itself when it is free and
    connected to :data:`START_AREA` of free floor, else the nearest cell that is (a person
    getting up from a seat, or standing in a scan's pocket of floor hemmed in by furniture,
    steps out to the room's floor; the nearest free cell alone may be an island). With
    ``within`` (m): when no such cell is that near, the nearest free cell."""
    from scipy.sparse.csgraph import connected_components

    _, comp = connected_components(graph, directed=False)
    sizes = np.bincount(comp)
    big = sizes >= min(int(sizes.max()), int(np.ceil(START_AREA / CELL**2)))
    s = tuple(int(v) for v in cell)
    if free[s] and big[comp[cell_of[s]]]:
        return s
    ij = np.argwhere(free)
    d = np.linalg.norm(ij - np.array(s), axis=1)
    open_floor = big[comp[cell_of[ij[:, 0], ij[:, 1]]]]
    best = np.flatnonzero(open_floor)[np.argmin(d[open_floor])]
    if within is not None and d[best] * CELL > within:  # no open floor near: the nearest cell
        best = int(np.argmin(d))
    return tuple(int(v) for v in ij[best])


def free_graph(free: np.ndarray):
    """The 8-connected graph of the free cells (no corner cutting), as a sparse matrix with
    edge lengths in cells; and the map from cell index to node (-1 for blocked cells)."""
    from scipy.sparse import coo_matrix

    nx, ny = free.shape
    node = np.full(free.shape, -1, np.int64)
    node[free] = np.arange(int(free.sum()))
    rows, cols, w = [], [], []
    ij = np.argwhere(free)
    for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
        nb = ij + np.array([dx, dy])
        inside = (nb[:, 0] < nx) & (nb[:, 1] >= 0) & (nb[:, 1] < ny)
        a, nb = ij[inside], nb[inside]
        ok = free[nb[:, 0], nb[:, 1]]
        if dx and dy:  # no corner cutting: both side cells free too
            ok &= free[a[:, 0] + dx, a[:, 1]] & free[a[:, 0], a[:, 1] + dy]
        rows.append(node[a[ok, 0], a[ok, 1]])
        cols.append(node[nb[ok, 0], nb[ok, 1]])
        w.append(np.full(int(ok.sum()), np.sqrt(2.0) if dx and dy else 1.0))
    n = int(free.sum())
    r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    g = coo_matrix((np.concatenate([v, v]), (np.concatenate([r, c]), np.concatenate([c, r]))),
                   shape=(n, n)).tocsr()
    return g, node


def scene_path(grid: PointGrid, start, goal, *, radius: float = WALK_RADIUS,
               end_radius: float = END_RADIUS, end_zone: float = END_ZONE,
               step: float = 0.02) -> np.ndarray:
    """A smooth collision-free walking path ``[M,2]`` from ``start`` to ``goal`` (xy),
    points ``step`` apart (:func:`jaxmotion.motion.planner.plan_path` on the point grid),
    keeping ``radius`` from obstacles where it can: where only a narrower passage connects
    the two, the path keeps less (down to ``end_radius``).
    A start inside furniture (getting up from a seat) moves to the nearest free place first.
    Raises :class:`PlanningError` with the reason."""
    start = np.asarray(start, float)
    if grid.clearance_at(start)[0] < end_radius:
        free = grid.clearance >= end_radius + 0.5 * CELL
        if not free.any():
            raise PlanningError("the scene has no free floor for a walking body")
        graph, cell_of = free_graph(free)
        near = grid.centers(np.asarray(start_cell(free, graph, cell_of,
                                                  grid.index(start[None])[0], within=1.0)
                                       )[None])[0]
        if np.linalg.norm(near - start) > 1.0:
            raise PlanningError(f"the start {start.round(2).tolist()} is more than 1 m from "
                                "free floor")
        start = near
    # a narrow passage: the body squeezes through (down to the clearance allowed at the ends)
    radii = [r for r in (radius, 0.5 * (radius + end_radius), end_radius) if r <= radius]
    for i, r in enumerate(radii):
        try:
            return plan_path(grid, start, np.asarray(goal, float), radius=r,
                             end_radius=min(end_radius, r), end_zone=end_zone, step=step)
        except PlanningError:
            if i == len(radii) - 1:
                raise
