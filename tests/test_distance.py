"""Nearest-point, signed, box distances and occupancy vs numpy brute force."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from jax.test_util import check_grads

from jaxmotion.geometry import distance as D


@given(
    st.integers(0, 2**31 - 1),
    st.sampled_from([1, 9, 130]),
    st.sampled_from([1, 17, 600]),
    st.sampled_from([(4, 8), (256, 8192), (7, 64)]),
)
def test_nearest_points_matches_brute_force(seed, m, n, chunks):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(m, 3)).astype(np.float32)
    p = rng.normal(size=(n, 3)).astype(np.float32)
    d, idx = D.nearest_points(q, p, query_chunk=chunks[0], point_chunk=chunks[1])
    full = np.linalg.norm(q[:, None].astype(np.float64) - p[None], axis=-1)
    np.testing.assert_allclose(d, full.min(1), atol=1e-5)
    np.testing.assert_allclose(full[np.arange(m), np.asarray(idx)], full.min(1), atol=1e-5)
    assert idx.dtype == jnp.int32


def sphere(n, rng, radius=1.0):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return (radius * v).astype(np.float32), v.astype(np.float32)


def test_signed_distance_of_a_sphere():
    rng = np.random.default_rng(0)
    pts, nrm = sphere(20_000, rng)
    q = rng.uniform(-1.6, 1.6, (300, 3)).astype(np.float32)
    sd = np.asarray(D.signed_distance(q, pts, nrm))
    exact = np.linalg.norm(q, axis=1) - 1.0  # positive outside
    np.testing.assert_allclose(sd, exact, atol=0.03)  # sampling density limits accuracy
    far = np.abs(exact) > 0.05
    assert np.all(np.sign(sd[far]) == np.sign(exact[far]))
    with pytest.raises(ValueError, match="normals must match"):
        D.signed_distance(q, pts, nrm[:5])


def test_empty_or_bad_clouds_are_explained():
    with pytest.raises(ValueError, match="points is empty"):
        D.nearest_points(np.zeros((2, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match=r"queries must be \[N, 3\]"):
        D.nearest_points(np.zeros((2, 2)), np.zeros((3, 3)))


def box_sd_numpy(p, lo, hi):
    """Brute force: distance to a dense sampling of the box surface, sign from containment."""
    out = np.empty((len(p), len(lo)))
    for k in range(len(lo)):
        g = [np.linspace(lo[k][a], hi[k][a], 41) for a in range(3)]
        faces = []
        for a in range(3):
            for v in (lo[k][a], hi[k][a]):
                others = [b for b in range(3) if b != a]
                u, w = np.meshgrid(g[others[0]], g[others[1]], indexing="ij")
                f = np.zeros(u.shape + (3,))
                f[..., a], f[..., others[0]], f[..., others[1]] = v, u, w
                faces.append(f.reshape(-1, 3))
        surf = np.concatenate(faces)
        d = np.linalg.norm(p[:, None] - surf[None], axis=-1).min(1)
        inside = np.all((p >= lo[k]) & (p <= hi[k]), axis=1)
        out[:, k] = np.where(inside, -d, d)
    return out


@given(st.integers(0, 2**31 - 1))
def test_box_signed_distance_and_containment(seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-1, 0, (3, 3))
    hi = lo + rng.uniform(0.2, 1.5, (3, 3))
    p = rng.uniform(-2, 2, (60, 3))
    sd = np.asarray(D.box_signed_distance(p, lo, hi))
    np.testing.assert_allclose(sd, box_sd_numpy(p, lo, hi), atol=0.04)  # grid step of the brute force
    inside = np.asarray(D.points_in_boxes(p, lo, hi))
    np.testing.assert_array_equal(inside, sd <= 0)
    grown = np.asarray(D.points_in_boxes(p, lo, hi, margin=0.1))
    cheb = np.max(np.abs(p[:, None] - 0.5 * (lo + hi)) - 0.5 * (hi - lo), axis=-1)
    np.testing.assert_array_equal(grown, cheb <= 0.1)  # the margin grows each side
    # the box field is exact where it is simple: straight out from a face
    c = 0.5 * (lo[0] + hi[0])
    q = c + np.array([0.0, 0.0, 0.5 * (hi[0][2] - lo[0][2]) + 0.3])
    np.testing.assert_allclose(D.box_signed_distance(q[None], lo[:1], hi[:1])[0, 0], 0.3, atol=1e-5)


def test_box_distance_gradient():
    with jax.enable_x64(True):
        lo, hi = jnp.array([[0.0, 0.0, 0.0]]), jnp.array([[1.0, 2.0, 0.5]])
        p = jnp.array([[1.3, 2.4, 0.2], [0.3, 0.4, 0.15], [-0.2, 1.1, 0.9]])
        check_grads(lambda x: D.box_signed_distance(x, lo, hi), (p,), order=1)


def test_voxel_grid_and_occupancy():
    g = np.asarray(D.voxel_grid_centers(jnp.array([1.0, 2.0, 3.0]), 2.0, 8))
    assert g.shape == (8, 8, 8, 3)
    np.testing.assert_allclose(g[0, 0, 0], [1 - 1.75, 2 - 1.75, 3 - 1.75], atol=1e-6)
    np.testing.assert_allclose(g[7, 0, 0, 0] - g[6, 0, 0, 0], 0.5, atol=1e-6)
    np.testing.assert_allclose(g.reshape(-1, 3).mean(0), [1, 2, 3], atol=1e-5)
    v = 0.5
    occ = np.asarray(D.occupancy_from_sdf(jnp.array([-1.0, 0.0, 0.125, 0.25, 3.0]), v))
    np.testing.assert_allclose(occ, [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-6)
