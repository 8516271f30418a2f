"""Volumetric scene sensors of Cen et al. (CVPR 2024): occupancy and normals on voxel grids.

A sensor is a cube of ``res³`` sample points ("voxel centres") placed in the scene. At each
one it reads the oriented point cloud of the room and returns ``SENSOR_CHANNELS = 7`` values:

- ``[..., 0]``   occupancy in ``[0, 1]`` (see below);
- ``[..., 1:4]`` the voxel centre itself, in the cloud's (world) frame, metres;
- ``[..., 4:7]`` the normal of the cloud point nearest to the voxel centre (as given, not
  re-normalised).

Occupancy, as the authors' code computes it: ``d`` is the distance from the voxel centre to
its nearest cloud point ``p`` (normal ``n``), made negative when the centre lies behind the
surface (``⟨q − p, n⟩ < 0``); with the voxel edge ``a = 2·half_size / res``,
``occ = 1 − min(max(d, 0), a/2) / (a/2)``: 1 on or behind the surface, falling linearly to 0
at half a voxel edge in front of it. Note that ``a`` is ``2·half_size / res`` while the
sample spacing is ``2·half_size / (res − 1)`` (the grid includes both faces of the cube); this
is the authors' convention and is kept as is.

Three sensors are built on :func:`voxel_sensor`:

- :func:`environment_sensor`: a 4 m axis-aligned cube (half 2 m) around the target's centre;
- :func:`target_sensor`: a cube over the target's bounding box (half its longest side);
- :func:`trajectory_sensor`: a 2 m cube per frame, at the root position, turned with the root.

Coordinates are metres, z-up. Everything is pure jax.numpy, float32, jit- and vmap-friendly
(``res`` and the chunk sizes are static; ``half_size`` may be traced). The nearest-point search
is :func:`jaxmotion.geometry.distance.nearest_points`, chunked over both clouds, so no
``[N, voxels]`` matrix is ever built and rooms of 100k points are fine.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from jaxmotion.geometry.distance import nearest_points, occupancy_from_sdf

__all__ = [
    "SENSOR_CHANNELS",
    "environment_sensor",
    "sensor_grid",
    "target_sensor",
    "trajectory_sensor",
    "voxel_sensor",
]

SENSOR_CHANNELS = 7
"""Channels per voxel: occupancy (1), voxel centre (3), nearest point's normal (3)."""


# ---------------------------------------------------------------------------------------------
# validation (on shapes, which are static under jit and vmap; values only when concrete)


def _check_res(res):
    if isinstance(res, bool) or not isinstance(res, int) or res < 2:
        raise ValueError(f"res must be a Python int >= 2 (voxels per cube side; it fixes the "
                         f"output shape, so it cannot be traced), got {res!r}")


def _concrete_float(x):
    """``float(x)`` for a concrete scalar, ``None`` for a traced one."""
    try:
        return float(x)
    except TypeError:  # jax.errors.ConcretizationTypeError and friends subclass TypeError
        return None


def _check_half_size(half_size, what="half_size"):
    half_size = jnp.asarray(half_size, jnp.float32)
    if half_size.shape != ():
        raise ValueError(f"{what} must be a scalar (metres), got shape {half_size.shape}; "
                         f"vmap over it for several cubes")
    value = _concrete_float(half_size)
    if value is not None and not value > 0:
        raise ValueError(f"{what} must be > 0 metres (half the cube's side), got {value}")
    return half_size


def _check_vector(name, x):
    x = jnp.asarray(x, jnp.float32)
    if x.shape != (3,):
        raise ValueError(f"{name} must be a point [3] (x, y, z in metres), got shape {x.shape}; "
                         f"vmap over it for several")
    return x


def _check_rotation(rotation):
    if rotation is None:
        return None
    rotation = jnp.asarray(rotation, jnp.float32)
    if rotation.shape != (3, 3):
        raise ValueError(f"rotation must be a [3, 3] rotation matrix or None, got shape "
                         f"{rotation.shape}")
    return rotation


def _check_cloud(points, normals):
    points = jnp.asarray(points, jnp.float32)
    normals = jnp.asarray(normals, jnp.float32)
    if points.ndim != 2 or points.shape[-1] != 3:
        raise ValueError(f"points must be [N, 3] (one cloud; vmap for a batch of scenes), "
                         f"got shape {points.shape}")
    if points.shape[0] == 0:
        raise ValueError("points is empty: a sensor needs at least one scene point")
    if normals.shape != points.shape:
        raise ValueError(f"normals must match points {points.shape} (one normal per point), "
                         f"got shape {normals.shape}")
    return points, normals


# ---------------------------------------------------------------------------------------------
# kernels


def _grid(centre, half_size, res, rotation):
    """``[res, res, res, 3]`` voxel centres (see :func:`sensor_grid`); inputs already checked."""
    ticks = jnp.linspace(-half_size, half_size, res, dtype=jnp.float32)
    local = jnp.stack(jnp.meshgrid(ticks, ticks, ticks, indexing="ij"), axis=-1)
    if rotation is not None:
        # R @ u per voxel, as an exact float32 product-sum (a dot could run at reduced
        # precision on accelerators).
        local = jnp.sum(rotation * local[..., None, :], axis=-1)
    return local + centre


def _sense(points, normals, grid, half_size, res, query_chunk, point_chunk):
    """Read the cloud at voxel centres ``grid [..., 3]`` -> ``[..., SENSOR_CHANNELS]``."""
    q = grid.reshape(-1, 3)
    d, idx = nearest_points(q, points, query_chunk=query_chunk, point_chunk=point_chunk)
    n = normals[idx]
    behind = jnp.sum((q - points[idx]) * n, axis=-1) < 0
    occ = occupancy_from_sdf(jnp.where(behind, -d, d), 2.0 * half_size / res)
    out = jnp.concatenate([occ[:, None], q, n], axis=-1)
    return out.reshape(*grid.shape[:-1], SENSOR_CHANNELS)


@partial(jax.jit, static_argnames=("res", "query_chunk", "point_chunk"))
def _voxel_sensor(points, normals, centre, half_size, rotation, res, query_chunk, point_chunk):
    grid = _grid(centre, half_size, res, rotation)
    return _sense(points, normals, grid, half_size, res, query_chunk, point_chunk)


@partial(jax.jit, static_argnames=("res", "query_chunk", "point_chunk"))
def _trajectory_sensor(points, normals, positions, rotations, half_size, res, query_chunk,
                       point_chunk):
    grids = jax.vmap(lambda c, r: _grid(c, half_size, res, r))(positions, rotations)
    # All T·res³ voxel centres in one chunked search.
    return _sense(points, normals, grids, half_size, res, query_chunk, point_chunk)


# ---------------------------------------------------------------------------------------------
# public API


def sensor_grid(centre, half_size, res: int = 8, rotation=None):
    """Voxel centres of a sensor cube: ``centre + R @ (u, v, w)``.

    Args:
      centre: ``[3]`` cube centre, metres (world frame, z-up).
      half_size: scalar, half the cube's side in metres (> 0; may be traced under jit).
      res: voxels per side (static Python int >= 2).
      rotation: ``[3, 3]`` rotation matrix ``R`` (cube frame -> world), or ``None`` for the
        identity (axis-aligned).
    Returns:
      ``[res, res, res, 3]`` float32: ``u, v, w`` each run over
      ``linspace(-half_size, half_size, res)`` along axes ``i, j, k`` (``indexing="ij"``), so
      index ``[i, 0, 0]`` moves along the cube's x axis; corners are ``centre ± half_size``
      (before rotation).
    """
    _check_res(res)
    return _grid(_check_vector("centre", centre), _check_half_size(half_size), res,
                 _check_rotation(rotation))


def voxel_sensor(points, normals, centre, half_size, res: int = 8, rotation=None, *,
                 query_chunk: int = 256, point_chunk: int = 8192):
    """Read an oriented point cloud on a sensor cube (occupancy, voxel centre, nearest normal).

    Args:
      points: ``[N, 3]`` scene points (N >= 1), metres, z-up.
      normals: ``[N, 3]`` their normals (outward; used for the inside/outside sign).
      centre, half_size, res, rotation: the cube, as in :func:`sensor_grid`.
      query_chunk, point_chunk: block sizes of the nearest-point search (static; memory is
        about ``query_chunk × point_chunk × 12`` bytes whatever N is). Results do not depend
        on them.
    Returns:
      ``[res, res, res, SENSOR_CHANNELS]`` float32: occupancy ``[..., 0]`` in ``[0, 1]``, the
      voxel centre ``[..., 1:4]`` (world frame), the nearest point's normal ``[..., 4:7]``.
      Occupancy is ``1 − min(max(d, 0), a/2) / (a/2)`` with ``d`` the distance to the nearest
      point, negative when behind its normal, and ``a = 2·half_size / res``.

    Works under ``jax.jit`` (``res`` and the chunks static, ``half_size`` may be traced) and
    ``jax.vmap`` (over centres, sizes, rotations, or a batch of equally sized scenes).
    """
    _check_res(res)
    points, normals = _check_cloud(points, normals)
    return _voxel_sensor(points, normals, _check_vector("centre", centre),
                         _check_half_size(half_size), _check_rotation(rotation), res=res,
                         query_chunk=int(query_chunk), point_chunk=int(point_chunk))


def environment_sensor(points, normals, centre, half_size=2.0, res: int = 8, *,
                       query_chunk: int = 256, point_chunk: int = 8192):
    """The environment sensor: an axis-aligned cube of side ``2·half_size`` (default 4 m)
    centred on the target's centre ``centre [3]``.

    Same arguments and ``[res, res, res, SENSOR_CHANNELS]`` result as :func:`voxel_sensor`.
    """
    return voxel_sensor(points, normals, centre, half_size, res, None,
                        query_chunk=query_chunk, point_chunk=point_chunk)


def target_sensor(points, normals, box_min, box_max, res: int = 8, *,
                  query_chunk: int = 256, point_chunk: int = 8192):
    """The target sensor: a cube over the target object's axis-aligned bounding box.

    The cube is centred on the box centre ``(box_min + box_max) / 2`` with half size half the
    box's longest side, so it just contains the box; its size follows the data (the box may
    be traced under jit).

    Args:
      points, normals: the scene cloud, ``[N, 3]`` each (metres, z-up).
      box_min, box_max: ``[3]`` corners of the target's box, metres, ``box_min <= box_max``.
      res, query_chunk, point_chunk: as in :func:`voxel_sensor`.
    Returns:
      ``[res, res, res, SENSOR_CHANNELS]`` float32 (see :func:`voxel_sensor`).
    """
    box_min = _check_vector("box_min", box_min)
    box_max = _check_vector("box_max", box_max)
    extent = box_max - box_min
    longest = _concrete_float(jnp.max(extent))
    if longest is not None:
        if _concrete_float(jnp.min(extent)) < 0:
            raise ValueError(f"box_max must be >= box_min on every axis (are they swapped?), "
                             f"got box_min={box_min.tolist()}, box_max={box_max.tolist()}")
        if not longest > 0:
            raise ValueError(f"the target box is a single point ({box_min.tolist()}): it needs "
                             f"a positive extent on at least one axis to size the sensor")
    return voxel_sensor(points, normals, 0.5 * (box_min + box_max), 0.5 * jnp.max(extent),
                        res, None, query_chunk=query_chunk, point_chunk=point_chunk)


def trajectory_sensor(points, normals, positions, rotations, half_size=1.0, res: int = 8, *,
                      query_chunk: int = 256, point_chunk: int = 8192):
    """The trajectory sensor: one cube per frame (default 2 m), at the root, turned with it.

    Frame ``t`` reads the cloud at ``positions[t] + rotations[t] @ (u, v, w)`` (see
    :func:`sensor_grid`). All ``T·res³`` voxel centres go through one chunked nearest-point
    search.

    Args:
      points, normals: the scene cloud, ``[N, 3]`` each (metres, z-up).
      positions: ``[T, 3]`` root positions, metres (T >= 1).
      rotations: ``[T, 3, 3]`` root rotation matrices (root frame -> world).
      half_size, res, query_chunk, point_chunk: as in :func:`voxel_sensor`.
    Returns:
      ``[T, res, res, res, SENSOR_CHANNELS]`` float32; frame ``t`` equals
      ``voxel_sensor(points, normals, positions[t], half_size, res, rotations[t])``.
    """
    _check_res(res)
    points, normals = _check_cloud(points, normals)
    positions = jnp.asarray(positions, jnp.float32)
    rotations = jnp.asarray(rotations, jnp.float32)
    if positions.ndim != 2 or positions.shape[-1] != 3 or positions.shape[0] == 0:
        raise ValueError(f"positions must be [T, 3] root positions with T >= 1, got shape "
                         f"{positions.shape}")
    if rotations.shape != (positions.shape[0], 3, 3):
        raise ValueError(f"rotations must be [T, 3, 3] with T = {positions.shape[0]} (one root "
                         f"rotation matrix per position), got shape {rotations.shape}")
    return _trajectory_sensor(points, normals, positions, rotations,
                              _check_half_size(half_size), res=res,
                              query_chunk=int(query_chunk), point_chunk=int(point_chunk))
