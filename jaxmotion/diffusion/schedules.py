"""Noise schedules and the forward process of Gaussian diffusion.

Notation (Ho et al. 2020, "DDPM"; Nichol & Dhariwal 2021, "Improved DDPM"). The
``T`` steps are indexed ``t = 0 … T−1``; ``x_t`` is the sample after ``t + 1``
noising steps and ``t = −1`` denotes clean data ``x_0`` (the index convention
of guided-diffusion and MDM, so the network's timestep input is ``t``)::

    β_t                       betas
    α_t   = 1 − β_t           alphas
    ᾱ_t   = ∏_{s ≤ t} α_s     alphas_cumprod
    ᾱ_{t−1}, ᾱ_{−1} := 1      alphas_cumprod_prev

    q(x_t | x_0)          = N(√ᾱ_t x_0, (1 − ᾱ_t) I)                        (forward)
    q(x_{t−1} | x_t, x_0) = N(c1_t x_0 + c2_t x_t, β̃_t I)                  (posterior)
        c1_t = β_t √ᾱ_{t−1} / (1 − ᾱ_t)              posterior_mean_coef1
        c2_t = (1 − ᾱ_{t−1}) √α_t / (1 − ᾱ_t)        posterior_mean_coef2
        β̃_t  = β_t (1 − ᾱ_{t−1}) / (1 − ᾱ_t)         posterior_variance (0 at t = 0)
        log β̃ clipped: log β̃_0 := log β̃_1           posterior_log_variance_clipped

Schedules:

- ``cosine`` (Nichol & Dhariwal 2021, eq. 17; the papers' choice):
  ``f(u) = cos²((u + s)/(1 + s) · π/2)``, ``s = 0.008``,
  ``β_t = min(1 − f((t+1)/T) / f(t/T), 0.999)``, hence
  ``ᾱ_t = f((t+1)/T) / f(0)`` wherever no clipping happened (always for
  ``t < T − 1``; the last beta is clipped to 0.999, so ``ᾱ_{T−1} ≈ 0``).
- ``linear`` (Ho et al. 2020, rescaled as in guided-diffusion so that any ``T``
  covers the same noise range): ``β_t = linspace(1e-4 k, 0.02 k, T)`` with
  ``k = 1000 / T`` (clipped at 0.999, which only matters for ``T ≤ 20``).

Every quantity is computed in float64 NumPy and stored as float32, so the
stored values are correctly rounded. ``log_alphas_cumprod`` is kept too: ratios
``ᾱ_t / ᾱ_s`` and ``1 − ᾱ_t / ᾱ_s`` (DDIM with strided steps) are evaluated
from it with ``exp`` / ``expm1`` without float32 cancellation.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "SCHEDULES",
    "Schedule",
    "cosine_betas",
    "gather",
    "linear_betas",
    "make_schedule",
    "q_posterior",
    "q_sample",
    "schedule_from_betas",
]

MAX_BETA = 0.999


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Schedule:
    """All per-step quantities of a diffusion schedule, float32 arrays of shape ``[T]``.

    A pytree (a frozen dataclass registered with JAX): pass it through ``jit``/``vmap`` as an
    ordinary argument. ``T`` is static (the arrays' shape), see :attr:`num_steps`.
    The formulas are in the module docstring.
    """

    betas: jax.Array
    alphas: jax.Array
    alphas_cumprod: jax.Array
    alphas_cumprod_prev: jax.Array
    log_alphas_cumprod: jax.Array
    sqrt_alphas_cumprod: jax.Array
    sqrt_one_minus_alphas_cumprod: jax.Array
    sqrt_recip_alphas_cumprod: jax.Array
    sqrt_recipm1_alphas_cumprod: jax.Array
    posterior_variance: jax.Array
    posterior_log_variance_clipped: jax.Array
    posterior_mean_coef1: jax.Array
    posterior_mean_coef2: jax.Array

    @property
    def num_steps(self) -> int:
        """``T``, the number of diffusion steps (a static Python int)."""
        return int(self.betas.shape[0])


def cosine_betas(num_steps: int, s: float = 0.008, max_beta: float = MAX_BETA) -> np.ndarray:
    """Betas of the cosine schedule, float64 ``[T]`` (see module docstring)."""
    _check_steps(num_steps)
    u = np.arange(num_steps + 1, dtype=np.float64) / num_steps
    f = np.cos((u + s) / (1.0 + s) * math.pi / 2.0) ** 2
    return np.minimum(1.0 - f[1:] / f[:-1], max_beta)


def linear_betas(num_steps: int, max_beta: float = MAX_BETA) -> np.ndarray:
    """Betas of the linear schedule 1e-4 → 0.02 scaled by ``1000 / T``, float64 ``[T]``."""
    _check_steps(num_steps)
    scale = 1000.0 / num_steps
    betas = np.linspace(1e-4 * scale, 0.02 * scale, num_steps, dtype=np.float64)
    return np.minimum(betas, max_beta)


SCHEDULES = {"cosine": cosine_betas, "linear": linear_betas}


def _check_steps(num_steps):
    if int(num_steps) != num_steps or num_steps < 1:
        raise ValueError(f"num_steps must be a positive integer, got {num_steps!r}")


def schedule_from_betas(betas) -> Schedule:
    """Build a :class:`Schedule` from betas ``[T]`` (values in (0, 1))."""
    b = np.asarray(betas, dtype=np.float64)
    if b.ndim != 1 or b.size == 0:
        raise ValueError(f"betas must be a non-empty 1-D array, got shape {b.shape}")
    if not np.all((b > 0) & (b < 1)):
        raise ValueError("betas must lie in (0, 1)")
    a = 1.0 - b
    ac = np.cumprod(a)
    log_ac = np.cumsum(np.log(a))
    ac_prev = np.concatenate([[1.0], ac[:-1]])
    one_m_ac = -np.expm1(log_ac)  # 1 − ᾱ without cancellation near ᾱ ≈ 1
    one_m_ac_prev = np.concatenate([[0.0], one_m_ac[:-1]])
    post_var = b * one_m_ac_prev / one_m_ac
    # β̃_0 = 0: clip its log to β̃_1 (guided-diffusion); a 1-step schedule has no β̃_1.
    floor = post_var[1] if b.size > 1 else 1e-20
    post_logvar = np.log(np.concatenate([[floor], post_var[1:]]))
    f32 = lambda v: jnp.asarray(v, dtype=jnp.float32)  # noqa: E731
    return Schedule(
        betas=f32(b),
        alphas=f32(a),
        alphas_cumprod=f32(ac),
        alphas_cumprod_prev=f32(ac_prev),
        log_alphas_cumprod=f32(log_ac),
        sqrt_alphas_cumprod=f32(np.sqrt(ac)),
        sqrt_one_minus_alphas_cumprod=f32(np.sqrt(one_m_ac)),
        sqrt_recip_alphas_cumprod=f32(np.sqrt(1.0 / ac)),
        sqrt_recipm1_alphas_cumprod=f32(np.sqrt(one_m_ac / ac)),
        posterior_variance=f32(post_var),
        posterior_log_variance_clipped=f32(post_logvar),
        posterior_mean_coef1=f32(b * np.sqrt(ac_prev) / one_m_ac),
        posterior_mean_coef2=f32(one_m_ac_prev * np.sqrt(a) / one_m_ac),
    )


def make_schedule(name: str = "cosine", num_steps: int = 1000) -> Schedule:
    """The named schedule (``"cosine"`` or ``"linear"``) with ``num_steps`` steps."""
    if name not in SCHEDULES:
        raise ValueError(f"unknown schedule {name!r}; choose one of {sorted(SCHEDULES)}")
    return schedule_from_betas(SCHEDULES[name](num_steps))


def gather(values, t, ndim: int):
    """``values[t]`` reshaped to broadcast against a ``[B, ...]`` array of rank ``ndim``.

    Args:
      values: ``[T]`` per-step table; t: ``[B]`` int timesteps; ndim: rank of the target.
    Returns:
      ``[B, 1, …, 1]`` (``ndim`` axes).
    """
    out = jnp.take(values, t, axis=0)
    return out.reshape(out.shape + (1,) * (ndim - out.ndim))


def q_sample(schedule: Schedule, x0, t, noise):
    """Forward noising ``x_t = √ᾱ_t x_0 + √(1 − ᾱ_t) ε``.

    Args:
      schedule: the :class:`Schedule`.
      x0: clean data ``[B, ...]``.
      t: timesteps ``[B]`` int in ``[0, T)``.
      noise: ``ε`` with the shape of ``x0`` (standard normal).
    Returns:
      ``x_t``, shape of ``x0``.
    """
    return (
        gather(schedule.sqrt_alphas_cumprod, t, x0.ndim) * x0
        + gather(schedule.sqrt_one_minus_alphas_cumprod, t, x0.ndim) * noise
    )


def q_posterior(schedule: Schedule, x0, x_t, t):
    """Mean and variance of ``q(x_{t−1} | x_t, x_0)``.

    Args:
      x0, x_t: ``[B, ...]``; t: ``[B]`` int.
    Returns:
      ``(mean [B, ...], variance [B, 1…], log_variance_clipped [B, 1…])``.
    """
    nd = x_t.ndim
    mean = (
        gather(schedule.posterior_mean_coef1, t, nd) * x0
        + gather(schedule.posterior_mean_coef2, t, nd) * x_t
    )
    return (
        mean,
        gather(schedule.posterior_variance, t, nd),
        gather(schedule.posterior_log_variance_clipped, t, nd),
    )
