"""Seated turn (jaxmotion.diffusion.seated_turn) against hand-made seats and numpy."""

import math

import numpy as np

from jaxmotion.constants import ACTION_CLASSES
from jaxmotion.diffusion import seated_turn as S
from jaxmotion.geometry.rotations import matrix_to_rotation_6d, rotation_6d_to_matrix

SIT, WALK = ACTION_CLASSES.index("sit"), ACTION_CLASSES.index("walk")
T = 90


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _facing(yaw):
    """A body's root matrix facing ``yaw`` in the world's xy: its forward axis (z) there, its
    up axis (y) up."""
    fwd = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return np.stack([np.cross(up, fwd), up, fwd], axis=-1)  # columns: body x, y, z


def _traj(yaw=0.0):
    """A sit ending on a seat at the origin, the body facing ``yaw`` (+x for 0)."""
    traj = np.zeros((T, 9), np.float32)
    traj[:, 0] = np.linspace(-1.0, 0.0, T)
    traj[:, 2] = np.linspace(0.93, 0.6, T)
    traj[:, 3:] = np.asarray(matrix_to_rotation_6d(_facing(yaw)[None]))[0]
    return traj


def _seat_and(rng, obstacle_lo=None, obstacle_hi=None):
    """A seat (the target) at the origin and, when given, a box of obstacle points."""
    seat = rng.uniform([-0.25, -0.25, 0.0], [0.25, 0.25, 0.45], (500, 3))
    pts, target = [seat], [np.ones(500, bool)]
    if obstacle_lo is not None:
        pts.append(rng.uniform(obstacle_lo, obstacle_hi, (500, 3)))
        target.append(np.zeros(500, bool))
    return np.concatenate(pts).astype(np.float32), np.concatenate(target)


def test_leg_cost_matches_brute_force():
    rng = np.random.default_rng(0)
    pts = rng.uniform([-1, -1, 0], [1, 1, 1], (2000, 3)).astype(np.float32)
    obstacle = rng.uniform(size=2000) < 0.7
    pelvis, fwd = np.array([0.1, -0.2]), np.array([0.6, 0.8])
    side = np.array([-fwd[1], fwd[0]])
    places = np.array([pelvis + r * fwd + w * side for r in S.LEG_REACH
                       for w in (-S.LEG_HALF_WIDTH, 0.0, S.LEG_HALF_WIDTH)])
    d = np.linalg.norm(places[:, None] - pts[None, :, :2], axis=-1)
    want = ((d < S.LEG_RADIUS).any(0) & obstacle).sum()
    assert float(S.leg_cost(pelvis, fwd, pts, obstacle)) == want


def test_turn_yaw_is_a_turn_about_the_vertical():
    rng = np.random.default_rng(1)
    m = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    m = m * np.sign(np.linalg.det(m))
    got = np.asarray(rotation_6d_to_matrix(S.turn_yaw(matrix_to_rotation_6d(m[None]), 0.7)))[0]
    np.testing.assert_allclose(got, _rz(0.7) @ m, atol=1e-5)


def test_a_seat_with_free_floor_in_front_is_not_turned():
    pts, target = _seat_and(np.random.default_rng(2))
    traj = _traj()
    out, angle = S.seated_turn(traj, pts, target, np.ones(T, bool), SIT)
    assert float(angle) == 0.0
    np.testing.assert_array_equal(np.asarray(out), traj)


def test_legs_turn_away_from_a_chair_in_front_by_the_least_that_frees_them():
    """The next chair stands 15 cm in front of the seat, a little to its right (-y): the body
    turns left (+yaw), as far as frees the legs (a point or two may stay: a turn costs
    10 points a radian) and no further; the hold is turned in full,
    the approach not at all, and positions stay."""
    pts, target = _seat_and(np.random.default_rng(3), [0.4, -0.6, 0.0], [1.0, 0.0, 0.9])
    traj = _traj()
    out, angle = S.seated_turn(traj, pts, target, np.ones(T, bool), SIT)
    out, angle = np.asarray(out), float(angle)
    assert 0.0 < angle < math.radians(45)
    obstacle = ~target & (pts[:, 2] > S.LEG_BAND[0]) & (pts[:, 2] < S.LEG_BAND[1])

    def cost(a):
        return float(S.leg_cost(np.zeros(2), np.array([math.cos(a), math.sin(a)]), pts,
                                obstacle))

    assert cost(0.0) > 40 and cost(angle) <= 0.05 * cost(0.0)  # the legs freed ...
    step = math.radians(10)  # ... by the least turn that is worth its cost
    assert cost(angle - step) >= cost(angle) + S.TURN_COST * step
    np.testing.assert_array_equal(out[:, :3], traj[:, :3])
    end = np.asarray(rotation_6d_to_matrix(out[-1, 3:]))
    np.testing.assert_allclose(end, _facing(angle), atol=1e-5)
    np.testing.assert_array_equal(out[:T - 30], traj[:T - 30])  # before the taper


def test_a_walk_and_given_frames_are_not_turned():
    pts, target = _seat_and(np.random.default_rng(4), [0.4, -0.6, 0.0], [1.0, 0.1, 0.9])
    traj = _traj()
    out, _ = S.seated_turn(traj, pts, target, np.ones(T, bool), WALK)
    np.testing.assert_array_equal(np.asarray(out), traj)
    out, _ = S.seated_turn(traj, pts, target, np.ones(T, bool), SIT, np.ones(T, bool))
    np.testing.assert_array_equal(np.asarray(out), traj)
