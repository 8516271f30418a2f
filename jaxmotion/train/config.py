"""Config dataclasses shared by every training config (``configs/<name>.py``).

A training config is a frozen dataclass derived from :class:`TrainConfig` with
its own ``model`` section. These top-level keys are used by external scripts and
must keep working as command-line overrides: ``preset=tiny``, ``data_dir=DIR``,
``workdir=DIR``, ``steps=N``.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

from jaxmotion.data.config import AffordanceConfig, CropConfig

__all__ = ["DiffusionConfig", "ObjectCentricTrainConfig", "OptimConfig", "TrainConfig",
           "object_centric_presets"]


@dataclasses.dataclass(frozen=True)
class OptimConfig:
    """AdamW with warm-up, optional cosine decay, clipping and EMA.

    Attributes:
      lr: peak learning rate; warmup_steps: linear warm-up from 0.
      cosine: decay to ``lr * final_lr_fraction`` by the last step (else constant).
      clip_norm: global gradient-norm clip; weight_decay: AdamW decoupled decay.
      ema_decay: EMA of the weights used for validation and sampling (0: off).
    """

    lr: float = 1e-4
    warmup_steps: int = 200
    cosine: bool = False
    final_lr_fraction: float = 0.1
    clip_norm: float = 1.0
    weight_decay: float = 0.0
    b1: float = 0.9
    b2: float = 0.999
    ema_decay: float = 0.999

    def __post_init__(self):
        if self.lr <= 0 or self.clip_norm <= 0:
            raise ValueError(f"need lr > 0 and clip_norm > 0, got {self.lr}, {self.clip_norm}")
        if not 0.0 <= self.ema_decay < 1.0:
            raise ValueError(f"ema_decay must be in [0, 1), got {self.ema_decay}")


@dataclasses.dataclass(frozen=True)
class DiffusionConfig:
    """Diffusion settings: schedule, number of steps, condition dropout."""

    schedule: Literal["cosine", "linear"] = "cosine"
    steps: int = 1000
    cond_drop_prob: float = 0.1


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Everything a training run needs except the model section (added by each config).

    Attributes:
      task: which model family trains (selects the task in ``jaxmotion.train.tasks``).
      data_dir: a dataset made by ``jaxmotion synth``; workdir: where checkpoints and logs go.
      steps: total optimiser steps; batch_size: global batch (a multiple of the device count).
      resume: continue from the last checkpoint in ``workdir`` when there is one.
      log_every / eval_every / ckpt_every: intervals in steps (eval_every 0: no validation).
      eval_batches: validation batches (fixed crops) per evaluation.
      max_frames: motions are padded to this many frames (with a frame mask).
      max_samples: use only the first N training samples (None: all).
      crop / affordance: the training crops and affordance maps (see jaxmotion.data.config).
      loader_workers: processes that prepare training batches (0: one background thread);
        the batches are the same with any number.
    """

    task: str = ""
    data_dir: str = "data/synth"
    workdir: str = "runs/default"
    steps: int = 10_000
    batch_size: int = 32
    seed: int = 0
    resume: bool = True
    log_every: int = 50
    eval_every: int = 500
    eval_batches: int = 4
    ckpt_every: int = 1000
    keep_checkpoints: int = 3
    progress: bool = True
    max_frames: int = 120
    max_samples: int | None = None
    loader_workers: int = 0
    crop: CropConfig = dataclasses.field(default_factory=CropConfig)
    affordance: AffordanceConfig = dataclasses.field(default_factory=AffordanceConfig)
    optim: OptimConfig = dataclasses.field(default_factory=OptimConfig)

    def __post_init__(self):
        if self.steps < 1 or self.batch_size < 1:
            raise ValueError(f"steps ({self.steps}) and batch_size ({self.batch_size}) must be >= 1")
        if self.log_every < 1 or self.ckpt_every < 1 or self.eval_every < 0:
            raise ValueError("log_every and ckpt_every must be >= 1 and eval_every >= 0")
        if self.loader_workers < 0:
            raise ValueError(f"loader_workers must be >= 0 (0: one thread), got {self.loader_workers}")


@dataclasses.dataclass(frozen=True)
class ObjectCentricTrainConfig(TrainConfig):
    """The object-centric pipeline's trajectory and completion models
    (``configs/trajectory.py``, ``configs/completion.py``).

    Attributes:
      loss: ``l1`` (the paper's) or ``mse``, masked over the valid frames.
      pose_weight: weight of the body rotations against the trajectory (10 in the paper).
      sensor_points: crop points the trajectory sensor reads (the first ones of the random
        draw; 0 = all), for the cost of a per-frame sensor on a CPU.
      stats_batches: training batches whose features give the normalisation statistics.
      std_floor: smallest standard deviation a feature is divided by.
      pretrain: drop the text and the scene sensors for every example (pre-training on
        motions alone, as the paper pre-trains on AMASS; the synthetic motions stand in).
      init_from: start from another run's weights (workdir or ``.safetensors``) of the same
        model config, e.g. the fine-tune after ``pretrain=true``; its statistics are kept.
        ``model.action_token`` may be switched on (its embedding starts at 0).
      action_unknown_prob: with ``model.action_token``, the share of training examples whose
        action is given as unknown (as an instruction the grounding stage cannot read).
      joint_weight, foot_contact_weight, joint_velocity_weight: completion model only; weights
        of geometric terms on the forward kinematics of the predicted clean motion
        (:mod:`jaxmotion.diffusion.geometric_losses`): joint positions (m²), MDM's foot
        contact (the predicted feet's speed where the data's feet stand still, (m/s)²) and
        joint velocities ((m/s)²). 0 (the default) leaves a term out.
      geometric_weighting: ``signal`` scales each example's geometric terms by ᾱ_t of its
        diffusion step (a prediction from pure noise is not held to the data's fine motion);
        ``uniform`` weighs every step the same.
    """

    loss: Literal["l1", "mse"] = "l1"
    pose_weight: float = 10.0
    sensor_points: int = 512
    stats_batches: int = 8
    std_floor: float = 0.05
    pretrain: bool = False
    init_from: str = ""
    action_unknown_prob: float = 0.1
    joint_weight: float = 0.0
    foot_contact_weight: float = 0.0
    joint_velocity_weight: float = 0.0
    geometric_weighting: Literal["signal", "uniform"] = "signal"
    diffusion: DiffusionConfig = dataclasses.field(
        default_factory=lambda: DiffusionConfig(schedule="cosine", steps=200, cond_drop_prob=0.1))

    def __post_init__(self):
        super().__post_init__()
        if self.loss not in ("l1", "mse"):
            raise ValueError(f"loss must be 'l1' or 'mse', got {self.loss!r}")
        if self.pose_weight <= 0 or self.std_floor <= 0:
            raise ValueError(f"pose_weight ({self.pose_weight}) and std_floor "
                             f"({self.std_floor}) must be > 0")
        if self.sensor_points < 0 or self.stats_batches < 1:
            raise ValueError(f"need sensor_points >= 0 and stats_batches >= 1, got "
                             f"{self.sensor_points}, {self.stats_batches}")
        geo = {"joint_weight": self.joint_weight, "foot_contact_weight": self.foot_contact_weight,
               "joint_velocity_weight": self.joint_velocity_weight}
        if any(w < 0 for w in geo.values()):
            raise ValueError(f"geometric weights must be >= 0, got {geo}")
        if any(geo.values()) and self.task != "completion":
            raise ValueError(f"{', '.join(k for k, w in geo.items() if w)} weigh(s) the body's "
                             f"joints, which only the completion model writes (task="
                             f"{self.task!r}); leave them at 0")
        if self.geometric_weighting not in ("signal", "uniform"):
            raise ValueError("geometric_weighting must be 'signal' or 'uniform', got "
                             f"{self.geometric_weighting!r}")


def object_centric_presets(paper_batch: int) -> dict[str, dict]:
    """The ``PRESETS`` of ``configs/trajectory.py`` and ``configs/completion.py``: ``default``
    (CPU), ``tiny`` (tests) and ``paper`` (batch ``paper_batch``, the trajectory sensor on).
    The model sizes come from :class:`~jaxmotion.models.configs.ObjectCentricConfig`'s presets;
    its ``kind``, ``traj_sensor`` and ``action_token`` stay each config file's."""
    from jaxmotion.models.configs import ObjectCentricConfig, preset_overrides

    def sizes(name):
        return {k: v for k, v in preset_overrides(ObjectCentricConfig, name, "model.").items()
                if k not in ("model.kind", "model.traj_sensor", "model.action_token")}

    return {
        "default": {"crop.num_points": 2048, "optim.lr": 2e-4, "optim.warmup_steps": 200,
                    "eval_every": 250, "ckpt_every": 250},
        "tiny": {**sizes("tiny"),
                 "crop.num_points": 256, "sensor_points": 64, "batch_size": 4, "steps": 20,
                 "log_every": 5, "eval_every": 10, "eval_batches": 1, "ckpt_every": 10,
                 "diffusion.steps": 50, "stats_batches": 2, "optim.lr": 1e-3,
                 "optim.warmup_steps": 2, "progress": False},
        "paper": {**sizes("paper"),
                  "model.traj_sensor": True, "crop.num_points": 8192, "sensor_points": 0,
                  "batch_size": paper_batch, "steps": 200_000, "optim.lr": 1e-4,
                  "optim.ema_decay": 0.0},
    }
