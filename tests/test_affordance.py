"""Affordance field vs a float64 numpy brute force; masks, memory shape, gradients."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from jax.test_util import check_grads

from jaxmotion.geometry import affordance as A


def brute_force(points, joints, mask=None):
    p = np.asarray(points, np.float64)
    j = np.asarray(joints, np.float64)
    if mask is not None:
        j = j[np.asarray(mask, bool)]
    if len(j) == 0:
        return np.full((len(p), joints.shape[1]), np.inf)
    d = np.linalg.norm(p[:, None, None, :] - j[None], axis=-1)  # [N, T, J]
    return d.min(axis=1)


def scene_like(rng, n, t, j, spread=2.0):
    points = rng.uniform(-spread, spread, (n, 3)).astype(np.float32)
    path = np.cumsum(rng.normal(scale=0.05, size=(t, 1, 3)), axis=0)
    joints = (path + rng.normal(scale=0.5, size=(1, j, 3))).astype(np.float32)
    # put some points exactly on / next to joints: the worst case for cancellation
    k = min(n // 4, t * j)
    points[:k] = joints.reshape(-1, 3)[:k] + rng.normal(scale=1e-3, size=(k, 3))
    return points, joints


@given(
    st.integers(0, 2**31 - 1),
    st.sampled_from([1, 7, 64, 300]),
    st.sampled_from([1, 5, 30]),
    st.sampled_from([1, 6, 22]),
    st.sampled_from([16, 2048]),
)
def test_distance_matches_brute_force(seed, n, t, j, chunk):
    rng = np.random.default_rng(seed)
    points, joints = scene_like(rng, n, t, j)
    got = np.asarray(A.affordance_distance(points, joints, chunk=chunk))
    assert got.shape == (n, j) and got.dtype == np.float32
    np.testing.assert_allclose(got, brute_force(points, joints), atol=2e-3, rtol=1e-5)


@given(st.integers(0, 2**31 - 1))
def test_frame_mask(seed):
    rng = np.random.default_rng(seed)
    points, joints = scene_like(rng, 50, 12, 6)
    mask = rng.random(12) < 0.5
    mask[rng.integers(12)] = True
    got = A.affordance_distance(points, joints, jnp.asarray(mask))
    np.testing.assert_allclose(got, brute_force(points, joints, mask), atol=2e-3, rtol=1e-5)
    # masked frames are ignored even when they hold far-away garbage
    junk = joints.copy()
    junk[~mask] = 1e3
    np.testing.assert_allclose(A.affordance_distance(points, junk, mask), got, atol=1e-5)


def test_no_valid_frame_gives_inf_and_zero_map():
    points, joints = scene_like(np.random.default_rng(0), 10, 4, 6)
    mask = jnp.zeros(4, bool)
    assert np.all(np.isinf(A.affordance_distance(points, joints, mask)))
    assert np.all(A.affordance_map(points, joints, mask) == 0)


def test_map_formula_and_inverse():
    rng = np.random.default_rng(1)
    points, joints = scene_like(rng, 200, 20, 6)
    d = brute_force(points, joints)
    for sigma in (0.8, 0.3):
        got = np.asarray(A.affordance_map(points, joints, sigma=sigma))
        np.testing.assert_allclose(got, np.exp(-(d**2) / (2 * sigma**2)), atol=2e-5)
    a = A.affordance_map(points, joints)
    np.testing.assert_allclose(A.affordance_to_distance(a), np.minimum(d, 7.6), atol=5e-3)
    np.testing.assert_allclose(A.distance_to_affordance(d), np.exp(-(d**2) / 1.28), atol=1e-6)
    # inverse clips like the reference code: a = 0 maps to sqrt(-2 σ² ln 1e-20)
    np.testing.assert_allclose(A.affordance_to_distance(0.0), np.sqrt(-2 * 0.64 * np.log(1e-20)), rtol=1e-5)


def test_constants():
    assert A.AFFORDANCE_JOINTS == (0, 10, 11, 12, 20, 21)
    assert A.AFFORDANCE_SIGMA == 0.8


def test_never_materialises_a_frames_by_points_tensor():
    """Largest array in the compiled program is far smaller than T*N*J."""
    n, t, j = 100_000, 300, 6
    points = jax.ShapeDtypeStruct((n, 3), jnp.float32)
    joints = jax.ShapeDtypeStruct((t, j, 3), jnp.float32)
    compiled = jax.jit(lambda p, j: A.affordance_map(p, j, None, 0.8, chunk=2048)).lower(
        points, joints).compile()
    mem = compiled.memory_analysis()
    total = mem.temp_size_in_bytes + mem.output_size_in_bytes + mem.argument_size_in_bytes
    assert total < 0.1 * n * t * j * 4, total  # [T,N,J] float32 would be 720 MB


@pytest.mark.slow
def test_million_points_three_hundred_frames_within_two_gib():
    import resource

    rng = np.random.default_rng(0)
    points = rng.uniform(-3, 3, (1_000_000, 3)).astype(np.float32)
    joints = rng.uniform(-1, 1, (300, 6, 3)).astype(np.float32)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out = jax.block_until_ready(A.affordance_map(points, joints))
    grown_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert out.shape == (1_000_000, 6)
    assert grown_kib < 2 * 1024**2
    idx = rng.choice(1_000_000, 500, replace=False)
    want = np.exp(-brute_force(points[idx], joints) ** 2 / 1.28)
    np.testing.assert_allclose(np.asarray(out)[idx], want, atol=1e-4)


def test_vmap_over_motions_and_gradients():
    rng = np.random.default_rng(2)
    points, joints = scene_like(rng, 40, 8, 6)
    batch = jnp.stack([joints, joints + 0.5])
    out = jax.vmap(lambda jt: A.affordance_map(points, jt))(batch)
    np.testing.assert_allclose(out[1], A.affordance_map(points, joints + 0.5), atol=1e-6)
    # Gradients: generic points (no near-ties between frames, where the min is kinked).
    with jax.enable_x64(True):
        p64 = jnp.asarray(rng.uniform(-2, 2, (40, 3)))
        j64 = jnp.asarray(rng.normal(size=(8, 6, 3)))
        f = lambda j_: A.affordance_map(p64, j_, None, 0.8, chunk=16)  # noqa: E731
        check_grads(f, (j64,), order=1, modes=["rev"])
        g = jax.grad(lambda p_: jnp.sum(A.affordance_distance(p_, j64, None, chunk=16)))(p64)
        assert np.all(np.isfinite(g))


def test_bad_inputs():
    with pytest.raises(ValueError, match=r"points must be \[N, 3\]"):
        A.affordance_map(np.zeros((5, 2)), np.zeros((3, 6, 3)))
    with pytest.raises(ValueError, match=r"\[T, J, 3\]"):
        A.affordance_map(np.zeros((5, 3)), np.zeros((6, 3)))
    with pytest.raises(ValueError, match="frame_mask"):
        A.affordance_map(np.zeros((5, 3)), np.zeros((3, 6, 3)), np.ones(4, bool))
