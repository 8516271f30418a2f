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

from jaxmotion.models.configs import ObjectCentricConfig
from jaxmotion.train.config import ObjectCentricTrainConfig, object_centric_presets

KIND = "trajectory"


@dataclasses.dataclass(frozen=True)
class TrajectoryTrainConfig(ObjectCentricTrainConfig):
    task: str = KIND
    workdir: str = "runs/trajectory"
    steps: int = 6000
    batch_size: int = 16
    model: ObjectCentricConfig = dataclasses.field(
        default_factory=lambda: ObjectCentricConfig(kind=KIND, action_token=True))


PRESETS: dict[str, dict[str, Any]] = object_centric_presets(paper_batch=256)


def get_config() -> TrajectoryTrainConfig:
    return TrajectoryTrainConfig()
