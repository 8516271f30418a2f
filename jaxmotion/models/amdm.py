"""Affordance-to-Motion Diffusion Model (AMDM), @Enc and @Dec, and the one-stage baseline.

``model(x, t, cond, *, deterministic=None) -> x0 [B, T, motion_dim]``: the x0 prediction of the
normalised motion (66 = 22 joints x 3), with

- ``x [B, T, motion_dim]``: noisy motion; ``t [B]``: diffusion step;
- ``cond["mask"] [B, T]`` bool, True = valid frame (key-padding mask; default all valid);
- ``cond["text"] [B, text_dim]``: sentence embedding;
- ``cond["xyz"] [B, N, 3]`` and ``cond["affordance"] [B, N, affordance_dim]`` (two-stage) or
  ``cond["rgb"] [B, N, 3]`` (one-stage baseline, ``scene_input="rgb"``);
- optional ``cond["drop_text"]``, ``cond["drop_affordance"] [B]`` (bool / 0-1): classifier-free
  guidance dropout done inside, as the authors do it: the text embedding and the encoded point
  tokens of those rows are zeroed before their projections. Zeroed inputs are valid too;
- optional ``cond["point_tokens"]``: the output of :meth:`AMDM.encode_condition`, so that a
  sampler encodes the (fixed) affordance once instead of at every step.

@Enc (``arch="enc"``, the paper's): Point Transformer encoder over [xyz, affordance] ->
``N / prod(strides)`` tokens -> Linear -> d; a transformer encoder over
``[time, text, point tokens, frames]`` with sinusoidal positions over the whole sequence
(+ dropout) and the key-padding mask; frames -> Linear -> motion_dim. Post-norm by default
(PyTorch's ``TransformerEncoderLayer`` default, which the authors use); ``norm_first=True``
gives pre-norm.

@Dec (``arch="dec"``): a Point Transformer U-Net gives features at every stage; the sequence is
``[time, text, frames]``; after self-attention layer ``i`` (for ``i < n_cross``,
``n_cross = min(stages, max(1, num_layers - 1))``: 4 of 5 in the paper size) a transformer
decoder layer (self-attention, cross-attention, feed-forward) attends to stage features
coarsest first, each projected by Linear + LayerNorm, as the authors' ``trans_dec``.

With ``temporal_basis=K`` the per-frame output is replaced by its least-squares fit by the first
K cosines of the valid frames (:func:`~jaxmotion.models.layers.low_frequency_projection`), so
the x0 prediction, and with it every sample, is built from K smooth components; trained with
it, the network learns the motion in that basis (padded frames come out 0).
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import nnx

from jaxmotion.models.configs import AMDMConfig
from jaxmotion.models.layers import (
    TimestepEmbedder,
    TransformerDecoderLayer,
    TransformerEncoderLayer,
    keep_rows,
    low_frequency_projection,
    sinusoidal_embedding,
)
from jaxmotion.models.point_transformer import PointTransformerEncoder, PointTransformerUNet

__all__ = ["AMDM"]


class AMDM(nnx.Module):
    """AMDM @Enc / @Dec; the one-stage baseline with ``scene_input="rgb"`` (module docstring)."""

    def __init__(self, cfg: AMDMConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        d, enc = cfg.d_model, cfg.encoder
        kw = dict(dropout=cfg.dropout, act="gelu", norm_first=cfg.norm_first, rngs=rngs)
        self.time_embed = TimestepEmbedder(cfg.time_dim, d, rngs=rngs)
        self.text_proj = nnx.Linear(cfg.text_dim, d, rngs=rngs)
        self.motion_in = nnx.Linear(cfg.motion_dim, d, rngs=rngs)
        self.motion_out = nnx.Linear(d, cfg.motion_dim, rngs=rngs)
        self.pos_drop = nnx.Dropout(cfg.dropout, rngs=rngs)
        self.layers = nnx.List([TransformerEncoderLayer(d, cfg.num_heads, cfg.ff_dim, **kw)
                                for _ in range(cfg.num_layers)])
        if cfg.arch == "enc":
            self.n_cross = 0
            self.point_encoder = PointTransformerEncoder(enc, cfg.point_channels, rngs=rngs)
            self.point_proj = nnx.Linear(enc.planes[-1], d, rngs=rngs)
        elif cfg.arch == "dec":
            self.n_cross = min(len(enc.planes), max(1, cfg.num_layers - 1))
            self.point_encoder = PointTransformerUNet(enc, cfg.point_channels, rngs=rngs)
            widths = enc.planes[::-1][: self.n_cross]
            self.memory_proj = nnx.List([nnx.Linear(w, d, rngs=rngs) for w in widths])
            self.memory_norm = nnx.List([nnx.LayerNorm(d, epsilon=1e-5, rngs=rngs)
                                         for _ in widths])
            self.cross_layers = nnx.List([TransformerDecoderLayer(d, cfg.num_heads, cfg.ff_dim,
                                                                  **kw) for _ in widths])
        else:
            raise ValueError(f"unknown AMDM arch {cfg.arch!r}; valid: enc, dec")

    @property
    def point_key(self) -> str:
        """The ``cond`` key of the per-point input: ``affordance`` or ``rgb``."""
        return "affordance" if self.cfg.scene_input == "affordance" else "rgb"

    def geometry(self, xyz):
        """Precomputable Point Transformer geometry of ``xyz [B, N, 3]``."""
        return self.point_encoder.geometry(xyz)

    def encode_condition(self, cond, *, deterministic: bool | None = None) -> dict:
        """``cond`` plus ``point_tokens``: ``[B, G, planes[-1]]`` (@Enc) or a tuple of stage
        features coarsest first (@Dec). Reused by ``__call__`` when present."""
        key = self.point_key
        if "xyz" not in cond or key not in cond:
            raise KeyError(f"AMDM cond needs 'xyz' [B, N, 3] and {key!r} [B, N, "
                           f"{self.cfg.point_channels}]; got keys {sorted(cond)}")
        xyz, feats = cond["xyz"], jnp.asarray(cond[key], jnp.float32)
        if self.cfg.arch == "enc":
            tokens = self.point_encoder(xyz, feats, geometry=cond.get("geometry"),
                                        deterministic=deterministic)[1]
        else:
            levels = self.point_encoder.levels(xyz, feats, geometry=cond.get("geometry"),
                                               deterministic=deterministic)
            tokens = tuple(levels[::-1][: self.n_cross])
        return {**cond, "point_tokens": tokens}

    def __call__(self, x, t, cond, *, deterministic: bool | None = None):
        det, cfg = deterministic, self.cfg
        x = jnp.asarray(x, jnp.float32)
        if x.ndim != 3 or x.shape[-1] != cfg.motion_dim:
            raise ValueError(f"x must be [B, T, {cfg.motion_dim}], got {x.shape}")
        b, nt = x.shape[:2]
        text = jnp.asarray(cond["text"], jnp.float32)
        if text.shape != (b, cfg.text_dim):
            raise ValueError(f"cond['text'] must be [{b}, {cfg.text_dim}], got {text.shape} "
                             "(set the config's text_dim to the text encoder's width)")
        mask = cond.get("mask")
        mask = jnp.ones((b, nt), bool) if mask is None else jnp.asarray(mask, bool)
        if "point_tokens" not in cond:
            cond = self.encode_condition(cond, deterministic=det)
        tokens, keep = cond["point_tokens"], keep_rows(cond, "drop_affordance", b)[:, :, None]
        t = jnp.broadcast_to(jnp.asarray(t), (b,))
        prefix = [self.time_embed(t)[:, None],
                  self.text_proj(text * keep_rows(cond, "drop_text", b))[:, None]]
        if cfg.arch == "enc":
            prefix.append(self.point_proj(tokens * keep))
        n_prefix = sum(p.shape[1] for p in prefix)
        seq = jnp.concatenate([*prefix, self.motion_in(x)], axis=1)
        seq_mask = jnp.concatenate([jnp.ones((b, n_prefix), bool), mask], axis=1)
        seq = seq + sinusoidal_embedding(jnp.arange(seq.shape[1]), cfg.d_model)[None]
        seq = self.pos_drop(seq, deterministic=det)
        for i, layer in enumerate(self.layers):
            seq = layer(seq, seq_mask, deterministic=det)
            if i < self.n_cross:
                mem = self.memory_norm[i](self.memory_proj[i](tokens[i] * keep))
                seq = self.cross_layers[i](seq, mem, seq_mask, None, deterministic=det)
        out = self.motion_out(seq[:, n_prefix:])
        if cfg.temporal_basis:
            out = low_frequency_projection(out, mask, cfg.temporal_basis)
        return out
