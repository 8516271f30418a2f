"""Rotation conversions against scipy / numpy brute force, round trips and gradients."""

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from jax.test_util import check_grads
from scipy.spatial.transform import Rotation

from jaxmotion.geometry import rotations as R

seeds = st.integers(0, 2**31 - 1)
batch = st.integers(1, 7)


def random_rotations(seed, n):
    return Rotation.random(n, random_state=seed)


@given(seeds, batch)
def test_axis_angle_to_matrix_matches_scipy(seed, n):
    rot = random_rotations(seed, n)
    got = R.axis_angle_to_matrix(jnp.asarray(rot.as_rotvec(), jnp.float32))
    np.testing.assert_allclose(got, rot.as_matrix(), atol=2e-6)


@given(seeds, batch)
def test_matrix_to_quaternion_matches_scipy(seed, n):
    rot = random_rotations(seed, n)
    got = np.asarray(R.matrix_to_quaternion(jnp.asarray(rot.as_matrix(), jnp.float32)))
    xyzw = rot.as_quat()
    want = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    want = np.where(want[:, :1] < 0, -want, want)
    np.testing.assert_allclose(got, want, atol=3e-6)
    assert np.all(got[:, 0] >= 0)


@given(seeds, batch)
def test_quaternion_to_matrix_matches_scipy(seed, n):
    rot = random_rotations(seed, n)
    xyzw = rot.as_quat()
    wxyz = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1) * 3.0  # unnormalised on purpose
    got = R.quaternion_to_matrix(jnp.asarray(wxyz, jnp.float32))
    np.testing.assert_allclose(got, rot.as_matrix(), atol=2e-6)


@given(seeds, batch)
def test_axis_angle_round_trips(seed, n):
    rot = random_rotations(seed, n)
    aa = jnp.asarray(rot.as_rotvec(), jnp.float32)
    np.testing.assert_allclose(R.matrix_to_axis_angle(R.axis_angle_to_matrix(aa)), aa, atol=2e-5)
    np.testing.assert_allclose(
        R.quaternion_to_axis_angle(R.axis_angle_to_quaternion(aa)), aa, atol=2e-5
    )
    np.testing.assert_allclose(
        R.quaternion_to_matrix(R.axis_angle_to_quaternion(aa)), rot.as_matrix(), atol=2e-6
    )


def test_edge_angles():
    # identity, tiny angles, and angles close to pi (the hard cases of the log map)
    aa = np.array(
        [[0, 0, 0], [1e-9, 0, 0], [0, 3e-7, -2e-7], [np.pi - 1e-4, 0, 0], [0, 0, np.pi]], np.float64
    )
    m = Rotation.from_rotvec(aa).as_matrix()
    np.testing.assert_allclose(R.axis_angle_to_matrix(jnp.asarray(aa, jnp.float32)), m, atol=2e-6)
    back = np.asarray(R.matrix_to_axis_angle(jnp.asarray(m, jnp.float32)), np.float64)
    np.testing.assert_allclose(Rotation.from_rotvec(back).as_matrix(), m, atol=2e-5)


@given(seeds, batch)
def test_6d_round_trip_and_convention(seed, n):
    m = random_rotations(seed, n).as_matrix()
    d6 = np.asarray(R.matrix_to_rotation_6d(jnp.asarray(m, jnp.float32)))
    np.testing.assert_allclose(d6, m[:, :2, :].reshape(n, 6), atol=1e-7)  # first two rows
    np.testing.assert_allclose(R.rotation_6d_to_matrix(jnp.asarray(d6)), m, atol=3e-6)


@given(seeds)
def test_6d_gram_schmidt_of_arbitrary_vectors_is_a_rotation(seed):
    x = np.random.default_rng(seed).normal(size=(5, 6)).astype(np.float32)
    m = np.asarray(R.rotation_6d_to_matrix(jnp.asarray(x)), np.float64)
    np.testing.assert_allclose(m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape), atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-5)
    # row 0 is the normalised first half
    np.testing.assert_allclose(m[:, 0], x[:, :3] / np.linalg.norm(x[:, :3], axis=1, keepdims=True), atol=1e-6)


@given(seeds)
def test_quaternion_multiply_composes(seed):
    a, b = random_rotations(seed, 4), random_rotations(seed + 1, 4)
    qa = jnp.asarray(R.matrix_to_quaternion(jnp.asarray(a.as_matrix(), jnp.float32)))
    qb = jnp.asarray(R.matrix_to_quaternion(jnp.asarray(b.as_matrix(), jnp.float32)))
    got = R.quaternion_to_matrix(R.quaternion_multiply(qa, qb))
    np.testing.assert_allclose(got, (a * b).as_matrix(), atol=3e-6)


def test_rotate_about_z_and_skew():
    m = R.rotate_about_z(jnp.float32(np.pi / 2))
    np.testing.assert_allclose(m @ jnp.array([1.0, 0, 0]), [0, 1, 0], atol=1e-7)
    v, u = np.array([0.3, -1.0, 2.0]), np.array([1.5, 0.2, -0.7])
    np.testing.assert_allclose(R.skew(jnp.asarray(v)) @ u, np.cross(v, u), atol=1e-6)


def test_leading_batch_dims_and_jit_vmap():
    aa = jnp.asarray(np.random.default_rng(0).normal(size=(2, 3, 4, 3)), jnp.float32)
    m = jax.jit(R.axis_angle_to_matrix)(aa)
    assert m.shape == (2, 3, 4, 3, 3)
    np.testing.assert_allclose(jax.vmap(R.axis_angle_to_matrix)(aa), m, atol=1e-6)


def test_gradients():
    with jax.enable_x64(True):
        rng = np.random.default_rng(1)
        aa = jnp.asarray(rng.normal(size=(3, 3)))
        check_grads(R.axis_angle_to_matrix, (aa,), order=2, modes=["fwd", "rev"])
        check_grads(R.axis_angle_to_quaternion, (aa,), order=1)
        check_grads(R.rotation_6d_to_matrix, (jnp.asarray(rng.normal(size=(3, 6))),), order=1)
        m = R.axis_angle_to_matrix(aa)
        check_grads(R.matrix_to_axis_angle, (m,), order=1)
        # the gradient at the identity is finite and equals the skew generator
        g = jax.jacfwd(R.axis_angle_to_matrix)(jnp.zeros(3))
        assert np.all(np.isfinite(g))
        np.testing.assert_allclose(g[..., 0], R.skew(jnp.array([1.0, 0, 0])), atol=1e-12)
        g = jax.grad(lambda x: jnp.sum(R.quaternion_to_axis_angle(x)))(jnp.array([1.0, 0, 0, 0]))
        assert np.all(np.isfinite(g))
