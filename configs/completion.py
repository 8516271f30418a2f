"""Object-centric pipeline, stage 2: the motion completion model (Cen et al. 2024).

Samples the whole motion (trajectory + the 21 body joints' 6D rotations, 135 features per
frame) along a given trajectory: one condition token per frame from the trajectory and, with
``model.traj_sensor=true`` (the paper's, default in the paper preset), the trajectory sensor
around it. The CPU default leaves the trajectory sensor out: on 2 cores it costs more than
the network (a 2 m cube of 8³ voxels per frame). Pose features weigh ``pose_weight`` = 10 in
the L1 loss, as the paper.

    python -m jaxmotion.train --config configs/completion.py data_dir=data/synth \
        workdir=runs/completion [preset=tiny|default|paper] [key=value ...]
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import ObjectCentricConfig, preset_overrides
from jaxmotion.train.config import ObjectCentricTrainConfig

KIND = "completion"


@dataclasses.dataclass(frozen=True)
class CompletionTrainConfig(ObjectCentricTrainConfig):
    task: str = KIND
    workdir: str = "runs/completion"
    steps: int = 6000
    batch_size: int = 16
    model: ObjectCentricConfig = dataclasses.field(
        default_factory=lambda: ObjectCentricConfig(kind=KIND, action_token=True,
                                                    traj_sensor=False))


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
              "batch_size": 128, "steps": 200_000, "optim.lr": 1e-4,
              "optim.ema_decay": 0.0},
}


def get_config() -> CompletionTrainConfig:
    return CompletionTrainConfig()
