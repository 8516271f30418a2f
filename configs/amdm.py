"""AMDM: the affordance-to-motion diffusion model (@Enc by default, model.arch=dec for @Dec;
model.scene_input=rgb gives the one-stage baseline).

With ``predicted_fraction > 0`` it needs a trained ADM (``adm_workdir``) and trains on a
mix of ground-truth and ADM-sampled affordance maps, as the paper does (50/50).

``velocity_weight`` / ``acceleration_weight`` (> 0) add the geometric losses of
:mod:`jaxmotion.diffusion.geometric_losses` on the predicted clean motion (joint velocities
in m/s, accelerations in m/s², squared errors) to the x0 loss: without them the model writes
motion finer than ~0.3 s as holds and jumps. ``geometric_weighting=signal`` scales each
example's terms by its signal level ᾱ_t, so they act where the fine detail is decided (low
noise) and do not pull the blurry high-noise estimates towards stillness. ``init_from=FILE`` starts from another AMDM's
weights (workdir or ``.safetensors``; same model config, except ``model.temporal_basis``, which
has no parameters) and keeps its normalisation statistics, so a fine-tune continues the same
function. ``model.temporal_basis=K`` builds the predicted motion from the first K cosines of
its frames (:class:`~jaxmotion.models.AMDMConfig`): the shipped AMDM's setting, K = 32.

    python -m jaxmotion.train --config configs/amdm.py data_dir=data/synth workdir=runs/amdm \
        adm_workdir=runs/adm [preset=tiny|default|paper] [key=value ...]
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import AMDMConfig, preset_overrides
from jaxmotion.train.config import DiffusionConfig, TrainConfig


@dataclasses.dataclass(frozen=True)
class AMDMTrainConfig(TrainConfig):
    task: str = "amdm"
    workdir: str = "runs/amdm"
    adm_workdir: str = "runs/adm"
    predicted_fraction: float = 0.5
    adm_sampler_steps: int = 10
    velocity_weight: float = 0.0
    acceleration_weight: float = 0.0
    geometric_weighting: str = "uniform"
    init_from: str = ""
    steps: int = 8000
    batch_size: int = 16
    model: AMDMConfig = dataclasses.field(default_factory=AMDMConfig)
    diffusion: DiffusionConfig = dataclasses.field(
        default_factory=lambda: DiffusionConfig(schedule="cosine", steps=1000, cond_drop_prob=0.1))

    def __post_init__(self):
        super().__post_init__()
        if not 0.0 <= self.predicted_fraction <= 1.0:
            raise ValueError(f"predicted_fraction must be in [0, 1], got {self.predicted_fraction}")
        if self.geometric_weighting not in ("uniform", "signal"):
            raise ValueError("geometric_weighting must be 'uniform' or 'signal' (each example's "
                             f"terms times ᾱ_t), got {self.geometric_weighting!r}")
        if self.velocity_weight < 0 or self.acceleration_weight < 0:
            raise ValueError("velocity_weight and acceleration_weight must be ≥ 0 (0 = off), got "
                             f"{self.velocity_weight} and {self.acceleration_weight}")


PRESETS: dict[str, dict[str, Any]] = {
    "default": {"crop.num_points": 2048, "optim.lr": 2e-4, "optim.warmup_steps": 200},
    "tiny": {**preset_overrides(AMDMConfig, "tiny", "model."),
             "crop.num_points": 256, "batch_size": 4, "steps": 20, "log_every": 5,
             "eval_every": 10, "eval_batches": 1, "ckpt_every": 10, "diffusion.steps": 50,
             "adm_sampler_steps": 2, "optim.lr": 1e-3, "optim.warmup_steps": 2,
             "progress": False},
    "paper": {**preset_overrides(AMDMConfig, "paper", "model."),
              "crop.num_points": 8192, "batch_size": 32, "steps": 200_000, "optim.lr": 1e-4,
              "optim.ema_decay": 0.0},
}


def get_config() -> AMDMTrainConfig:
    return AMDMTrainConfig()
