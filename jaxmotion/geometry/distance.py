"""Nearest-point and signed distances, boxes and occupancy.

Kernels shared by the sensors, the body metrics and the synthetic world. All are
pure jax.numpy, jitted at their entry points, and work on one cloud at a time
(``vmap`` for batches). Distances here use exact differences (not the expanded
``|p|² − 2p·q + |q|²`` form) because metric thresholds of a few centimetres
need full float32 accuracy.

Sign conventions
----------------
- :func:`signed_distance`: positive **outside** (on the side the surface normal
  points to), negative behind the surface: the usual SDF of a closed surface
  with outward normals. The body metrics of HUMANISE use the opposite sign
  (positive inside the body); they negate this.
- :func:`box_signed_distance`: negative inside an axis-aligned box.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

__all__ = [
    "box_signed_distance",
    "carry_field",
    "nearest_points",
    "occupancy_from_sdf",
    "points_in_boxes",
    "signed_distance",
    "voxel_grid_centers",
]


def _check_cloud(name, x):
    if x.ndim != 2 or x.shape[-1] != 3:
        raise ValueError(f"{name} must be [N, 3], got shape {x.shape}")
    if x.shape[0] == 0:
        raise ValueError(f"{name} is empty: need at least one point")


@partial(jax.jit, static_argnames=("query_chunk", "point_chunk"))
def _nearest(queries, points, query_chunk, point_chunk):
    m, n = queries.shape[0], points.shape[0]
    qc, pc = max(1, min(query_chunk, m)), max(1, min(point_chunk, n))
    q = jnp.pad(queries, ((0, -m % qc), (0, 0))).reshape(-1, qc, 3)
    n_pad = -n % pc
    # Padding points sit at +inf distance so they never win.
    p = jnp.pad(points, ((0, n_pad), (0, 0))).reshape(-1, pc, 3)
    valid = (jnp.arange(n + n_pad) < n).reshape(-1, pc)
    offsets = jnp.arange(p.shape[0]) * pc

    def per_query_chunk(qb):  # [qc, 3]
        def step(carry, blk):
            best_d2, best_i = carry
            pts, ok, off = blk
            d2 = jnp.sum((qb[:, None, :] - pts[None, :, :]) ** 2, axis=-1)  # [qc, pc]
            d2 = jnp.where(ok[None], d2, jnp.inf)
            i = jnp.argmin(d2, axis=1)
            d2_min = jnp.take_along_axis(d2, i[:, None], axis=1)[:, 0]
            better = d2_min < best_d2
            return (jnp.where(better, d2_min, best_d2), jnp.where(better, i + off, best_i)), None

        init = (jnp.full((qc,), jnp.inf, queries.dtype), jnp.zeros((qc,), jnp.int32))
        (d2, idx), _ = jax.lax.scan(step, init, (p, valid, offsets))
        return d2, idx

    d2, idx = jax.lax.map(per_query_chunk, q)
    d2, idx = d2.reshape(-1)[:m], idx.reshape(-1)[:m]
    # Recompute the winning distance so gradients flow to both clouds.
    diff = queries - points[idx]
    return jnp.sqrt(jnp.maximum(jnp.sum(diff * diff, -1), 1e-30)), idx


def nearest_points(queries, points, *, query_chunk: int = 256, point_chunk: int = 8192):
    """Nearest neighbour of each query in a point cloud (brute force, chunked).

    Args:
      queries: ``[M, 3]``; points: ``[N, 3]`` (N >= 1), metres.
      query_chunk, point_chunk: block sizes (memory ``query_chunk × point_chunk``).
    Returns:
      ``(distance [M] float32, index [M] int32)`` into ``points``.
    """
    queries = jnp.asarray(queries, jnp.float32)
    points = jnp.asarray(points, jnp.float32)
    _check_cloud("queries", queries)
    _check_cloud("points", points)
    return _nearest(queries, points, query_chunk=query_chunk, point_chunk=point_chunk)


@partial(jax.jit, static_argnames=("k", "query_chunk"))
def _carry(queries, points, values, k, eps, query_chunk):
    m = queries.shape[0]
    qc = max(1, min(query_chunk, m))
    q = jnp.pad(queries, ((0, -m % qc), (0, 0))).reshape(-1, qc, 3)

    def per_chunk(qb):
        d2 = jnp.sum((qb[:, None, :] - points[None, :, :]) ** 2, axis=-1)  # [qc, N]
        neg, idx = jax.lax.top_k(-d2, k)
        w = 1.0 / (jnp.sqrt(jnp.maximum(-neg, 0.0)) + eps)  # [qc, k]
        w = w / jnp.sum(w, axis=1, keepdims=True)
        return jnp.einsum("qk,qkc->qc", w, values[idx])

    out = jax.lax.map(per_chunk, q)
    return out.reshape(-1, values.shape[-1])[:m]


def carry_field(queries, points, values, *, k: int = 4, eps: float = 1e-3,
                query_chunk: int = 512):
    """Carry a per-point field from one cloud to another: at each query, the mean of the
    values at its ``k`` nearest points weighted by ``1 / (distance + eps)``.

    Used to move an affordance map from the ADM's view of the room to the AMDM's crop (both
    sampled from the same room, so most queries sit on or next to a source point, whose value
    then dominates).

    Args:
      queries: ``[M, 3]``; points: ``[N, 3]`` (N >= 1); values: ``[N, C]``; all in one frame.
      k: neighbours (clipped to N); eps: metres added to each distance (no division by zero).
    Returns:
      ``[M, C]`` float32.
    """
    queries = jnp.asarray(queries, jnp.float32)
    points = jnp.asarray(points, jnp.float32)
    values = jnp.asarray(values, jnp.float32)
    _check_cloud("queries", queries)
    _check_cloud("points", points)
    if values.ndim != 2 or values.shape[0] != points.shape[0]:
        raise ValueError(f"values must be [N, C] with N = {points.shape[0]} (one row per point), "
                         f"got shape {values.shape}")
    if k < 1 or eps <= 0:
        raise ValueError(f"need k >= 1 and eps > 0, got k={k}, eps={eps}")
    return _carry(queries, points, values, k=min(int(k), points.shape[0]), eps=float(eps),
                  query_chunk=int(query_chunk))


def signed_distance(queries, points, normals, **chunks):
    """Signed distance to an oriented point cloud: ``[M,3], [N,3], [N,3] -> [M]``.

    ``|q − p*|`` for the nearest point ``p*``, with the sign of
    ``⟨q − p*, n*⟩`` (positive in front of the surface, i.e. outside). Points
    exactly on the tangent plane count as outside.
    """
    points = jnp.asarray(points, jnp.float32)
    normals = jnp.asarray(normals, jnp.float32)
    if normals.shape != points.shape:
        raise ValueError(f"normals must match points {points.shape}, got {normals.shape}")
    d, idx = nearest_points(queries, points, **chunks)
    side = jnp.sum((jnp.asarray(queries, jnp.float32) - points[idx]) * normals[idx], axis=-1)
    return jnp.where(side < 0, -d, d)


def points_in_boxes(points, box_min, box_max, margin: float = 0.0):
    """Which points lie inside which axis-aligned boxes: ``[N,3], [K,3], [K,3] -> [N,K]`` bool.

    ``margin`` grows (positive) or shrinks (negative) every box on all sides.
    """
    p = jnp.asarray(points)[:, None, :]
    lo = jnp.asarray(box_min)[None] - margin
    hi = jnp.asarray(box_max)[None] + margin
    return jnp.all((p >= lo) & (p <= hi), axis=-1)


def box_signed_distance(points, box_min, box_max):
    """Exact signed distance to axis-aligned boxes, negative inside: ``[N,3],[K,3],[K,3] -> [N,K]``.

    Outside: Euclidean distance to the box. Inside: minus the distance to the
    nearest face.
    """
    p = jnp.asarray(points, jnp.float32)[:, None, :]
    lo = jnp.asarray(box_min, jnp.float32)[None]
    hi = jnp.asarray(box_max, jnp.float32)[None]
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    q = jnp.abs(p - centre) - half  # [N, K, 3]
    outside_sq = jnp.sum(jnp.maximum(q, 0.0) ** 2, axis=-1)
    safe = jnp.where(outside_sq > 0, outside_sq, 1.0)
    outside = jnp.where(outside_sq > 0, jnp.sqrt(safe), 0.0)
    inside = jnp.minimum(jnp.max(q, axis=-1), 0.0)
    return outside + inside


def voxel_grid_centers(center, half_size, resolution: int):
    """Centres of a cubic voxel grid: ``[3], scalar -> [R, R, R, 3]`` (x, y, z index order).

    The cube spans ``center ± half_size``; voxel edge = ``2 half_size / R``.
    """
    center = jnp.asarray(center, jnp.float32)
    edge = 2.0 * jnp.asarray(half_size, jnp.float32) / resolution
    ticks = (jnp.arange(resolution, dtype=jnp.float32) + 0.5) * edge - half_size
    gx, gy, gz = jnp.meshgrid(ticks, ticks, ticks, indexing="ij")
    return jnp.stack([gx, gy, gz], axis=-1) + center


def occupancy_from_sdf(sdf, voxel_size):
    """Soft occupancy of a voxel from the signed distance at its centre.

    ``1 − clip(max(sdf, 0), 0, v/2) / (v/2)``: 1 inside or on the surface, falling
    linearly to 0 at half a voxel outside (the sensors of Cen et al. 2024).
    """
    half = 0.5 * jnp.asarray(voxel_size, jnp.float32)
    return 1.0 - jnp.clip(jnp.maximum(jnp.asarray(sdf), 0.0), 0.0, half) / half
