"""Text–motion evaluator (Guo et al. 2022 protocol): contrastive motion and text encoders whose
features give FID, R-precision, MultiModal distance, Diversity and MultiModality.

Trains on any dataset in the sample schema (joints, masks and texts only; no scene):

    python -m jaxmotion.train --config configs/evaluator.py data_dir=data/synth \
        workdir=runs/evaluator [preset=tiny|default|paper] [key=value ...]

Load the result with ``jaxmotion.eval.evaluator.load_evaluator(workdir)``. Its
``model.safetensors`` records ``evaluator_version`` and the sha256 of the data's manifest.

Default (CPU) size: 20k steps of batch 32 (40 epochs of the 16k-sample synthetic train split),
about 4.6 steps/s on 2 busy CPU cores, so a bit over an hour.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import preset_overrides
from jaxmotion.models.evaluator import EvaluatorConfig
from jaxmotion.train.config import OptimConfig, TrainConfig


@dataclasses.dataclass(frozen=True)
class EvaluatorTrainConfig(TrainConfig):
    """Adds the hinge ``margin`` (Guo et al.: 10) and ``stats_batches``, the training batches
    that give the motion feature statistics."""

    task: str = "evaluator"
    workdir: str = "runs/evaluator"
    steps: int = 20_000
    batch_size: int = 32
    ckpt_every: int = 2000
    margin: float = 10.0
    stats_batches: int = 16
    model: EvaluatorConfig = dataclasses.field(default_factory=EvaluatorConfig)
    optim: OptimConfig = dataclasses.field(
        default_factory=lambda: OptimConfig(lr=1e-4, warmup_steps=200))

    def __post_init__(self):
        super().__post_init__()
        if self.margin <= 0 or self.stats_batches < 1:
            raise ValueError(f"need margin > 0 and stats_batches >= 1, got {self.margin}, "
                             f"{self.stats_batches}")


PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    "tiny": {**preset_overrides(EvaluatorConfig, "tiny", "model."),
             "batch_size": 8, "steps": 20, "log_every": 5, "eval_every": 10, "eval_batches": 1,
             "ckpt_every": 10, "stats_batches": 2, "optim.lr": 1e-3, "optim.warmup_steps": 2,
             "progress": False},
    "paper": {**preset_overrides(EvaluatorConfig, "paper", "model."),
              "batch_size": 32, "steps": 100_000, "optim.lr": 1e-4},
}


def get_config() -> EvaluatorTrainConfig:
    return EvaluatorTrainConfig()
