"""Training loss of x0-prediction diffusion with condition dropout.

``denoise_fn(x_t, t, cond) -> x0_hat`` is any pure function: ``x_t`` is
``[B, ...]``, ``t`` is ``[B]`` int32 in ``[0, T)``, ``cond`` is a pytree whose
leaves all have the leading batch axis ``B`` (or ``None`` for an
unconditional model).

Condition dropout (classifier-free guidance, Ho & Salimans 2022): each example
keeps its condition with probability ``1 − p``; a dropped condition is
replaced by the *null condition*. When ``cond`` is a mapping (``{"text": …,
"affordance": …}``) every top-level entry is dropped independently, as the
affordance paper drops text and affordance independently; any other pytree is
dropped as a whole. The null condition is

- ``None``: zeros of the condition's shapes and dtypes (the papers' choice);
- a callable ``null_cond(cond) -> pytree`` of the same structure and shapes;
- a pytree of the same structure whose leaves broadcast to the condition's
  leaves (e.g. an unbatched learned "empty text" embedding ``[D]``).

Masks follow the *prefix rule*: a mask of shape ``[B, T]`` for data
``[B, T, D]`` gets trailing singleton axes appended (one flag per frame covers
all its features); a mask of the full data shape works too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import jax
import jax.numpy as jnp

from jaxmotion.diffusion.schedules import Schedule, q_sample

__all__ = [
    "diffusion_loss",
    "drop_condition",
    "expand_mask",
    "masked_mean",
    "null_condition",
]


def expand_mask(mask, ndim: int):
    """Append trailing singleton axes to ``mask`` until it has rank ``ndim`` (prefix rule)."""
    mask = jnp.asarray(mask)
    if mask.ndim > ndim:
        raise ValueError(f"mask of rank {mask.ndim} cannot cover data of rank {ndim}")
    return mask.reshape(mask.shape + (1,) * (ndim - mask.ndim))


def null_condition(cond, null_cond=None):
    """The null condition for ``cond`` with the same structure, shapes and dtypes.

    Args:
      cond: condition pytree, leaves ``[B, ...]``.
      null_cond: ``None`` (zeros), a callable ``cond -> pytree``, or a pytree whose
        leaves broadcast to ``cond``'s leaves.
    """
    if cond is None:
        return None
    if null_cond is None:
        return jax.tree.map(jnp.zeros_like, cond)
    null = null_cond(cond) if callable(null_cond) else null_cond
    return jax.tree.map(
        lambda c, n: jnp.broadcast_to(jnp.asarray(n, dtype=c.dtype), c.shape), cond, null
    )


def _select(keep, cond, null):
    """Per-example ``where(keep, cond, null)`` over matching pytrees; keep is ``[B]`` bool."""
    return jax.tree.map(lambda c, n: jnp.where(expand_mask(keep, c.ndim), c, n), cond, null)


def drop_condition(key, cond, drop_prob, null_cond=None, *, batch_size: int | None = None):
    """Replace the condition of randomly chosen examples by the null condition.

    Args:
      key: PRNG key.
      cond: condition pytree with leaves ``[B, ...]``; a mapping drops each top-level
        entry independently, anything else as a whole. ``None`` passes through.
      drop_prob: probability ``p`` that an example's condition (entry) is dropped.
      null_cond: see :func:`null_condition`.
      batch_size: ``B``; read from the first leaf when omitted.
    Returns:
      ``(new_cond, keep)`` where ``keep`` is ``[B]`` bool (whole pytree) or a dict of
      ``[B]`` bool per top-level entry (mapping).
    """
    if cond is None:
        return None, None
    leaves = jax.tree.leaves(cond)
    if batch_size is None:
        if not leaves:
            return cond, None
        batch_size = leaves[0].shape[0]
    null = null_condition(cond, null_cond)
    keep_prob = 1.0 - jnp.asarray(drop_prob, jnp.float32)
    if isinstance(cond, Mapping):
        # Entry i of the sorted names draws from fold_in(key, i): the draws do not
        # depend on the mapping's insertion order.
        index = {name: i for i, name in enumerate(sorted(cond))}
        keep = {
            name: jax.random.bernoulli(jax.random.fold_in(key, i), keep_prob, (batch_size,))
            for name, i in index.items()
        }
        out = {name: _select(keep[name], cond[name], null[name]) for name in cond}  # input order
        return (out if type(cond) is dict else type(cond)(out)), keep
    keep = jax.random.bernoulli(key, keep_prob, (batch_size,))
    return _select(keep, cond, null), keep


def masked_mean(err, mask=None):
    """Mean of ``err [B, ...]`` over valid entries (mask by the prefix rule); 0 if none valid."""
    if mask is None:
        return jnp.mean(err)
    m = jnp.broadcast_to(expand_mask(mask, err.ndim), err.shape).astype(err.dtype)
    return jnp.sum(err * m) / jnp.maximum(jnp.sum(m), 1.0)


def diffusion_loss(
    key,
    denoise_fn: Callable,
    schedule: Schedule,
    x0,
    cond=None,
    mask=None,
    *,
    cond_drop_prob: float = 0.1,
    null_cond=None,
    t=None,
    loss_type: str = "mse",
    feature_weights=None,
    return_aux: bool = False,
):
    """Masked x0-prediction loss ``E_{t,ε} ‖x0_hat(x_t, t, c) − x0‖²``, condition dropout.

    Draws ``t ~ U{0, …, T−1}`` and ``ε ~ N(0, I)`` per example, noises ``x0`` with
    :func:`q_sample`, drops conditions (:func:`drop_condition`) and averages the
    squared error over the valid entries of the whole batch.

    Args:
      key: PRNG key (split into t, noise and dropout keys).
      denoise_fn: ``(x_t [B, ...], t [B] int32, cond) -> x0_hat [B, ...]``.
      schedule: :class:`Schedule` with ``T`` steps.
      x0: clean data ``[B, ...]`` (e.g. motion ``[B, T, D]``).
      cond: condition pytree with leaves ``[B, ...]``, or ``None``.
      mask: validity mask, prefix of ``x0``'s shape (e.g. frame mask ``[B, T]``);
        masked entries contribute nothing. ``None``: all valid.
      cond_drop_prob: dropout probability ``p`` (0 disables dropout).
      null_cond: null condition, see :func:`null_condition`.
      t: optional fixed timesteps ``[B]`` (e.g. validation on a grid) instead of random ones.
      loss_type: ``"mse"`` (the affordance paper) or ``"l1"`` (the object-centric paper).
      feature_weights: optional weights broadcasting over the last axis of ``x0``
        (e.g. pose weight 10); the mean stays over valid entries.
      return_aux: also return a dict with ``t``, ``x_t``, ``x0_hat`` and ``keep``.
    Returns:
      scalar float32 loss, or ``(loss, aux)``.
    """
    if loss_type not in ("mse", "l1"):
        raise ValueError(f"loss_type must be 'mse' or 'l1', got {loss_type!r}")
    batch = x0.shape[0]
    k_t, k_noise, k_drop = jax.random.split(key, 3)
    if t is None:
        t = jax.random.randint(k_t, (batch,), 0, schedule.num_steps, dtype=jnp.int32)
    t = jnp.asarray(t, jnp.int32)
    noise = jax.random.normal(k_noise, x0.shape, x0.dtype)
    x_t = q_sample(schedule, x0, t, noise)
    keep = None
    if cond is not None and not (isinstance(cond_drop_prob, (int, float)) and cond_drop_prob == 0):
        cond, keep = drop_condition(k_drop, cond, cond_drop_prob, null_cond, batch_size=batch)
    x0_hat = denoise_fn(x_t, t, cond)
    if x0_hat.shape != x0.shape:
        raise ValueError(f"denoise_fn returned shape {x0_hat.shape}, expected {x0.shape}")
    diff = x0_hat - x0
    err = diff * diff if loss_type == "mse" else jnp.abs(diff)
    if feature_weights is not None:
        err = err * jnp.asarray(feature_weights, err.dtype)
    loss = masked_mean(err, mask)
    if return_aux:
        return loss, {"t": t, "x_t": x_t, "x0_hat": x0_hat, "keep": keep}
    return loss
