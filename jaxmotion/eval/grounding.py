"""Grounding metrics: affordance maps against the target object, target-object choice.

Affordance grounding ("Move as You Say, Interact as You Can", Tab. 5). With a
predicted distance field ``d[N, C]`` (per scene point and affordance joint, the
channels of :data:`jaxmotion.geometry.AFFORDANCE_JOINTS`, pelvis first) and the
target mask ``T`` (the scene points of the target's class)::

    min_dist    = mean_{n∈T} min_j d[n, j]
    pelvis_dist = mean_{n∈T} d[n, pelvis]
    all_dist    = mean_{n∈T, j} d[n, j]
    success@δ   = [ min_{n∈T, j} d[n, j] < δ ],   δ ∈ {0.1, 0.3, 0.5} m

All in metres; success is 0/1 per case (average over cases for a rate). A
predicted affordance map ``a`` is first inverted as the authors' code does:
``d = sqrt(−2σ² ln clip(a, 1e-20, 1))`` (de-normalise z-scored maps first).

Target-object grounding accuracy (object-centric pipeline): the fraction of
cases whose predicted target instance id equals the true one.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from jaxmotion.eval._common import as_mask, require_any
from jaxmotion.geometry.affordance import AFFORDANCE_SIGMA, affordance_to_distance

__all__ = [
    "SUCCESS_THRESHOLDS",
    "affordance_grounding",
    "affordance_grounding_from_map",
    "grounding_accuracy",
]

#: Success thresholds δ of the affordance grounding table, metres.
SUCCESS_THRESHOLDS: tuple[float, ...] = (0.1, 0.3, 0.5)


def affordance_grounding(
    distance, target_mask, *, thresholds=SUCCESS_THRESHOLDS, pelvis_channel: int = 0
):
    """Affordance grounding metrics of one case (formulas in the module docstring).

    Args:
      distance: ``[N, C]`` predicted point–joint distances, metres.
      target_mask: ``[N]`` bool, True on the target's points; padding points False.
      thresholds: success thresholds δ (static), metres.
      pelvis_channel: channel of the pelvis in ``distance``.
    Returns:
      dict of float32 scalars: ``min_dist``, ``pelvis_dist``, ``all_dist`` and
      ``success@0.1`` etc. (key ``f"success@{δ:g}"``). An empty target mask raises
      ``ValueError`` eagerly and gives NaN (success 0) under ``jit`` / ``vmap``.
    """
    d = jnp.asarray(distance, jnp.float32)
    if d.ndim != 2 or d.shape[1] == 0:
        raise ValueError(f"distance must be [N, C] with C >= 1, got shape {d.shape}")
    if not 0 <= pelvis_channel < d.shape[1]:
        raise ValueError(f"pelvis_channel {pelvis_channel} out of range for C = {d.shape[1]}")
    mask = as_mask(target_mask, d.shape[0], "target_mask")
    require_any(mask, "target_mask selects no point: the target object is empty")
    thresholds = tuple(float(x) for x in thresholds)
    return _grounding(d, mask, thresholds=thresholds, pelvis_channel=int(pelvis_channel))


@partial(jax.jit, static_argnames=("thresholds", "pelvis_channel"))
def _grounding(d, mask, thresholds, pelvis_channel):
    count = jnp.sum(mask)
    nan_if_empty = jnp.where(count > 0, 1.0, jnp.nan)
    denom = jnp.maximum(count, 1).astype(jnp.float32)

    def mean_over_target(v):  # [N] -> ()
        return jnp.sum(jnp.where(mask, v, 0.0)) / denom * nan_if_empty

    per_point_min = jnp.min(d, axis=1)
    best = jnp.min(jnp.where(mask, per_point_min, jnp.inf))
    out = {
        "min_dist": mean_over_target(per_point_min),
        "pelvis_dist": mean_over_target(d[:, pelvis_channel]),
        "all_dist": mean_over_target(jnp.mean(d, axis=1)),
    }
    for delta in thresholds:
        out[f"success@{delta:g}"] = (best < delta).astype(jnp.float32)
    return out


def affordance_grounding_from_map(affordance, target_mask, *, sigma=AFFORDANCE_SIGMA, **kwargs):
    """:func:`affordance_grounding` of an affordance map ``a[N, C]`` in [0, 1].

    Converts with ``d = sqrt(−2σ² ln clip(a, 1e-20, 1))`` (σ = 0.8 m); pass the
    de-normalised map (not z-scores).
    """
    return affordance_grounding(affordance_to_distance(affordance, sigma), target_mask, **kwargs)


def grounding_accuracy(pred_ids, true_ids, mask=None):
    """Target-object grounding accuracy: ``mean_b [pred_ids[b] == true_ids[b]]`` in [0, 1].

    Args:
      pred_ids, true_ids: ``[B]`` integer instance ids (a failed prediction can
        be any id that matches no object, e.g. −1).
      mask: ``[B]`` valid cases, or None.
    """
    pred = jnp.asarray(pred_ids)
    true = jnp.asarray(true_ids)
    if pred.ndim != 1 or pred.shape != true.shape:
        raise ValueError(f"pred_ids and true_ids must both be [B], got {pred.shape}, {true.shape}")
    if pred.shape[0] == 0:
        raise ValueError("no cases: pred_ids is empty")
    mask = as_mask(mask, pred.shape[0], "mask")
    require_any(mask, "mask selects no case")
    hit = (pred == true).astype(jnp.float32)
    if mask is None:
        return jnp.mean(hit)
    n = jnp.sum(mask)
    return jnp.where(n > 0, jnp.sum(jnp.where(mask, hit, 0.0)) / jnp.maximum(n, 1), jnp.nan)
