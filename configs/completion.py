"""Object-centric pipeline, stage 2: the motion completion model (Cen et al. 2024).

Samples the whole motion (trajectory + the 21 body joints' 6D rotations, 135 features per
frame) along a given trajectory: one condition token per frame from the trajectory and, with
``model.traj_sensor=true`` (the paper's, default in the paper preset), the trajectory sensor
around it. The CPU default leaves the trajectory sensor out: on 2 cores it costs more than
the network (a 2 m cube of 8³ voxels per frame). Pose features weigh ``pose_weight`` = 10 in
the L1 loss, as the paper. ``joint_weight``, ``foot_contact_weight`` and
``joint_velocity_weight`` add geometric terms on the forward kinematics of the prediction
(joint positions, MDM's foot contact, joint velocities; 0 by default); the shipped model was
fine-tuned with 200 / 3 / 2 (docs/results.md in the git history, "The completion model's legs").
``model.traj_velocity=true`` gives each frame's trajectory token the root's motion in the
body's heading frame as well (where a walk's steps show). With ``init_from`` a model without
the velocity or the trajectory sensor grows the switched-on inputs at zero weight (it starts
as the same function), and ``geometric_weighting=uniform`` asks the geometric
terms of every diffusion step, not only the nearly clean ones.

    python -m jaxmotion.train --config configs/completion.py data_dir=data/synth \
        workdir=runs/completion [preset=tiny|default|paper] [key=value ...]
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import ObjectCentricConfig
from jaxmotion.train.config import ObjectCentricTrainConfig, object_centric_presets

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


PRESETS: dict[str, dict[str, Any]] = object_centric_presets(paper_batch=128)


def get_config() -> CompletionTrainConfig:
    return CompletionTrainConfig()
