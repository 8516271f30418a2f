"""Action recognizer (walk / sit / stand up / lie) for the object-centric paper's action
accuracy: trained on a dataset's motions (joints only, position- and heading-invariant).

Trains on any dataset in the sample schema (joints, masks and actions only; no scene):

    python -m jaxmotion.train --config configs/recognizer.py data_dir=data/synth \
        workdir=runs/recognizer [preset=tiny|default] [key=value ...]

Load the result with ``jaxmotion.eval.recognizer.load_recognizer(workdir)``. Its
``model.safetensors`` records ``recognizer_version`` and the sha256 of the data's manifest.

Default (CPU) size: 3000 steps of batch 32 (60 epochs of a 1600-motion train split).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import preset_overrides
from jaxmotion.models.recognizer import RecognizerConfig
from jaxmotion.train.config import OptimConfig, TrainConfig


@dataclasses.dataclass(frozen=True)
class RecognizerTrainConfig(TrainConfig):
    """Adds ``stats_batches`` (training batches that give the feature statistics),
    ``time_crop`` (each training motion loses a random fraction up to this at its start and
    another at its end) and ``label_smoothing`` of the cross-entropy."""

    task: str = "recognizer"
    workdir: str = "runs/recognizer"
    steps: int = 3000
    batch_size: int = 32
    eval_every: int = 250
    ckpt_every: int = 500
    stats_batches: int = 16
    time_crop: float = 0.1
    label_smoothing: float = 0.05
    model: RecognizerConfig = dataclasses.field(default_factory=RecognizerConfig)
    optim: OptimConfig = dataclasses.field(
        default_factory=lambda: OptimConfig(lr=1e-3, warmup_steps=100, cosine=True,
                                            weight_decay=1e-4, ema_decay=0.99))

    def __post_init__(self):
        super().__post_init__()
        if self.stats_batches < 1:
            raise ValueError(f"need stats_batches >= 1, got {self.stats_batches}")
        if not 0.0 <= self.time_crop < 0.5:
            raise ValueError(f"time_crop must be in [0, 0.5), got {self.time_crop}")
        if not 0.0 <= self.label_smoothing < 1.0:
            raise ValueError(f"label_smoothing must be in [0, 1), got {self.label_smoothing}")


PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    "tiny": {**preset_overrides(RecognizerConfig, "tiny", "model."),
             "batch_size": 8, "steps": 20, "log_every": 5, "eval_every": 10, "eval_batches": 1,
             "ckpt_every": 10, "stats_batches": 2, "time_crop": 0.0, "label_smoothing": 0.0,
             "optim.lr": 3e-3, "optim.warmup_steps": 2, "optim.cosine": False,
             "optim.ema_decay": 0.0, "progress": False},
}


def get_config() -> RecognizerTrainConfig:
    return RecognizerTrainConfig()
