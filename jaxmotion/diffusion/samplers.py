"""Samplers of x0-prediction diffusion: ancestral DDPM and DDIM, with guidance.

All samplers are pure functions of ``denoise_fn(x_t, t, cond) -> x0_hat``
(``x_t`` ``[B, ...]``, ``t`` ``[B]`` int32, ``cond`` a pytree of ``[B, ...]``
leaves or ``None``). Loops are ``jax.lax.scan``; shapes and step counts are
static, so the caller jits a sampler once (``denoise_fn``, ``shape``,
``num_steps``, ``spacing``, ``clip_fn``, ``refine_fn`` and ``known_mode`` static; ``key``,
``schedule``, ``cond``, ``eta``, ``guidance_scale`` may be traced) and can
``vmap`` it over keys, conditions or batches.

Randomness: ``key`` is split into an initial-noise key and a step key; the
noise added when leaving timestep ``t`` is drawn from ``fold_in(step_key, t)``
(keyed by the timestep, not the loop index), so DDIM with all ``T`` steps and
``eta = 1`` uses exactly DDPM's noise and follows the same path for the same key.

Per-step updates (``t_prev`` is the next, smaller timestep; ``−1`` = clean data,
``ᾱ_{−1} = 1``; ``ε̂ = (x_t − √ᾱ_t x̂0) / √(1 − ᾱ_t)``):

- DDPM (Ho et al. 2020): ``x_{t−1} = c1_t x̂0 + c2_t x_t + σ_t z`` with the
  posterior variance ``σ_t² = β̃_t`` (clipped-log form) and no noise at ``t = 0``.
- DDIM (Song et al. 2021, eq. 12 and 16):
  ``x_prev = √ᾱ_prev x̂0 + √(1 − ᾱ_prev − σ²) ε̂ + σ z`` with
  ``σ² = η² (1 − ᾱ_prev)/(1 − ᾱ_t) · (1 − ᾱ_t/ᾱ_prev)``. With ``η = 1`` and
  ``t_prev = t − 1`` this is exactly DDPM's posterior mean and variance. The
  direction coefficient is evaluated in the cancellation-free form
  ``1 − ᾱ_prev − σ² = (1 − ᾱ_prev)/(1 − ᾱ_t) · [(1 − η²)(1 − ᾱ_t) + η² r (1 − ᾱ_prev)]``
  with ``r = ᾱ_t/ᾱ_prev``, ratios taken from ``log_alphas_cumprod``.

DDIM timesteps (:func:`ddim_timesteps`): ``"linspace"`` (default) takes ``S``
evenly spaced steps from ``0`` to ``T − 1`` inclusive, rounded half up (as
guided-diffusion's ``space_timesteps``); it always starts at ``T − 1``, where
``ᾱ ≈ 0`` matches the pure-noise start, and ``S = T`` gives every step.
``"leading"`` is the DDIM paper's ``0, k, 2k, …`` with ``k = T // S``.

Classifier-free guidance (Ho & Salimans 2022) with scale ``w``:
``x̂0 = x̂0(c̸) + w (x̂0(c) − x̂0(c̸))``, both evaluated in one ``denoise_fn``
call on the doubled batch ``[x; x]`` with ``[cond; null_cond]``. ``w = 1`` (a
Python number) skips the unconditional half. The null condition for a mapping
condition nulls every entry (see :func:`jaxmotion.diffusion.losses.null_condition`).

Known values (inpainting, trajectory conditioning): ``known_mask`` (prefix rule
or full shape) and ``known_values`` ``[B, ...]``. Mode ``"x0"`` (MDM's
inpainting) overwrites the known entries of ``x̂0`` before every update; mode
``"noised"`` (replacement / RePaint without resampling) overwrites the known
entries of each new ``x_prev`` by the values noised to that level. Either way
the returned sample carries the known values exactly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.diffusion.losses import expand_mask, null_condition
from jaxmotion.diffusion.schedules import Schedule, gather, q_posterior

__all__ = [
    "ddim_posterior",
    "ddim_sample",
    "ddim_timesteps",
    "ddpm_posterior",
    "ddpm_sample",
    "guided_denoise",
    "sample",
]

_SPACINGS = ("linspace", "leading")
_KNOWN_MODES = ("x0", "noised")


def ddim_timesteps(num_train_steps: int, num_steps: int, spacing: str = "linspace") -> np.ndarray:
    """The ``S`` timesteps DDIM visits, ascending int32 NumPy ``[S]`` (see module docstring)."""
    T, S = int(num_train_steps), int(num_steps)
    if not 1 <= S <= T:
        raise ValueError(f"num_steps must be in [1, {T}] for a {T}-step schedule, got {S}")
    if spacing == "linspace":
        ts = np.array([T - 1]) if S == 1 else np.floor(np.linspace(0, T - 1, S) + 0.5)
    elif spacing == "leading":
        ts = np.arange(S) * (T // S)
    else:
        raise ValueError(f"spacing must be one of {_SPACINGS}, got {spacing!r}")
    ts = ts.astype(np.int32)
    assert np.all(np.diff(ts) > 0), ts  # strictly increasing by construction
    return ts


def _is_one(w) -> bool:
    return isinstance(w, (int, float)) and float(w) == 1.0


def guided_denoise(denoise_fn: Callable, x, t, cond, *, guidance_scale=1.0, null_cond=None):
    """``x0_hat`` with classifier-free guidance.

    Args:
      denoise_fn: ``(x [B, ...], t [B], cond) -> x0_hat [B, ...]``.
      x: ``[B, ...]``; t: ``[B]`` int32; cond: pytree of ``[B, ...]`` or ``None``.
      guidance_scale: ``w``; a Python ``1`` (or ``cond is None``) makes one plain call,
        anything else one call on the doubled batch ``2B``.
      null_cond: see :func:`jaxmotion.diffusion.losses.null_condition`.
    Returns:
      ``x0_u + w (x0_c − x0_u)``, ``[B, ...]``.
    """
    if cond is None or _is_one(guidance_scale):
        return denoise_fn(x, t, cond)
    b = x.shape[0]
    null = null_condition(cond, null_cond)
    both = jax.tree.map(lambda c, n: jnp.concatenate([c, n], axis=0), cond, null)
    out = denoise_fn(jnp.concatenate([x, x], 0), jnp.concatenate([t, t], 0), both)
    x0_c, x0_u = out[:b], out[b:]
    return x0_u + jnp.asarray(guidance_scale, out.dtype) * (x0_c - x0_u)


def ddpm_posterior(schedule: Schedule, x_t, t, x0_hat):
    """DDPM step ``x_t → x_{t−1}``: mean and standard deviation of ``q(x_{t−1} | x_t, x̂0)``.

    Args:
      x_t, x0_hat: ``[B, ...]``; t: ``[B]`` int32.
    Returns:
      ``(mean [B, ...], std [B, 1, …])``; ``std = 0`` where ``t = 0``.
    """
    mean, _, log_var = q_posterior(schedule, x0_hat, x_t, t)
    t_b = expand_mask(t, x_t.ndim)
    return mean, jnp.where(t_b > 0, jnp.exp(0.5 * log_var), 0.0)


def ddim_posterior(schedule: Schedule, x_t, t, t_prev, x0_hat, eta=0.0):
    """DDIM step ``x_t → x_{t_prev}``: mean and standard deviation (module docstring).

    Args:
      x_t, x0_hat: ``[B, ...]``; t: ``[B]`` int32; t_prev: ``[B]`` int32 ``< t``
        (``−1`` = clean data); eta: ``η ≥ 0`` (0 deterministic, 1 DDPM-like).
    Returns:
      ``(mean [B, ...], std [B, 1, …])``.
    """
    nd = x_t.ndim
    has_prev = expand_mask(t_prev >= 0, nd)
    tp = jnp.maximum(t_prev, 0)
    sqrt_ab = gather(schedule.sqrt_alphas_cumprod, t, nd)
    sqrt_1m_ab = gather(schedule.sqrt_one_minus_alphas_cumprod, t, nd)
    sqrt_ab_prev = jnp.where(has_prev, gather(schedule.sqrt_alphas_cumprod, tp, nd), 1.0)
    sqrt_1m_ab_prev = gather(schedule.sqrt_one_minus_alphas_cumprod, tp, nd)
    one_m_ab_prev = jnp.where(has_prev, sqrt_1m_ab_prev**2, 0.0)
    one_m_ab = sqrt_1m_ab**2
    log_ratio = gather(schedule.log_alphas_cumprod, t, nd) - jnp.where(
        has_prev, gather(schedule.log_alphas_cumprod, tp, nd), 0.0
    )  # log(ᾱ_t / ᾱ_prev) ≤ 0
    eta2 = jnp.asarray(eta, x_t.dtype) ** 2
    var = eta2 * one_m_ab_prev / one_m_ab * -jnp.expm1(log_ratio)
    dir2 = one_m_ab_prev / one_m_ab * (
        (1.0 - eta2) * one_m_ab + eta2 * jnp.exp(log_ratio) * one_m_ab_prev
    )
    eps_hat = (x_t - sqrt_ab * x0_hat) / sqrt_1m_ab
    mean = sqrt_ab_prev * x0_hat + jnp.sqrt(jnp.maximum(dir2, 0.0)) * eps_hat
    return mean, jnp.sqrt(var)


def _reverse_loop(
    key, denoise_fn, schedule, shape, cond, ts, posterior, *,
    guidance_scale, null_cond, clip_fn, known_mask, known_values, known_mode, x_init,
    refine_fn=None,
):
    """Shared scan over descending timesteps ``ts`` (NumPy ascending ``[S]``)."""
    if known_mode not in _KNOWN_MODES:
        raise ValueError(f"known_mode must be one of {_KNOWN_MODES}, got {known_mode!r}")
    if (known_mask is None) != (known_values is None):
        raise ValueError("give both known_mask and known_values, or neither")
    if x_init is None and shape is None:
        raise ValueError("give shape or x_init")
    if x_init is not None and shape is not None and tuple(x_init.shape) != tuple(shape):
        raise ValueError(f"x_init has shape {x_init.shape}, expected {tuple(shape)}")
    k_init, k_steps = jax.random.split(key)
    x = jax.random.normal(k_init, tuple(shape), jnp.float32) if x_init is None else x_init
    b, nd = x.shape[0], x.ndim
    known = known_mask is not None
    if known:
        m = jnp.broadcast_to(expand_mask(known_mask, nd), x.shape).astype(bool)
        v = jnp.broadcast_to(jnp.asarray(known_values, x.dtype), x.shape)

    def noised_known(x, level, k):  # known entries := values at noise level `level` (−1 = clean)
        has = expand_mask(level >= 0, nd)
        lv = jnp.maximum(level, 0)
        a = jnp.where(has, gather(schedule.sqrt_alphas_cumprod, lv, nd), 1.0)
        s = jnp.where(has, gather(schedule.sqrt_one_minus_alphas_cumprod, lv, nd), 0.0)
        return jnp.where(m, a * v + s * jax.random.normal(k, x.shape, x.dtype), x)

    ts_desc = jnp.asarray(ts[::-1], jnp.int32)
    prev_desc = jnp.asarray(np.concatenate([[-1], ts[:-1]])[::-1], jnp.int32)
    if known and known_mode == "noised":
        x = noised_known(x, jnp.full((b,), ts[-1], jnp.int32), jax.random.fold_in(k_init, 1))

    def body(x, step):
        t, t_prev = step
        tb = jnp.full((b,), t, jnp.int32)
        tpb = jnp.full((b,), t_prev, jnp.int32)
        x0_hat = guided_denoise(
            denoise_fn, x, tb, cond, guidance_scale=guidance_scale, null_cond=null_cond
        )
        if clip_fn is not None:
            x0_hat = clip_fn(x0_hat)
        if refine_fn is not None:
            x0_hat = refine_fn(x0_hat, tb)
        if known and known_mode == "x0":
            x0_hat = jnp.where(m, v, x0_hat)
        mean, std = posterior(x, tb, tpb, x0_hat)
        k = jax.random.fold_in(k_steps, t)
        x = mean + std * jax.random.normal(k, x.shape, x.dtype)
        if known and known_mode == "noised":
            x = noised_known(x, tpb, jax.random.fold_in(k, 1))
        return x, None

    x, _ = jax.lax.scan(body, x, (ts_desc, prev_desc))
    if known:
        x = jnp.where(m, v, x)
    return x


def ddpm_sample(
    key, denoise_fn: Callable, schedule: Schedule, shape=None, cond=None, *,
    guidance_scale=1.0, null_cond=None, clip_fn: Callable | None = None,
    known_mask=None, known_values=None, known_mode: str = "x0", x_init=None,
    refine_fn: Callable | None = None,
):
    """Ancestral DDPM sampling through all ``T`` steps.

    Args:
      key: PRNG key.
      denoise_fn: ``(x [B, ...], t [B] int32, cond) -> x0_hat [B, ...]``.
      schedule: :class:`Schedule` (``T`` steps).
      shape: output shape ``(B, ...)`` (static); may be omitted when ``x_init`` is given.
      cond: condition pytree of ``[B, ...]`` leaves, or ``None``.
      guidance_scale: classifier-free guidance scale ``w`` (see :func:`guided_denoise`).
      null_cond: null condition for guidance.
      clip_fn: optional ``x0_hat -> x0_hat`` (e.g. clipping to the data range) applied
        before each update.
      known_mask, known_values: optional known entries (prefix-rule mask, values ``[B, ...]``).
      known_mode: ``"x0"`` or ``"noised"`` (module docstring).
      x_init: optional starting ``x_{T−1}`` ``[B, ...]`` instead of fresh noise.
      refine_fn: optional ``(x0_hat [B, ...], t [B]) -> x0_hat`` applied after ``clip_fn``
        at every step (guidance that edits the clean estimate, e.g.
        :func:`jaxmotion.diffusion.affordance_guidance.make_x0_refiner`).
    Returns:
      samples ``[B, ...]`` float32.
    """
    ts = np.arange(schedule.num_steps, dtype=np.int32)
    post = lambda x, t, t_prev, x0: ddpm_posterior(schedule, x, t, x0)  # noqa: E731
    return _reverse_loop(
        key, denoise_fn, schedule, shape, cond, ts, post, guidance_scale=guidance_scale,
        null_cond=null_cond, clip_fn=clip_fn, known_mask=known_mask,
        known_values=known_values, known_mode=known_mode, x_init=x_init, refine_fn=refine_fn,
    )


def ddim_sample(
    key, denoise_fn: Callable, schedule: Schedule, shape=None, cond=None, *,
    num_steps: int = 50, eta=0.0, spacing: str = "linspace",
    guidance_scale=1.0, null_cond=None, clip_fn: Callable | None = None,
    known_mask=None, known_values=None, known_mode: str = "x0", x_init=None,
    refine_fn: Callable | None = None,
):
    """DDIM sampling with ``num_steps`` ``S ≤ T`` steps and stochasticity ``eta``.

    Args:
      num_steps: ``S`` (static), the number of ``denoise_fn`` evaluations.
      eta: ``η`` (0: deterministic; 1: DDPM's posterior variance when ``S = T``).
      spacing: ``"linspace"`` or ``"leading"`` (:func:`ddim_timesteps`).
      Other arguments as :func:`ddpm_sample`.
    Returns:
      samples ``[B, ...]`` float32.
    """
    ts = ddim_timesteps(schedule.num_steps, num_steps, spacing)
    post = lambda x, t, t_prev, x0: ddim_posterior(schedule, x, t, t_prev, x0, eta)  # noqa: E731
    return _reverse_loop(
        key, denoise_fn, schedule, shape, cond, ts, post, guidance_scale=guidance_scale,
        null_cond=null_cond, clip_fn=clip_fn, known_mask=known_mask,
        known_values=known_values, known_mode=known_mode, x_init=x_init, refine_fn=refine_fn,
    )


def sample(key, denoise_fn, schedule, shape=None, cond=None, *, method: str = "ddpm",
           num_steps: int | None = None, eta=0.0, **kwargs):
    """Dispatch to :func:`ddpm_sample` (``method="ddpm"``) or :func:`ddim_sample` (``"ddim"``).

    ``num_steps`` is ignored by DDPM unless it differs from ``T`` (then an error);
    for DDIM ``None`` means all ``T`` steps.
    """
    if method == "ddpm":
        if num_steps not in (None, schedule.num_steps):
            raise ValueError(f"DDPM runs all {schedule.num_steps} steps; use method='ddim'")
        return ddpm_sample(key, denoise_fn, schedule, shape, cond, **kwargs)
    if method == "ddim":
        n = schedule.num_steps if num_steps is None else num_steps
        return ddim_sample(key, denoise_fn, schedule, shape, cond, num_steps=n, eta=eta, **kwargs)
    raise ValueError(f"method must be 'ddpm' or 'ddim', got {method!r}")


@dataclass(frozen=True)
class SamplerSpec:
    """How to sample one stage: ``method`` ddpm|ddim, ``steps`` (DDIM only), ``eta``,
    classifier-free ``guidance``, and ``consistency``: the strength in [0, 1] of
    affordance-consistency guidance (AMDM stage only; 0 = off; see
    :mod:`jaxmotion.diffusion.affordance_guidance`)."""

    method: str = "ddim"
    steps: int = 50
    eta: float = 0.0
    guidance: float = 1.0
    consistency: float = 0.0

    def __post_init__(self):
        if not 0.0 <= float(self.consistency) <= 1.0:
            raise ValueError(f"consistency must be in [0, 1] (0 = off), got {self.consistency}")

    def run(self, key, denoise, schedule, shape, cond, null_cond, refine_fn=None, *,
            known_mask=None, known_values=None):
        """Sample with this spec; ``known_mask`` / ``known_values`` hold entries fixed
        (inpainting in x0 mode, as :func:`ddim_sample`)."""
        kw = dict(cond=cond, guidance_scale=self.guidance, null_cond=null_cond,
                  refine_fn=refine_fn, known_mask=known_mask, known_values=known_values)
        if self.method == "ddpm":
            return ddpm_sample(key, denoise, schedule, shape, **kw)
        if self.method == "ddim":
            return ddim_sample(key, denoise, schedule, shape, num_steps=self.steps, eta=self.eta, **kw)
        raise ValueError(f"unknown sampler {self.method!r}; valid: ddpm, ddim")
