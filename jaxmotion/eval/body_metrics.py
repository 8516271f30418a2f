"""Body–scene metrics from a body mesh: signed distance, non-collision, contact, goal distance.

Body signed distance (HUMANISE / afford-motion), positive **inside** the body::

    s(p) = ± || p − v* ||,   v* = argmin_v || p − v ||,   sign = sign ⟨v* − p, n_{v*}⟩

with ``n`` the outward vertex normals: a point behind the surface (inside) gets
``s > 0``; a point on the tangent plane counts as outside. Metrics on
``sdf[T, N]`` (frames × scene points), averaged over valid frames:

- non-collision = mean_t (1/N) Σ_n [s_{t,n} ≤ 0]
- contact       = mean_t [max_n s_{t,n} > τ],  τ = −0.05 m (afford-motion; HUMANISE τ = 0)
- goal distance = min_o max(0, −s_a(o)) over target-object points o at the anchor
  frame a (last valid frame; the first for "stand up"): 0 when the body touches it.

Pure jax.numpy, one motion at a time (``vmap`` for batches), ``jit``-compatible
(``action`` strings are static). Metres; frame masks ``[T]`` bool, True = valid.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from jaxmotion.eval._common import as_mask, masked_mean, require_any, require_nonempty
from jaxmotion.eval._nearest import nearest_vertex
from jaxmotion.geometry.distance import signed_distance

__all__ = [
    "CONTACT_THRESHOLD",
    "anchor_goal_distance",
    "anchor_index",
    "contact",
    "goal_distance",
    "is_stand_up",
    "non_collision",
    "signed_distance_to_body",
    "signed_distance_to_body_frames",
]

#: Contact threshold τ of afford-motion, metres (a scene point with s > τ is "in contact").
CONTACT_THRESHOLD = -0.05


def signed_distance_to_body(
    points, vertices, vertex_normals, *, exact: bool = False, query_chunk: int = 64, **kw
):
    """Signed distance of scene points to a body mesh, **positive inside**: ``[N,3] -> [N]``.

    ``s(p) = |p − v*|`` with the sign of ``⟨v* − p, n_{v*}⟩`` for the nearest
    vertex ``v*`` (HUMANISE / afford-motion); ``≤ 0`` outside or on the surface
    (a point on the tangent plane counts as outside).

    Args:
      points: ``[N, 3]`` scene points; vertices: ``[V, 3]`` body vertices;
        vertex_normals: ``[V, 3]`` outward normals (any length), metres.
      exact: False (default): the blocked search of :mod:`jaxmotion.eval._nearest`
        (~0.5 s for 50k × 10k on 2 CPU cores; distances exact to well below 1 mm,
        the chosen vertex can differ only between near-equidistant vertices).
        True: :func:`jaxmotion.geometry.nearest_points`, exact differences for
        every pair (~20× slower).
      query_chunk, kw: chunk sizes (``block`` for the fast search; ``point_chunk``
        for the exact one). Memory is ``~4 · query_chunk · V`` bytes (fast) or
        ``~16 · query_chunk · point_chunk`` (exact): an ``[N, V]`` matrix is never
        built. Under ``vmap`` that block is multiplied by the batch size: for many
        frames prefer :func:`signed_distance_to_body_frames` (a sequential loop).
    Returns:
      ``[N]`` float32, metres.
    """
    if exact:
        return -signed_distance(points, vertices, vertex_normals, query_chunk=query_chunk, **kw)
    points = jnp.asarray(points, jnp.float32)
    vertices = jnp.asarray(vertices, jnp.float32)
    vertex_normals = jnp.asarray(vertex_normals, jnp.float32)
    for name, x in (("points", points), ("vertices", vertices)):
        if x.ndim != 2 or x.shape[-1] != 3:
            raise ValueError(f"{name} must be [N, 3], got shape {x.shape}")
    require_nonempty(vertices, "vertices", "the body has no vertices")
    if vertex_normals.shape != vertices.shape:
        raise ValueError(
            f"vertex_normals must match vertices {vertices.shape}, got {vertex_normals.shape}"
        )
    if points.shape[0] == 0:
        return jnp.zeros((0,), jnp.float32)
    return _body_sdf(points, vertices, vertex_normals, query_chunk=query_chunk, **kw)


@partial(jax.jit, static_argnames=("query_chunk", "block"))
def _body_sdf(points, vertices, normals, *, query_chunk, block=64):
    d, idx = nearest_vertex(points, vertices, query_chunk=query_chunk, block=block)
    inside = jnp.sum((vertices[idx] - points) * normals[idx], axis=-1) > 0
    return jnp.where(inside, d, -d)


def signed_distance_to_body_frames(points, vertices, vertex_normals, **chunks):
    """:func:`signed_distance_to_body` for every frame: ``[N,3], [T,V,3], [T,V,3] -> [T, N]``.

    Frames are processed one after the other (``lax.map``), so memory stays that
    of one frame.
    """
    vertices = jnp.asarray(vertices, jnp.float32)
    vertex_normals = jnp.asarray(vertex_normals, jnp.float32)
    if vertices.ndim != 3 or vertex_normals.shape != vertices.shape:
        raise ValueError(
            f"vertices and vertex_normals must both be [T, V, 3], got "
            f"{vertices.shape} and {vertex_normals.shape}"
        )
    points = jnp.asarray(points, jnp.float32)
    return jax.lax.map(
        lambda vn: signed_distance_to_body(points, vn[0], vn[1], **chunks),
        (vertices, vertex_normals),
    )


# ----------------------------------------------------------------------------- per-frame rates
def _check_sdf(sdf, mask, point_mask):
    sdf = jnp.asarray(sdf, jnp.float32)
    if sdf.ndim != 2:
        raise ValueError(f"sdf must be [T, N] (frames, scene points), got shape {sdf.shape}")
    require_nonempty(sdf, "sdf", "need at least one frame")
    if sdf.shape[1] == 0:
        raise ValueError("sdf has no scene points: need N >= 1")
    mask = as_mask(mask, sdf.shape[0], "mask")
    point_mask = as_mask(point_mask, sdf.shape[1], "point_mask")
    require_any(mask, "mask selects no frame: the metric is undefined")
    require_any(point_mask, "point_mask selects no scene point: the metric is undefined")
    return sdf, mask, point_mask


def non_collision(sdf, mask=None, *, point_mask=None):
    """Non-collision score: ``mean_t (1/N) Σ_n [sdf[t, n] ≤ 0]`` over valid frames, in [0, 1].

    Args:
      sdf: ``[T, N]`` body signed distance of each scene point per frame
        (positive inside the body), metres.
      mask: ``[T]`` valid frames, or None.
      point_mask: ``[N]`` valid (non-padding) scene points, or None.
    Returns:
      Scalar float32 (1 = no scene point inside the body in any frame).
    """
    sdf, mask, point_mask = _check_sdf(sdf, mask, point_mask)
    return _non_collision(sdf, mask, point_mask)


@jax.jit
def _non_collision(sdf, mask, point_mask):
    free = sdf <= 0.0
    if point_mask is None:
        per_frame = jnp.mean(free, axis=1)
    else:
        count = jnp.sum(point_mask)
        per_frame = jnp.sum(free & point_mask, axis=1) / jnp.maximum(count, 1)
        per_frame = jnp.where(count > 0, per_frame, jnp.nan)
    return masked_mean(per_frame, mask)


def contact(sdf, threshold: float = CONTACT_THRESHOLD, mask=None, *, point_mask=None):
    """Contact score: ``mean_t [max_n sdf[t, n] > threshold]`` over valid frames, in [0, 1].

    ``threshold`` −0.05 m is afford-motion's choice (a body within 5 cm of the
    scene is in contact); HUMANISE used 0. Arguments as :func:`non_collision`.
    """
    sdf, mask, point_mask = _check_sdf(sdf, mask, point_mask)
    return _contact(sdf, jnp.float32(threshold), mask, point_mask)


@jax.jit
def _contact(sdf, threshold, mask, point_mask):
    hit = sdf > threshold
    if point_mask is not None:
        hit = hit & point_mask
    return masked_mean(jnp.any(hit, axis=1).astype(jnp.float32), mask)


# ----------------------------------------------------------------------------- goal distance
def is_stand_up(action: str) -> bool:
    """Whether an action label or instruction is "stand up" (anchor = first frame).

    True for ``"stand_up"``, ``"stand up"`` and any text starting with "stand up"
    (case-insensitive), e.g. "Stand up from the chair".
    """
    return str(action).strip().lower().replace("_", " ").startswith("stand up")


def anchor_index(mask, action: str = ""):
    """Anchor frame of HUMANISE: the last valid frame, the first one for "stand up".

    Args:
      mask: ``[T]`` bool valid frames (``jnp.ones(T, bool)`` when all are valid).
      action: action label ("walk", "sit", "stand_up", "lie") or the instruction
        text; static (a Python string).
    Returns:
      int32 scalar frame index. With no valid frame: ``ValueError`` eagerly;
      under ``jit`` the first/last frame.
    """
    mask = jnp.asarray(mask).astype(bool)
    if mask.ndim != 1 or mask.shape[0] == 0:
        raise ValueError(f"mask must be a non-empty [T] array, got shape {mask.shape}")
    require_any(mask, "mask selects no frame: there is no anchor frame")
    return _anchor(mask, first=is_stand_up(action))


@partial(jax.jit, static_argnames=("first",))
def _anchor(mask, first):
    if first:
        return jnp.argmax(mask).astype(jnp.int32)
    return (mask.shape[0] - 1 - jnp.argmax(mask[::-1])).astype(jnp.int32)


@jax.jit
def min_penetration_gap(s, target_mask):
    """``min_o max(0, −s(o))`` over the (masked) target points; NaN if none."""
    gap = jnp.maximum(-s, 0.0)
    if target_mask is None:
        return jnp.min(gap)
    best = jnp.min(jnp.where(target_mask, gap, jnp.inf))
    return jnp.where(jnp.any(target_mask), best, jnp.nan)


def check_target(target_points, target_mask):
    target_points = jnp.asarray(target_points, jnp.float32)
    if target_points.ndim != 2 or target_points.shape[-1] != 3:
        raise ValueError(f"target_points must be [M, 3], got shape {target_points.shape}")
    require_nonempty(target_points, "target_points", "the target object has no points")
    target_mask = as_mask(target_mask, target_points.shape[0], "target_mask")
    require_any(target_mask, "target_mask selects no point: the target object is empty")
    return target_points, target_mask


def goal_distance(target_points, vertices, normals, *, target_mask=None, **chunks):
    """Goal distance of one body pose: ``min_o max(0, −s(o))`` over target-object points.

    ``s`` is :func:`signed_distance_to_body` (positive inside), so the result is
    the gap between body and object in metres, 0 when they touch or overlap.

    Args:
      target_points: ``[M, 3]`` points of the target object (M ≥ 1).
      vertices, normals: ``[V, 3]`` body at the anchor frame (see :func:`anchor_index`).
      target_mask: ``[M]`` valid target points (padding), or None.
    """
    target_points, target_mask = check_target(target_points, target_mask)
    s = signed_distance_to_body(target_points, vertices, normals, **chunks)
    return min_penetration_gap(s, target_mask)


def anchor_goal_distance(target_points, vertices, normals, mask=None, action: str = "", **kw):
    """:func:`goal_distance` at the anchor frame of a motion: ``[M,3], [T,V,3], [T,V,3] -> ()``."""
    vertices = jnp.asarray(vertices, jnp.float32)
    if vertices.ndim != 3:
        raise ValueError(f"vertices must be [T, V, 3], got shape {vertices.shape}")
    if mask is None:
        mask = jnp.ones(vertices.shape[0], bool)
    a = anchor_index(mask, action)
    return goal_distance(target_points, vertices[a], jnp.asarray(normals)[a], **kw)
