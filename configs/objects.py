"""The object classifier of object discovery (``jaxmotion scene segment``, ``generate`` on a
room without labels): shape descriptors of the instances segmentation finds -> categories.

Its data are built from synthetic rooms in the workdir on the first run (no dataset needed):

    python -m jaxmotion.train --config configs/objects.py workdir=runs/objects \
        [preset=tiny|default] [key=value ...]

The shipped ``jaxmotion/assets/objects.safetensors`` is this command's ``model.safetensors``
with the default preset (``results``: the recall and category accuracy it gives).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.object_classifier import ObjectClassifierConfig
from jaxmotion.train.config import OptimConfig, TrainConfig


@dataclasses.dataclass(frozen=True)
class ObjectsTrainConfig(TrainConfig):
    """Adds ``rooms`` (synthetic rooms scanned for data, seeds ``room_seed ..``), their
    ``room_points`` before degradation (built on ``loader_workers`` processes), ``val_rooms``
    (the last ones: validation) and the
    cross-entropy's ``label_smoothing``."""

    task: str = "objects"
    workdir: str = "runs/objects"
    steps: int = 4000
    batch_size: int = 128
    eval_every: int = 500
    ckpt_every: int = 1000
    rooms: int = 240
    room_seed: int = 100_000
    room_points: int = 80_000
    loader_workers: int = 2
    val_rooms: int = 24
    label_smoothing: float = 0.05
    model: ObjectClassifierConfig = dataclasses.field(default_factory=ObjectClassifierConfig)
    optim: OptimConfig = dataclasses.field(
        default_factory=lambda: OptimConfig(lr=2e-3, warmup_steps=100, cosine=True,
                                            weight_decay=1e-4, ema_decay=0.99))

    def __post_init__(self):
        super().__post_init__()
        if not 0 < self.val_rooms < self.rooms:
            raise ValueError(f"need 0 < val_rooms < rooms, got {self.val_rooms}, {self.rooms}")


PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    "tiny": {"rooms": 3, "val_rooms": 1, "room_points": 20_000, "steps": 20, "batch_size": 8,
             "log_every": 5, "eval_every": 10, "eval_batches": 1, "ckpt_every": 10,
             "model.hidden": 16, "model.layers": 1, "optim.warmup_steps": 2,
             "progress": False},
}


def get_config() -> ObjectsTrainConfig:
    return ObjectsTrainConfig()
