"""The exporters' numpy rotation conversions against SciPy's ``Rotation`` (brute-force reference)."""

import numpy as np
from scipy.spatial.transform import Rotation

from jaxmotion.export.rotations import euler_zxy, rotvec_to_matrix, rotvec_to_quat


def _rotvecs(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3)) * rng.uniform(0, 3.1, size=(n, 1))
    v[:10] *= 1e-9  # near the identity: the series branch
    v[10] = 0.0
    return v


def test_rotvec_to_matrix_matches_scipy():
    v = _rotvecs()
    np.testing.assert_allclose(rotvec_to_matrix(v), Rotation.from_rotvec(v).as_matrix(),
                               atol=1e-12)
    assert rotvec_to_matrix(v.reshape(40, 50, 3)).shape == (40, 50, 3, 3)


def test_rotvec_to_quat_matches_scipy():
    v = _rotvecs(seed=1)
    np.testing.assert_allclose(rotvec_to_quat(v), Rotation.from_rotvec(v).as_quat(), atol=1e-12)


def test_euler_zxy_matches_scipy_and_recomposes():
    m = Rotation.from_rotvec(_rotvecs(seed=2)).as_matrix()
    e = euler_zxy(m, degrees=True)
    np.testing.assert_allclose(e, Rotation.from_matrix(m).as_euler("ZXY", degrees=True),
                               atol=1e-9)
    back = Rotation.from_euler("ZXY", e, degrees=True).as_matrix()
    np.testing.assert_allclose(back, m, atol=1e-12)


def test_euler_zxy_gimbal_lock_recomposes():
    # b = ±90°: the third angle is 0 and the first carries the rest, as SciPy does
    for b in (90.0, -90.0):
        m = Rotation.from_euler("ZXY", [30.0, b, 20.0], degrees=True).as_matrix()
        e = euler_zxy(m, degrees=True)
        assert e[2] == 0.0
        np.testing.assert_allclose(Rotation.from_euler("ZXY", e, degrees=True).as_matrix(), m,
                                   atol=1e-9)
