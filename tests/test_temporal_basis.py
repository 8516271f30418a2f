"""The AMDM's low-frequency temporal basis (``AMDMConfig.temporal_basis``)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx
from jax.test_util import check_grads

from jaxmotion.models import AMDM, AMDMConfig
from jaxmotion.models.layers import dct_basis, low_frequency_projection


def _numpy_projection(x, length, k):
    """Brute force: orthonormal DCT-II of the valid frames, keep the first k, invert."""
    n = np.arange(length)
    rows = []
    for f in range(min(k, length)):
        c = np.cos(np.pi * (n + 0.5) * f / length)
        rows.append(c / np.linalg.norm(c))
    basis = np.array(rows)  # [k, L], orthonormal rows
    out = np.zeros_like(x)
    out[:length] = basis.T @ (basis @ x[:length])
    return out


@pytest.mark.parametrize("k", [1, 4, 9])
def test_projection_matches_numpy(k):
    rng = np.random.default_rng(k)
    x = rng.normal(size=(3, 12, 5)).astype(np.float32)
    lengths = np.array([12, 7, 3])
    mask = np.arange(12)[None] < lengths[:, None]
    got = np.asarray(low_frequency_projection(x, mask, k))
    for b, length in enumerate(lengths):
        np.testing.assert_allclose(got[b], _numpy_projection(x[b], length, k), atol=2e-5)


def test_basis_is_orthonormal_and_exact_for_smooth_motion():
    basis = np.asarray(dct_basis(jnp.array([30, 10]), 30, 12))
    np.testing.assert_allclose(basis[0] @ basis[0].T, np.eye(12), atol=1e-5)
    np.testing.assert_allclose(basis[1] @ basis[1].T, np.diag([1.0] * 10 + [0.0] * 2), atol=1e-5)
    assert not basis[1][:, 10:].any()  # nothing beyond the valid frames
    # constants pass unchanged (so per-channel normalisation commutes with it); k >= length
    # is the identity on the valid frames; a projection is idempotent
    mask = np.ones((1, 30), bool)
    const = np.full((1, 30, 2), 3.5, np.float32)
    np.testing.assert_allclose(low_frequency_projection(const, mask, 4), const, rtol=1e-5)
    x = np.random.default_rng(0).normal(size=(1, 30, 2)).astype(np.float32)
    np.testing.assert_allclose(low_frequency_projection(x, mask, 30), x, atol=1e-4)
    once = low_frequency_projection(x, mask, 6)
    np.testing.assert_allclose(low_frequency_projection(once, mask, 6), once, atol=1e-5)


def test_projection_removes_a_jump_and_gradients_are_right():
    t = np.arange(60) / 30.0
    walk = np.stack([0.8 * t, 0 * t], -1)[None].astype(np.float32)  # 0.8 m/s
    jump = walk.copy()
    jump[0, 30:, 0] += 0.5  # 0.5 m between two frames: 15 m/s
    mask = np.ones((1, 60), bool)
    smooth = np.asarray(low_frequency_projection(walk, mask, 16))
    np.testing.assert_allclose(smooth, walk, atol=0.02)  # a ramp needs few cosines
    step = np.abs(np.diff(np.asarray(low_frequency_projection(jump, mask, 16))[0, :, 0]))
    assert step.max() * 30 < 6.0  # the 15 m/s jump is spread over several frames
    check_grads(lambda x: low_frequency_projection(x, mask, 5), (jnp.asarray(jump),), order=1,
                modes=["rev"], atol=1e-2, rtol=1e-2)


@pytest.mark.slow
def test_amdm_with_a_basis_outputs_only_slow_content():
    cfg = dataclasses.replace(AMDMConfig.tiny(), temporal_basis=4)
    model = AMDM(cfg, rngs=nnx.Rngs(0))
    model.eval()
    b, n, t = 2, 32, 16
    xyz = jax.random.uniform(jax.random.key(1), (b, n, 3))
    mask = jnp.arange(t)[None] < jnp.array([[t], [11]])
    cond = dict(text=jnp.ones((b, cfg.text_dim)), xyz=xyz,
                affordance=jax.random.normal(jax.random.key(2), (b, n, cfg.affordance_dim)),
                mask=mask)
    x = jax.random.normal(jax.random.key(3), (b, t, cfg.motion_dim))
    y = np.asarray(model(x, jnp.array([3, 500]), cond))
    plain = AMDM(dataclasses.replace(cfg, temporal_basis=0), rngs=nnx.Rngs(0))
    plain.eval()
    raw = np.asarray(plain(x, jnp.array([3, 500]), cond))  # the same weights without the basis
    for i, length in enumerate([t, 11]):
        np.testing.assert_allclose(y[i], _numpy_projection(raw[i], length, 4), atol=1e-4)
    assert not y[1, 11:].any()


def test_config_rejects_a_negative_basis():
    with pytest.raises(ValueError, match="temporal_basis"):
        dataclasses.replace(AMDMConfig.tiny(), temporal_basis=-1)
