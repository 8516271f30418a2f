"""Small helpers shared by the metric modules: masks, masked means, emptiness checks.

Empty inputs are handled in two ways, on purpose:

- an axis of size zero (no frames, no target points) is a static shape, so it
  raises :class:`ValueError` always, also under ``jit``;
- a mask that selects nothing raises :class:`ValueError` when the function is
  called eagerly with a concrete mask, and gives ``NaN`` (the mean of an empty
  set) under ``jit`` / ``vmap``, where raising is impossible.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def is_concrete(x) -> bool:
    """True when ``x`` holds values (not a tracer inside ``jit`` / ``vmap``)."""
    return not isinstance(x, jax.core.Tracer)


def as_mask(mask, n: int, name: str):
    """``None`` or a ``[n]`` bool array; checks the length."""
    if mask is None:
        return None
    mask = jnp.asarray(mask)
    if mask.shape != (n,):
        raise ValueError(f"{name} must have shape [{n}], got {mask.shape}")
    return mask.astype(bool)


def require_any(mask, message: str):
    """Raise ``ValueError(message)`` if a concrete mask selects nothing (no-op when traced)."""
    if mask is not None and is_concrete(mask) and not bool(np.any(np.asarray(mask))):
        raise ValueError(message)


def require_nonempty(x, name: str, what: str):
    """Raise ``ValueError`` when the leading axis of ``x`` has size zero."""
    if x.shape[0] == 0:
        raise ValueError(f"{name} is empty: {what}")


def masked_mean(values, mask):
    """Mean of ``values[T]`` over ``mask[T]`` (all when None); NaN when the mask is empty."""
    values = jnp.asarray(values, jnp.float32)
    if mask is None:
        return jnp.mean(values)
    w = mask.astype(values.dtype)
    count = jnp.sum(w)
    total = jnp.sum(jnp.where(mask, values, 0.0))
    return jnp.where(count > 0, total / jnp.maximum(count, 1.0), jnp.nan)


def safe_norm(x, axis=-1):
    """Euclidean norm with a finite gradient at zero."""
    sq = jnp.sum(x * x, axis=axis)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def padded_rows(n: int) -> int:
    """Rows a chunk of ``n`` is padded to: a power of two, at least 8 (few compiled shapes)."""
    return max(8, 1 << max(0, n - 1).bit_length())


def run_in_chunks(fn, state, arrays, batch_size: int) -> np.ndarray:
    """``fn(state, *rows)`` over ``arrays`` (leading axis B) in chunks of ``batch_size``, each
    padded to :func:`padded_rows` by repeating its last row (a valid input, whose outputs are
    dropped): float32 numpy ``[B, ...]``, one compiled shape per padded chunk size."""
    n = arrays[0].shape[0]
    out = []
    for s in range(0, n, batch_size):
        part = [a[s:s + batch_size] for a in arrays]
        pad = padded_rows(len(part[0])) - len(part[0])
        part = [np.concatenate([a, np.repeat(a[-1:], pad, 0)]) for a in part]
        out.append(np.asarray(fn(state, *part))[: len(part[0]) - pad])
    return np.concatenate(out).astype(np.float32)


def motion_batch(joints, mask=None, *, multiple: int = 32):
    """A batch of motions checked and padded for a jitted motion network (host-side numpy):
    ``joints [B, T, 22, 3]`` (B ≥ 1, finite on valid frames) and a prefix ``mask [B, T]``
    (None: every frame valid) -> both padded in T to a multiple of ``multiple`` (few compiled
    shapes; padded frames are invalid). ``ValueError`` names what is wrong."""
    joints = np.asarray(joints, np.float32)
    if joints.ndim != 4 or joints.shape[2:] != (22, 3) or joints.shape[0] == 0:
        raise ValueError(f"joints must be [B, T, 22, 3] with B >= 1, got {joints.shape}")
    b, t = joints.shape[:2]
    mask = np.ones((b, t), bool) if mask is None else np.asarray(mask)
    if mask.shape != (b, t):
        raise ValueError(f"mask must be [B, T] = {(b, t)} like joints, got {mask.shape}")
    mask = mask.astype(bool)
    n = mask.sum(1)
    if (n == 0).any() or not all(mask[i, : n[i]].all() for i in range(b)):
        raise ValueError("every mask row needs valid frames first (a non-empty prefix)")
    if not np.isfinite(joints[mask]).all():
        raise ValueError("joints contain NaN or inf in valid frames")
    pad = -t % multiple
    joints = np.pad(joints, ((0, 0), (0, pad), (0, 0), (0, 0)))
    mask = np.pad(mask, ((0, 0), (0, pad)))
    return joints, mask


def sample_sets(gen_joints, gen_mask, n: int, of: str):
    """Generated motions as K sample sets of the N cases: ``(joints [N, K, T, 22, 3], mask
    [N, K, T])`` from those shapes or from ``[N, T, 22, 3]`` / ``[N, T]`` (K = 1);
    :class:`ValueError` naming the shapes otherwise (``of``: what the N are, e.g. "texts")."""
    gen_joints, gen_mask = np.asarray(gen_joints), np.asarray(gen_mask)
    if gen_joints.ndim == 4:
        gen_joints, gen_mask = gen_joints[:, None], gen_mask[:, None]
    if gen_joints.ndim != 5 or gen_joints.shape[0] != n or gen_mask.shape != gen_joints.shape[:3]:
        raise ValueError(f"for {n} {of} gen_joints must be [N, T, 22, 3] or [N, K, T, 22, 3] "
                         f"with gen_mask [N, T] or [N, K, T]; got {gen_joints.shape} and "
                         f"{gen_mask.shape}")
    return gen_joints, gen_mask


def seed_of(rng) -> int:
    """An int seed from an int or a :class:`numpy.random.Generator` (one draw from it)."""
    return int(rng.integers(2**62) if isinstance(rng, np.random.Generator) else rng)
