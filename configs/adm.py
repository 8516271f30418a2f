"""ADM: the affordance diffusion model (Perceiver; variants by model.arch=mlp|point_transformer).

Needs the pretrained backbone (configs/segmentation.py) as ``backbone_workdir``.

    python -m jaxmotion.train --config configs/adm.py data_dir=data/synth workdir=runs/adm \
        backbone_workdir=runs/segmentation [preset=tiny|default|paper] [key=value ...]

Word-level text (``model.text_tokens=24``): the Perceiver also reads the text encoder's first 24
token states as latents, so relation words ("closest", "farthest") and the anchor's name stay
apart instead of being averaged into one sentence vector (0 = the paper's pooled text only).
Token states are cached under ``<data_dir>/.cache/text-tokens`` (float16; ~140 MB for the
synthetic set's 14.5k texts).

Room view (``crop.centre=room crop.size=8``): the ADM reads the whole room (any room up to 8 m
across) instead of the AMDM's 4 m crop around the motion, so the anchor of "the chair closest to
the desk" is in view; the pipeline carries its map to the AMDM's crop by nearest neighbours.
``init_from=DIR`` starts the ADM from another ADM run's weights (workdir or ``.safetensors``;
same model config) instead of random ones, e.g. to fine-tune a crop-view ADM to the room view.

Known target (``model.target_input=true``): the ADM also reads a 0/1 mask of the target
object's points, so once the target is known (``jaxmotion generate`` finds it with the scene
graph, or takes ``--object``) the map is drawn for that object, not for whatever the sentence
vector suggests. The mask is zeroed with probability ``target_drop`` per example in training,
so the same weights draw maps from the text alone when no target is known (the paper
protocol, rooms without an object table). ``init_from`` may name an ADM without the target
input: its weights are kept and the new input starts at zero, i.e. from that ADM exactly.

Selection by grounding (``grounding_every=N``): every N steps the EMA weights draw maps
(DDIM, ``grounding_steps``, guidance ``grounding_guidance``) on the first ``grounding_cases``
val crops (the paper protocol's crops), and the run logs how often a map reaches the target
instance (``grounding/instance_success@0.3``), its class, and the class's mean distance. The
weights with the best instance success so far are exported to ``model_best.safetensors``
(``best.json`` says which step): validation loss keeps falling after grounding stops improving,
so pick the ADM by this, not by the loss.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from jaxmotion.models.configs import ADMConfig, preset_overrides
from jaxmotion.train.config import DiffusionConfig, TrainConfig


@dataclasses.dataclass(frozen=True)
class ADMTrainConfig(TrainConfig):
    task: str = "adm"
    workdir: str = "runs/adm"
    backbone_workdir: str = "runs/segmentation"
    init_from: str = ""
    grounding_every: int = 0
    grounding_cases: int = 128
    grounding_steps: int = 10
    grounding_guidance: float = 5.0
    target_drop: float = 0.5
    steps: int = 6000
    batch_size: int = 16
    model: ADMConfig = dataclasses.field(default_factory=ADMConfig)
    diffusion: DiffusionConfig = dataclasses.field(
        default_factory=lambda: DiffusionConfig(schedule="cosine", steps=500, cond_drop_prob=0.1))

    def __post_init__(self):
        super().__post_init__()
        if self.grounding_every < 0 or self.grounding_cases < 1 or self.grounding_steps < 1 \
                or not self.grounding_guidance > 0:
            raise ValueError(
                "grounding_every must be >= 0 (0: off), grounding_cases and grounding_steps >= 1 "
                f"and grounding_guidance > 0; got {self.grounding_every}, {self.grounding_cases}, "
                f"{self.grounding_steps}, {self.grounding_guidance}")
        if not 0.0 <= self.target_drop <= 1.0:
            raise ValueError(f"target_drop must be in [0, 1], got {self.target_drop}")


PRESETS: dict[str, dict[str, Any]] = {
    "default": {"crop.num_points": 2048, "optim.lr": 2e-4, "optim.warmup_steps": 200},
    "tiny": {**preset_overrides(ADMConfig, "tiny", "model."),
             "crop.num_points": 256, "batch_size": 4, "steps": 20, "log_every": 5,
             "eval_every": 10, "eval_batches": 1, "ckpt_every": 10, "diffusion.steps": 50,
             "optim.lr": 1e-3, "optim.warmup_steps": 2, "progress": False},
    "paper": {**preset_overrides(ADMConfig, "paper", "model."),
              "crop.num_points": 8192, "batch_size": 32, "steps": 100_000, "optim.lr": 1e-4,
              "optim.ema_decay": 0.0},
}


def get_config() -> ADMTrainConfig:
    return ADMTrainConfig()
