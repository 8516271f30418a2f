"""Rotation representations and conversions: axis-angle, matrix, quaternion, 6D.

All functions take arrays with arbitrary leading batch dimensions ``[...]`` and
are pure jax.numpy, so they jit, vmap and differentiate.

Conventions
-----------
- Matrices act on column vectors: ``v_rotated = R @ v``.
- Axis-angle ``[..., 3]``: unit axis times angle in radians (SMPL-X convention).
- Quaternions ``[..., 4]``: scalar first, ``(w, x, y, z)``, unit norm. ``q`` and
  ``-q`` are the same rotation; :func:`matrix_to_quaternion` returns ``w >= 0``.
- 6D ``[..., 6]`` (Zhou et al., CVPR 2019, in the PyTorch3D layout most motion
  code uses): the first two **rows** of the matrix, ``(R[0,0], R[0,1], R[0,2],
  R[1,0], R[1,1], R[1,2])``. :func:`rotation_6d_to_matrix` maps any 6-vector
  with two independent halves back to a rotation by Gram-Schmidt: row 0 is the
  normalised first half, row 1 the normalised second half with its component
  along row 0 removed, row 2 their cross product.

Small-angle branches use Taylor expansions selected with ``jnp.where`` on a
"safe" argument, so gradients stay finite at the identity.
"""

from __future__ import annotations

import jax.numpy as jnp

__all__ = [
    "axis_angle_to_matrix",
    "axis_angle_to_quaternion",
    "matrix_to_axis_angle",
    "matrix_to_quaternion",
    "matrix_to_rotation_6d",
    "quaternion_multiply",
    "quaternion_to_axis_angle",
    "quaternion_to_matrix",
    "rotation_6d_to_matrix",
    "rotate_about_z",
    "skew",
]

_SMALL = 1e-6


def skew(v: jnp.ndarray) -> jnp.ndarray:
    """Cross-product matrix: ``skew(v) @ u == cross(v, u)``. ``[...,3] -> [...,3,3]``."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = jnp.zeros_like(x)
    return jnp.stack(
        [jnp.stack([o, -z, y], -1), jnp.stack([z, o, -x], -1), jnp.stack([-y, x, o], -1)], -2
    )


def _safe_norm(v: jnp.ndarray):
    """Return (norm, small-mask, safe norm) with finite gradients at v = 0."""
    sq = jnp.sum(v * v, axis=-1)
    small = sq < _SMALL**2
    safe_sq = jnp.where(small, 1.0, sq)
    return jnp.where(small, 0.0, jnp.sqrt(safe_sq)), small, jnp.sqrt(safe_sq)


def axis_angle_to_matrix(aa: jnp.ndarray) -> jnp.ndarray:
    """Rodrigues' formula. ``[...,3] -> [...,3,3]``.

    ``R = I + a K + b K^2`` with ``K = skew(aa)``, ``a = sin θ / θ``,
    ``b = (1 - cos θ) / θ²``; Taylor series below θ = 1e-6.
    """
    sq = jnp.sum(aa * aa, axis=-1)
    small = sq < _SMALL**2
    theta = jnp.sqrt(jnp.where(small, 1.0, sq))
    a = jnp.where(small, 1.0 - sq / 6.0, jnp.sin(theta) / theta)
    b = jnp.where(small, 0.5 - sq / 24.0, (1.0 - jnp.cos(theta)) / jnp.where(small, 1.0, sq))
    k = skew(aa)
    eye = jnp.eye(3, dtype=aa.dtype)
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


def axis_angle_to_quaternion(aa: jnp.ndarray) -> jnp.ndarray:
    """``[...,3] -> [...,4]`` (w, x, y, z)."""
    sq = jnp.sum(aa * aa, axis=-1)
    small = sq < _SMALL**2
    theta = jnp.sqrt(jnp.where(small, 1.0, sq))
    half = 0.5 * theta
    # sin(θ/2)/θ -> 1/2 - θ²/48 near zero.
    s = jnp.where(small, 0.5 - sq / 48.0, jnp.sin(half) / theta)
    w = jnp.where(small, 1.0 - sq / 8.0, jnp.cos(half))
    return jnp.concatenate([w[..., None], aa * s[..., None]], axis=-1)


def quaternion_to_axis_angle(q: jnp.ndarray) -> jnp.ndarray:
    """``[...,4] -> [...,3]``, angle in [0, π] (the sign of ``q`` is fixed first)."""
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    q = jnp.where(q[..., :1] < 0, -q, q)
    w, v = q[..., 0], q[..., 1:]
    sin_half, small, safe = _safe_norm(v)
    angle = 2.0 * jnp.arctan2(sin_half, w)
    # angle / sin(θ/2) -> 2 / w (1 + |v|²/(3 w²)) near zero.
    scale = jnp.where(small, 2.0 / w, angle / safe)
    return v * scale[..., None]


def quaternion_to_matrix(q: jnp.ndarray) -> jnp.ndarray:
    """``[...,4] -> [...,3,3]``; ``q`` need not be normalised."""
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    r0 = jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1)
    r1 = jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1)
    r2 = jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)
    return jnp.stack([r0, r1, r2], -2)


def matrix_to_quaternion(m: jnp.ndarray) -> jnp.ndarray:
    """``[...,3,3] -> [...,4]`` with ``w >= 0`` (Shepperd's method, numerically stable).

    Four candidate quaternions are formed, each divided by its largest,
    well-conditioned component; the one with the largest diagonal term wins.
    """
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4 q_i^2 for each component; clipped at a tiny positive value for sqrt.
    t = jnp.stack(
        [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1
    )
    r = 2.0 * jnp.sqrt(jnp.maximum(t, 1e-12))  # 4 |q_i|
    cand = jnp.stack(
        [
            jnp.stack([r[..., 0] ** 2 / 4, m21 - m12, m02 - m20, m10 - m01], -1) / r[..., 0:1],
            jnp.stack([m21 - m12, r[..., 1] ** 2 / 4, m10 + m01, m02 + m20], -1) / r[..., 1:2],
            jnp.stack([m02 - m20, m10 + m01, r[..., 2] ** 2 / 4, m12 + m21], -1) / r[..., 2:3],
            jnp.stack([m10 - m01, m02 + m20, m12 + m21, r[..., 3] ** 2 / 4], -1) / r[..., 3:4],
        ],
        -2,
    )  # [..., 4 candidates, 4]
    best = jnp.argmax(t, axis=-1)
    q = jnp.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    return jnp.where(q[..., :1] < 0, -q, q)


def matrix_to_axis_angle(m: jnp.ndarray) -> jnp.ndarray:
    """``[...,3,3] -> [...,3]``, angle in [0, π]."""
    return quaternion_to_axis_angle(matrix_to_quaternion(m))


def matrix_to_rotation_6d(m: jnp.ndarray) -> jnp.ndarray:
    """First two rows, row-major: ``[...,3,3] -> [...,6]``."""
    return m[..., :2, :].reshape(*m.shape[:-2], 6)


def rotation_6d_to_matrix(d6: jnp.ndarray) -> jnp.ndarray:
    """Gram-Schmidt of the two 3-vectors: ``[...,6] -> [...,3,3]`` (rows b1, b2, b1×b2)."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = a1 / jnp.linalg.norm(a1, axis=-1, keepdims=True)
    a2 = a2 - jnp.sum(b1 * a2, axis=-1, keepdims=True) * b1
    b2 = a2 / jnp.linalg.norm(a2, axis=-1, keepdims=True)
    b3 = jnp.cross(b1, b2)
    return jnp.stack([b1, b2, b3], axis=-2)


def quaternion_multiply(q1: jnp.ndarray, q2: jnp.ndarray) -> jnp.ndarray:
    """Hamilton product: the rotation ``q1`` applied after ``q2``. ``[...,4] x [...,4]``."""
    w1, x1, y1, z1 = jnp.moveaxis(q1, -1, 0)
    w2, x2, y2, z2 = jnp.moveaxis(q2, -1, 0)
    return jnp.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        -1,
    )


def rotate_about_z(angle: jnp.ndarray) -> jnp.ndarray:
    """Rotation matrix about the world up axis (z), counter-clockwise seen from above.

    ``[...] -> [...,3,3]``.
    """
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, i = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([c, -s, o], -1), jnp.stack([s, c, o], -1), jnp.stack([o, o, i], -1)], -2
    )
