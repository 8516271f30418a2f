"""The HUMANISE conditional VAE (Wang et al., NeurIPS 2022): the baseline both papers compare with.

``CVAE(cfg, rngs=...)``; shapes: B batch, N points, G scene tokens, L word tokens, T frames.

- **Condition** (:meth:`CVAE.condition`): a Point Transformer encoder over the crop's points
  (xyz + rgb) gives ``G = N / prod(strides)`` scene tokens (the paper: 32,768 points, 128 tokens
  of width 512) -> Linear -> d; the frozen sentence encoder's token states ``[B, L, text_dim]``
  (MiniLM, 384-d; the paper used BERT-base, 768-d) -> Linear -> d. One transformer encoder
  layer fuses ``[scene tokens ‖ word tokens]`` (padded words masked). Scene branch: each fused
  scene token with its xyz -> Linear -> ``scene_token_dim`` (16), flattened -> Linear -> d;
  text branch: the fused first word token ([CLS]). ``condition = Linear([scene, text, betas])``.
- **Auxiliary head**: ``Linear(d -> 3)`` on the condition regresses the target object's box
  centre (crop frame, metres).
- **Encoder** (:meth:`CVAE.encode`): a bidirectional GRU over the valid frames of the motion
  features -> the two final states -> residual block -> ``(mu, log sigma^2)`` of the latent.
- **Decoder** (:meth:`CVAE.decode`): a transformer decoder whose queries are the sinusoidal
  positions of the frames and whose memory is one token ``Linear([z, condition])``; per frame
  :data:`FEATURE_DIM` = 72 features: pelvis position 3 + global orientation 6D + body pose
  axis-angle 63 (HUMANISE's "translation" is SMPL-X ``transl``; here it is the pelvis itself,
  as :mod:`jaxmotion.motion.representation` takes it, so a crop's rigid transform moves it as
  any point). :func:`features_to_joints` gives the 22 joints by forward kinematics of the body
  of shape ``betas``.

Losses (:func:`cvae_loss_terms`) are pure functions checked against NumPy in the tests.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.geometry.rotations import (
    axis_angle_to_matrix,
    matrix_to_rotation_6d,
    rotation_6d_to_matrix,
)
from jaxmotion.geometry.skeleton import forward_kinematics, rest_joints
from jaxmotion.models.configs import PointTransformerConfig, Presets
from jaxmotion.models.layers import (
    MLP,
    TransformerDecoderLayer,
    TransformerEncoderLayer,
    sinusoidal_embedding,
)
from jaxmotion.models.point_transformer import PointTransformerEncoder

__all__ = ["CVAE", "FEATURE_DIM", "CVAEConfig", "cvae_features", "cvae_loss_terms",
           "features_to_joints", "kl_divergence", "reparameterize"]

#: Per-frame features of the cVAE: pelvis 3, global orientation 6D, body pose axis-angle 63.
FEATURE_DIM = 3 + 6 + 63


def _encoder_cpu() -> PointTransformerConfig:
    return PointTransformerConfig(planes=(32, 64, 128, 128), blocks=(1, 2, 2, 2))


def _encoder_paper() -> PointTransformerConfig:
    # the encoder half of the segmentation backbone: 5 stages, N / 256 tokens of width 512
    return PointTransformerConfig(planes=(32, 64, 128, 256, 512), blocks=(2, 3, 4, 6, 3),
                                  strides=(1, 4, 4, 4, 4), nsample=(8, 16, 16, 16, 16))


@dataclasses.dataclass(frozen=True)
class CVAEConfig(Presets):
    """Sizes of the HUMANISE cVAE (``tiny`` / ``cpu`` default / ``paper`` presets).

    Attributes:
      num_points: crop points the scene encoder reads (static: the scene branch flattens
        ``num_points / prod(encoder.strides)`` tokens); must equal the data's crop size.
      text_dim, text_tokens: width and count of the word-token states read (the paper: 32
        BERT tokens; here MiniLM's, [CLS] first).
      betas_dim: body shape coefficients in the condition.
      d_model, num_heads, ff_dim, dropout: the fusion layer and the decoder (GELU, post-norm).
      scene_token_dim: width of each scene token in the scene branch before flattening (16).
      gru_hidden: hidden width of each direction of the motion encoder's GRU.
      latent_dim: the latent (256 in the paper's training script).
      num_layers: decoder layers (2).
      encoder: the Point Transformer over xyz + rgb.
    """

    num_points: int = 2048
    text_dim: int = 384
    text_tokens: int = 32
    betas_dim: int = 10
    d_model: int = 128
    num_heads: int = 4
    ff_dim: int = 256
    dropout: float = 0.1
    scene_token_dim: int = 16
    gru_hidden: int = 128
    latent_dim: int = 64
    num_layers: int = 2
    encoder: PointTransformerConfig = dataclasses.field(default_factory=_encoder_cpu)

    _PRESETS: ClassVar[dict[str, Callable[[], dict[str, Any]]]] = {
        "tiny": lambda: {"num_points": 256, "text_tokens": 8, "d_model": 16, "num_heads": 2,
                         "ff_dim": 32, "scene_token_dim": 4, "gru_hidden": 16, "latent_dim": 8,
                         "num_layers": 1, "encoder": PointTransformerConfig.tiny()},
        "paper": lambda: {"num_points": 32768, "text_tokens": 32, "d_model": 512,
                          "num_heads": 8, "ff_dim": 1024, "dropout": 0.1,
                          "scene_token_dim": 16, "gru_hidden": 512, "latent_dim": 256,
                          "num_layers": 2, "encoder": _encoder_paper()},
    }

    def __post_init__(self):
        if self.d_model % self.num_heads or self.d_model % 2:
            raise ValueError(f"d_model={self.d_model} must be even and divisible by "
                             f"num_heads={self.num_heads}")
        if self.num_points % self.encoder.total_stride:
            raise ValueError(f"num_points={self.num_points} must be divisible by the encoder's "
                             f"total stride {self.encoder.total_stride}")
        small = {k: getattr(self, k) for k in ("text_tokens", "scene_token_dim", "gru_hidden",
                                                "latent_dim", "num_layers", "betas_dim")}
        if min(small.values()) < 1:
            raise ValueError(f"these sizes must be >= 1: {small}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")

    @property
    def num_tokens(self) -> int:
        """Scene tokens G after the encoder."""
        return self.num_points // self.encoder.total_stride


# ----------------------------------------------------------------------------- representation
def cvae_features(pelvis, global_rot, body_pose):
    """``[..., T, 72]`` features from the pelvis ``[..., T, 3]``, the global orientation
    matrices ``[..., T, 3, 3]`` and the axis-angle body pose ``[..., T, 21, 3]``."""
    body = jnp.asarray(body_pose, jnp.float32)
    return jnp.concatenate([jnp.asarray(pelvis, jnp.float32),
                            matrix_to_rotation_6d(jnp.asarray(global_rot, jnp.float32)),
                            body.reshape(*body.shape[:-2], 63)], -1)


def features_to_joints(features, betas=None):
    """Joints ``[..., T, 22, 3]`` of features ``[..., T, 72]`` by forward kinematics of the body
    of shape ``betas [..., B]`` (None: neutral): bone lengths are that body's in every frame."""
    f = jnp.asarray(features, jnp.float32)
    if f.shape[-1] != FEATURE_DIM:
        raise ValueError(f"cVAE features must be [..., T, {FEATURE_DIM}], got {f.shape}")
    g = rotation_6d_to_matrix(f[..., 3:9])
    body = axis_angle_to_matrix(f[..., 9:].reshape(*f.shape[:-1], 21, 3))
    local = jnp.concatenate([g[..., None, :, :], body], axis=-3)
    rest = rest_joints(betas)[..., None, :, :]  # the same body in every frame
    return forward_kinematics(local, f[..., :3] - rest[..., 0, :], rest)


# ----------------------------------------------------------------------------- losses
def reparameterize(key, mu, logvar):
    """``z = mu + exp(logvar / 2) * eps``, ``eps ~ N(0, I)`` drawn from ``key``."""
    return mu + jnp.exp(0.5 * logvar) * jax.random.normal(key, mu.shape, mu.dtype)


def kl_divergence(mu, logvar):
    """``KL(N(mu, exp(logvar)) || N(0, I))`` per latent dimension, averaged over the batch and
    the dimensions (a mean, not a sum: the weight 0.1 then does not scale with the latent's
    width)."""
    return jnp.mean(-0.5 * (1.0 + logvar - mu * mu - jnp.exp(logvar)))


def _masked_l1(a, b, mask):
    """Mean |a - b| over the valid frames ``mask [B, T]`` and the trailing axes."""
    err = jnp.abs(a - b).reshape(*a.shape[:2], -1)
    m = mask.astype(jnp.float32)
    return jnp.sum(err * m[..., None]) / (jnp.maximum(jnp.sum(m), 1.0) * err.shape[-1])


def cvae_loss_terms(pred, true, mask, mu, logvar, centre_pred, centre_true, centre_valid, *,
                    pred_joints=None, true_joints=None) -> dict:
    """The cVAE's loss terms (unweighted).

    Args:
      pred, true: ``[B, T, 72]`` features; mask: ``[B, T]`` bool, the valid frames.
      mu, logvar: ``[B, Z]`` the posterior.
      centre_pred, centre_true: ``[B, 3]`` the target's box centre; centre_valid: ``[B]`` bool
        (an example whose crop holds none of the target's points has no centre).
      pred_joints, true_joints: ``[B, T, 22, 3]`` forward kinematics of both (optional).
    Returns:
      ``translation``, ``orientation``, ``pose`` (masked L1 means of the three feature
      groups), ``kl`` (:func:`kl_divergence`), ``centre`` (MSE over the valid examples) and,
      with joints given, ``joints`` (masked L1 mean, metres).
    """
    mask = jnp.asarray(mask, bool)
    out = {"translation": _masked_l1(pred[..., :3], true[..., :3], mask),
           "orientation": _masked_l1(pred[..., 3:9], true[..., 3:9], mask),
           "pose": _masked_l1(pred[..., 9:], true[..., 9:], mask),
           "kl": kl_divergence(mu, logvar)}
    v = jnp.asarray(centre_valid, jnp.float32)
    sq = jnp.mean((centre_pred - centre_true) ** 2, axis=-1)
    out["centre"] = jnp.sum(sq * v) / jnp.maximum(jnp.sum(v), 1.0)
    if pred_joints is not None:
        out["joints"] = _masked_l1(pred_joints, true_joints, mask)
    return out


# ----------------------------------------------------------------------------- network
class BiGRU(nnx.Module):
    """A bidirectional GRU (PyTorch's equations) over the valid frames of ``x [B, T, D]``.

    ``__call__(x, mask) -> [B, 2H]``: the forward direction's state after the last valid frame
    and the backward direction's after the first. Frames outside ``mask [B, T]`` leave the
    state unchanged, so padding at the end is never read by either direction.
    """

    def __init__(self, in_dim: int, hidden: int, *, rngs: nnx.Rngs):
        self.hidden = hidden
        self.ih = nnx.List([nnx.Linear(in_dim, 3 * hidden, rngs=rngs) for _ in range(2)])
        self.hh = nnx.List([nnx.Linear(hidden, 3 * hidden, rngs=rngs) for _ in range(2)])

    def run(self, x, mask, direction: int):
        h_dim = self.hidden
        gates_x = self.ih[direction](x)  # [B, T, 3H], the input half of every frame at once
        w, b = self.hh[direction].kernel[...], self.hh[direction].bias[...]

        def step(h, inputs):
            gx, m = inputs
            gh = h @ w + b
            r = jax.nn.sigmoid(gx[:, :h_dim] + gh[:, :h_dim])
            z = jax.nn.sigmoid(gx[:, h_dim:2 * h_dim] + gh[:, h_dim:2 * h_dim])
            n = jnp.tanh(gx[:, 2 * h_dim:] + r * gh[:, 2 * h_dim:])
            new = (1.0 - z) * n + z * h
            return jnp.where(m[:, None], new, h), None

        h0 = jnp.zeros((x.shape[0], h_dim), x.dtype)
        h, _ = jax.lax.scan(step, h0, (gates_x.swapaxes(0, 1), mask.swapaxes(0, 1)),
                            reverse=direction == 1)
        return h

    def __call__(self, x, mask):
        mask = jnp.asarray(mask, bool)
        return jnp.concatenate([self.run(x, mask, 0), self.run(x, mask, 1)], axis=-1)


class CVAE(nnx.Module):
    """The HUMANISE cVAE (module docstring)."""

    def __init__(self, cfg: CVAEConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        d = cfg.d_model
        kw = {"dropout": cfg.dropout, "act": "gelu", "norm_first": False, "rngs": rngs}
        self.point_encoder = PointTransformerEncoder(cfg.encoder, 3, rngs=rngs)
        self.scene_proj = nnx.Linear(cfg.encoder.planes[-1], d, rngs=rngs)
        self.text_proj = nnx.Linear(cfg.text_dim, d, rngs=rngs)
        self.fusion = TransformerEncoderLayer(d, cfg.num_heads, cfg.ff_dim, **kw)
        self.scene_token = nnx.Linear(d + 3, cfg.scene_token_dim, rngs=rngs)
        self.scene_flat = nnx.Linear(cfg.num_tokens * cfg.scene_token_dim, d, rngs=rngs)
        self.cond_proj = nnx.Linear(2 * d + cfg.betas_dim, d, rngs=rngs)
        self.centre_head = nnx.Linear(d, 3, rngs=rngs)
        self.gru = BiGRU(FEATURE_DIM, cfg.gru_hidden, rngs=rngs)
        self.enc_in = nnx.Linear(2 * cfg.gru_hidden, d, rngs=rngs)
        self.enc_res = MLP(d, d, d, act="gelu", rngs=rngs)
        self.enc_norm = nnx.LayerNorm(d, epsilon=1e-5, rngs=rngs)
        self.mu = nnx.Linear(d, cfg.latent_dim, rngs=rngs)
        self.logvar = nnx.Linear(d, cfg.latent_dim, rngs=rngs)
        self.memory = nnx.Linear(cfg.latent_dim + d, d, rngs=rngs)
        self.layers = nnx.List([TransformerDecoderLayer(d, cfg.num_heads, cfg.ff_dim, **kw)
                                for _ in range(cfg.num_layers)])
        self.out = nnx.Linear(d, FEATURE_DIM, rngs=rngs)

    def condition(self, cond: dict, *, deterministic: bool | None = None):
        """``(condition [B, d], predicted target centre [B, 3])`` of ``cond``: ``xyz`` and
        ``rgb [B, N, 3]`` (crop frame, rgb in [-1, 1]), ``tokens [B, L, text_dim]`` with
        ``token_mask [B, L]`` (True = a word), ``betas [B, betas_dim]``."""
        cfg, det = self.cfg, deterministic
        need = {"xyz": (cfg.num_points, 3), "rgb": (cfg.num_points, 3),
                "tokens": (cfg.text_tokens, cfg.text_dim), "token_mask": (cfg.text_tokens,),
                "betas": (cfg.betas_dim,)}
        b = None
        for k, shape in need.items():
            if k not in cond:
                raise KeyError(f"cVAE cond needs {k!r} [B, {', '.join(map(str, shape))}]; got "
                               f"keys {sorted(cond)}")
            got = tuple(jnp.shape(cond[k]))
            b = got[0] if b is None else b
            if got != (b, *shape):
                raise ValueError(f"cVAE cond[{k!r}] must be [B, {', '.join(map(str, shape))}] "
                                 f"(the model's config), got {list(got)}")
        xyz_g, feats = self.point_encoder(cond["xyz"], jnp.asarray(cond["rgb"], jnp.float32),
                                          deterministic=det)
        words = jnp.asarray(cond["tokens"], jnp.float32)
        seq = jnp.concatenate([self.scene_proj(feats), self.text_proj(words)], axis=1)
        g = feats.shape[1]
        seq_mask = jnp.concatenate([jnp.ones((b, g), bool),
                                    jnp.asarray(cond["token_mask"], bool)], axis=1)
        seq = self.fusion(seq, seq_mask, deterministic=det)
        scene = self.scene_token(jnp.concatenate([seq[:, :g], xyz_g], axis=-1))
        scene = self.scene_flat(scene.reshape(b, -1))
        text = seq[:, g]  # the first word token ([CLS])
        c = self.cond_proj(jnp.concatenate(
            [scene, text, jnp.asarray(cond["betas"], jnp.float32)], axis=-1))
        return c, self.centre_head(c)

    def encode(self, features, mask):
        """``(mu, logvar) [B, Z]`` of motion features ``[B, T, 72]`` (valid frames ``mask``)."""
        h = self.enc_in(self.gru(jnp.asarray(features, jnp.float32), mask))
        h = self.enc_norm(h + self.enc_res(jax.nn.gelu(h)))  # the residual block
        return self.mu(h), self.logvar(h)

    def decode(self, z, c, mask, *, deterministic: bool | None = None):
        """Features ``[B, T, 72]`` of latents ``z [B, Z]`` under conditions ``c [B, d]`` for
        frames ``mask [B, T]`` (padded frames are masked out of the self-attention)."""
        b, nt = mask.shape
        mem = self.memory(jnp.concatenate([z, c], axis=-1))[:, None]  # one memory token
        x = jnp.broadcast_to(sinusoidal_embedding(jnp.arange(nt), self.cfg.d_model)[None],
                             (b, nt, self.cfg.d_model))
        for layer in self.layers:
            x = layer(x, mem, jnp.asarray(mask, bool), None, deterministic=deterministic)
        return self.out(x)

    def __call__(self, key, features, mask, cond, *, deterministic: bool | None = None) -> dict:
        """Reconstruction of ``features [B, T, 72]`` through the posterior (``z`` drawn with
        ``key``): ``{"features", "mu", "logvar", "centre"}``."""
        c, centre = self.condition(cond, deterministic=deterministic)
        mu, logvar = self.encode(features, mask)
        z = reparameterize(key, mu, logvar)
        return {"features": self.decode(z, c, mask, deterministic=deterministic), "mu": mu,
                "logvar": logvar, "centre": centre}

    def sample(self, key, cond, mask, num_samples: int = 1):
        """``[B, K, T, 72]``: K motions per condition of ``cond`` from ``z ~ N(0, I)``
        (``key``), for frames ``mask [B, T]``; no dropout."""
        c, _ = self.condition(cond, deterministic=True)
        b = c.shape[0]
        z = jax.random.normal(key, (b, num_samples, self.cfg.latent_dim))
        cc = jnp.repeat(c[:, None], num_samples, axis=1).reshape(b * num_samples, -1)
        mk = jnp.repeat(jnp.asarray(mask, bool)[:, None], num_samples, axis=1)
        out = self.decode(z.reshape(b * num_samples, -1), cc,
                          mk.reshape(b * num_samples, -1), deterministic=True)
        return out.reshape(b, num_samples, *out.shape[1:])
