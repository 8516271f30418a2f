"""Shared layers: sinusoidal embeddings, MLP, masked multi-head attention, transformer layers.

Shapes: B batch, L / S sequence lengths, D width. Masks are boolean with True = valid (attend
to it), the convention of the data loader's frame mask; padded keys get a large finite negative
logit, so a row whose keys are all padded averages them instead of producing NaN.

Every ``__call__`` takes ``deterministic``: ``True`` turns dropout off, ``None`` defers to the
module attribute that ``model.eval()`` / ``model.train()`` set (NNX modules start in training
mode).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import nnx

__all__ = [
    "keep_rows",
    "sinusoidal_embedding", "TimestepEmbedder", "MLP", "MultiHeadAttention",
    "TransformerEncoderLayer", "TransformerDecoderLayer", "PerceiverLayer", "activation",
    "param_count", "dct_basis", "low_frequency_projection",
]

_NEG = -1e30  # finite "minus infinity" for masked logits


def activation(name: str) -> Callable[[jax.Array], jax.Array]:
    """``gelu`` (exact erf form, as PyTorch), ``relu`` or ``silu``."""
    table = {"gelu": lambda x: jax.nn.gelu(x, approximate=False), "relu": jax.nn.relu,
             "silu": jax.nn.silu}
    if name not in table:
        raise ValueError(f"unknown activation {name!r}; valid: {sorted(table)}")
    return table[name]


def keep_rows(cond: dict, key: str, b: int) -> jax.Array:
    """Condition-dropout multiplier ``[B, 1]``: 0 for the rows where ``cond[key]`` ([B], bool or
    0-1) is set, 1 elsewhere, and 1 for every row when ``cond`` has no ``key``."""
    if cond.get(key) is None:
        return jnp.ones((b, 1), jnp.float32)
    return 1.0 - jnp.asarray(cond[key], jnp.float32).reshape(b, 1)


def sinusoidal_embedding(positions: jax.Array, dim: int, max_period: float = 10000.0) -> jax.Array:
    """Sinusoidal features ``[...] -> [..., dim]`` of integer or real positions / timesteps.

    Interleaved as in the Transformer / MDM code the papers build on:
    ``out[..., 2i] = sin(p w_i)``, ``out[..., 2i+1] = cos(p w_i)``, ``w_i = max_period^(-2i/dim)``.
    """
    if dim % 2:
        raise ValueError(f"sinusoidal_embedding needs an even dim, got {dim}")
    freqs = jnp.exp(-math.log(max_period) * jnp.arange(0, dim, 2, dtype=jnp.float32) / dim)
    ang = jnp.asarray(positions, jnp.float32)[..., None] * freqs
    return jnp.stack([jnp.sin(ang), jnp.cos(ang)], axis=-1).reshape(*ang.shape[:-1], dim)


def dct_basis(lengths: jax.Array, num_frames: int, k: int) -> jax.Array:
    """Orthonormal DCT-II rows ``[B, k, num_frames]`` over each sequence's first ``lengths[b]``
    frames (zero beyond them, and for the rows ``>= lengths[b]``, which would alias)."""
    n = jnp.arange(num_frames, dtype=jnp.float32)[None, None, :]
    rows = jnp.arange(k, dtype=jnp.float32)[None, :, None]
    length = jnp.maximum(jnp.asarray(lengths, jnp.float32), 1.0)[:, None, None]
    scale = jnp.sqrt(2.0 / length) * jnp.where(rows == 0, math.sqrt(0.5), 1.0)
    basis = jnp.cos(math.pi * (n + 0.5) * rows / length) * scale
    return jnp.where((n < length) & (rows < length), basis, 0.0)


def low_frequency_projection(x: jax.Array, mask: jax.Array, k: int) -> jax.Array:
    """``x [B, T, D]`` projected, per sequence, onto the first ``k`` cosines (DCT-II) of its valid
    frames (``mask [B, T]``, a prefix of each row): the closest sequence, in the least-squares
    sense, whose content is slower than ``k / (2 · length)`` cycles per frame. Padded frames
    come out 0. Linear, and exact for constants, so it commutes with per-channel affine
    normalisation; ``k >= length`` returns the valid frames unchanged."""
    lengths = jnp.sum(jnp.asarray(mask, jnp.int32), axis=1)
    basis = dct_basis(lengths, x.shape[1], k)
    return jnp.einsum("bkt,bkd->btd", basis, jnp.einsum("bkt,btd->bkd", basis, x))


def param_count(module: nnx.Module) -> int:
    """Number of trainable parameters (``nnx.Param`` leaves) of a module."""
    return sum(int(x.size) for x in jax.tree.leaves(nnx.state(module, nnx.Param)))


class TimestepEmbedder(nnx.Module):
    """Diffusion step ``t [B] -> [B, out_dim]``: sinusoid (``freq_dim``), Linear-SiLU-Linear."""

    def __init__(self, freq_dim: int, out_dim: int, *, rngs: nnx.Rngs):
        self.freq_dim = freq_dim
        self.fc1 = nnx.Linear(freq_dim, out_dim, rngs=rngs)
        self.fc2 = nnx.Linear(out_dim, out_dim, rngs=rngs)

    def __call__(self, t: jax.Array) -> jax.Array:
        return self.fc2(jax.nn.silu(self.fc1(sinusoidal_embedding(t, self.freq_dim))))


class MLP(nnx.Module):
    """Linear -> activation -> dropout -> Linear on the last axis."""

    def __init__(self, in_dim: int, hidden_dim: int, out_dim: int, *, act: str = "gelu",
                 dropout: float = 0.0, rngs: nnx.Rngs):
        self.fc1 = nnx.Linear(in_dim, hidden_dim, rngs=rngs)
        self.fc2 = nnx.Linear(hidden_dim, out_dim, rngs=rngs)
        self.act = act
        self.dropout = nnx.Dropout(dropout, rngs=rngs)

    def __call__(self, x: jax.Array, *, deterministic: bool | None = None) -> jax.Array:
        h = self.dropout(activation(self.act)(self.fc1(x)), deterministic=deterministic)
        return self.fc2(h)


class MultiHeadAttention(nnx.Module):
    """Multi-head dot-product attention with a key-padding mask.

    ``q [B, Lq, q_dim]``, ``kv [B, Lk, kv_dim]``, ``key_mask [B, Lk]`` (True = valid) ->
    ``[B, Lq, out_dim]``. ``qk_dim`` defaults to ``q_dim``, ``v_dim`` to ``qk_dim``, ``out_dim``
    to ``q_dim``. ``dropout`` acts on the attention weights.
    """

    def __init__(self, q_dim: int, kv_dim: int, num_heads: int, *, qk_dim: int | None = None,
                 v_dim: int | None = None, out_dim: int | None = None, dropout: float = 0.0,
                 rngs: nnx.Rngs):
        qk_dim = qk_dim or q_dim
        v_dim = v_dim or qk_dim
        if qk_dim % num_heads or v_dim % num_heads:
            raise ValueError(f"attention widths {qk_dim}, {v_dim} must be divisible by "
                             f"num_heads={num_heads}")
        self.num_heads = num_heads
        self.q = nnx.Linear(q_dim, qk_dim, rngs=rngs)
        self.k = nnx.Linear(kv_dim, qk_dim, rngs=rngs)
        self.v = nnx.Linear(kv_dim, v_dim, rngs=rngs)
        self.o = nnx.Linear(v_dim, out_dim or q_dim, rngs=rngs)
        self.dropout = nnx.Dropout(dropout, rngs=rngs)

    def __call__(self, q: jax.Array, kv: jax.Array, key_mask: jax.Array | None = None, *,
                 deterministic: bool | None = None) -> jax.Array:
        h = self.num_heads
        qh = self.q(q).reshape(*q.shape[:-1], h, -1)  # [B, Lq, H, Dh]
        kh = self.k(kv).reshape(*kv.shape[:-1], h, -1)
        vh = self.v(kv).reshape(*kv.shape[:-1], h, -1)
        logits = jnp.einsum("bqhd,bkhd->bhqk", qh, kh) / math.sqrt(qh.shape[-1])
        if key_mask is not None:
            logits = jnp.where(key_mask[:, None, None, :], logits, _NEG)
        w = self.dropout(jax.nn.softmax(logits, axis=-1), deterministic=deterministic)
        out = jnp.einsum("bhqk,bkhd->bqhd", w, vh)
        return self.o(out.reshape(*out.shape[:-2], -1))


class TransformerEncoderLayer(nnx.Module):
    """Self-attention + feed-forward, as ``torch.nn.TransformerEncoderLayer``.

    Post-norm (``norm_first=False``, PyTorch's default and the authors' choice):
    ``x = LN(x + Drop(SA(x)))``, ``x = LN(x + Drop(FF(x)))``; pre-norm puts the LayerNorm
    in front of each branch instead. Dropout on attention weights, inside FF and on both
    residual branches.
    """

    def __init__(self, d_model: int, num_heads: int, ff_dim: int, *, dropout: float = 0.1,
                 act: str = "gelu", norm_first: bool = False, rngs: nnx.Rngs):
        self.norm_first = norm_first
        self.attn = MultiHeadAttention(d_model, d_model, num_heads, dropout=dropout, rngs=rngs)
        self.ff = MLP(d_model, ff_dim, d_model, act=act, dropout=dropout, rngs=rngs)
        self.norm1 = nnx.LayerNorm(d_model, epsilon=1e-5, rngs=rngs)
        self.norm2 = nnx.LayerNorm(d_model, epsilon=1e-5, rngs=rngs)
        self.drop1 = nnx.Dropout(dropout, rngs=rngs)
        self.drop2 = nnx.Dropout(dropout, rngs=rngs)

    def __call__(self, x: jax.Array, mask: jax.Array | None = None, *,
                 deterministic: bool | None = None) -> jax.Array:
        det = deterministic

        def sa(y):
            return self.drop1(self.attn(y, y, mask, deterministic=det), deterministic=det)

        def ff(y):
            return self.drop2(self.ff(y, deterministic=det), deterministic=det)

        if self.norm_first:
            x = x + sa(self.norm1(x))
            return x + ff(self.norm2(x))
        x = self.norm1(x + sa(x))
        return self.norm2(x + ff(x))


class TransformerDecoderLayer(nnx.Module):
    """Self-attention, cross-attention to a memory, feed-forward (as PyTorch's decoder layer).

    ``x [B, L, D]`` with ``mask [B, L]``, ``memory [B, S, D]`` with ``memory_mask [B, S]``.
    Norm placement as :class:`TransformerEncoderLayer`.
    """

    def __init__(self, d_model: int, num_heads: int, ff_dim: int, *, dropout: float = 0.1,
                 act: str = "gelu", norm_first: bool = False, rngs: nnx.Rngs):
        self.norm_first = norm_first
        self.self_attn = MultiHeadAttention(d_model, d_model, num_heads, dropout=dropout,
                                            rngs=rngs)
        self.cross_attn = MultiHeadAttention(d_model, d_model, num_heads, dropout=dropout,
                                             rngs=rngs)
        self.ff = MLP(d_model, ff_dim, d_model, act=act, dropout=dropout, rngs=rngs)
        self.norms = nnx.List([nnx.LayerNorm(d_model, epsilon=1e-5, rngs=rngs) for _ in range(3)])
        self.drops = nnx.List([nnx.Dropout(dropout, rngs=rngs) for _ in range(3)])

    def __call__(self, x: jax.Array, memory: jax.Array, mask: jax.Array | None = None,
                 memory_mask: jax.Array | None = None, *,
                 deterministic: bool | None = None) -> jax.Array:
        det = deterministic
        branches = (
            lambda y: self.self_attn(y, y, mask, deterministic=det),
            lambda y: self.cross_attn(y, memory, memory_mask, deterministic=det),
            lambda y: self.ff(y, deterministic=det),
        )
        for f, norm, drop in zip(branches, self.norms, self.drops):
            if self.norm_first:
                x = x + drop(f(norm(x)), deterministic=det)
            else:
                x = norm(x + drop(f(x), deterministic=det))
        return x


class PerceiverLayer(nnx.Module):
    """Pre-norm Perceiver layer: cross-attention, or self-attention if ``kv_dim`` is None.

    ``x = x + Attn(LN(x), LN_kv(kv))``; ``x = x + MLP(LN(x))`` with an MLP of width
    ``widening * q_dim`` and GELU, as the Perceiver IO code the ADM authors use; ``dropout``
    is on the attention weights, ``residual_dropout`` on both branches. Attention widths
    (query-key and value) equal ``q_dim``.
    """

    def __init__(self, q_dim: int, kv_dim: int | None, num_heads: int, *, widening: int = 1,
                 dropout: float = 0.0, residual_dropout: float = 0.0, rngs: nnx.Rngs):
        self.is_self = kv_dim is None
        self.q_norm = nnx.LayerNorm(q_dim, epsilon=1e-5, rngs=rngs)
        self.kv_norm = None if self.is_self else nnx.LayerNorm(kv_dim, epsilon=1e-5, rngs=rngs)
        self.attn = MultiHeadAttention(q_dim, q_dim if self.is_self else kv_dim, num_heads,
                                       dropout=dropout, rngs=rngs)
        self.mlp_norm = nnx.LayerNorm(q_dim, epsilon=1e-5, rngs=rngs)
        self.mlp = MLP(q_dim, widening * q_dim, q_dim, act="gelu", rngs=rngs)
        self.drop = nnx.Dropout(residual_dropout, rngs=rngs)

    def __call__(self, x: jax.Array, kv: jax.Array | None = None,
                 key_mask: jax.Array | None = None, *,
                 deterministic: bool | None = None) -> jax.Array:
        det = deterministic
        q = self.q_norm(x)
        kv = q if self.is_self else self.kv_norm(kv)
        x = x + self.drop(self.attn(q, kv, key_mask, deterministic=det), deterministic=det)
        return x + self.drop(self.mlp(self.mlp_norm(x), deterministic=det), deterministic=det)
