"""Anchor guidance (jaxmotion.diffusion.anchor_guidance) against hand-made seats."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.diffusion import anchor_guidance as A
from jaxmotion.models.object_centric import ACTION_CLASSES

SIT, STAND_UP, LIE, WALK = (ACTION_CLASSES.index(a) for a in ("sit", "stand_up", "lie", "walk"))


def _chair(seat_z=0.45, x0=1.0, y0=1.0, size=0.5, step=0.02):
    """A square seat (normals up) with a backrest face (normals along +x) and legs to the floor."""
    n = round(size / step) + 1
    g = np.stack(np.meshgrid(np.linspace(x0, x0 + size, n), np.linspace(y0, y0 + size, n)),
                 -1).reshape(-1, 2)
    seat = np.c_[g, np.full(len(g), seat_z)]
    back = np.c_[np.full(40, x0 + size), np.linspace(y0, y0 + size, 40),
                 np.linspace(seat_z, seat_z + 0.45, 40)]
    legs = np.c_[np.full(20, x0), np.full(20, y0), np.linspace(0.0, seat_z, 20)]
    pts = np.r_[seat, back, legs].astype(np.float32)
    nrm = np.r_[np.tile([0, 0, 1.0], (len(seat), 1)), np.tile([1.0, 0, 0], (40, 1)),
                np.tile([0, 1.0, 0], (20, 1))].astype(np.float32)
    return pts, nrm, len(seat)


def test_support_surface_of_an_l_sofa_is_its_seat_and_a_high_bed_keeps_its_mattress():
    """A real L-shaped sofa: its seat (0.42 m) holds fewer up-facing points than the tops of
    its back and arms (0.72 m), but more than half as many: the seat is the surface. A bed
    whose mattress is at 0.72 m with a low frame rail (few points) keeps the mattress."""
    rng = np.random.default_rng(3)
    seat = np.c_[rng.uniform(0, 2, (400, 2)), rng.normal(0.42, 0.01, 400)]
    back = np.c_[rng.uniform(0, 2.6, (700, 1)), rng.uniform(2.0, 2.3, (700, 1)),
                 rng.normal(0.72, 0.01, 700)]
    pts = np.r_[seat, back].astype(np.float32)
    up = np.tile([0, 0, 1.0], (len(pts), 1)).astype(np.float32)
    s = np.asarray(A.support_surface(jnp.asarray(pts), jnp.asarray(up), jnp.ones(len(pts), bool)))
    assert s[:400].all() and not s[400:].any()
    # fewer seat points than half the back's: the back's layer stays
    s = np.asarray(A.support_surface(jnp.asarray(pts[100:]), jnp.asarray(up[100:]),
                                     jnp.ones(len(pts) - 100, bool)))
    assert not s[:300].any() and s[300:].all()
    mattress = np.c_[rng.uniform(0, 2, (800, 2)), rng.normal(0.72, 0.01, 800)]
    rail = np.c_[rng.uniform(0, 2, (60, 1)), np.zeros((60, 1)), rng.normal(0.35, 0.01, 60)]
    bed = np.r_[mattress, rail].astype(np.float32)
    bed_up = np.tile([0, 0, 1.0], (len(bed), 1)).astype(np.float32)
    s = np.asarray(A.support_surface(jnp.asarray(bed), jnp.asarray(bed_up),
                                     jnp.ones(len(bed), bool)))
    assert s[:800].all() and not s[800:].any()


def _brute_gap(xy, pts, surface):
    return np.min(np.linalg.norm(pts[surface][:, :2] - xy, axis=-1))


def test_support_surface_is_the_seat_not_the_backrest_or_the_legs():
    pts, nrm, n_seat = _chair()
    s = np.asarray(A.support_surface(jnp.asarray(pts), jnp.asarray(nrm),
                                     jnp.ones(len(pts), bool)))
    assert s[:n_seat].all() and not s[n_seat:].any()
    # a seat's underside (normals down) is left out while a top faces up
    under = np.r_[pts, pts[:n_seat] - [0, 0, 0.05]].astype(np.float32)
    under_n = np.r_[nrm, -nrm[:n_seat]].astype(np.float32)
    s = np.asarray(A.support_surface(jnp.asarray(under), jnp.asarray(under_n),
                                     jnp.ones(len(under), bool)))
    assert s[:n_seat].all() and not s[n_seat:].any()
    # normals of the wrong sign everywhere: |n_z| decides
    s = np.asarray(A.support_surface(jnp.asarray(pts), jnp.asarray(-nrm),
                                     jnp.ones(len(pts), bool)))
    assert s[:n_seat].all() and not s[n_seat:].any()
    # without normals, the points of the band at the seat's height (most of them are there);
    # without the band, every target point
    s = np.asarray(A.support_surface(jnp.asarray(pts), jnp.zeros_like(jnp.asarray(nrm)),
                                     jnp.ones(len(pts), bool)))
    np.testing.assert_array_equal(s, np.abs(pts[:, 2] - 0.45) <= A.LAYER_HALF_THICKNESS + 1e-6)
    # the top of a backrest and armrests face up too, but hold fewer points than the seat
    tops = np.r_[np.c_[np.full(26, 1.5), np.linspace(1, 1.5, 26), np.full(26, 0.9)],
                 np.c_[np.linspace(1, 1.5, 26), np.full(26, 0.98), np.full(26, 0.65)]]
    more = np.r_[pts, tops].astype(np.float32)
    more_n = np.r_[nrm, np.tile([0, 0, 1.0], (52, 1))].astype(np.float32)
    s = np.asarray(A.support_surface(jnp.asarray(more), jnp.asarray(more_n),
                                     jnp.ones(len(more), bool)))
    assert s[:n_seat].all() and not s[n_seat:].any()
    low = pts.copy()
    low[:, 2] = 0.05
    s = np.asarray(A.support_surface(jnp.asarray(low), jnp.asarray(nrm),
                                     jnp.ones(len(pts), bool)))
    assert s.all()
    # only the target's points count
    target = np.zeros(len(pts), bool)
    target[: n_seat // 2] = True
    s = np.asarray(A.support_surface(jnp.asarray(pts), jnp.asarray(nrm), jnp.asarray(target)))
    np.testing.assert_array_equal(s, target)


@pytest.mark.parametrize("start", [(0.3, 1.25), (1.25, 0.2), (2.4, 2.3), (0.9, 0.95)])
def test_anchor_offset_lands_inside_the_seat_from_any_side(start):
    pts, _, n_seat = _chair()
    surface = np.zeros(len(pts), bool)
    surface[:n_seat] = True
    p = np.asarray(start, np.float32)
    off = np.asarray(A.anchor_offset(jnp.asarray(p), jnp.asarray(pts[:, :2]),
                                     jnp.asarray(surface)))
    goal = p + off
    assert _brute_gap(goal, pts, surface) <= A.ON_SURFACE + 1e-6
    # carried in past the edge by the largest inset (the seat is 0.5 m wide: it fits); from
    # a corner the inset runs along the diagonal of approach
    edge = min(goal[0] - 1.0, 1.5 - goal[0], goal[1] - 1.0, 1.5 - goal[1])
    straight = start in ((0.3, 1.25), (1.25, 0.2))
    assert edge >= (max(A.INSETS) - 0.03 if straight else 0.05)
    # and never farther than the nearest surface point plus the inset
    assert np.linalg.norm(off) <= _brute_gap(p, pts, surface) + max(A.INSETS) + 1e-5


def test_anchor_offset_keeps_a_pelvis_already_over_the_seat_and_ignores_an_empty_surface():
    pts, _, n_seat = _chair()
    surface = np.zeros(len(pts), bool)
    surface[:n_seat] = True
    for p in ([1.1, 1.4], [1.49, 1.01], [1.25, 1.25]):
        off = A.anchor_offset(jnp.asarray(p, jnp.float32), jnp.asarray(pts[:, :2]),
                              jnp.asarray(surface))
        np.testing.assert_array_equal(np.asarray(off), 0.0)
    off = A.anchor_offset(jnp.asarray([0.0, 0.0]), jnp.asarray(pts[:, :2]),
                          jnp.zeros(len(pts), bool))
    np.testing.assert_array_equal(np.asarray(off), 0.0)


def test_anchor_frame_is_the_first_for_stand_up_else_the_last():
    mask = jnp.asarray([False, True, True, True, False])
    assert int(A.anchor_frame(mask, STAND_UP)) == 1
    for a in (SIT, LIE, WALK):
        assert int(A.anchor_frame(mask, a)) == 3


def _refine(action, x0, mean, std, strength=1.0, mask=None):
    pts, nrm, _ = _chair()
    t = x0.shape[1]
    mask = jnp.ones(t, bool) if mask is None else mask
    fn = A.make_anchor_refiner(jnp.asarray(pts), jnp.asarray(nrm), jnp.ones(len(pts), bool),
                               mask, action, mean, std, strength)
    return np.asarray(fn(x0, jnp.zeros(x0.shape[0], jnp.int32))), pts


def test_refiner_shifts_the_whole_path_rigidly_to_put_the_anchor_on_the_seat():
    rng = np.random.default_rng(0)
    t = 30
    path = np.zeros((2, t, 9), np.float32)  # walk in along +x towards the chair, stop short
    path[:, :, 0] = np.linspace(-1.0, 0.6, t)
    path[:, :, 1] = 1.25 + rng.normal(0, 0.02, (2, t))
    path[:, :, 2] = 0.9
    path[:, :, 3:] = rng.normal(size=(2, t, 6))
    mean = np.array([0.1, -0.2, 0.5, 0, 0, 0, 0, 0, 0], np.float32)
    std = np.array([0.7, 1.3, 0.2, 1, 1, 1, 1, 1, 1], np.float32)
    x0 = jnp.asarray((path - mean) / std)
    for action, frame in ((SIT, t - 1), (LIE, t - 1), (STAND_UP, 0)):
        out, pts = _refine(action, x0, mean, std)
        metres = out * std + mean
        delta = metres - path
        if action != LIE:
            np.testing.assert_allclose(delta[..., 3:], 0.0, atol=1e-5)  # rotation kept
        else:  # turned to lying at the anchor, kept beyond the taper
            for k in range(2):
                want = A.lying_rotation_6d(jnp.asarray(path[k, frame, 3:]),
                                           jnp.asarray(pts[:26 * 26, :2]), jnp.ones(26 * 26, bool))
                np.testing.assert_allclose(metres[k, frame, 3:], np.asarray(want), atol=1e-4)
            far = np.abs(np.arange(t) - frame) >= A.HOLD + A.TAPER
            np.testing.assert_allclose(delta[:, far, 3:], 0.0, atol=1e-5)
        # the pelvis rests on the seat (0.45 m) at the anchor, the hold moves as one, the taper
        # falls linearly and frames beyond it keep the model's height
        rest = A.LYING_PELVIS if action == LIE else A.SEATED_PELVIS
        np.testing.assert_allclose(metres[:, frame, 2], 0.45 + rest, atol=1e-5)
        dist = np.abs(np.arange(t) - frame)
        lift = delta[:, frame, 2]
        want = np.clip(1 - (dist - (A.HOLD - 1)) / A.TAPER, 0, 1)[None] * lift[:, None]
        np.testing.assert_allclose(delta[..., 2], want, atol=1e-5)
        np.testing.assert_allclose(delta[:, :, :2], np.broadcast_to(delta[:, :1, :2],
                                                                    delta[:, :, :2].shape),
                                   atol=1e-5)  # one offset for the whole path
        surface = np.zeros(len(pts), bool)
        surface[: 26 * 26] = True
        for b in range(2):
            assert _brute_gap(metres[b, frame, :2], pts, surface) <= A.ON_SURFACE + 1e-4
    out, _ = _refine(WALK, x0, mean, std)  # a walk keeps its path and ends standing
    metres = out * std + mean
    np.testing.assert_allclose(metres[..., :2], path[..., :2], atol=1e-5)
    np.testing.assert_allclose(metres[:, -1, 2], float(A.standing_height()), atol=1e-5)
    np.testing.assert_allclose(metres[:, :5, 2], path[:, :5, 2], atol=1e-5)
    out, _ = _refine(SIT, x0, mean, std, strength=0.5)  # half the offset
    full, _ = _refine(SIT, x0, mean, std)
    np.testing.assert_allclose((out - np.asarray(x0)) * 2, full - np.asarray(x0), atol=1e-5)


def test_refiner_takes_a_traced_action_under_jit_and_vmap():
    pts, nrm, _ = _chair()
    mean, std = np.zeros(9, np.float32), np.ones(9, np.float32)
    x0 = jnp.zeros((1, 8, 9)).at[..., 0].set(0.3).at[..., 1].set(1.25)

    @jax.jit
    @jax.vmap
    def run(action):
        fn = A.make_anchor_refiner(jnp.asarray(pts), jnp.asarray(nrm), jnp.ones(len(pts), bool),
                                   jnp.ones(8, bool), action, mean, std)
        return fn(x0, jnp.zeros(1, jnp.int32))

    out = np.asarray(run(jnp.asarray([WALK, SIT, STAND_UP, LIE, len(ACTION_CLASSES) - 1])))
    moved = np.abs(out - np.asarray(x0)[None]).max(axis=(1, 2, 3)) > 0.1
    np.testing.assert_array_equal(moved, [True, True, True, True, False])  # walk: stands up
    np.testing.assert_array_equal(out[-1], np.asarray(x0))  # the unknown action: untouched


def test_surface_height_is_the_median_surface_height_under_the_pelvis():
    rng = np.random.default_rng(1)
    pts = rng.uniform([0, 0, 0.3], [1, 1, 0.6], (400, 3)).astype(np.float32)
    surface = rng.random(400) < 0.5
    for xy in ([0.5, 0.5], [0.05, 0.9], [0.3, 0.1]):
        near = surface & (np.linalg.norm(pts[:, :2] - xy, axis=-1) <= A.SURFACE_RADIUS)
        got = float(A.surface_height(jnp.asarray(xy, jnp.float32), jnp.asarray(pts),
                                     jnp.asarray(surface)))
        assert got == pytest.approx(np.median(pts[near, 2]), abs=1e-6)
    far = np.asarray([5.0, 5.0], np.float32)  # nothing within the radius: the nearest point
    nearest = np.argmin(np.where(surface, np.linalg.norm(pts[:, :2] - far, axis=-1), np.inf))
    got = float(A.surface_height(jnp.asarray(far), jnp.asarray(pts), jnp.asarray(surface)))
    assert got == pytest.approx(pts[nearest, 2], abs=1e-6)
    assert np.isnan(float(A.surface_height(jnp.asarray(far), jnp.asarray(pts),
                                           jnp.zeros(400, bool))))


def test_an_armrest_beside_the_pelvis_does_not_raise_the_seat():
    pts, nrm, _ = _chair()
    arm = np.c_[np.linspace(1.0, 1.5, 30), np.full(30, 1.52), np.full(30, 0.65)]  # armrest top
    pts = np.r_[pts, arm].astype(np.float32)
    nrm = np.r_[nrm, np.tile([0, 0, 1.0], (30, 1))].astype(np.float32)
    s = A.support_surface(jnp.asarray(pts), jnp.asarray(nrm), jnp.ones(len(pts), bool))
    h = float(A.surface_height(jnp.asarray([1.25, 1.4]), jnp.asarray(pts), s))
    assert h == pytest.approx(0.45, abs=1e-6)


def test_the_horizontal_offset_waits_for_the_final_prediction_the_height_does_not():
    mean, std = np.zeros(9, np.float32), np.ones(9, np.float32)
    x0 = jnp.zeros((1, 30, 9)).at[..., 0].set(0.3).at[..., 1].set(1.25).at[..., 2].set(0.9)
    pts, nrm, _ = _chair()
    fn = A.make_anchor_refiner(jnp.asarray(pts), jnp.asarray(nrm), jnp.ones(len(pts), bool),
                               jnp.ones(30, bool), SIT, mean, std)
    noisy = np.asarray(fn(x0, jnp.full((1,), 500, jnp.int32)))
    clean = np.asarray(fn(x0, jnp.zeros((1,), jnp.int32)))
    np.testing.assert_array_equal(noisy[..., :2], np.asarray(x0)[..., :2])
    np.testing.assert_allclose(noisy[0, -1, 2], 0.45 + A.SEATED_PELVIS, atol=1e-5)
    assert np.abs(clean[0, -1, :2] - np.asarray(x0)[0, -1, :2]).max() > 0.5
    everywhere = A.make_anchor_refiner(jnp.asarray(pts), jnp.asarray(nrm),
                                       jnp.ones(len(pts), bool), jnp.ones(30, bool), SIT, mean,
                                       std, shift_until=None)
    np.testing.assert_allclose(np.asarray(everywhere(x0, jnp.full((1,), 500, jnp.int32))),
                               clean, atol=1e-5)


def test_standing_height_matches_a_standing_skeleton():
    from jaxmotion.geometry.skeleton import rest_joints

    for betas in (None, np.linspace(-1.5, 1.5, 10)):
        j = np.asarray(rest_joints(None if betas is None else jnp.asarray(betas, jnp.float32)))
        leg = np.mean([np.linalg.norm(j[h] - j[k]) + np.linalg.norm(j[k] - j[a])
                       for h, k, a in ((1, 4, 7), (2, 5, 8))])
        got = float(A.standing_height(betas))
        assert got == pytest.approx(A.ANKLE_HEIGHT + A.STANDING_LEGS * leg, abs=1e-5)
        assert 0.8 < got < 1.1


def test_walk_offset_brings_a_walk_to_its_target_or_out_of_it_and_leaves_a_near_one():
    pts, _, _ = _chair()
    xy, target = jnp.asarray(pts[:, :2]), jnp.ones(len(pts), bool)
    for start in ([-1.0, 1.25], [1.25, 3.0], [2.5, -0.5]):
        p = np.asarray(start, np.float32)
        goal = p + np.asarray(A.walk_offset(jnp.asarray(p), xy, target))
        gaps = np.linalg.norm(pts[:, :2] - goal, axis=-1)
        assert gaps.min() == pytest.approx(A.WALK_STOP, abs=0.02)  # stops in front, not inside
    for near in ([0.7, 1.25], [1.25, 1.8]):
        np.testing.assert_array_equal(np.asarray(A.walk_offset(jnp.asarray(near), xy, target)),
                                      0.0)
    np.testing.assert_array_equal(
        np.asarray(A.walk_offset(jnp.asarray([5.0, 5.0]), xy, jnp.zeros(len(pts), bool))), 0.0)
    # a walk that ends over its target (or touching it) is moved out, to WALK_STOP from it
    for inside in ([1.2, 1.3], [1.45, 1.05], [1.25, 1.25], [0.95, 1.2]):
        p = np.asarray(inside, np.float32)
        goal = p + np.asarray(A.walk_offset(jnp.asarray(p), xy, target))
        gaps = np.linalg.norm(pts[:, :2] - goal, axis=-1)
        assert gaps.min() == pytest.approx(A.WALK_STOP, abs=0.02), (inside, goal)
        seat = (goal >= 1.0) & (goal <= 1.5)
        assert not seat.all(), goal  # off the seat's footprint


def test_lying_rotation_lies_face_up_along_the_long_side():
    from jaxmotion.geometry import matrix_to_rotation_6d, rotation_6d_to_matrix

    g = np.stack(np.meshgrid(np.linspace(0, 2.0, 41), np.linspace(0, 0.9, 19)), -1).reshape(-1, 2)
    for facing, head in (([1.0, 0.1], -1.0), ([-1.0, 0.1], 1.0)):  # a bed 2 m along x
        # standing (body y up) and facing along +-x: lying back puts the head behind
        fwd = np.array([*facing, 0.0]) / np.linalg.norm(facing)
        up = np.array([0.0, 0.0, 1.0])
        now = np.stack([np.cross(up, fwd), up, fwd], axis=-1)
        r = np.asarray(rotation_6d_to_matrix(A.lying_rotation_6d(
            matrix_to_rotation_6d(jnp.asarray(now, jnp.float32)), jnp.asarray(g, jnp.float32),
            jnp.ones(len(g), bool))))
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-5)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-5)
        np.testing.assert_allclose(r[:, 1], [head, 0, 0], atol=1e-4)  # spine along the bed
        np.testing.assert_allclose(r[:, 2], [0, 0, 1], atol=1e-4)  # face up


def test_walk_offset_leaves_a_door_on_the_side_the_walk_came_from():
    """A door in a wall (a thin box along y = 0): a walk that ends against it is moved out to
    WALK_STOP on the room's side — where its first frame was — even when its last pelvis is
    past the door's middle line; without the start, out through the pelvis (the old rule)."""
    g = np.stack(np.meshgrid(np.linspace(0.0, 1.0, 21), np.linspace(0.0, 0.09, 4)), -1)
    xy = jnp.asarray(g.reshape(-1, 2), jnp.float32)
    target = jnp.ones(len(xy), bool)
    for end in ([0.5, 0.02], [0.3, 0.06], [0.8, -0.05]):
        p = jnp.asarray(end, jnp.float32)
        goal = np.asarray(p + A.walk_offset(p, xy, target, jnp.asarray([0.5, 2.0])))
        assert goal[1] > 0.09, (end, goal)  # in the room
        gaps = np.linalg.norm(np.asarray(xy) - goal, axis=-1)
        assert gaps.min() == pytest.approx(A.WALK_STOP, abs=0.02)
    # through the pelvis (no start known): a pelvis past the middle line goes out the far side
    p = jnp.asarray([0.5, 0.02], jnp.float32)
    assert float((p + A.walk_offset(p, xy, target))[1]) < 0.0
