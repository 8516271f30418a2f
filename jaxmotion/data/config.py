"""Data and training-crop config dataclasses: synthetic dataset, scene crops, affordance maps.

Values follow the papers and the authors' code (see docs and REFERENCE_FACTS): 4 m x 4 m xy crops
of 8192 points recentred on the 2nd-percentile z, random rotation about z in [-pi, pi], 30 fps
motions of 30-120 frames (1-4 s, HUMANISE), affordance joints pelvis, feet, neck and wrists with
sigma 0.8 m. The config file ``configs/data.py`` builds it with presets; training configs
nest it as their ``data`` section.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

from jaxmotion.constants import NUM_JOINTS as JOINT_COUNT  # affordance joint ids index into them


@dataclasses.dataclass(frozen=True)
class CropConfig:
    """Scene crop around the pelvis trajectory for training.

    Attributes:
      size: side of the square xy crop, metres.
      num_points: points per crop (duplicated when the crop has fewer).
      z_percentile: the crop is shifted so this percentile of point z lands at z = 0.
      rotate: random rotation about z as augmentation.
      rotation_range: the rotation angle is uniform in [-rotation_range, rotation_range], radians.
      margin: the pelvis trajectory's xy extent is padded by this much before the crop centre
        is drawn so that it fits, metres.
      centre: ``motion``: the centre is drawn so that the padded trajectory fits (the papers'
        crop); ``room``: the centre of the room's xy bounding box, moved only as far as needed
        for the padded trajectory to fit, so a square at least as large as the room shows all
        of it and says nothing about where the motion is (the ADM's "room view").
    """

    size: float = 4.0
    num_points: int = 8192
    z_percentile: float = 2.0
    rotate: bool = True
    rotation_range: float = math.pi
    margin: float = 0.3
    centre: Literal["motion", "room"] = "motion"

    def __post_init__(self):
        if self.centre not in ("motion", "room"):
            raise ValueError(f"crop.centre must be 'motion' or 'room', got {self.centre!r}")
        if self.size <= 0 or self.num_points < 1:
            raise ValueError(f"crop size ({self.size}) and num_points ({self.num_points}) "
                             "must be positive")
        if not 0.0 <= self.z_percentile <= 100.0:
            raise ValueError(f"z_percentile must be in [0, 100], got {self.z_percentile}")
        if self.rotation_range < 0:
            raise ValueError(f"rotation_range must be >= 0, got {self.rotation_range}")


@dataclasses.dataclass(frozen=True)
class AffordanceConfig:
    """Per-point affordance map ``C[n, j] = exp(-d[n, j]^2 / (2 sigma^2))``.

    Attributes:
      joints: SMPL-X joint ids of the channels: pelvis 0, l_foot 10, r_foot 11, neck 12,
        l_wrist 20, r_wrist 21.
      sigma: Gaussian width, metres.
      clip_min: predicted maps are clipped to [clip_min, 1] before inverting to distances.
    """

    joints: tuple[int, ...] = (0, 10, 11, 12, 20, 21)
    sigma: float = 0.8
    clip_min: float = 1e-20

    def __post_init__(self):
        if not self.joints or any(not 0 <= j < JOINT_COUNT for j in self.joints):
            raise ValueError(f"joints must be non-empty ids in [0, {JOINT_COUNT}), "
                             f"got {self.joints}")
        if self.sigma <= 0 or not 0 < self.clip_min < 1:
            raise ValueError(f"need sigma > 0 and 0 < clip_min < 1, got {self.sigma}, "
                             f"{self.clip_min}")


@dataclasses.dataclass(frozen=True)
class DataConfig:
    """Where the data lives and how motions are cut and batched.

    Attributes:
      dataset: which data set the loaders read; ``synth`` is the built-in synthetic world.
      data_dir: folder of the data set (relative paths are relative to the working directory).
      fps: motion frame rate, frames per second.
      max_frames: motions are padded (with a frame mask) or cut to this many frames.
      min_frames: shorter motions are dropped.
      max_samples: read at most this many sequences (None: all of them).
      seed: seed of the data pipeline (crop centres, rotations, shuffling).
      batch_size: sequences per training batch.
    """

    dataset: Literal["synth", "humanise", "humanml3d", "prox"] = "synth"
    data_dir: str = "data/synth"
    fps: int = 30
    max_frames: int = 120
    min_frames: int = 30
    max_samples: int | None = None
    seed: int = 0
    batch_size: int = 32
    crop: CropConfig = dataclasses.field(default_factory=CropConfig)
    affordance: AffordanceConfig = dataclasses.field(default_factory=AffordanceConfig)

    def __post_init__(self):
        if not 1 <= self.min_frames <= self.max_frames:
            raise ValueError(f"need 1 <= min_frames <= max_frames, got min_frames="
                             f"{self.min_frames}, max_frames={self.max_frames}")
        if self.fps < 1 or self.batch_size < 1:
            raise ValueError(f"fps ({self.fps}) and batch_size ({self.batch_size}) must be >= 1")
        if self.max_samples is not None and self.max_samples < 1:
            raise ValueError(f"max_samples must be None or >= 1, got {self.max_samples}")
