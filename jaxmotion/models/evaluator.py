"""Text–motion evaluator (Guo et al. 2022 protocol): contrastive motion and text encoders.

FID, R-precision, MultiModal distance, Diversity and MultiModality are computed on the features
of this network (:mod:`jaxmotion.eval.text_motion_metrics` does the arithmetic,
:mod:`jaxmotion.eval.evaluator` loads a trained one). Features are **not** L2-normalised: the
metrics use Euclidean distances, as Guo et al.

Motion input: ``joints [B, T, 22, 3]`` (z-up, metres, floor at z = 0) and a prefix frame mask
``[B, T]``. :func:`canonical_motion_features` makes them invariant to where the motion is in
the room: it subtracts the first frame's pelvis xy and rotates about z so that the first frame
faces +y (facing = up × (right hip − left hip + right shoulder − left shoulder)). Heights stay
absolute (the floor is z = 0 by convention). Per frame (F = 134):

- pelvis position in that canonical frame (3): the trajectory from the start, and the height;
- facing direction in the canonical frame (2, unit xy vector);
- the 21 other joints relative to the pelvis, rotated into the frame's own facing (63);
- joint velocities in the canonical frame, metres per frame (66; 0 at the first frame).

Velocities are per frame, so an evaluator is tied to its training data's frame rate.

Motion encoder (Guo et al.'s design): z-scored features -> "movement encoder" (two Conv1d,
kernel 4, stride 2, LeakyReLU 0.2, dropout: T/4 tokens) -> bidirectional GRU (packed:
each direction stops at the last valid token) -> ``[h_fwd, h_bwd]`` -> Linear, LayerNorm,
LeakyReLU, Linear -> ``output_dim``. Activations past a motion's end are zeroed at every
level, so the features do not depend on padding values or the padded length.

Text encoder: an MLP (Linear, LayerNorm, LeakyReLU, dropout; twice) -> Linear on the frozen
MiniLM sentence embedding (384-d) instead of Guo et al.'s bi-GRU over GloVe word vectors.

Loss (:func:`contrastive_loss`): Guo et al.'s hinge on Euclidean distances, matched pairs
``d²`` plus mismatched pairs ``max(0, margin − d)²`` (margin 10), taken over every mismatched
pair of the batch whose texts differ (Guo et al. use one random cyclic shift of the batch).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.models.configs import Presets

__all__ = [
    "EVALUATOR_VERSION", "FEATURE_DIM", "EvaluatorConfig", "FeatureStats", "TextMotionEvaluator",
    "canonical_motion_features", "contrastive_loss", "motion_lengths",
]

# Bump when the features, architecture or loss change: features of different versions are
# not comparable, and loading refuses files of another version.
EVALUATOR_VERSION = "jm-eval-1"
FEATURE_DIM = 3 + 2 + 63 + 66
UNIT = 4  # frames per motion token (two stride-2 convolutions)

_PELVIS, _L_HIP, _R_HIP, _L_SHOULDER, _R_SHOULDER = 0, 1, 2, 16, 17


@dataclasses.dataclass(frozen=True)
class EvaluatorConfig(Presets):
    """Sizes of :class:`TextMotionEvaluator` (``tiny`` / ``cpu`` default / ``paper``).

    Attributes:
      text_dim: sentence embedding width (384, all-MiniLM-L6-v2).
      movement_dim: channels of the two movement convolutions (Guo et al.: 512).
      motion_hidden: GRU hidden size per direction (Guo et al.: 1024).
      text_hidden: text MLP width (Guo et al.'s text GRU: 512).
      output_dim: feature width D of both encoders (Guo et al.: 512).
      dropout: dropout of the movement encoder and the text MLP (Guo et al.: 0.2).
    """

    text_dim: int = 384
    movement_dim: int = 256
    motion_hidden: int = 512
    text_hidden: int = 512
    output_dim: int = 512
    dropout: float = 0.2

    _PRESETS = {
        "tiny": lambda: dict(movement_dim=16, motion_hidden=16, text_hidden=16, output_dim=16),
        "paper": lambda: dict(movement_dim=512, motion_hidden=1024, text_hidden=512,
                              output_dim=512, dropout=0.2),
    }

    def __post_init__(self):
        sizes = (self.text_dim, self.movement_dim, self.motion_hidden, self.text_hidden,
                 self.output_dim)
        if min(sizes) < 1:
            raise ValueError(f"evaluator sizes must be >= 1, got {sizes}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")


class FeatureStats(nnx.Variable):
    """Per-dimension statistics of the motion features (data, not trained by the optimiser)."""


def motion_lengths(mask: jax.Array) -> jax.Array:
    """Valid frames per motion ``[B, T] -> [B]`` int32 (the mask must be a prefix)."""
    return jnp.sum(mask, axis=-1).astype(jnp.int32)


def _facing(joints: jax.Array) -> jax.Array:
    """Unit facing direction in xy ``[..., 22, 3] -> [..., 2]`` (up × across)."""
    across = (joints[..., _R_HIP, :2] - joints[..., _L_HIP, :2]
              + joints[..., _R_SHOULDER, :2] - joints[..., _L_SHOULDER, :2])
    fwd = jnp.stack([-across[..., 1], across[..., 0]], axis=-1)
    return fwd / jnp.maximum(jnp.linalg.norm(fwd, axis=-1, keepdims=True), 1e-6)


def _rotation_to_y(facing: jax.Array) -> jax.Array:
    """``[..., 2]`` unit vectors -> ``[..., 2, 2]`` rotations taking them to +y."""
    fx, fy = facing[..., 0], facing[..., 1]
    return jnp.stack([jnp.stack([fy, -fx], -1), jnp.stack([fx, fy], -1)], -2)


def canonical_motion_features(joints: jax.Array, mask: jax.Array) -> jax.Array:
    """Position- and heading-invariant per-frame features ``[B, T, 22, 3], [B, T] -> [B, T, F]``.

    See the module docstring for the F = 134 channels. Frames past the end are zero; their
    joint values (even NaN) never reach a valid frame.
    """
    m = mask.astype(bool)
    first = joints[:, :1]
    joints = jnp.where(m[:, :, None, None], joints, first)  # padding: no NaN, no influence
    rot = _rotation_to_y(_facing(first[:, 0]))  # [B, 2, 2]
    origin = first[:, 0, _PELVIS, :2]
    xy = jnp.einsum("bij,btkj->btki", rot, joints[..., :2] - origin[:, None, None])
    canon = jnp.concatenate([xy, joints[..., 2:]], axis=-1)  # [B, T, 22, 3]
    pelvis = canon[:, :, _PELVIS]
    facing = _facing(canon)  # [B, T, 2]
    local = canon[:, :, 1:] - pelvis[:, :, None]
    frame_rot = _rotation_to_y(facing)  # [B, T, 2, 2]
    local = jnp.concatenate(
        [jnp.einsum("btij,btkj->btki", frame_rot, local[..., :2]), local[..., 2:]], axis=-1)
    vel = jnp.concatenate([jnp.zeros_like(canon[:, :1]), canon[:, 1:] - canon[:, :-1]], axis=1)
    b, t = joints.shape[:2]
    feats = jnp.concatenate(
        [pelvis, facing, local.reshape(b, t, -1), vel.reshape(b, t, -1)], axis=-1)
    return jnp.where(m[..., None], feats, 0.0)


class _GRU(nnx.Module):
    """One direction of a GRU (PyTorch's equations) returning the state after the last valid
    step; masked steps keep the state, so with a prefix mask this is a packed sequence."""

    def __init__(self, in_dim: int, hidden: int, *, rngs: nnx.Rngs):
        self.ih = nnx.Linear(in_dim, 3 * hidden, rngs=rngs)
        self.hh = nnx.Linear(hidden, 3 * hidden, rngs=rngs)
        self.hidden = hidden

    def __call__(self, x: jax.Array, mask: jax.Array, *, reverse: bool) -> jax.Array:
        xi = jnp.swapaxes(self.ih(x), 0, 1)  # [L, B, 3H], input projections outside the scan
        w, bias = self.hh.kernel[...], self.hh.bias[...]

        def step(h, inp):
            xt, mt = inp
            xr, xz, xn = jnp.split(xt, 3, axis=-1)
            hr, hz, hn = jnp.split(h @ w + bias, 3, axis=-1)
            r, z = jax.nn.sigmoid(xr + hr), jax.nn.sigmoid(xz + hz)
            new = (1.0 - z) * jnp.tanh(xn + r * hn) + z * h
            return jnp.where(mt[:, None], new, h), None

        h0 = jnp.zeros((x.shape[0], self.hidden), x.dtype)
        h, _ = jax.lax.scan(step, h0, (xi, jnp.swapaxes(mask, 0, 1)), reverse=reverse)
        return h


class TextMotionEvaluator(nnx.Module):
    """Motion and text encoders into one D-dimensional space (module docstring).

    ``encode_motion(joints [B, T, 22, 3], mask [B, T]) -> [B, D]``,
    ``encode_text(text_emb [B, text_dim]) -> [B, D]``. ``feature_mean`` / ``feature_std``
    ``[F]`` (:class:`FeatureStats`) z-score the motion features; set them from the data.
    """

    def __init__(self, cfg: EvaluatorConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        mv, hid = cfg.movement_dim, cfg.motion_hidden
        self.feature_mean = FeatureStats(jnp.zeros(FEATURE_DIM, jnp.float32))
        self.feature_std = FeatureStats(jnp.ones(FEATURE_DIM, jnp.float32))
        conv = dict(kernel_size=(4,), strides=(2,), padding=((1, 1),), rngs=rngs)
        self.conv1 = nnx.Conv(FEATURE_DIM, mv, **conv)
        self.conv2 = nnx.Conv(mv, mv, **conv)
        self.movement_out = nnx.Linear(mv, mv, rngs=rngs)
        self.drop = nnx.Dropout(cfg.dropout, rngs=rngs)
        self.gru_fwd = _GRU(mv, hid, rngs=rngs)
        self.gru_bwd = _GRU(mv, hid, rngs=rngs)
        self.motion_fc1 = nnx.Linear(2 * hid, hid, rngs=rngs)
        self.motion_norm = nnx.LayerNorm(hid, epsilon=1e-5, rngs=rngs)
        self.motion_fc2 = nnx.Linear(hid, cfg.output_dim, rngs=rngs)
        th = cfg.text_hidden
        self.text_fc1 = nnx.Linear(cfg.text_dim, th, rngs=rngs)
        self.text_norm1 = nnx.LayerNorm(th, epsilon=1e-5, rngs=rngs)
        self.text_fc2 = nnx.Linear(th, th, rngs=rngs)
        self.text_norm2 = nnx.LayerNorm(th, epsilon=1e-5, rngs=rngs)
        self.text_fc3 = nnx.Linear(th, cfg.output_dim, rngs=rngs)

    def encode_motion(self, joints: jax.Array, mask: jax.Array, *,
                      deterministic: bool | None = None) -> jax.Array:
        """``joints [B, T, 22, 3]``, prefix ``mask [B, T]`` -> features ``[B, D]``."""
        b, t = mask.shape
        pad = -t % UNIT
        length = motion_lengths(mask)
        feats = canonical_motion_features(joints, mask)
        feats = (feats - self.feature_mean[...]) / self.feature_std[...]
        feats = jnp.pad(feats, ((0, 0), (0, pad), (0, 0)))

        def keep(x, div):  # zero tokens past ceil(length / div): padding-independent
            valid = jnp.arange(x.shape[1])[None] < -(-length[:, None] // div)
            return jnp.where(valid[..., None], x, 0.0), valid

        x, _ = keep(feats, 1)
        x, _ = keep(self.drop(nnx.leaky_relu(self.conv1(x), 0.2), deterministic=deterministic), 2)
        x = self.drop(nnx.leaky_relu(self.conv2(x), 0.2), deterministic=deterministic)
        x, valid = keep(self.movement_out(x), UNIT)
        h = jnp.concatenate([self.gru_fwd(x, valid, reverse=False),
                             self.gru_bwd(x, valid, reverse=True)], axis=-1)
        h = nnx.leaky_relu(self.motion_norm(self.motion_fc1(h)), 0.2)
        return self.motion_fc2(h)

    def encode_text(self, text_emb: jax.Array, *, deterministic: bool | None = None) -> jax.Array:
        """Sentence embeddings ``[B, text_dim]`` -> features ``[B, D]``."""
        h = text_emb
        for fc, norm in ((self.text_fc1, self.text_norm1), (self.text_fc2, self.text_norm2)):
            h = self.drop(nnx.leaky_relu(norm(fc(h)), 0.2), deterministic=deterministic)
        return self.text_fc3(h)


def contrastive_loss(text_f: jax.Array, motion_f: jax.Array, same_text: jax.Array,
                     margin: float = 10.0) -> tuple[jax.Array, dict]:
    """Guo et al.'s hinge loss on Euclidean distances ``[B, D], [B, D], [B, B] -> ()``.

    ``mean_i d_ii² + mean_{i≠j, not same_text[i, j]} max(0, margin − d_ij)²`` with
    ``d_ij = |text_f[i] − motion_f[j]|``; ``same_text`` marks pairs with identical sentences,
    which are neither pushed apart nor pulled together. Aux: the two terms, the mean matched
    and mismatched distances, and the in-batch top-1 text-to-motion retrieval accuracy.
    """
    b = text_f.shape[0]
    diff = text_f[:, None, :] - motion_f[None, :, :]
    d2 = jnp.sum(diff * diff, axis=-1)
    d = jnp.sqrt(jnp.maximum(d2, 1e-12))
    eye = jnp.eye(b, dtype=bool)
    neg = ~eye & ~same_text
    n_neg = jnp.maximum(jnp.sum(neg), 1)
    pos_term = jnp.mean(jnp.diagonal(d2))
    neg_term = jnp.sum(jnp.where(neg, jnp.square(jnp.maximum(margin - d, 0.0)), 0.0)) / n_neg
    top1 = jnp.mean(jnp.argmin(jnp.where(neg | eye, d, jnp.inf), axis=1) == jnp.arange(b))
    aux = {"pos_term": pos_term, "neg_term": neg_term, "dist_matched": jnp.mean(jnp.diagonal(d)),
           "dist_mismatched": jnp.sum(jnp.where(neg, d, 0.0)) / n_neg, "batch_top1": top1}
    return pos_term + neg_term, aux
