"""Foot guidance (jaxmotion.diffusion.foot_guidance) and the standing height of anchor
guidance, against brute-force NumPy and hand-made motions."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxmotion.constants import ACTION_CLASSES, FOOT_JOINTS
from jaxmotion.diffusion import anchor_guidance as A
from jaxmotion.diffusion import foot_guidance as F
from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS, foot_skating
from jaxmotion.geometry.rotations import matrix_to_rotation_6d
from jaxmotion.geometry.skeleton import upright_orientation
from jaxmotion.motion.representation import MOTION_DIM, TRAJECTORY_DIM, motion_to_joints

SIT, LIE, WALK = (ACTION_CLASSES.index(a) for a in ("sit", "lie", "walk"))
STD = 0.05  # the shipped completion model's feature spread of most body rotations


def _seated_motion(t=40, seed=0):
    """Motion features of a body whose pelvis drifts 20 cm sideways while its legs keep
    their pose: the feet ride along with the pelvis (what seated sliding looks like)."""
    rng = np.random.default_rng(seed)
    f = np.zeros((t, MOTION_DIM), np.float32)
    f[:, 0] = np.linspace(0.0, 0.2, t)  # x drifts
    f[:, 2] = float(A.standing_height()) - 0.02
    eye = matrix_to_rotation_6d(jnp.eye(3))
    f[:, 3:9] = np.asarray(matrix_to_rotation_6d(upright_orientation(0.0)))
    body = np.tile(np.asarray(eye), 21) + rng.normal(0, 0.01, (t, 21 * 6))
    f[:, TRAJECTORY_DIM:] = body
    return f


def _brute_loss(features, betas, mask, action):
    j = np.asarray(motion_to_joints(jnp.asarray(features), betas), np.float64)
    feet = j[:, list(FOOT_JOINTS)]
    h = feet[..., 2] - np.asarray(FOOT_FLOOR_OFFSETS)
    near = 1 / (1 + np.exp(-(F.CONTACT_HEIGHT - h) / F.CONTACT_SOFTNESS))
    total, pairs = 0.0, 0
    for t in range(len(j) - 1):
        if not (mask[t] and mask[t + 1]):
            continue
        pairs += 1
        for f in range(feet.shape[1]):
            v = (feet[t + 1, f, :2] - feet[t, f, :2]) * 30.0 / F.SLIDE_SCALE
            total += near[t, f] * near[t + 1, f] * float(v @ v)
    slide = total / max(pairs, 1)
    floor = 0.0
    if action != LIE:
        for t in range(len(j)):
            if mask[t]:
                low = -F.CONTACT_SOFTNESS * np.log(np.sum(np.exp(-h[t] / F.CONTACT_SOFTNESS)))
                floor += (low / F.FLOOR_SCALE) ** 2
    sink = sum(max(-h[t, f] - F.SINK_TOLERANCE, 0.0) ** 2 for t in range(len(j)) if mask[t]
               for f in range(feet.shape[1])) / F.FLOOR_SCALE ** 2 / F.SINK_FRAMES
    fast = 0.0
    for t in range(len(j) - 1):
        if mask[t] and mask[t + 1]:
            for f in range(feet.shape[1]):
                speed = np.linalg.norm(feet[t + 1, f] - feet[t, f]) * 30.0
                fast += max(speed - F.FAST_SPEED, 0.0) ** 2 / F.FAST_SCALE ** 2
    return slide + floor / max(mask.sum(), 1) + sink + fast / F.SINK_FRAMES


def _swung(t=40):
    """The seated motion with the body jerked 0.3 m in one frame (9 m/s: the speed of a
    leg swung onto a bed that reached the teleport threshold)."""
    f = _seated_motion(t)
    f[t // 2:, 1] += 0.3
    return f


@pytest.mark.parametrize("action", [SIT, LIE])
@pytest.mark.parametrize("make", [_seated_motion, _swung])
def test_foot_loss_matches_a_frame_loop(action, make):
    f = make()
    mask = np.ones(len(f), bool)
    mask[-5:] = False
    got = float(F.foot_loss(jnp.asarray(f), None, jnp.asarray(mask), action))
    np.testing.assert_allclose(got, _brute_loss(f, None, mask, action), rtol=2e-4)


def test_a_foot_faster_than_the_limit_is_slowed():
    """The speed term: nothing under FAST_SPEED, and gradient steps on the body's rotations
    slow a foot over it."""
    slow, fast = _seated_motion(), _swung()
    mask = jnp.ones(len(slow), bool)
    off = {"floor_weight": 0.0}

    def speed(x):  # the fastest foot joint, m/s
        feet = np.asarray(motion_to_joints(jnp.asarray(x), None, FOOT_JOINTS))
        return np.linalg.norm(np.diff(feet, axis=0), axis=-1).max() * 30

    assert speed(slow) < F.FAST_SPEED and speed(fast) > 8.5
    base = float(F.foot_loss(jnp.asarray(slow), None, mask, LIE, **off))
    assert float(F.foot_loss(jnp.asarray(fast), None, mask, LIE, **off)) > base + 1.0
    grad = jax.grad(lambda x: F.foot_loss(x, None, mask, LIE, **off))
    x = jnp.asarray(fast)
    for _ in range(20):
        x = x - 3e-4 * grad(x).at[:, :TRAJECTORY_DIM].set(0.0)
    assert speed(np.asarray(x)) < F.FAST_SPEED


def test_foot_loss_gradients():
    f = jnp.asarray(_seated_motion(t=12))
    mask = jnp.ones(12, bool)
    check_grads(lambda x: F.foot_loss(x, None, mask, SIT), (f,), order=1, modes=["rev"],
                atol=5e-2, rtol=5e-2, eps=1e-3)


def test_refiner_plants_sliding_feet_and_moves_only_the_body():
    f = _seated_motion()
    t = len(f)
    mask = jnp.ones(t, bool)
    mean = np.zeros(MOTION_DIM, np.float32)
    std = np.full(MOTION_DIM, STD, np.float32)
    refine = jax.jit(F.make_foot_refiner(None, mask, SIT, mean, std))
    x = jnp.asarray(f / std)[None]  # normalised features
    y = x
    for _ in range(20):  # as over the 20 reverse steps of DDIM-20
        y = refine(y, jnp.zeros((1,), jnp.int32))
    out = np.asarray(y) * std
    np.testing.assert_allclose(out[0, :, :TRAJECTORY_DIM], f[:, :TRAJECTORY_DIM], atol=1e-6)
    before = float(F.foot_loss(jnp.asarray(f), None, mask, SIT))
    after = float(F.foot_loss(jnp.asarray(out[0]), None, mask, SIT))
    assert after < 0.85 * before
    j0 = np.asarray(motion_to_joints(jnp.asarray(f)))
    j1 = np.asarray(motion_to_joints(jnp.asarray(out[0])))
    feet = list(FOOT_JOINTS)
    drift0 = np.linalg.norm(j0[-1, feet, :2] - j0[0, feet, :2], axis=-1).mean()
    drift1 = np.linalg.norm(j1[-1, feet, :2] - j1[0, feet, :2], axis=-1).mean()
    assert drift1 < 0.8 * drift0  # the feet stay behind while the pelvis drifts
    # smooth: the correction zigzags from frame to frame less than an unsmoothed step's
    def zigzag(r):
        d = np.asarray(r(x, jnp.zeros((1,), jnp.int32)) - x)[0, :, TRAJECTORY_DIM:]
        return np.abs(np.diff(d, 2, axis=0)).mean() / np.abs(d).mean()

    smoothing = F.SMOOTHING
    try:
        F.SMOOTHING = 0.1
        raw = zigzag(F.make_foot_refiner(None, mask, SIT, mean, std))
    finally:
        F.SMOOTHING = smoothing
    assert zigzag(refine) < 0.5 * raw
    # half the strength moves less; under jit and vmap with a traced action it runs
    once = np.asarray(refine(x, jnp.zeros((1,), jnp.int32)))
    half = np.asarray(F.make_foot_refiner(None, mask, SIT, mean, std, 0.5)(x, jnp.zeros(1, int)))
    assert np.abs(half - x).max() < np.abs(once - x).max()
    batched = jax.jit(jax.vmap(lambda a, y: F.make_foot_refiner(None, mask, a, mean, std)(
        y[None], jnp.zeros((1,), jnp.int32))[0]))(jnp.array([SIT, WALK]), jnp.stack([x[0]] * 2))
    np.testing.assert_allclose(np.asarray(batched[0]), once[0], atol=1e-4)


def _perched_motion(t=30, sunk=0.08, seed=0):
    """A seated body (hips and knees bent 80°, shins down) whose feet are ``sunk`` metres in
    the floor: a seat too high for its legs, the pelvis held there by the kept root."""
    rng = np.random.default_rng(seed)
    c, s = np.cos(1.4), np.sin(1.4)
    bend = lambda a: np.array([[1, 0, 0], [0, c, -a * s], [0, a * s, c]], np.float32)  # noqa
    rots = np.tile(np.eye(3, dtype=np.float32), (21, 1, 1))
    rots[0] = rots[1] = bend(-1.0)  # hips: thighs forward
    rots[3] = rots[4] = bend(1.0)  # knees: shins down
    f = np.zeros((t, MOTION_DIM), np.float32)
    f[:, 3:9] = np.asarray(matrix_to_rotation_6d(upright_orientation(0.0)))
    f[:, TRAJECTORY_DIM:] = (np.asarray(matrix_to_rotation_6d(jnp.asarray(rots))).reshape(-1)
                             + rng.normal(0, 0.01, (t, 21 * 6)))
    low = np.min(np.asarray(motion_to_joints(jnp.asarray(f), None))[:, list(FOOT_JOINTS), 2]
                 - np.asarray(FOOT_FLOOR_OFFSETS))
    f[:, 2] = -low - sunk
    return f


@pytest.mark.parametrize("action", [SIT, LIE])
def test_feet_in_the_floor_are_lifted_in_every_action(action, monkeypatch):
    """The sink term: a perched body whose feet are 8 cm in the floor bends its legs until
    they are (nearly) out, whatever the action; feet above the floor give it nothing."""
    sunk = _perched_motion()
    mask = jnp.ones(len(sunk), bool)
    feet = lambda x: np.asarray(motion_to_joints(jnp.asarray(x), None))[:, list(FOOT_JOINTS), 2]
    under = lambda x: float(np.min(feet(x) - np.asarray(FOOT_FLOOR_OFFSETS)))
    assert under(sunk) < -0.075
    mean, std = jnp.zeros(MOTION_DIM), jnp.full(MOTION_DIM, STD)
    refine = F.make_foot_refiner(None, mask, action, mean, std, iterations=20)
    x = ((jnp.asarray(sunk) - mean) / std)[None]
    y = refine(x, jnp.zeros(1))
    np.testing.assert_array_equal(np.asarray(y)[..., :TRAJECTORY_DIM],
                                  np.asarray(x)[..., :TRAJECTORY_DIM])  # the root is kept
    out = np.asarray(y[0]) * STD
    assert under(out) > -0.025, under(out)
    up = sunk.copy()
    up[:, 2] += 0.1  # every foot above the floor: the sink term adds exactly nothing
    grad = lambda: jax.grad(lambda x: F.foot_loss(x, None, mask, action))(jnp.asarray(up))
    with_sink = np.asarray(grad())
    monkeypatch.setattr(F, "SINK_FRAMES", np.inf)
    np.testing.assert_array_equal(with_sink, np.asarray(grad()))


def test_a_lying_body_is_not_pulled_to_the_floor():
    f = _seated_motion()
    f[:, 0] = 0.0
    f[:, 2] += 0.4  # resting high, on a bed: no foot near the floor, nothing to slide
    mask = jnp.ones(len(f), bool)
    assert float(F.foot_loss(jnp.asarray(f), None, mask, LIE)) < 1e-6
    assert float(F.foot_loss(jnp.asarray(f), None, mask, SIT)) > 10.0


def test_skating_of_the_planted_motion_is_lower():
    f = _seated_motion()
    f[:, 0] = np.linspace(0.0, 0.6, len(f))  # 0.45 m/s: near the skating threshold
    f[:, 2] += 0.02  # its feet on the floor, not in it (the sink term: the test above)
    mask = jnp.ones(len(f), bool)
    zeros, std = np.zeros(MOTION_DIM, np.float32), np.full(MOTION_DIM, STD, np.float32)
    refine = jax.jit(F.make_foot_refiner(None, mask, SIT, zeros, std))
    y = jnp.asarray(f / std)[None]
    for _ in range(20):
        y = refine(y, jnp.zeros((1,), jnp.int32))
    out = y[0] * std
    before = np.asarray(motion_to_joints(jnp.asarray(f)))
    after = np.asarray(motion_to_joints(out))
    speed = lambda j: np.linalg.norm(np.diff(j[:, list(FOOT_JOINTS), :2], axis=0), axis=-1) * 30
    assert speed(after).mean() < speed(before).mean()
    assert float(foot_skating(after)["skate_ratio"]) <= float(foot_skating(before)["skate_ratio"])


def _brute_standing(height, stand, mask, seat):
    w = np.zeros(len(height))
    for t, z in enumerate(height):
        way = (z - seat) / max(stand - seat, 0.1)
        u = min(max((way - A.STANDING_BAND[0]) / (A.STANDING_BAND[1] - A.STANDING_BAND[0]),
                    0.0), 1.0)
        w[t] = u * u * (3 - 2 * u) * mask[t]
    keep = [stand - A.WALKING_DROP - z for z, wt in zip(height, w) if wt > 0.5]
    return w, (float(np.median(keep)) if len(keep) >= 2 else 0.0)


@pytest.mark.parametrize("seat", [0.6, 0.74])  # a chair, a bar stool
def test_standing_offset_matches_numpy_and_leaves_seated_frames(seat):
    rng = np.random.default_rng(1)
    stand = 0.93
    # walk in 6 cm too high, sit down to the seated pelvis
    height = np.r_[np.full(30, stand + 0.06) + rng.normal(0, 0.01, 30),
                   np.linspace(stand + 0.06, seat, 15), np.full(15, seat)].astype(np.float32)
    mask = np.ones(60, bool)
    mask[-3:] = False
    w, off = A.standing_offset(jnp.asarray(height), stand, jnp.asarray(mask), seat)
    bw, boff = _brute_standing(height, stand, mask, seat)
    np.testing.assert_allclose(np.asarray(w), bw, atol=1e-6)
    np.testing.assert_allclose(float(off), boff, atol=1e-5)
    moved = height + np.asarray(w) * float(off)
    np.testing.assert_allclose(np.median(moved[:30]), stand - A.WALKING_DROP, atol=0.01)
    np.testing.assert_array_equal(moved[45:], height[45:])  # seated frames stay
    assert np.abs(np.diff(moved)).max() < 0.05  # no step in height
    # a motion with no standing frame (lying, seated throughout) is not moved
    w, off = A.standing_offset(jnp.full(20, seat), stand, jnp.ones(20, bool), seat)
    assert float(off) == 0.0
    # without a seat, a walk counts from SEATED_DROP under standing
    w, _ = A.standing_offset(jnp.asarray(height), stand, jnp.asarray(mask))
    np.testing.assert_allclose(np.asarray(w), _brute_standing(height, stand, mask,
                                                              stand - A.SEATED_DROP)[0],
                               atol=1e-6)


def test_anchor_refiner_puts_a_walk_at_the_bodys_walking_height():
    t = 40
    path = np.zeros((1, t, 9), np.float32)
    path[..., 0] = np.linspace(-1.0, 0.5, t)
    path[..., 2] = float(A.standing_height()) + 0.07  # drawn 7 cm too high
    path[..., 3:] = np.asarray(matrix_to_rotation_6d(jnp.eye(3)))
    mean, std = np.zeros(9, np.float32), np.ones(9, np.float32)
    pts = np.array([[3.0, 3.0, 0.4]], np.float32)
    nrm = np.array([[0.0, 0.0, 1.0]], np.float32)
    target = np.ones(1, bool)
    mask = jnp.ones(t, bool)
    off = A.make_anchor_refiner(pts, nrm, target, mask, WALK, mean, std, 0.0, standing=0.0)
    on = A.make_anchor_refiner(pts, nrm, target, mask, WALK, mean, std, 0.0, standing=1.0)
    zero = jnp.zeros((1,), jnp.int32)
    np.testing.assert_allclose(np.asarray(off(jnp.asarray(path), zero)), path, atol=1e-6)
    out = np.asarray(on(jnp.asarray(path), zero))
    np.testing.assert_allclose(out[0, :, 2], float(A.standing_height()) - A.WALKING_DROP,
                               atol=1e-5)
    np.testing.assert_allclose(out[..., [0, 1, 3, 4, 5, 6, 7, 8]],
                               path[..., [0, 1, 3, 4, 5, 6, 7, 8]], atol=1e-6)


def test_the_refiner_acts_only_below_its_noise_level():
    """``active_below``: the early (noisy) reverse steps pass the prediction through, the
    late ones are the always-on refiner's, under jit and under vmap over candidates (the
    sampler's noise level is not batched)."""
    f = _seated_motion(t=16)
    mask = jnp.ones(len(f), bool)
    mean, std = np.zeros(MOTION_DIM, np.float32), np.full(MOTION_DIM, STD, np.float32)
    x = jnp.asarray(f / std)[None]
    always = jax.jit(F.make_foot_refiner(None, mask, SIT, mean, std))
    late = jax.jit(F.make_foot_refiner(None, mask, SIT, mean, std, active_below=60))
    early_t, late_t = jnp.full((1,), 60, jnp.int32), jnp.full((1,), 52, jnp.int32)
    np.testing.assert_array_equal(np.asarray(late(x, early_t)), np.asarray(x))
    np.testing.assert_allclose(np.asarray(late(x, late_t)), np.asarray(always(x, late_t)),
                               atol=1e-6)
    assert np.abs(np.asarray(late(x, late_t)) - np.asarray(x)).max() > 1e-3
    candidates = jnp.stack([x, x + 0.01])
    for t in (early_t, late_t):
        got = jax.jit(jax.vmap(lambda y: late(y, t)))(candidates)
        want = np.stack([np.asarray(late(y, t)) for y in candidates])
        np.testing.assert_allclose(np.asarray(got), want, atol=1e-5)
