"""Affordance-consistency guidance: the loss against numpy, its gradients, the refinement
and the sampler hook."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxmotion.diffusion import ddim_sample, make_schedule
from jaxmotion.diffusion.affordance_guidance import (
    ConsistencyGuidance,
    consistency_loss,
    guidance_targets,
    make_x0_refiner,
    refine_translation,
)
from jaxmotion.geometry.affordance import AFFORDANCE_JOINTS, affordance_map


def _walk(t=40, end=(1.5, 0.5)):
    """A body gliding from the origin to ``end``: pelvis 0.9 m up, the other joints offset."""
    rng = np.random.default_rng(0)
    rest = rng.normal(0, 0.25, (22, 3)).astype(np.float32)
    rest[:, 2] = np.abs(rest[:, 2]) + 0.1
    rest[0] = (0, 0, 0.9)
    path = np.linspace(0, 1, t)[:, None] * np.array([*end, 0.0])[None]
    return (rest[None] + path[:, None]).astype(np.float32)


def _room(n=1500, seed=1):
    rng = np.random.default_rng(seed)
    floor = rng.uniform([-1, -1, 0], [3, 2, 0], (n // 2, 3))
    room = rng.uniform([-1, -1, 0], [3, 2, 1.2], (n - n // 2, 3))
    return np.concatenate([floor, room]).astype(np.float32)


def test_targets_are_the_top_points_with_inverted_distances():
    pts = _room()
    joints = _walk()
    aff = np.asarray(affordance_map(pts, joints[:, AFFORDANCE_JOINTS]))
    sel, target = guidance_targets(jnp.asarray(pts), jnp.asarray(aff), 64, c_max=0.999)
    assert sel.shape == (6, 64, 3) and target.shape == (6, 64)
    for j in range(6):
        top = np.argsort(-aff[:, j])[:64]
        np.testing.assert_allclose(np.sort(np.asarray(sel[j]), 0), np.sort(pts[top], 0))
        d = np.sqrt(-2 * 0.8**2 * np.log(np.clip(aff[top, j], 1e-6, 0.999)))
        np.testing.assert_allclose(np.sort(np.asarray(target[j])), np.sort(d), rtol=1e-4, atol=1e-5)
    assert float(target.min()) >= 0.8 * np.sqrt(-2 * np.log(0.999)) - 1e-6


def test_loss_matches_numpy_and_tends_to_the_hard_minimum():
    pts = _room(300)
    joints = _walk(20)[:, AFFORDANCE_JOINTS]
    aff = affordance_map(pts, joints)
    sel, target = guidance_targets(jnp.asarray(pts), aff, 16)
    rng = np.random.default_rng(2)
    offset = rng.normal(0, 0.3, (20, 2)).astype(np.float32)
    mask = np.ones(20, bool)
    mask[15:] = False
    # numpy brute force with the hard minimum over valid frames and the Huber loss
    sh = joints + np.pad(offset, ((0, 0), (0, 1)))[:, None]
    d = np.linalg.norm(np.asarray(sel)[:, :, None] - np.swapaxes(sh, 0, 1)[:, None], axis=-1)
    r = d[..., :15].min(-1) - np.asarray(target)
    a = np.abs(r)
    want = np.where(a <= 0.5, 0.5 * r * r, 0.5 * (a - 0.25)).sum()
    got = consistency_loss(jnp.asarray(offset), joints, sel, target, jnp.asarray(mask), tau=1e-4)
    np.testing.assert_allclose(float(got), want, rtol=2e-3)
    # a soft minimum is never above the hard one: the loss moves smoothly with tau
    soft = consistency_loss(jnp.asarray(offset), joints, sel, target, jnp.asarray(mask), tau=0.05)
    assert np.isfinite(float(soft)) and abs(float(soft) - want) < 0.5 * want


def test_loss_gradients():
    with jax.enable_x64(True):
        pts = _room(120).astype(np.float64)
        joints = _walk(8)[:, AFFORDANCE_JOINTS].astype(np.float64)
        aff = affordance_map(pts, joints)
        sel, target = guidance_targets(jnp.asarray(pts), aff.astype(np.float64), 10)
        target = target.astype(np.float64) + 0.05
        offset = jnp.asarray(np.random.default_rng(3).normal(0, 0.2, (8, 2)))
        mask = jnp.ones(8, bool)
        check_grads(lambda o: consistency_loss(o, joints, sel, target, mask, tau=0.05),
                    (offset,), order=2, modes=("rev",), atol=1e-4, rtol=1e-4)


def test_refinement_moves_a_displaced_motion_back():
    pts = _room()
    gt = _walk()
    aff = affordance_map(pts, gt[:, AFFORDANCE_JOINTS])
    moved = gt + np.array([0.45, -0.3, 0.0], np.float32)  # ends 0.54 m from where the map says
    mask = jnp.ones(gt.shape[0], bool)
    cfg = ConsistencyGuidance(strength=1.0, iterations=8)
    out = np.asarray(refine_translation(jnp.asarray(moved), jnp.asarray(pts), aff, mask, cfg))
    before = np.linalg.norm(moved[-1, 0] - gt[-1, 0])
    after = np.linalg.norm(out[-1, 0] - gt[-1, 0])
    assert after < 0.3 * before, (before, after)
    # only a horizontal translation per frame: poses and heights are untouched
    shift = out - moved
    np.testing.assert_allclose(shift, np.broadcast_to(shift[:, :1], shift.shape), atol=1e-5)
    np.testing.assert_allclose(shift[..., 2], 0.0, atol=1e-6)
    # strength 0 is the identity; half strength moves less than full strength
    same = refine_translation(jnp.asarray(moved), jnp.asarray(pts), aff, mask,
                              ConsistencyGuidance(strength=0.0))
    np.testing.assert_array_equal(np.asarray(same), moved)
    half = np.asarray(refine_translation(jnp.asarray(moved), jnp.asarray(pts), aff, mask,
                                         ConsistencyGuidance(strength=0.5, iterations=1)))
    full = np.asarray(refine_translation(jnp.asarray(moved), jnp.asarray(pts), aff, mask,
                                         ConsistencyGuidance(strength=1.0, iterations=1)))
    assert 0 < np.abs(half - moved).max() < np.abs(full - moved).max()


def test_consistent_motion_stays_and_masked_frames_do_not_move():
    pts = _room()
    gt = _walk()
    mask = np.ones(gt.shape[0], bool)
    mask[30:] = False
    aff = affordance_map(pts, gt[:, AFFORDANCE_JOINTS], mask)
    out = np.asarray(refine_translation(jnp.asarray(gt), jnp.asarray(pts), aff, jnp.asarray(mask),
                                        ConsistencyGuidance(strength=1.0)))
    assert np.abs(out[:30] - gt[:30]).max() < 0.06  # already consistent: at most a nudge
    np.testing.assert_array_equal(out[30:], gt[30:])


def test_x0_refiner_normalisation_and_final_step():
    pts = _room()
    gt = _walk()
    aff = affordance_map(pts, gt[:, AFFORDANCE_JOINTS])
    mean = jnp.asarray(np.random.default_rng(4).normal(0, 0.1, 66), jnp.float32)
    std = jnp.full((66,), 0.7, jnp.float32)
    moved = (gt + np.array([0.4, 0.0, 0.0], np.float32)).reshape(1, gt.shape[0], 66)
    x0 = (jnp.asarray(moved) - mean) / std
    mask = jnp.ones(gt.shape[0], bool)
    refine = make_x0_refiner(jnp.asarray(pts), aff, mask, mean, std,
                             ConsistencyGuidance(strength=1.0, iterations=6))
    out = refine(x0, jnp.array([5]))
    j = np.asarray(out * std + mean).reshape(-1, 22, 3)
    assert np.linalg.norm(j[-1, 0] - gt[-1, 0]) < 0.15
    np.testing.assert_array_equal(np.asarray(refine(x0, jnp.array([0]))), np.asarray(x0))
    last = make_x0_refiner(jnp.asarray(pts), aff, mask, mean, std,
                           ConsistencyGuidance(strength=1.0, final_step=True))
    assert not np.array_equal(np.asarray(last(x0, jnp.array([0]))), np.asarray(x0))


@pytest.mark.parametrize("kw, msg", [
    (dict(strength=1.5), "strength must be in"), (dict(strength=-0.1), "strength must be in"),
    (dict(strength=0.5, iterations=0), "at least 1"), (dict(tau=0.0), "must be positive"),
    (dict(c_max=1.0), "c_max"),
])
def test_settings_are_checked(kw, msg):
    with pytest.raises(ValueError, match=msg):
        ConsistencyGuidance(**kw)


def test_sampler_hook_sees_every_step_and_identity_changes_nothing():
    sched = make_schedule("cosine", 50)
    fn = lambda x, t, c: 0.5 * x  # noqa: E731
    key = jax.random.key(0)
    base = ddim_sample(key, fn, sched, (2, 3), num_steps=5)
    same = ddim_sample(key, fn, sched, (2, 3), num_steps=5, refine_fn=lambda x0, t: x0)
    np.testing.assert_array_equal(np.asarray(base), np.asarray(same))
    seen = []

    def record(x0, t):
        jax.debug.callback(lambda v: seen.append(int(v[0])), t)
        return jnp.zeros_like(x0)

    out = ddim_sample(key, fn, sched, (2, 3), num_steps=5, refine_fn=record)
    jax.effects_barrier()
    assert seen == [49, 37, 25, 12, 0]
    np.testing.assert_allclose(np.asarray(out), 0.0, atol=1e-6)  # the last x̂0 is returned
