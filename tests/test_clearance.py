"""Path clearance (jaxmotion.diffusion.clearance) against hand-made rooms and brute force."""

import numpy as np
import pytest

from jaxmotion.constants import ACTION_CLASSES
from jaxmotion.diffusion import clearance as C

SIT, WALK = ACTION_CLASSES.index("sit"), ACTION_CLASSES.index("walk")
T = 120


def _box(rng, lo, hi, n):
    return rng.uniform(lo, hi, size=(n, 3))


def _room(rng, *boxes):
    """Crop points: a 4 m floor grid at z = 0 and filled boxes; ``(points, ids)``."""
    g = np.linspace(-2, 2, 61)
    floor = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    pts, ids = [np.c_[floor, np.zeros(len(floor))]], [np.zeros(len(floor), int)]
    for k, (lo, hi) in enumerate(boxes, 1):
        pts.append(_box(rng, lo, hi, 600))
        ids.append(np.full(600, k))
    return np.concatenate(pts).astype(np.float32), np.concatenate(ids)


def _overlap_numpy(xy, points, radii):
    """Brute force: each frame's deepest overlap with an obstacle point's disc (0: clear)."""
    d = np.linalg.norm(xy[:, None, :] - points[None, :, :2], axis=-1)
    return np.maximum(np.where(radii[None] > 0, radii[None] - d, -np.inf).max(1), 0.0)


def test_overlap_matches_brute_force():
    rng = np.random.default_rng(0)
    pts, ids = _room(rng, ([0.2, -0.3, 0.0], [0.7, 0.3, 0.9]))
    target = ids == 1
    xy = rng.uniform(-1, 1, size=(T, 2)).astype(np.float32)
    w = np.ones(T, np.float32)
    for action in (SIT, WALK):
        radii = np.where((pts[:, 2] > C.LOW) & (pts[:, 2] < 1.9),
                         np.where(target, C.TARGET_RADIUS if action == SIT else C.RADIUS,
                                  C.RADIUS), 0.0)
        got = np.asarray(C.path_overlap(xy, pts, target, action, w))
        np.testing.assert_allclose(got, _overlap_numpy(xy, pts, radii), atol=1e-5)


def test_a_walk_through_a_cabinet_goes_around_it_smoothly():
    rng = np.random.default_rng(1)
    pts, ids = _room(rng, ([-0.3, -0.3, 0.0], [0.3, 0.3, 1.2]),  # cabinet in the way
                     ([1.4, -0.4, 0.0], [1.8, 0.4, 0.75]))  # the table walked to
    target = ids == 2
    xy = np.c_[np.linspace(-1.5, 1.05, T), np.zeros(T)].astype(np.float32)
    w = np.asarray(C.free_frames(np.ones(T, bool), WALK))
    before = np.asarray(C.path_overlap(xy, pts, target, WALK, w))
    assert before.max() > 0.2  # straight through the cabinet
    out = np.asarray(C.clear_path(xy, pts, target, WALK, w))
    after = np.asarray(C.path_overlap(out, pts, target, WALK, w))
    assert after.max() < 0.05, after.max()  # the grid counts a point at its cell centre
    speed = np.linalg.norm(np.diff(out, axis=0), axis=1) * 30
    assert speed.max() < 2.0 * np.linalg.norm(np.diff(xy, axis=0), axis=1).max() * 30
    assert np.linalg.norm(out[0] - xy[0]) < 0.1
    table = pts[ids == 2, :2]  # the stop: still in front of the table it walked to
    assert np.linalg.norm(table - out[-1], axis=1).min() < 0.45


def test_a_path_in_free_space_is_unchanged():
    rng = np.random.default_rng(2)
    pts, ids = _room(rng, ([1.2, 1.2, 0.0], [1.8, 1.8, 0.9]))
    xy = np.c_[np.linspace(-1.5, 0.5, T), np.linspace(-1.0, -0.5, T)].astype(np.float32)
    w = np.asarray(C.free_frames(np.ones(T, bool), WALK))
    np.testing.assert_array_equal(np.asarray(C.clear_path(xy, pts, ids == 1, WALK, w)), xy)


def test_a_sit_keeps_its_seated_frames_and_leaves_the_seat_to_stand():
    """The path starts standing over the seat (as anchor guidance's offset can put it): the
    standing frames move off the seat, the frames on the seat stay where they are."""
    rng = np.random.default_rng(3)
    pts, ids = _room(rng, ([-0.25, -0.25, 0.0], [0.25, 0.25, 0.45]),  # the seat, the target
                     ([-0.25, 0.45, 0.0], [0.25, 0.9, 0.9]))  # a neighbouring chair
    target = ids == 1
    xy = np.zeros((T, 2), np.float32)  # stands on the seat, then sits there
    mask = np.ones(T, bool)
    w = np.asarray(C.free_frames(mask, SIT))
    assert w[-10:].max() == 0.0  # the hold at the anchor
    out = np.asarray(C.clear_path(xy, pts, target, SIT, w))
    np.testing.assert_array_equal(out[w == 0], xy[w == 0])  # seated: not moved
    assert np.asarray(C.path_overlap(out, pts, target, SIT, w))[:40].max() < 0.05
    assert (np.linalg.norm(out[:40], axis=1) > 0.3).all()  # stood off the seat, not in the chair
    assert np.abs(out[:40, 1] - 0.675).min() > C.RADIUS - 0.05  # and out of the neighbour


def test_given_frames_stay_and_the_move_ramps_in():
    rng = np.random.default_rng(4)
    pts, ids = _room(rng, ([-0.3, -0.3, 0.0], [0.3, 0.3, 1.2]))
    xy = np.c_[np.linspace(-1.5, 1.5, T), np.zeros(T)].astype(np.float32)
    given = np.arange(T) < 30
    w = np.asarray(C.free_frames(np.ones(T, bool), WALK, given))
    out = np.asarray(C.clear_path(xy, pts, ids == 5, WALK, w))
    np.testing.assert_array_equal(out[given], xy[given])
    assert np.linalg.norm(np.diff(out, axis=0), axis=1).max() * 30 < 3.0


@pytest.mark.parametrize("action", [SIT, WALK])
def test_clear_path_vmaps_and_jits(action):
    """Batched under jit: every row cleared, the same result twice (the rounds' decisions
    are discrete, so a row may differ from its unbatched run by float rounding near an
    obstacle's edge: compared by what it achieves)."""
    import jax

    rng = np.random.default_rng(5)
    pts, ids = _room(rng, ([-0.3, -0.3, 0.0], [0.3, 0.3, 1.2]))
    xy = np.stack([np.c_[np.linspace(-1.5, 1.5, T), np.full(T, y)] for y in (0.0, 0.1)])
    w = np.asarray(C.free_frames(np.ones(T, bool), action))
    f = jax.jit(jax.vmap(C.clear_path, in_axes=(0, None, None, None, None)))
    batched = np.asarray(f(xy.astype(np.float32), pts, ids == 1, action, w))
    np.testing.assert_array_equal(batched, np.asarray(f(xy.astype(np.float32), pts, ids == 1,
                                                          action, w)))
    for row in batched:
        assert np.asarray(C.path_overlap(row, pts, ids == 1, action, w)).max() < 0.05
