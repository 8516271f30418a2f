"""Gaussian diffusion core: schedules, forward noising, the x0 loss and samplers.

Pure functions of a ``denoise_fn(x_t, t, cond) -> x0_hat`` (``x_t [B, ...]``,
``t [B]`` int32, ``cond`` a pytree of ``[B, ...]`` leaves or ``None``); the
network predicts ``x0`` as in both papers. Nothing is compiled at import; jit
at the call site. Typical use::

    sched = make_schedule("cosine", 1000)
    loss = diffusion_loss(key, denoise_fn, sched, x0, cond, frame_mask, cond_drop_prob=0.1)
    x = ddpm_sample(key, denoise_fn, sched, (B, T, D), cond, guidance_scale=2.5)
    x = ddim_sample(key, denoise_fn, sched, (B, T, D), cond, num_steps=50, eta=0.0)

Modules: :mod:`~jaxmotion.diffusion.schedules` (formulas),
:mod:`~jaxmotion.diffusion.losses` (loss, condition dropout),
:mod:`~jaxmotion.diffusion.samplers` (DDPM, DDIM, guidance, known values).
"""

from jaxmotion.diffusion.losses import (
    diffusion_loss,
    drop_condition,
    expand_mask,
    masked_mean,
    null_condition,
)
from jaxmotion.diffusion.samplers import (
    SamplerSpec,
    ddim_posterior,
    ddim_sample,
    ddim_timesteps,
    ddpm_posterior,
    ddpm_sample,
    guided_denoise,
    sample,
)
from jaxmotion.diffusion.schedules import (
    SCHEDULES,
    Schedule,
    cosine_betas,
    gather,
    linear_betas,
    make_schedule,
    q_posterior,
    q_sample,
    schedule_from_betas,
)

__all__ = [
    "SCHEDULES",
    "SamplerSpec",
    "Schedule",
    "cosine_betas",
    "ddim_posterior",
    "ddim_sample",
    "ddim_timesteps",
    "ddpm_posterior",
    "ddpm_sample",
    "diffusion_loss",
    "drop_condition",
    "expand_mask",
    "gather",
    "guided_denoise",
    "linear_betas",
    "make_schedule",
    "masked_mean",
    "null_condition",
    "q_posterior",
    "q_sample",
    "sample",
    "schedule_from_betas",
]
