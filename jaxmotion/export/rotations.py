"""Rotation conversions in float64 numpy for the exporters (no SciPy: it costs ~0.3 s to import
in every ``generate``). Conventions as ``scipy.spatial.transform.Rotation``'s, which the tests
compare them with: quaternions scalar-last ``[x, y, z, w]``, Euler angles intrinsic."""

from __future__ import annotations

import numpy as np

__all__ = ["euler_zxy", "rotvec_to_matrix", "rotvec_to_quat"]


def _angle_axis_terms(v):
    v = np.asarray(v, np.float64)
    angle = np.linalg.norm(v, axis=-1)
    small = angle < 1e-6
    safe = np.where(small, 1.0, angle)
    return v, angle, small, safe


def rotvec_to_matrix(v) -> np.ndarray:
    """Rotation matrices ``[..., 3, 3]`` of axis-angle vectors ``[..., 3]`` (Rodrigues)."""
    v, angle, small, safe = _angle_axis_terms(v)
    # sin(a)/a and (1 - cos a)/a², with their series near 0
    a2 = angle * angle
    s = np.where(small, 1.0 - a2 / 6.0, np.sin(angle) / safe)
    c = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(angle)) / (safe * safe))
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = np.zeros_like(x)
    k = np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1),
                  np.stack([-y, x, o], -1)], -2)
    return np.eye(3) + s[..., None, None] * k + c[..., None, None] * (k @ k)


def rotvec_to_quat(v) -> np.ndarray:
    """Quaternions ``[..., 4]`` (``[x, y, z, w]``) of axis-angle vectors ``[..., 3]``."""
    v, angle, small, safe = _angle_axis_terms(v)
    a2 = angle * angle
    scale = np.where(small, 0.5 - a2 / 48.0, np.sin(angle / 2.0) / safe)
    return np.concatenate([v * scale[..., None], np.cos(angle / 2.0)[..., None]], axis=-1)


def euler_zxy(m, degrees: bool = False) -> np.ndarray:
    """Intrinsic Z-X-Y Euler angles ``[..., 3]`` of rotation matrices ``[..., 3, 3]``:
    ``m = Rz(a) @ Rx(b) @ Ry(c)``, ``b`` in [−90°, 90°]; at gimbal lock (``b`` = ±90°) ``c``
    is 0."""
    m = np.asarray(m, np.float64)
    b = np.arcsin(np.clip(m[..., 2, 1], -1.0, 1.0))
    locked = np.abs(m[..., 2, 1]) > 1.0 - 1e-12
    a = np.where(locked, np.arctan2(m[..., 1, 0], m[..., 0, 0]),
                 np.arctan2(-m[..., 0, 1], m[..., 1, 1]))
    c = np.where(locked, 0.0, np.arctan2(-m[..., 2, 0], m[..., 2, 2]))
    out = np.stack([a, b, c], axis=-1)
    return np.degrees(out) if degrees else out
