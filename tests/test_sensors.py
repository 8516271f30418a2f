"""Volumetric sensors (Cen et al. 2024) vs a brute-force numpy version."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion import geometry
from jaxmotion.geometry import sensors as S


def cloud(n, rng, centre=(0.0, 0.0, 0.0), spread=1.0):
    pts = rng.uniform(-spread, spread, (n, 3)) + np.asarray(centre)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pts.astype(np.float32), nrm.astype(np.float32)


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q.astype(np.float32)


def reference(points, normals, centre, half, res, rotation=None):
    """Brute force in float64: full distance matrix, the authors' occupancy.

    Returns ``(sensor [res,res,res,7], ambiguous [res,res,res] bool)``; ambiguous voxels have a
    near tie for the nearest point or sit almost on its tangent plane, where float32 rounding
    may legitimately pick the other answer.
    """
    t = np.linspace(-half, half, res)
    local = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    r = np.eye(3) if rotation is None else rotation.astype(np.float64)
    q = local @ r.T + np.asarray(centre, np.float64)
    p, n = points.astype(np.float64), normals.astype(np.float64)
    dist = np.linalg.norm(q[:, None] - p[None], axis=-1)  # [M, N]
    idx = dist.argmin(1)
    d = dist[np.arange(len(q)), idx]
    side = np.sum((q - p[idx]) * n[idx], -1)
    sdf = np.where(side < 0, -d, d)
    a = 2 * half / res
    occ = 1 - np.minimum(np.maximum(sdf, 0), a / 2) / (a / 2)
    out = np.concatenate([occ[:, None], q, n[idx]], -1).reshape(res, res, res, 7)
    second = np.sort(dist, 1)[:, 1] if len(p) > 1 else np.inf
    ambiguous = (second - d < 1e-4) | (np.abs(side) < 1e-4)
    return out, ambiguous.reshape(res, res, res)


def assert_matches(got, want, ambiguous):
    got = np.asarray(got)
    assert got.shape == want.shape and got.dtype == np.float32
    assert ambiguous.mean() < 0.02
    np.testing.assert_allclose(got[..., 1:4], want[..., 1:4], atol=1e-5)  # centres: always
    ok = ~ambiguous
    np.testing.assert_allclose(got[ok], want[ok], atol=1e-5)


@pytest.mark.parametrize("rotated", [False, True])
@pytest.mark.parametrize("seed", [0, 1])
def test_voxel_sensor_matches_brute_force(rotated, seed):
    rng = np.random.default_rng(seed)
    centre = np.array([0.5, -1.0, 0.8], np.float32)
    pts, nrm = cloud(300, rng, centre)
    rot = random_rotation(rng) if rotated else None
    half, res = 0.9, 6
    got = S.voxel_sensor(pts, nrm, centre, half, res, rot)
    want, amb = reference(pts, nrm, centre, half, res, rot)
    assert_matches(got, want, amb)
    occ = want[..., 0]  # the case is not trivial: empty, full and partial voxels
    assert (occ == 0).any() and (occ == 1).any() and ((occ > 0) & (occ < 1)).any()


def test_grid_corners_and_axis_order():
    centre, half = np.array([1.0, 2.0, 3.0], np.float32), 0.5
    g = np.asarray(S.sensor_grid(centre, half, 5))
    assert g.shape == (5, 5, 5, 3)
    np.testing.assert_allclose(g[0, 0, 0], centre - half, atol=1e-6)
    np.testing.assert_allclose(g[-1, -1, -1], centre + half, atol=1e-6)
    np.testing.assert_allclose(g[-1, 0, 0], centre + [half, -half, -half], atol=1e-6)
    np.testing.assert_allclose(g[0, -1, 0], centre + [-half, half, -half], atol=1e-6)
    np.testing.assert_allclose(g[0, 0, -1], centre + [-half, -half, half], atol=1e-6)
    np.testing.assert_allclose(g[:, 0, 0, 0], centre[0] + np.linspace(-half, half, 5), atol=1e-6)
    np.testing.assert_allclose(g[:, 0, 0, 1:], np.broadcast_to(centre[1:] - half, (5, 2)))
    # the sensor's centre channels are this grid; a rotation turns the offsets
    pts, nrm = cloud(20, np.random.default_rng(0))
    out = np.asarray(S.voxel_sensor(pts, nrm, centre, half, 5))
    np.testing.assert_allclose(out[..., 1:4], g, atol=1e-6)
    quarter = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], np.float32)  # +90° about z
    gr = np.asarray(S.sensor_grid(centre, half, 5, quarter))
    np.testing.assert_allclose(gr[-1, 0, 0] - gr[0, 0, 0], [0, 2 * half, 0], atol=1e-6)


@pytest.mark.parametrize("offset, expected", [
    (0.0, 1.0),      # on the point
    (0.025, 0.75),   # in front, a quarter voxel: linear
    (0.05, 0.5),
    (0.1, 0.0),      # a/2 in front
    (0.3, 0.0),      # beyond
    (-0.02, 1.0),    # behind the surface
    (-0.5, 1.0),
])
def test_occupancy_profile(offset, expected):
    # res 3, half 0.3: voxel edge a = 0.2 and the middle voxel sits on the centre; one point
    # `offset` below it with normal +z puts that voxel `offset` in front of the surface.
    centre = np.array([0.2, 0.1, 1.0], np.float32)
    pts = (centre - [0, 0, offset]).astype(np.float32)[None]
    out = np.asarray(S.voxel_sensor(pts, np.array([[0, 0, 1.0]], np.float32), centre, 0.3, 3))
    assert out[1, 1, 1, 0] == pytest.approx(expected, abs=1e-5)
    np.testing.assert_allclose(out[..., 4:7], np.broadcast_to([0, 0, 1.0], (3, 3, 3, 3)))
    assert np.all((out[..., 0] >= 0) & (out[..., 0] <= 1))


def test_target_and_environment_sensors():
    rng = np.random.default_rng(3)
    pts, nrm = cloud(200, rng, spread=2.5)
    lo, hi = np.array([0.1, -0.4, 0.0], np.float32), np.array([0.9, 0.2, 1.5], np.float32)
    got = S.target_sensor(pts, nrm, lo, hi, res=4)
    want, amb = reference(pts, nrm, (lo + hi) / 2, 0.75, 4)  # half of the 1.5 m side
    assert_matches(got, want, amb)
    np.testing.assert_allclose(np.asarray(got)[-1, -1, -1, 1:4], [1.25, 0.65, 1.5], atol=1e-6)

    c = np.array([0.3, 0.2, 0.5], np.float32)
    env = S.environment_sensor(pts, nrm, c, res=4)
    np.testing.assert_allclose(env, S.voxel_sensor(pts, nrm, c, 2.0, 4), atol=0)
    np.testing.assert_allclose(np.asarray(env)[0, 0, 0, 1:4], c - 2.0, atol=1e-6)


def trajectory_case(rng, t=5, n=150):
    pts, nrm = cloud(n, rng, spread=2.0)
    pos = rng.uniform(-1, 1, (t, 3)).astype(np.float32)
    rot = np.stack([random_rotation(rng) for _ in range(t)])
    return pts, nrm, pos, rot


def test_trajectory_sensor_stacks_voxel_sensors():
    pts, nrm, pos, rot = trajectory_case(np.random.default_rng(4))
    got = np.asarray(S.trajectory_sensor(pts, nrm, pos, rot, res=4))
    assert got.shape == (5, 4, 4, 4, S.SENSOR_CHANNELS)
    per_frame = np.stack([np.asarray(S.voxel_sensor(pts, nrm, p, 1.0, 4, r))
                          for p, r in zip(pos, rot)])
    np.testing.assert_allclose(got, per_frame, atol=1e-6)
    want, amb = reference(pts, nrm, pos[2], 1.0, 4, rot[2])
    assert_matches(got[2], want, amb)


def test_jit_and_vmap_over_scenes():
    rng = np.random.default_rng(5)
    cases = [trajectory_case(rng, t=3, n=90) for _ in range(2)]
    pts, nrm, pos, rot = (np.stack(x) for x in zip(*cases))
    fn = jax.jit(jax.vmap(lambda p, n, x, r: S.trajectory_sensor(p, n, x, r, res=3)))
    got = np.asarray(fn(pts, nrm, pos, rot))
    assert got.shape == (2, 3, 3, 3, 3, 7)
    for b in range(2):
        np.testing.assert_allclose(got[b], S.trajectory_sensor(pts[b], nrm[b], pos[b], rot[b],
                                                               res=3), atol=1e-6)
    # vmap over centres of one scene
    centres = pos[0]
    many = jax.vmap(lambda c: S.voxel_sensor(pts[0], nrm[0], c, 0.5, 3))(centres)
    for i, c in enumerate(centres):
        np.testing.assert_allclose(many[i], S.voxel_sensor(pts[0], nrm[0], c, 0.5, 3), atol=1e-6)


def test_traced_half_size_under_jit():
    rng = np.random.default_rng(6)
    pts, nrm = cloud(120, rng)
    lo, hi = jnp.array([-0.3, -0.2, 0.0]), jnp.array([0.3, 0.1, 0.4])
    by_box = jax.jit(lambda p, n, a, b: S.target_sensor(p, n, a, b, res=4))
    np.testing.assert_allclose(by_box(pts, nrm, lo, hi), S.target_sensor(pts, nrm, lo, hi, 4),
                               atol=1e-6)
    traces = []

    @jax.jit
    def by_half(h):
        traces.append(h)
        return S.voxel_sensor(pts, nrm, jnp.zeros(3), h, 4)

    for h in (0.4, 0.7):  # one compilation, two sizes
        want, amb = reference(pts, nrm, np.zeros(3), h, 4)
        assert_matches(by_half(jnp.float32(h)), want, amb)
    assert len(traces) == 1 and isinstance(traces[0], jax.core.Tracer)


def test_chunking_does_not_change_the_result():
    rng = np.random.default_rng(7)
    pts, nrm = cloud(1001, rng)  # not a multiple of any chunk below
    c = np.array([0.1, 0.0, -0.2], np.float32)
    base = np.asarray(S.voxel_sensor(pts, nrm, c, 0.8, 5))
    for qc, pc in ((7, 64), (256, 1000), (100, 3), (1000, 4096)):
        got = S.voxel_sensor(pts, nrm, c, 0.8, 5, query_chunk=qc, point_chunk=pc)
        np.testing.assert_array_equal(got, base)
    want, amb = reference(pts, nrm, c, 0.8, 5)
    assert_matches(base, want, amb)


def test_bad_inputs_are_explained():
    pts, nrm = cloud(10, np.random.default_rng(8))
    c = np.zeros(3, np.float32)
    with pytest.raises(ValueError, match="normals must match"):
        S.voxel_sensor(pts, nrm[:4], c, 1.0)
    with pytest.raises(ValueError, match="points is empty"):
        S.voxel_sensor(pts[:0], nrm[:0], c, 1.0)
    with pytest.raises(ValueError, match=r"points must be \[N, 3\]"):
        S.voxel_sensor(pts[:, :2], nrm[:, :2], c, 1.0)
    with pytest.raises(ValueError, match=r"centre must be a point \[3\]"):
        S.voxel_sensor(pts, nrm, np.zeros((2, 3)), 1.0)
    with pytest.raises(ValueError, match="res must be a Python int >= 2"):
        S.voxel_sensor(pts, nrm, c, 1.0, res=1)
    with pytest.raises(ValueError, match="res must be a Python int >= 2"):
        S.sensor_grid(c, 1.0, res=4.0)
    with pytest.raises(ValueError, match="half_size must be > 0"):
        S.voxel_sensor(pts, nrm, c, 0.0)
    with pytest.raises(ValueError, match="half_size must be a scalar"):
        S.voxel_sensor(pts, nrm, c, np.ones(2))
    with pytest.raises(ValueError, match=r"rotation must be a \[3, 3\]"):
        S.voxel_sensor(pts, nrm, c, 1.0, rotation=np.eye(4))
    with pytest.raises(ValueError, match="box_max must be >= box_min"):
        S.target_sensor(pts, nrm, np.ones(3), np.zeros(3))
    with pytest.raises(ValueError, match="single point"):
        S.target_sensor(pts, nrm, np.ones(3), np.ones(3))
    with pytest.raises(ValueError, match=r"rotations must be \[T, 3, 3\] with T = 2"):
        S.trajectory_sensor(pts, nrm, np.zeros((2, 3)), np.stack([np.eye(3)] * 3))
    with pytest.raises(ValueError, match=r"positions must be \[T, 3\]"):
        S.trajectory_sensor(pts, nrm, np.zeros((0, 3)), np.zeros((0, 3, 3)))


def test_exported_from_the_package():
    for name in S.__all__:
        assert getattr(geometry, name) is getattr(S, name)
    assert S.SENSOR_CHANNELS == 7
