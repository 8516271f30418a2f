"""Affordance Diffusion Model (ADM): denoise a per-point affordance map given scene, text and time.

All variants share one call: ``model(x, t, cond, *, deterministic=None) -> x0 [B, N, A]``, the
x0 prediction of the normalised affordance, with

- ``x [B, N, A]``: noisy affordance (A = 6 joints); ``t [B]``: diffusion step (int or float);
- ``cond["text"] [B, text_dim]``: sentence embedding (zeros = no text, for guidance);
- ``cond["features"] [B, N, feature_dim]``: the frozen segmentation backbone's per-point
  features (computed outside: the module never sees the backbone);
- ``cond["xyz"] [B, N, 3]``: point positions (crop frame, metres);
- with ``ADMConfig.target_input`` (Perceiver only): ``cond["target"] [B, N]``, 1 on a known
  target object's points, 0 elsewhere (all 0 = none known), appended to the per-point input;
- optional ``cond["drop_text"] [B]`` (bool / 0-1): zero those rows' text embedding inside the
  model (and mask out their token latents); the caller may equally zero ``cond["text"]`` itself
  (and ``cond["text_mask"]``);
- with ``ADMConfig.text_tokens = L > 0`` (Perceiver only): ``cond["text_tokens"] [B, L,
  text_dim]``, the text encoder's per-token states, and ``cond["text_mask"] [B, L]`` (True =
  a real token). A row whose mask is all False reads no token: the model then sees exactly
  what the pooled-only model would.

Variants (``ADMConfig.arch``; :func:`make_adm` builds the right one):

- :class:`ADM` (``perceiver``, the paper's): points -> Linear -> point width; latents =
  [text token, time token] (+ L word latents with ``text_tokens = L``); encode =
  cross-attention latents <- points; ``self_layers`` self-attention layers on the latents; decode = cross-attention points <- latents (queries =
  Linear of the point array); Linear -> A. Pre-norm Perceiver IO layers as the authors' code.
  Permutation-equivariant over points; memory linear in N.
- :class:`ADMMLP` (``mlp``): PointNet-style; per-point [x, features, xyz, text, time] through
  shared MLP layers, each followed by a global (max or mean) pooled feature concatenated back
  and a second MLP (the authors' ``PointSceneMLP``); Linear -> A.
- :class:`ADMPointTransformer` (``point_transformer``): the Point Transformer U-Net over xyz +
  [x, features]; the context [text, time embedding] is concatenated to the encoder features of
  every stage but the finest and mixed by Linear-Norm-ReLU-Linear before decoding (as the
  authors' ``ContactPointTransV2``, without its extra self-attention); Linear -> A.
  ``cond["geometry"]`` may carry precomputed :meth:`ADMPointTransformer.geometry` (the points do
  not change across diffusion steps).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.models.configs import ADMConfig
from jaxmotion.models.layers import MLP, PerceiverLayer, TimestepEmbedder
from jaxmotion.models.point_transformer import Norm, PointTransformerUNet
from jaxmotion.text.condition import pooled_text

__all__ = ["ADM", "ADMMLP", "ADMPointTransformer", "adm_text_cond", "make_adm", "pooled_text"]


def adm_text_cond(text) -> dict:
    """The ADM cond entries of a text condition: a pooled embedding array ``[B, D]``, or a
    word-level mapping ``{"pooled": [B, D], "tokens": [B, L, D], "mask": [B, L]}``."""
    if isinstance(text, dict):
        return {"text": text["pooled"], "text_tokens": text["tokens"], "text_mask": text["mask"]}
    return {"text": text}


def _inputs(cfg: ADMConfig, x, t, cond):
    """Validated float32 inputs: (x, t [B], text [B, Dt], features, xyz); with
    ``cfg.target_input`` the features end with the target channel (``cond["target"]``)."""
    x = jnp.asarray(x, jnp.float32)
    b, n = x.shape[:2]
    want = {"text": (b, cfg.text_dim), "features": (b, n, cfg.feature_dim), "xyz": (b, n, 3)}
    if cfg.target_input:
        if "target" not in cond:
            raise KeyError("this ADM reads a known target (target_input=True): cond needs "
                           f"'target' {[b, n]} (all zeros when no target is known); got keys "
                           f"{sorted(cond)}")
        want["target"] = (b, n)
    if x.shape[-1] != cfg.affordance_dim:
        raise ValueError(f"x must be [B, N, {cfg.affordance_dim}], got {x.shape}")
    out = {}
    for key, shape in want.items():
        if key not in cond:
            raise KeyError(f"ADM cond needs {key!r} {list(shape)}; got keys {sorted(cond)}")
        v = jnp.asarray(cond[key], jnp.float32)
        if v.shape != shape:
            raise ValueError(f"cond[{key!r}] must have shape {shape}, got {v.shape}")
        out[key] = v
    text = out["text"]
    if cond.get("drop_text") is not None:
        text = text * (1.0 - jnp.asarray(cond["drop_text"], jnp.float32).reshape(b, 1))
    t = jnp.broadcast_to(jnp.asarray(t), (b,))
    feats = out["features"]
    if cfg.target_input:
        feats = jnp.concatenate([feats, out["target"][..., None]], axis=-1)
    return x, t, text, feats, out["xyz"]


def _token_inputs(cfg: ADMConfig, b: int, cond):
    """``(tokens [B, L, Dt], mask [B, L] bool)`` of a word-level ADM, drop_text applied."""
    want = (b, cfg.text_tokens, cfg.text_dim)
    if "text_tokens" not in cond or "text_mask" not in cond:
        raise KeyError(f"this ADM reads word-level text (text_tokens={cfg.text_tokens}): cond "
                       f"needs 'text_tokens' {list(want)} and 'text_mask' {list(want[:2])}; got "
                       f"keys {sorted(cond)}")
    tokens = jnp.asarray(cond["text_tokens"], jnp.float32)
    mask = jnp.asarray(cond["text_mask"]).astype(bool)
    if tokens.shape != want or mask.shape != want[:2]:
        raise ValueError(f"cond['text_tokens'] must be {want} and cond['text_mask'] "
                         f"{want[:2]}, got {tokens.shape} and {mask.shape}")
    if cond.get("drop_text") is not None:
        mask = mask & ~jnp.asarray(cond["drop_text"]).astype(bool).reshape(b, 1)
    return tokens, mask


class ADM(nnx.Module):
    """The paper's Perceiver ADM (see the module docstring)."""

    def __init__(self, cfg: ADMConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        pw, lw, h = cfg.point_width, cfg.latent_width, cfg.num_heads
        kw = dict(widening=cfg.widening, dropout=cfg.dropout, rngs=rngs)
        self.time_embed = TimestepEmbedder(cfg.time_dim, cfg.time_dim, rngs=rngs)
        self.text_proj = nnx.Linear(cfg.text_dim, lw, rngs=rngs)
        if cfg.text_tokens:
            self.token_norm = nnx.LayerNorm(cfg.text_dim, epsilon=1e-5, rngs=rngs)
            self.token_proj = nnx.Linear(cfg.text_dim, lw, rngs=rngs)
        self.time_proj = nnx.Linear(cfg.time_dim, lw, rngs=rngs)
        n_in = cfg.affordance_dim + cfg.feature_dim + int(cfg.target_input) + 3
        self.point_in = nnx.Linear(n_in, pw, rngs=rngs)
        self.encode = PerceiverLayer(lw, pw, h, **kw)
        self.process = nnx.List([PerceiverLayer(lw, None, h, **kw) for _ in range(cfg.self_layers)])
        self.decode_in = nnx.Linear(pw, pw, rngs=rngs)
        self.decode = PerceiverLayer(pw, lw, h, **kw)
        self.out = nnx.Linear(pw, cfg.affordance_dim, rngs=rngs)

    def __call__(self, x, t, cond, *, deterministic: bool | None = None):
        det = deterministic
        x, t, text, feats, xyz = _inputs(self.cfg, x, t, cond)
        points = self.point_in(jnp.concatenate([x, feats, xyz], axis=-1))  # [B, N, pw]
        latents = jnp.stack([self.text_proj(text), self.time_proj(self.time_embed(t))], axis=1)
        latent_mask = None
        if self.cfg.text_tokens:
            tokens, tmask = _token_inputs(self.cfg, x.shape[0], cond)
            words = self.token_proj(self.token_norm(tokens))  # [B, L, lw]
            latents = jnp.concatenate([latents, words], axis=1)
            latent_mask = jnp.concatenate([jnp.ones((x.shape[0], 2), bool), tmask], axis=1)
        latents = self.encode(latents, points, deterministic=det)
        for layer in self.process:
            latents = layer(latents, key_mask=latent_mask, deterministic=det)
        y = self.decode(self.decode_in(points), latents, key_mask=latent_mask, deterministic=det)
        return self.out(y)


class _PointSceneMLP(nnx.Module):
    """Per-point MLP, then [h, pool_n(h)] through a second MLP (authors' ``PointSceneMLP``)."""

    def __init__(self, in_dim, out_dim, pool, *, rngs):
        self.pool = pool
        self.norm_pre = nnx.LayerNorm(in_dim, epsilon=1e-5, rngs=rngs)
        self.pre = MLP(in_dim, in_dim, out_dim, act="gelu", rngs=rngs)
        self.norm_post = nnx.LayerNorm(2 * out_dim, epsilon=1e-5, rngs=rngs)
        self.post = MLP(2 * out_dim, 2 * out_dim, out_dim, act="gelu", rngs=rngs)

    def __call__(self, h):
        h = self.pre(self.norm_pre(h))
        pool = jnp.max if self.pool == "max" else jnp.mean
        g = pool(h, axis=1, keepdims=True)
        return self.post(self.norm_post(jnp.concatenate([h, jnp.broadcast_to(g, h.shape)], -1)))


class ADMMLP(nnx.Module):
    """PointNet-style ADM ablation (see the module docstring)."""

    def __init__(self, cfg: ADMConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        self.time_embed = TimestepEmbedder(cfg.time_dim, cfg.time_dim, rngs=rngs)
        d = cfg.affordance_dim + cfg.feature_dim + 3 + cfg.text_dim + cfg.time_dim
        layers = []
        for width in cfg.mlp_dims:
            layers.append(_PointSceneMLP(d, width, cfg.pool, rngs=rngs))
            d = width
        self.layers = nnx.List(layers)
        self.out = nnx.Linear(d, cfg.affordance_dim, rngs=rngs)

    def __call__(self, x, t, cond, *, deterministic: bool | None = None):
        x, t, text, feats, xyz = _inputs(self.cfg, x, t, cond)
        b, n = x.shape[:2]
        ctx = jnp.concatenate([text, self.time_embed(t)], axis=-1)[:, None]
        h = jnp.concatenate([x, feats, xyz, jnp.broadcast_to(ctx, (b, n, ctx.shape[-1]))], -1)
        for layer in self.layers:
            h = layer(h)
        return self.out(h)


class ADMPointTransformer(nnx.Module):
    """Point Transformer U-Net ADM ablation (see the module docstring)."""

    def __init__(self, cfg: ADMConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        pt = cfg.point_transformer
        self.time_embed = TimestepEmbedder(cfg.time_dim, cfg.time_dim, rngs=rngs)
        self.unet = PointTransformerUNet(pt, cfg.affordance_dim + cfg.feature_dim, rngs=rngs)
        ctx = cfg.text_dim + cfg.time_dim
        self.ctx1 = nnx.List([nnx.Linear(p + ctx, p, rngs=rngs) for p in pt.planes[1:]])
        self.ctx_norm = nnx.List([Norm(pt.norm, p, rngs=rngs) for p in pt.planes[1:]])
        self.ctx2 = nnx.List([nnx.Linear(p, p, rngs=rngs) for p in pt.planes[1:]])
        self.out = nnx.Linear(pt.planes[0], cfg.affordance_dim, rngs=rngs)

    def geometry(self, xyz):
        """Precomputable geometry; pass it as ``cond["geometry"]``."""
        return self.unet.geometry(xyz)

    def __call__(self, x, t, cond, *, deterministic: bool | None = None):
        det = deterministic
        x, t, text, feats, xyz = _inputs(self.cfg, x, t, cond)
        geometry = cond.get("geometry")
        geometry = self.unet.geometry(xyz) if geometry is None else geometry
        xs = list(self.unet.encoder.levels(xyz, jnp.concatenate([x, feats], -1),
                                           geometry=geometry, deterministic=det))
        ctx = jnp.concatenate([text, self.time_embed(t)], axis=-1)[:, None]
        for i, (l1, nm, l2) in enumerate(zip(self.ctx1, self.ctx_norm, self.ctx2)):
            h = xs[i + 1]
            h = jnp.concatenate([h, jnp.broadcast_to(ctx, (*h.shape[:2], ctx.shape[-1]))], -1)
            xs[i + 1] = l2(jax.nn.relu(nm(l1(h), deterministic=det)))
        y = self.unet.decode(tuple(xs), geometry, deterministic=det)[0]
        return self.out(y)


def make_adm(cfg: ADMConfig, *, rngs: nnx.Rngs):
    """The ADM variant named by ``cfg.arch``."""
    table = {"perceiver": ADM, "mlp": ADMMLP, "point_transformer": ADMPointTransformer}
    return table[cfg.arch](cfg, rngs=rngs)
