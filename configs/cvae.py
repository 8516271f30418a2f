"""The HUMANISE conditional VAE (Wang et al., NeurIPS 2022): the baseline both papers compare with.

A trainable baseline; no weights ship with jaxmotion. Architecture: :mod:`jaxmotion.models.cvae`;
loss and data: :mod:`jaxmotion.train.cvae_task`. ``action=sit`` (walk / sit / stand_up / lie)
trains an action-specific model on that action's samples, as HUMANISE trains one per action;
``action=""`` (the default) the action-agnostic one. Generate with it:
``jaxmotion generate --pipeline cvae --cvae runs/cvae [runs/cvae_sit ...]``.

Loss weights: translation 1, orientation 1, body pose 10, KL 0.1 and target centre 0.1 are
HUMANISE's; its marker term (L1 on 67 surface markers, x10) is the L1 on the 22 joints of the
forward kinematics here (``joint_weight`` 10, our choice: the project's bodies are joints).
The KL is the mean over latent dimensions (not the sum; :func:`~jaxmotion.models.cvae.
kl_divergence`), our choice where the facts are silent. The paper's scene encoder is a
pretrained Point Transformer fine-tuned at 0.1 x lr; here it trains from scratch with the rest.

    python -m jaxmotion.train --config configs/cvae.py data_dir=data/synth workdir=runs/cvae \
        [action=sit] [preset=tiny|default|paper] [key=value ...]
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.data.format import ACTIONS
from jaxmotion.models.configs import preset_overrides
from jaxmotion.models.cvae import CVAEConfig
from jaxmotion.train.config import TrainConfig


@dataclasses.dataclass(frozen=True)
class CVAETrainConfig(TrainConfig):
    """Attributes (besides :class:`~jaxmotion.train.config.TrainConfig`'s):
      action: ``""`` (action-agnostic) or one of walk / sit / stand_up / lie (action-specific:
        trained on that action's samples only).
      translation_weight, orientation_weight, pose_weight, joint_weight, kl_weight,
        centre_weight: the loss terms' weights (module docstring).
    """

    task: str = "cvae"
    workdir: str = "runs/cvae"
    action: str = ""
    steps: int = 6000
    batch_size: int = 16
    translation_weight: float = 1.0
    orientation_weight: float = 1.0
    pose_weight: float = 10.0
    joint_weight: float = 10.0
    kl_weight: float = 0.1
    centre_weight: float = 0.1
    model: CVAEConfig = dataclasses.field(default_factory=CVAEConfig)

    def __post_init__(self):
        super().__post_init__()
        if self.action and self.action not in ACTIONS:
            raise ValueError(f"action must be '' (action-agnostic) or one of "
                             f"{', '.join(ACTIONS)}, got {self.action!r}")
        weights = {k: getattr(self, k) for k in (
            "translation_weight", "orientation_weight", "pose_weight", "joint_weight",
            "kl_weight", "centre_weight")}
        if any(w < 0 for w in weights.values()):
            raise ValueError(f"loss weights must be >= 0, got {weights}")


PRESETS: dict[str, dict[str, Any]] = {
    "default": {"crop.num_points": 2048, "optim.lr": 2e-4, "optim.warmup_steps": 200,
                "eval_every": 250, "ckpt_every": 250},
    "tiny": {**preset_overrides(CVAEConfig, "tiny", "model."),
             "crop.num_points": 256, "batch_size": 4, "steps": 20, "log_every": 5,
             "eval_every": 10, "eval_batches": 1, "ckpt_every": 10, "optim.lr": 1e-3,
             "optim.warmup_steps": 2, "progress": False},
    # HUMANISE's training script: Adam lr 1e-4, batch 24 (150 epochs of 16.5k sequences)
    "paper": {**preset_overrides(CVAEConfig, "paper", "model."),
              "crop.num_points": 32768, "batch_size": 24, "steps": 103_000, "optim.lr": 1e-4,
              "optim.warmup_steps": 0, "optim.ema_decay": 0.0},
}


def get_config() -> CVAETrainConfig:
    return CVAETrainConfig()
