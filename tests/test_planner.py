"""Walking paths: clearance grid, A*, smoothing, errors (hand-built rooms, metres)."""

import numpy as np
import pytest

from jaxmotion.motion.planner import (
    CELL,
    PlanningError,
    build_grid,
    obstacle_boxes,
    plan_path,
    resample,
    wall_distance,
)


def box(i, lo, hi, cat="table"):
    return {"id": i, "category": cat, "bbox_min": list(lo), "bbox_max": list(hi)}


L_ROOM = [(0.0, 0.0, 6.0, 3.0), (0.0, 0.0, 3.0, 6.0)]  # an L: the corner (3..6, 3..6) is missing


def seg_len(path):
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def test_wall_distance_of_an_l_shaped_floor():
    p = np.array([[1.0, 1.0], [2.5, 2.5], [5.5, 1.5], [1.5, 5.5], [4.0, 4.0], [-0.5, 1.0]])
    d = wall_distance(p, L_ROOM)
    np.testing.assert_allclose(d[:4], [1.0, np.hypot(0.5, 0.5), 0.5, 0.5], atol=1e-9)
    assert d[4] < 0 and d[5] < 0  # off the floor
    # The inner corner (3, 3) is a boundary point; the shared edge x=3, y<3 is not a wall.
    np.testing.assert_allclose(wall_distance(np.array([[3.0, 1.0]]), L_ROOM), [1.0], atol=1e-9)


def test_clearance_grid_matches_exact_distances():
    objs = [box(1, (2.0, 1.0, 0), (3.0, 2.0, 0.8))]
    g = build_grid([(0, 0, 5, 3)], objs)
    assert g.clearance.shape == (round(5 / CELL) + 1, round(3 / CELL) + 1)
    ij = np.array([[10, 10], [50, 30], [60, 5]])
    xy = g.centers(ij)
    np.testing.assert_allclose(g.clearance[tuple(ij.T)], g.clearance_at(xy), atol=1e-9)
    assert g.clearance_at([[2.5, 1.5]])[0] < 0  # inside the table
    np.testing.assert_allclose(g.clearance_at([[3.4, 1.5]]), [0.4], atol=1e-9)


def test_high_objects_are_not_obstacles():
    objs = [box(1, (1, 1, 2.0), (2, 2, 2.4), "shelf"), box(2, (3, 1, 0), (4, 2, 1.0))]
    assert obstacle_boxes(objs).tolist() == [[3.0, 1.0, 4.0, 2.0]]
    assert obstacle_boxes(objs, exclude=(2,)).shape == (0, 4)


def test_path_goes_around_an_obstacle_with_clearance():
    objs = [box(1, (2.0, 0.0, 0), (2.6, 2.2, 0.9))]  # a wall-like cabinet from the bottom wall
    g = build_grid([(0, 0, 5, 3.5)], objs)
    start, goal = np.array([0.8, 0.8]), np.array([4.2, 0.8])
    radius = 0.25
    path = plan_path(g, start, goal, radius)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.max() < 0.021 and steps.min() > 0.015  # resampled by arc length
    clr = g.clearance_at(path)
    assert clr.min() >= radius - 0.02, clr.min()  # respects the clearance (within the grid)
    assert path[:, 1].max() > 2.2 + radius - 0.02  # it really went round the cabinet
    # Smooth: no sharp corners left (heading changes at most ~15 deg per 2 cm).
    d = np.diff(path, axis=0)
    turn = np.abs(np.angle(np.exp(1j * np.diff(np.arctan2(d[:, 1], d[:, 0])))))
    assert np.degrees(turn).max() < 15
    # Not absurdly long: within 25 % of the shortest route around the cabinet's corner.
    corner = np.array([2.3, 2.2 + radius])
    assert seg_len(path) < 1.25 * (np.linalg.norm(corner - start) + np.linalg.norm(goal - corner))


def test_path_in_open_room_is_straight():
    g = build_grid([(0, 0, 5, 5)], [])
    path = plan_path(g, [1, 1], [4, 3.5])
    np.testing.assert_allclose(seg_len(path), np.hypot(3, 2.5), rtol=1e-6)


def test_path_turns_the_corner_of_an_l_room():
    g = build_grid(L_ROOM, [])
    path = plan_path(g, [5.5, 1.5], [1.5, 5.5], radius=0.3)
    assert wall_distance(path, L_ROOM).min() >= 0.3 - 0.02
    # It cuts the inner corner at (3, 3) at a distance, not through the missing quadrant.
    assert not np.any((path[:, 0] > 3.0) & (path[:, 1] > 3.0))


def test_end_zone_allows_a_closer_approach_and_final_segment():
    table = box(1, (2.0, 1.0, 0), (3.0, 2.0, 0.8))
    g = build_grid([(0, 0, 5, 3)], [table])
    goal = np.array([3.15, 1.5])  # 15 cm from the table: too close for the cruising radius
    with pytest.raises(PlanningError, match="not free"):
        plan_path(g, [0.5, 0.5], goal, radius=0.25)
    path = plan_path(
        g, [0.5, 0.5], [3.5, 1.5], radius=0.25, end_radius=0.1, end_zone=0.45, final=goal
    )
    np.testing.assert_allclose(path[-1], goal)
    far = np.linalg.norm(path - goal, axis=1) > 0.45
    assert g.clearance_at(path[far]).min() >= 0.25 - 0.02
    assert g.clearance_at(path).min() >= 0.1 - 0.01


def test_blocked_room_raises():
    wall = box(1, (2.0, 0.0, 0), (2.3, 3.0, 1.0))  # splits the room in two
    g = build_grid([(0, 0, 5, 3)], [wall])
    with pytest.raises(PlanningError, match="no collision-free path"):
        plan_path(g, [0.8, 1.5], [4.0, 1.5])
    # A doorway narrower than the body is still blocked; a wide one is not.
    narrow = [box(1, (2.0, 0.0, 0), (2.3, 1.3, 1)), box(2, (2.0, 1.65, 0), (2.3, 3.0, 1))]
    with pytest.raises(PlanningError):
        plan_path(build_grid([(0, 0, 5, 3)], narrow), [0.8, 1.5], [4.0, 1.5], radius=0.25)
    wide = [box(1, (2.0, 0.0, 0), (2.3, 1.0, 1)), box(2, (2.0, 2.0, 0), (2.3, 3.0, 1))]
    path = plan_path(build_grid([(0, 0, 5, 3)], wide), [0.8, 1.5], [4.0, 1.5], radius=0.25)
    assert build_grid([(0, 0, 5, 3)], wide).clearance_at(path).min() >= 0.23


def test_goal_off_the_floor_or_inside_furniture_raises():
    g = build_grid([(0, 0, 5, 3)], [box(1, (2, 1, 0), (3, 2, 1))])
    with pytest.raises(PlanningError, match="goal"):
        plan_path(g, [0.5, 0.5], [2.5, 1.5])
    with pytest.raises(PlanningError, match="goal"):
        plan_path(g, [0.5, 0.5], [7.0, 1.5])


def test_resample_spacing_and_ends():
    poly = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.5]])
    r = resample(poly, 0.1)
    np.testing.assert_allclose(r[[0, -1]], poly[[0, -1]])
    np.testing.assert_allclose(np.linalg.norm(np.diff(r, axis=0), axis=1), 0.1, atol=1e-9)
