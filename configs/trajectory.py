"""Object-centric pipeline, stage 1: the trajectory diffusion model (Cen et al. 2024).

Samples the root trajectory (pelvis position + 6D orientation per frame, 120 frames at
30 fps) from the text, the body shape and the environment and target sensors; cosine
schedule, 200 steps, x0 prediction, masked L1 loss.

    python -m jaxmotion.train --config configs/trajectory.py data_dir=data/synth \
        workdir=runs/trajectory [preset=tiny|default|paper] [key=value ...]

``pretrain=true`` trains without text and scene (the paper's AMASS pre-training; then
fine-tune with ``init_from=runs/trajectory_pre``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import ObjectCentricConfig, preset_overrides
from jaxmotion.train.config import ObjectCentricTrainConfig

KIND = "trajectory"


@dataclasses.dataclass(frozen=True)
class TrajectoryTrainConfig(ObjectCentricTrainConfig):
    task: str = KIND
    workdir: str = "runs/trajectory"
    steps: int = 6000
    batch_size: int = 16
    model: ObjectCentricConfig = dataclasses.field(
        default_factory=lambda: ObjectCentricConfig(kind=KIND, action_token=True))


def _model_preset(name: str) -> dict[str, Any]:
    """The model sizes of preset ``name`` (its ``kind`` stays this file's)."""
    return {k: v for k, v in preset_overrides(ObjectCentricConfig, name, "model.").items()
            if k not in ("model.kind", "model.traj_sensor", "model.action_token")}


PRESETS: dict[str, dict[str, Any]] = {
    "default": {"crop.num_points": 2048, "optim.lr": 2e-4, "optim.warmup_steps": 200,
                "eval_every": 250, "ckpt_every": 250},
    "tiny": {**_model_preset("tiny"),
             "crop.num_points": 256, "sensor_points": 64, "batch_size": 4, "steps": 20,
             "log_every": 5, "eval_every": 10, "eval_batches": 1, "ckpt_every": 10,
             "diffusion.steps": 50, "stats_batches": 2, "optim.lr": 1e-3,
             "optim.warmup_steps": 2, "progress": False},
    "paper": {**_model_preset("paper"),
              "model.traj_sensor": True, "crop.num_points": 8192, "sensor_points": 0,
              "batch_size": 256, "steps": 200_000, "optim.lr": 1e-4,
              "optim.ema_decay": 0.0},
}


def get_config() -> TrajectoryTrainConfig:
    return TrajectoryTrainConfig()
