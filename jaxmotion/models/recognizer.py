"""Action recognizer: which of the four actions (walk / sit / stand up / lie) a motion does.

The object-centric paper (Cen et al. 2024) scores generated motions with the accuracy of an
action recognizer trained on the dataset's motions: the action it recognises in a generated
motion against the action the instruction asks for, with its accuracy on the dataset's own
test motions as the ceiling. :mod:`jaxmotion.eval.recognizer` loads a trained one and scores
motions; :mod:`jaxmotion.train.recognizer_task` trains it.

Motion input: ``joints [B, T, 22, 3]`` (z-up, metres, floor at z = 0) and a prefix frame mask
``[B, T]``, made position- and heading-invariant by the text–motion evaluator's
:func:`~jaxmotion.models.evaluator.canonical_motion_features` (F = 134 per frame; velocities
are per frame, so a recognizer is tied to its training data's frame rate, 30 fps).

Network (small enough to train in minutes on a CPU): z-scored features -> ``conv_layers``
Conv1d (kernel 4, stride 2, LeakyReLU 0.2, dropout; T / 2^L tokens, each seeing about
``3 * 2^L`` frames) -> pooling over the valid tokens: mean, max, the first and the last token
(the first and last keep the order: *sit* ends low, *stand up* starts low) -> Linear,
LayerNorm, LeakyReLU, dropout (:meth:`ActionRecognizer.features`, ``[B, hidden]``, the
features FID / diversity / multimodality are measured on) -> Linear -> 4 logits in the order
of :data:`ACTIONS`.
Activations past a motion's end are zeroed at every level, so the logits do not depend on
padding values or the padded length.

Loss (:func:`classification_loss`): cross-entropy, optionally label-smoothed.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.data.format import ACTIONS
from jaxmotion.models.configs import Presets
from jaxmotion.models.evaluator import (
    FEATURE_DIM,
    FeatureStats,
    canonical_motion_features,
    motion_lengths,
)

__all__ = ["ACTIONS", "RECOGNIZER_VERSION", "ActionRecognizer", "RecognizerConfig",
           "classification_loss", "valid_tokens"]

# Bump when the features, architecture, loss or label set change: predictions of different
# versions are not comparable, and loading refuses files of another version.
RECOGNIZER_VERSION = "jm-action-1"


@dataclasses.dataclass(frozen=True)
class RecognizerConfig(Presets):
    """Sizes of :class:`ActionRecognizer` (``tiny`` / ``cpu`` default).

    Attributes:
      conv_dim: channels of the temporal convolutions.
      conv_layers: stride-2 convolutions (tokens are ``2^conv_layers`` frames apart).
      hidden: width of the head's hidden layer.
      dropout: dropout after each convolution and in the head.
    """

    conv_dim: int = 64
    conv_layers: int = 3
    hidden: int = 64
    dropout: float = 0.1

    _PRESETS = {
        "tiny": lambda: dict(conv_dim=16, conv_layers=2, hidden=16, dropout=0.0),
    }

    def __post_init__(self):
        if min(self.conv_dim, self.conv_layers, self.hidden) < 1:
            raise ValueError("conv_dim, conv_layers and hidden must be >= 1, got "
                             f"{(self.conv_dim, self.conv_layers, self.hidden)}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")

    @property
    def unit(self) -> int:
        """Frames per token (the padded length is a multiple of it)."""
        return 2 ** self.conv_layers


class ActionRecognizer(nnx.Module):
    """``joints [B, T, 22, 3]``, prefix ``mask [B, T]`` -> logits ``[B, 4]`` (module docstring).

    ``feature_mean`` / ``feature_std`` ``[F]`` (:class:`FeatureStats`) z-score the motion
    features; set them from the data.
    """

    def __init__(self, cfg: RecognizerConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        d = cfg.conv_dim
        self.feature_mean = FeatureStats(jnp.zeros(FEATURE_DIM, jnp.float32))
        self.feature_std = FeatureStats(jnp.ones(FEATURE_DIM, jnp.float32))
        conv = dict(kernel_size=(4,), strides=(2,), padding=((1, 1),), rngs=rngs)
        self.convs = nnx.List([nnx.Conv(FEATURE_DIM if i == 0 else d, d, **conv)
                               for i in range(cfg.conv_layers)])
        self.drop = nnx.Dropout(cfg.dropout, rngs=rngs)
        self.fc1 = nnx.Linear(4 * d, cfg.hidden, rngs=rngs)
        self.norm = nnx.LayerNorm(cfg.hidden, epsilon=1e-5, rngs=rngs)
        self.fc2 = nnx.Linear(cfg.hidden, len(ACTIONS), rngs=rngs)

    def __call__(self, joints: jax.Array, mask: jax.Array, *,
                 deterministic: bool | None = None) -> jax.Array:
        return self.fc2(self.features(joints, mask, deterministic=deterministic))

    def features(self, joints: jax.Array, mask: jax.Array, *,
                 deterministic: bool | None = None) -> jax.Array:
        """The penultimate (pre-logit) activations ``[B, hidden]``: the head's hidden layer
        after LayerNorm, LeakyReLU and dropout (none with ``deterministic=True``). Like the
        logits they depend neither on padded frames nor on where the motion is or which way
        it faces; FID, diversity and multimodality "on the recognizer's features" use them."""
        t = mask.shape[1]
        length = motion_lengths(mask)
        feats = canonical_motion_features(joints, mask)
        feats = (feats - self.feature_mean[...]) / self.feature_std[...]
        x = jnp.pad(feats, ((0, 0), (0, -t % self.cfg.unit), (0, 0)))
        x = jnp.where(valid_tokens(x, length, 1)[..., None], x, 0.0)
        for i, conv in enumerate(self.convs):
            x = self.drop(nnx.leaky_relu(conv(x), 0.2), deterministic=deterministic)
            valid = valid_tokens(x, length, 2 ** (i + 1))
            x = jnp.where(valid[..., None], x, 0.0)  # padding-independent at every level
        n = jnp.maximum(jnp.sum(valid, axis=1), 1)  # [B]
        mean = jnp.sum(x, axis=1) / n[:, None]
        peak = jnp.max(jnp.where(valid[..., None], x, -jnp.inf), axis=1)
        last = jnp.take_along_axis(x, (n - 1)[:, None, None], axis=1)[:, 0]
        h = jnp.concatenate([mean, peak, x[:, 0], last], axis=-1)
        return self.drop(nnx.leaky_relu(self.norm(self.fc1(h)), 0.2),
                         deterministic=deterministic)


def valid_tokens(x: jax.Array, length: jax.Array, frames: int) -> jax.Array:
    """Valid tokens ``[B, L]`` of ``x [B, L, D]`` whose tokens are ``frames`` frames apart:
    the first ``ceil(length / frames)``."""
    return jnp.arange(x.shape[1])[None] < -(-length[:, None] // frames)


def classification_loss(logits: jax.Array, labels: jax.Array, *,
                        label_smoothing: float = 0.0) -> tuple[jax.Array, dict]:
    """Mean cross-entropy ``[B, C], [B] int -> ()``; aux: the batch ``accuracy``."""
    c = logits.shape[-1]
    target = jax.nn.one_hot(labels, c) * (1.0 - label_smoothing) + label_smoothing / c
    loss = -jnp.mean(jnp.sum(target * jax.nn.log_softmax(logits), axis=-1))
    acc = jnp.mean(jnp.argmax(logits, axis=-1) == labels)
    return loss, {"accuracy": acc}
