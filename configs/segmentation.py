"""Pretraining of the Point Transformer backbone on the synthetic rooms' semantic labels.

The trained ``model.safetensors`` is ADM's frozen per-point feature extractor
(``backbone_workdir`` in ``configs/adm.py``).

    python -m jaxmotion.train --config configs/segmentation.py data_dir=data/synth \
        workdir=runs/segmentation [preset=tiny|default|paper] [key=value ...]
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import PointTransformerConfig, preset_overrides
from jaxmotion.train.config import TrainConfig


@dataclasses.dataclass(frozen=True)
class SegmentationConfig(TrainConfig):
    task: str = "segmentation"
    workdir: str = "runs/segmentation"
    steps: int = 3000
    batch_size: int = 8
    max_frames: int = 120
    model: PointTransformerConfig = dataclasses.field(default_factory=PointTransformerConfig)


PRESETS: dict[str, dict[str, Any]] = {
    # CPU default: 2048-point crops (the models' recommended CPU size).
    "default": {"crop.num_points": 2048, "optim.lr": 1e-3, "optim.warmup_steps": 100,
                "optim.cosine": True},
    "tiny": {**preset_overrides(PointTransformerConfig, "tiny", "model."),
             "crop.num_points": 256, "batch_size": 4, "steps": 20, "log_every": 5,
             "eval_every": 10, "eval_batches": 1, "ckpt_every": 10, "max_frames": 120,
             "optim.lr": 1e-3, "optim.warmup_steps": 2, "progress": False},
    "paper": {**preset_overrides(PointTransformerConfig, "paper", "model."),
              "crop.num_points": 8192, "batch_size": 16, "steps": 40_000, "optim.lr": 5e-4,
              "optim.cosine": True},
}


def get_config() -> SegmentationConfig:
    return SegmentationConfig()
