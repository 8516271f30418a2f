"""Model sizes as frozen dataclasses, with ``tiny`` / ``cpu`` (the default) / ``paper`` presets.

Every size of :mod:`jaxmotion.models` comes from here. Each class takes its ``cpu`` values as
field defaults, so ``ADMConfig()`` is the CPU default; ``ADMConfig.preset("paper")`` (or
``ADMConfig.paper()``) gives the numbers of REFERENCE_FACTS and the authors' code, ``tiny`` the
test sizes (width 16, one transformer layer, two Point Transformer stages with one block, for
clouds of a few dozen points, e.g. 64). Training configs under ``configs/`` nest these classes;
:func:`preset_overrides` turns a preset into the ``{dotted key: value}`` dict that a config
file's ``PRESETS`` holds.

Conventions that follow the official Point Transformer code (Zhao et al. 2021):
``blocks[l]`` counts the transition-down layer of stage ``l`` plus ``blocks[l] - 1`` Point
Transformer blocks, and ``decoder_blocks`` counts the transition-up plus ``decoder_blocks - 1``
blocks per decoder stage (the official U-Net uses 2). Point counts must be divisible by
``prod(strides)`` (8192 / 256 = 32 points at the coarsest level of the paper backbone).

CPU default: meant for **2048-point crops** (data config ``crop.num_points=2048``; the 4 m x 4 m
crop keeps its size, so points are ~9 cm apart instead of ~4 cm), batch 8. Point Transformer
stages have no block at full resolution (no full-resolution k-NN), widths 32-256, transformers
of width 128 with 3 layers. Forward + backward per batch of 8 on 2 shared CPU cores (best of
5, jitted, training mode; T = 120 frames; ranges over runs on a busy machine): segmentation
0.31-0.46 s, frozen features 0.14-0.18 s, ADM Perceiver 0.08-0.15 s (+ the frozen features),
AMDM @Enc 0.29-0.48 s, @Dec 0.36-0.57 s: roughly 8k AMDM or 12k ADM steps per hour. With
8192 points the same models take 1.5-2.5 s (AMDM @Enc), 1.9-3.0 s (segmentation) and 1.8 s
(frozen features, most of it k-NN and sampling): too slow for an hour on a CPU, fine on an
accelerator.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, Literal

__all__ = ["PointTransformerConfig", "ADMConfig", "AMDMConfig", "ObjectCentricConfig", "PRESET_NAMES",
           "preset_overrides"]

PRESET_NAMES = ("tiny", "cpu", "paper")


class Presets:
    """Mixin: ``cls.preset(name)`` and ``cls.tiny() / cpu() / paper()``."""

    _PRESETS: dict[str, Callable[[], dict[str, Any]]] = {}

    @classmethod
    def preset(cls, name: str = "cpu"):
        if name == "cpu" or name == "default":
            return cls()
        if name not in cls._PRESETS:
            raise ValueError(f"unknown preset {name!r} for {cls.__name__}; valid: {PRESET_NAMES}")
        return cls(**cls._PRESETS[name]())

    @classmethod
    def tiny(cls):
        return cls.preset("tiny")

    @classmethod
    def cpu(cls):
        return cls.preset("cpu")

    @classmethod
    def paper(cls):
        return cls.preset("paper")


@dataclasses.dataclass(frozen=True)
class PointTransformerConfig(Presets):
    """Point Transformer backbone (vector attention over k-NN, strided downsampling, U-Net).

    Attributes:
      planes: feature width of each stage (stage 0 = full resolution).
      blocks: per stage, 1 transition-down layer + ``blocks[l] - 1`` Point Transformer blocks.
      strides: downsampling factor of each stage (stage 0 is normally 1).
      nsample: k of the k-NN of each stage (blocks and transition-down grouping).
      share_planes: channels that share one attention weight (``planes % share_planes == 0``).
      decoder_blocks: per decoder stage, 1 transition-up + ``decoder_blocks - 1`` blocks.
      norm: ``batch`` (official; running statistics, call ``model.eval()`` for inference) or
        ``layer`` (stateless; the relative-position MLP then has no norm, since a LayerNorm over
        3 coordinates would discard the offset's length).
      sampling: ``fps`` (farthest point sampling from index 0, the official choice) or ``stride``
        (every s-th point: cheap, and uniform when the points are in random order, as training
        crops are).
      knn_budget: squared distances per brute-force k-NN chunk over the whole batch (memory
        ``4 * knn_budget`` bytes; the default 2^20 = 4 MiB stays in cache and was fastest on
        CPU; raise it on a GPU, e.g. 2^26). Unchunked, 8 clouds of 8192 points would need
        2 GiB per k-NN.
      in_channels: per-point input channels besides xyz of the segmentation backbone (rgb = 3);
        the ADM and AMDM models set their own.
      out_dim: per-point feature width returned by the segmentation backbone (projected from
        ``planes[0]`` when different).
      num_classes: semantic classes of the segmentation head (synthetic world ids 0..43,
        -1 = unlabelled).
    """

    planes: tuple[int, ...] = (32, 64, 128, 256)
    blocks: tuple[int, ...] = (1, 2, 2, 2)
    strides: tuple[int, ...] = (1, 4, 4, 4)
    nsample: tuple[int, ...] = (8, 16, 16, 16)
    share_planes: int = 8
    decoder_blocks: int = 1
    norm: Literal["batch", "layer"] = "batch"
    sampling: Literal["fps", "stride"] = "fps"
    knn_budget: int = 1 << 20
    in_channels: int = 3
    out_dim: int = 32
    num_classes: int = 44

    _PRESETS = {
        "tiny": lambda: dict(planes=(16, 16), blocks=(1, 2), strides=(1, 4), nsample=(4, 4),
                             share_planes=4, decoder_blocks=1, out_dim=16),
        "paper": lambda: dict(planes=(32, 64, 128, 256, 512), blocks=(2, 3, 4, 6, 3),
                              strides=(1, 4, 4, 4, 4), nsample=(8, 16, 16, 16, 16),
                              share_planes=8, decoder_blocks=2, norm="batch", sampling="fps",
                              out_dim=32),
    }

    def __post_init__(self):
        n = len(self.planes)
        if n == 0 or not (len(self.blocks) == len(self.strides) == len(self.nsample) == n):
            raise ValueError("planes, blocks, strides and nsample need one entry per stage, got "
                             f"{self.planes}, {self.blocks}, {self.strides}, {self.nsample}")
        if min(self.blocks) < 1 or min(self.strides) < 1 or min(self.nsample) < 1:
            raise ValueError("blocks, strides and nsample must be >= 1 (a stage's transition "
                             f"counts as one block): {self.blocks}, {self.strides}, {self.nsample}")
        bad = [p for p in self.planes if p % self.share_planes]
        if bad or self.share_planes < 1:
            raise ValueError(f"every plane width must be divisible by share_planes="
                             f"{self.share_planes}; not: {bad}")
        if self.decoder_blocks < 1 or self.knn_budget < 1 or self.out_dim < 1:
            raise ValueError("decoder_blocks, knn_budget and out_dim must be >= 1")

    @property
    def total_stride(self) -> int:
        """Point count ratio between the input and the coarsest stage."""
        return math.prod(self.strides)


def _amdm_encoder_paper() -> PointTransformerConfig:
    return PointTransformerConfig(planes=(32, 64, 128, 256), blocks=(2, 2, 2, 2),
                                  strides=(1, 4, 4, 4), nsample=(8, 16, 16, 16), share_planes=8,
                                  decoder_blocks=2, norm="batch", sampling="fps")


def _adm_pt_paper() -> PointTransformerConfig:
    return PointTransformerConfig(planes=(64, 128, 256, 512), blocks=(2, 2, 2, 2),
                                  strides=(1, 4, 4, 4), nsample=(8, 16, 16, 16), share_planes=8,
                                  decoder_blocks=2, norm="batch", sampling="fps")


def _pt_cpu_small() -> PointTransformerConfig:
    return PointTransformerConfig(planes=(32, 64, 128, 128), blocks=(1, 2, 2, 2))


@dataclasses.dataclass(frozen=True)
class ADMConfig(Presets):
    """Affordance Diffusion Model: per-point affordance from scene features, text and time.

    Attributes:
      arch: ``perceiver`` (the paper's model), ``mlp`` (PointNet-style ablation) or
        ``point_transformer`` (Point Transformer U-Net ablation).
      affordance_dim: affordance channels (6 joints).
      feature_dim: width of the frozen backbone's per-point features (its ``out_dim``).
      text_dim: text embedding width (384 all-MiniLM-L6-v2, 512 CLIP ViT-B/32 as in the paper).
      time_dim: width of the sinusoidal timestep embedding and its MLP.
      point_width / latent_width: Perceiver widths of the point array and the latents.
      text_tokens: word-level text conditioning (``perceiver`` only). 0 (the paper's): the
        latents are [text, time], the text being one pooled sentence vector. L > 0: the
        first L token states of the text encoder (``[CLS]`` and ``[SEP]`` included) become L
        more latents (LayerNorm, Linear), padded tokens masked out of every attention. A
        pooled vector averages the words away: "the chair closest to the window" and "...
        farthest from the window" have cosine 0.90 in MiniLM; token latents keep the relation
        word and the anchor's name apart.
      target_input: the ADM also reads a known target object (``perceiver`` only):
        ``cond["target"] [B, N]``, 1 on the target's points and 0 elsewhere (all 0 = no
        target known: the map is grounded from the text alone), one more per-point input.
        ``jaxmotion generate`` passes the object the scene graph (or ``--object``) chose, so
        the map lights that object's affordance rather than what the pooled sentence
        suggests; trained with the target dropped at ``target_drop`` (training config) so
        the same weights serve both.
      num_heads, self_layers: attention heads; self-attention layers on the latents.
      widening: MLP widening factor of the Perceiver layers.
      dropout: attention dropout of the Perceiver (residual dropout is 0, as the authors').
      mlp_dims, pool: the ``mlp`` variant's per-point layers and global pooling.
      point_transformer: the ``point_transformer`` variant's U-Net.
    """

    arch: Literal["perceiver", "mlp", "point_transformer"] = "perceiver"
    affordance_dim: int = 6
    feature_dim: int = 32
    text_dim: int = 384
    time_dim: int = 64
    point_width: int = 64
    latent_width: int = 128
    num_heads: int = 4
    self_layers: int = 2
    text_tokens: int = 0
    target_input: bool = False
    widening: int = 1
    dropout: float = 0.1
    mlp_dims: tuple[int, ...] = (128, 128)
    pool: Literal["max", "mean"] = "max"
    point_transformer: PointTransformerConfig = dataclasses.field(default_factory=_pt_cpu_small)

    _PRESETS = {
        "tiny": lambda: dict(feature_dim=16, time_dim=16, point_width=16, latent_width=16,
                             num_heads=2, self_layers=1, mlp_dims=(16,),
                             point_transformer=PointTransformerConfig.tiny()),
        "paper": lambda: dict(feature_dim=32, text_dim=512, time_dim=128, point_width=256,
                              latent_width=512, num_heads=8, self_layers=2, widening=1,
                              dropout=0.1, mlp_dims=(512, 512), pool="mean",
                              point_transformer=_adm_pt_paper()),
    }

    def __post_init__(self):
        for name in ("point_width", "latent_width"):
            if getattr(self, name) % self.num_heads:
                raise ValueError(f"{name}={getattr(self, name)} must be divisible by "
                                 f"num_heads={self.num_heads}")
        if self.time_dim % 2:
            raise ValueError(f"time_dim must be even (sin/cos pairs), got {self.time_dim}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        if self.text_tokens < 0:
            raise ValueError(f"text_tokens must be >= 0 (0 = pooled text only), got "
                             f"{self.text_tokens}")
        if self.text_tokens and self.arch != "perceiver":
            raise ValueError(f"text_tokens={self.text_tokens} needs arch='perceiver' (the "
                             f"{self.arch!r} ADM reads the pooled text only); set text_tokens=0")
        if self.target_input and self.arch != "perceiver":
            raise ValueError(f"target_input needs arch='perceiver' (the {self.arch!r} ADM has no "
                             "target channel); set target_input=false")


@dataclasses.dataclass(frozen=True)
class AMDMConfig(Presets):
    """Affordance-to-Motion Diffusion Model (and the one-stage baseline).

    Attributes:
      arch: ``enc`` (@Enc: one transformer encoder over [time, text, point tokens, frames]) or
        ``dec`` (@Dec: self-attention over [time, text, frames], cross-attention to the
        multi-scale point features of a Point Transformer U-Net).
      scene_input: ``affordance`` (two-stage: xyz + affordance map) or ``rgb`` (the one-stage
        baseline reading the scene: xyz + rgb).
      motion_dim, affordance_dim, text_dim: input widths (66 = 22 joints x 3).
      time_dim: sinusoidal timestep width (projected to d_model by an MLP).
      d_model, num_heads, num_layers, ff_dim, dropout: the transformer.
      norm_first: pre-norm layers if True; the authors use PyTorch's default post-norm.
      encoder: the Point Transformer over the points.
      temporal_basis: 0, or K > 0: the predicted clean motion is the least-squares fit of the
        network's per-frame output by the first K cosines (DCT-II) of its valid frames, so a
        sample is a sum of K smooth components (K / (2 · seconds) Hz at most: 4 Hz for K = 32
        over 4 s) and cannot jump between two frames. The synthetic motions lose 1 mm to it
        at K = 32 (2 mm at 24); real captures need a larger K. No parameters.
    """

    arch: Literal["enc", "dec"] = "enc"
    scene_input: Literal["affordance", "rgb"] = "affordance"
    motion_dim: int = 66
    affordance_dim: int = 6
    text_dim: int = 384
    time_dim: int = 128
    d_model: int = 128
    num_heads: int = 4
    num_layers: int = 3
    ff_dim: int = 256
    dropout: float = 0.1
    norm_first: bool = False
    encoder: PointTransformerConfig = dataclasses.field(default_factory=_pt_cpu_small)
    temporal_basis: int = 0

    _PRESETS = {
        "tiny": lambda: dict(time_dim=16, d_model=16, num_heads=2, num_layers=1, ff_dim=32,
                             encoder=PointTransformerConfig.tiny()),
        "paper": lambda: dict(text_dim=512, time_dim=512, d_model=512, num_heads=8,
                              num_layers=5, ff_dim=1024, dropout=0.1, norm_first=False,
                              encoder=_amdm_encoder_paper()),
    }

    def __post_init__(self):
        if self.d_model % self.num_heads or self.d_model % 2:
            raise ValueError(f"d_model={self.d_model} must be even and divisible by "
                             f"num_heads={self.num_heads}")
        if self.time_dim % 2:
            raise ValueError(f"time_dim must be even (sin/cos pairs), got {self.time_dim}")
        if self.num_layers < 1:
            raise ValueError(f"num_layers must be >= 1, got {self.num_layers}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        if self.temporal_basis < 0:
            raise ValueError("temporal_basis must be 0 (off) or the number K > 0 of cosines "
                             f"the motion is built from, got {self.temporal_basis}")

    @property
    def point_channels(self) -> int:
        """Per-point input channels of the encoder besides xyz."""
        return self.affordance_dim if self.scene_input == "affordance" else 3


@dataclasses.dataclass(frozen=True)
class ObjectCentricConfig(Presets):
    """The object-centric pipeline's two denoisers (Cen et al. 2024): trajectory and completion.

    Attributes:
      kind: ``trajectory`` (stage 1: the root trajectory, 9-d per frame) or ``completion``
        (stage 2: the whole motion, 135-d, along a given trajectory).
      text_dim, betas_dim: widths of the sentence embedding and the body shape.
      sensor_res: voxels per side of every sensor (8 in the paper: 8³ voxels x 7 channels).
      sensor_hidden: width of the two-layer SiLU MLP that turns a flattened sensor into a token.
      traj_sensor: completion only: one token per frame from the stage-1 trajectory and the
        trajectory sensor around it (the paper's); False: from the trajectory alone.
      time_dim: sinusoidal timestep width; d_model, num_heads, num_layers, ff_dim, dropout,
        norm_first: the transformer decoder (its memory is the timestep token).
      temporal_basis: 0, or K > 0: the x0 estimate is the least-squares fit of the network's
        per-frame output by the first K cosines of its valid frames (as ``AMDMConfig``).
      action_token: the text token also carries a learned embedding of the action the
        instruction asks for (walk / sit / stand up / lie, or unknown), as the grounding stage
        reads it (``cond["action"]``); dropped with the text.
      traj_velocity: completion only: each frame's trajectory token also reads how the root
        moves in the body's heading frame (``cond["traj_velocity"]``,
        :func:`jaxmotion.motion.representation.trajectory_velocity`: forward / sideways /
        vertical speed, turning rate), where the steps of a walk show.
    """

    kind: Literal["trajectory", "completion"] = "trajectory"
    text_dim: int = 384
    betas_dim: int = 10
    sensor_res: int = 8
    sensor_hidden: int = 256
    traj_sensor: bool = True
    time_dim: int = 128
    d_model: int = 128
    num_heads: int = 4
    num_layers: int = 3
    ff_dim: int = 256
    dropout: float = 0.1
    norm_first: bool = False
    temporal_basis: int = 0
    action_token: bool = False
    traj_velocity: bool = False

    _PRESETS = {
        "tiny": lambda: dict(sensor_res=4, sensor_hidden=16, time_dim=16, d_model=16,
                             num_heads=2, num_layers=1, ff_dim=32),
        "paper": lambda: dict(text_dim=384, sensor_hidden=512, time_dim=512, d_model=512,
                              num_heads=8, num_layers=4, ff_dim=1024, dropout=0.1),
    }

    def __post_init__(self):
        if self.kind not in ("trajectory", "completion"):
            raise ValueError(f"kind must be 'trajectory' or 'completion', got {self.kind!r}")
        if self.d_model % self.num_heads or self.d_model % 2:
            raise ValueError(f"d_model={self.d_model} must be even and divisible by "
                             f"num_heads={self.num_heads}")
        if self.time_dim % 2:
            raise ValueError(f"time_dim must be even (sin/cos pairs), got {self.time_dim}")
        if self.num_layers < 1 or self.sensor_res < 2:
            raise ValueError(f"need num_layers >= 1 and sensor_res >= 2, got {self.num_layers}, "
                             f"{self.sensor_res}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        if self.temporal_basis < 0:
            raise ValueError(f"temporal_basis must be 0 (off) or K > 0, got {self.temporal_basis}")

    @property
    def motion_dim(self) -> int:
        """Features per frame: 9 (trajectory) or 135 (trajectory + 21 body rotations, 6D)."""
        return 9 if self.kind == "trajectory" else 135


def preset_overrides(cls: type, name: str, prefix: str = "") -> dict[str, Any]:
    """``{prefix + dotted key: value}`` of preset ``name`` of config class ``cls``.

    For a config file's ``PRESETS``, e.g. ``{"paper": preset_overrides(AMDMConfig, "paper",
    "model.")}``.
    """
    from jaxmotion.config import flatten_config

    return {prefix + k: v for k, v in flatten_config(cls.preset(name)).items()}
