"""Walking paths on a scene's points and the root trajectories along them: clearances against
brute-force numpy, walking distances against a plain Dijkstra, refusals with reasons."""

from __future__ import annotations

import heapq

import numpy as np
import pytest

from jaxmotion.motion.planner import CELL, PlanningError
from jaxmotion.planning import (
    approach_point,
    path_trajectory,
    point_grid,
    scene_path,
    trajectory_features,
)
from jaxmotion.planning.paths import END_RADIUS, WALK_RADIUS, free_graph


def _room(gap=True, seed=0):
    """A 6 x 4 m room: floor points, four walls, and a wall across x = 3 with a 1 m door
    (``gap``) at y in [1.5, 2.5]; a 0.5 m box (instance 7) at (4.5, 3)."""
    rng = np.random.default_rng(seed)
    floor = np.c_[rng.uniform(0, 6, (6000, 2)), np.zeros(6000)]
    pts, inst = [floor], [np.full(6000, -1)]

    def wall(x0, y0, x1, y1, n):
        u = rng.uniform(0, 1, n)
        return np.c_[x0 + u * (x1 - x0), y0 + u * (y1 - y0), rng.uniform(0, 2.4, n)]

    floor[:, 1] *= 4 / 6
    for w in ((0, 0, 6, 0), (0, 4, 6, 4), (0, 0, 0, 4), (6, 0, 6, 4)):
        pts.append(wall(*w, 800))
        inst.append(np.full(800, -1))
    if gap:
        pts += [wall(3, 0, 3, 1.5, 400), wall(3, 2.5, 3, 4, 400)]
    else:
        pts.append(wall(3, 0, 3, 4, 800))
    inst += [np.full(len(p), -1) for p in pts[len(inst):]]
    box = np.c_[rng.uniform(4.25, 4.75, (300, 2)) + [0, -1.5], rng.uniform(0, 0.5, 300)]
    pts.append(box)
    inst.append(np.full(300, 7))
    return np.concatenate(pts).astype(np.float32), np.concatenate(inst)


def test_clearance_is_the_distance_to_the_nearest_obstacle_point():
    xyz, inst = _room()
    g = point_grid(xyz, inst)
    rng = np.random.default_rng(1)
    q = rng.uniform([0.3, 0.3], [5.7, 3.7], (200, 2))
    obs = xyz[(xyz[:, 2] >= 0.1) & (xyz[:, 2] <= 1.9), :2]
    brute = np.min(np.linalg.norm(q[:, None] - obs[None], axis=-1), axis=1)
    np.testing.assert_allclose(g.clearance_at(q), brute, rtol=1e-6)
    assert (g.clearance_at(np.array([[7.0, 2.0], [-1.0, 1.0]])) < 0).all()  # off the floor
    # an excluded object is no obstacle
    box_centre = np.array([[4.5, 3.0]])
    assert g.clearance_at(box_centre)[0] < 0.05
    assert point_grid(xyz, inst, exclude=[7]).clearance_at(box_centre)[0] > 0.4


def _dijkstra(free, start):
    """Plain 8-connected Dijkstra (no corner cutting): walking distance in cells."""
    nx, ny = free.shape
    dist = np.full(free.shape, np.inf)
    dist[start] = 0.0
    heap = [(0.0, start)]
    while heap:
        d, (x, y) = heapq.heappop(heap)
        if d > dist[x, y]:
            continue
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                u, v = x + dx, y + dy
                if (dx or dy) and 0 <= u < nx and 0 <= v < ny and free[u, v] and (
                        not (dx and dy) or (free[x + dx, y] and free[x, y + dy])):
                    nd = d + (np.sqrt(2) if dx and dy else 1.0)
                    if nd < dist[u, v]:
                        dist[u, v] = nd
                        heapq.heappush(heap, (nd, (u, v)))
    return dist


def testfree_graph_gives_the_walking_distances_of_a_plain_dijkstra():
    from scipy.sparse.csgraph import dijkstra

    rng = np.random.default_rng(3)
    free = rng.uniform(size=(14, 11)) > 0.3
    free[0, 0] = True
    graph, node = free_graph(free)
    fast = np.full(free.shape, np.inf)
    fast[free] = dijkstra(graph, indices=node[0, 0])
    np.testing.assert_allclose(fast, _dijkstra(free, (0, 0)))


def test_a_path_goes_through_the_door_and_keeps_its_clearance():
    xyz, inst = _room()
    g = point_grid(xyz, inst)
    start = np.array([1.0, 3.0])
    goal = approach_point(g, xyz[inst == 7, :2], start)
    d_box = np.min(np.linalg.norm(xyz[inst == 7, :2] - goal, axis=1))
    assert 0.3 - CELL <= d_box <= 0.6 + CELL
    path = scene_path(g, start, goal)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal)
    crossing = path[np.argmin(np.abs(path[:, 0] - 3.0))]
    assert 1.5 + 0.2 <= crossing[1] <= 2.5 - 0.2  # through the door, clear of its jambs
    clr = g.clearance_at(path)
    far = np.minimum(np.linalg.norm(path - start, axis=1), np.linalg.norm(path - goal, axis=1))
    assert clr[far > 0.6].min() >= WALK_RADIUS - 1e-6
    assert clr.min() >= END_RADIUS - 1e-6
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() < 0.03  # resampled


def test_unreachable_and_impossible_requests_say_why():
    xyz, inst = _room(gap=False)
    g = point_grid(xyz, inst)
    with pytest.raises(PlanningError, match="not connected"):
        approach_point(g, xyz[inst == 7, :2], np.array([1.0, 3.0]))
    with pytest.raises(PlanningError, match="no floor"):
        point_grid(xyz[xyz[:, 2] > 0.2])
    with pytest.raises(PlanningError, match="no free place"):
        approach_point(g, xyz[inst == 7, :2], np.array([4.5, 3.0]), reach=(5.0, 6.0))


def test_path_trajectory_walks_at_a_human_pace_and_faces_where_told():
    from jaxmotion.geometry.rotations import rotation_6d_to_matrix

    path = np.stack([np.linspace(0, 3, 151), np.zeros(151)], -1)
    path = np.concatenate([path, np.stack([np.full(50, 3.0), np.linspace(0.02, 1, 50)], -1)])
    tr = path_trajectory(path, start_heading=np.pi, end_heading=-np.pi / 2, height=0.93)
    speed = np.linalg.norm(np.diff(tr[:, :2], axis=0), axis=1) * 30
    assert speed.max() <= 1.1 + 0.02 and speed[:3].max() < 0.2 and speed[-3:].max() < 0.1
    assert np.diff(speed).max() * 30 < 3.0  # no jolt: |acceleration| under 3 m/s²
    np.testing.assert_allclose(tr[0, :2], path[0], atol=2e-3)  # the smoothed start
    np.testing.assert_allclose(tr[-1, :2], path[-1], atol=1e-3)
    np.testing.assert_allclose(tr[:, 2], 0.93)
    rot = np.asarray(rotation_6d_to_matrix(tr[:, 3:]))
    # upright, rolling and twisting a few degrees within the steps (walking_rhythm)
    assert rot[:, 2, 1].min() > np.cos(0.041) and abs(rot[-1, 2, 1] - 1.0) < 1e-6
    forward = rot[:, :2, 2]  # the body's forward axis (SMPL-X z) in the xy plane
    np.testing.assert_allclose(forward[0], [-1, 0], atol=0.02)  # setting off: twisted ≤ 1°
    np.testing.assert_allclose(forward[-1], [0, -1], atol=1e-5)
    mid = forward[len(tr) // 3]  # walking along +x in between
    assert mid[0] > 0.9
    same = trajectory_features(np.zeros((1, 3)), np.array([0.3]))
    np.testing.assert_allclose(np.asarray(rotation_6d_to_matrix(same[:, 3:]))[0, :2, 2],
                               [np.cos(0.3), np.sin(0.3)], atol=1e-6)
    with pytest.raises(ValueError, match="no length"):
        path_trajectory(np.zeros((3, 2)))
