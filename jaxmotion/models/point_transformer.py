"""Point Transformer (Zhao et al., ICCV 2021): vector attention over k-NN, FPS downsampling, U-Net.

Layout follows the official code: stage ``l`` is a transition down (stride ``s_l``: farthest
point sampling keeps ``N_{l-1} / s_l`` points, each pools an MLP of its k nearest previous-level
points' ``[p_j - p_i, x_j]`` by max) followed by ``blocks[l] - 1`` residual bottleneck blocks of
vector attention; the U-Net decoder upsamples by 3-NN inverse-distance interpolation plus a skip
linear. The input features are ``[xyz, features]`` concatenated, as the official code does.

Geometry (FPS, k-NN, interpolation weights) depends on xyz only, so it is built once per
forward by :func:`build_geometry` (or by the caller, who may cache it across diffusion steps:
every ``__call__`` takes ``geometry=``). Static shapes: ``N`` must be divisible by
``prod(strides)``; k-NN is brute force in query chunks of about ``knn_budget`` distances
(4 MiB by default), ``O(N^2)`` time: on 2 CPU cores, batch 8, a full-resolution 8192-point
k-NN takes ~1 s, a 2048-point one ~0.1 s. Stages with no block skip their own k-NN,
which is why the CPU presets have ``blocks[0] == 1``: no k-NN at full resolution.

Shapes: ``xyz [B, N, 3]``, features ``[B, N, C]``; every function is batched over B.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
from flax import nnx
from jax import lax

from jaxmotion.models.configs import PointTransformerConfig

__all__ = [
    "knn", "farthest_point_sampling", "gather", "build_geometry", "Level", "Norm",
    "VectorAttention", "PointTransformerBlock", "TransitionDown", "TransitionUp",
    "PointTransformerEncoder", "PointTransformerUNet",
]


# ----------------------------------------------------------------------------- geometry kernels

def knn(queries: jax.Array, points: jax.Array, k: int, *, budget: int = 1 << 20):
    """k nearest of ``points [..., N, 3]`` for each of ``queries [..., M, 3]`` (same leading dims).

    Returns ``idx [..., M, k]`` int32 and squared distances ``[..., M, k]``, nearest first.
    Brute force over query chunks holding about ``budget`` distances for the whole batch
    (``4 * budget`` bytes; 2^20 = 4 MiB stays in cache, measured fastest on CPU). Distances use
    ``|q|^2 - 2 q.p + |p|^2`` after centring on the points' mean (a matrix product, ~3x faster
    on CPU than explicit differences; the rounding, ~1e-6 of the squared cloud radius, can
    only reorder near-ties).
    """
    *lead, m, _ = queries.shape
    n = points.shape[-2]
    if k > n:
        raise ValueError(f"knn: k={k} neighbours requested from only {n} points")
    q, p = queries.reshape(-1, m, 3), points.reshape(-1, n, 3)
    b = q.shape[0]
    centre = jnp.mean(p, axis=1, keepdims=True)
    p, q = p - centre, q - centre
    c = max(1, min(m, budget // (b * n)))
    qc = jnp.pad(q, ((0, 0), (0, -m % c), (0, 0))).reshape(b, -1, c, 3).swapaxes(0, 1)
    p2 = jnp.sum(p * p, axis=-1)[:, None, :]

    def one(qb):  # [b, c, 3]
        d2 = (jnp.sum(qb * qb, -1, keepdims=True) - 2.0 * jnp.einsum("bcd,bnd->bcn", qb, p)
              + p2)
        neg, idx = lax.top_k(-d2, k)
        return idx.astype(jnp.int32), jnp.maximum(-neg, 0.0)

    idx, d2 = lax.map(one, qc)  # [chunks, b, c, k]
    idx = idx.swapaxes(0, 1).reshape(b, -1, k)[:, :m].reshape(*lead, m, k)
    d2 = d2.swapaxes(0, 1).reshape(b, -1, k)[:, :m].reshape(*lead, m, k)
    return idx, d2


def farthest_point_sampling(points: jax.Array, m: int) -> jax.Array:
    """Indices ``[B, m]`` of ``m`` farthest-point samples of ``points [B, N, 3]``, first index 0.

    Deterministic (ties go to the lowest index) and distinct even with duplicate points (a
    chosen point's distance is set to -1). ``lax.fori_loop`` over ``m`` steps of O(N) work;
    the max + masked-min pick is ~2.5x faster on CPU than ``argmax``.
    """
    b, n, _ = points.shape
    if not 1 <= m <= n:
        raise ValueError(f"farthest_point_sampling: cannot pick {m} of {n} points")
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    rows, ar = jnp.arange(b), jnp.arange(n)[None]

    def body(i, state):
        idx, mind, last = state
        d = ((x - x[rows, last][:, None]) ** 2 + (y - y[rows, last][:, None]) ** 2
             + (z - z[rows, last][:, None]) ** 2)
        mind = jnp.minimum(mind, d)
        best = jnp.max(mind, axis=1, keepdims=True)
        nxt = jnp.min(jnp.where(mind == best, ar, n), axis=1).astype(jnp.int32)
        mind = jnp.where(ar == nxt[:, None], -1.0, mind)
        return lax.dynamic_update_slice(idx, nxt[:, None], (0, i)), mind, nxt

    mind0 = jnp.where(ar == 0, -1.0, jnp.full((b, n), jnp.inf, points.dtype))
    state = (jnp.zeros((b, m), jnp.int32), mind0, jnp.zeros(b, jnp.int32))
    return lax.fori_loop(1, m, body, state)[0]


def gather(x: jax.Array, idx: jax.Array) -> jax.Array:
    """``x [B, N, ...]``, ``idx [B, M, ...]`` -> ``x[b, idx[b]]`` of shape ``[B, M, ..., ...]``."""
    return jax.vmap(lambda a, i: a[i])(x, idx)


class Level(NamedTuple):
    """Geometry of one stage (arrays batched over B; None where not needed).

    xyz ``[B, N_l, 3]``; neighbors ``[B, N_l, k_l]``: k-NN within the stage (blocks);
    group ``[B, N_l, k_l]``: k-NN of the stage's points among the previous stage's (transition
    down); up_idx / up_weight ``[B, N_{l-1}, 3]``: the 3 nearest stage-l points of each
    previous-stage point and their normalised inverse-distance weights (transition up).
    """

    xyz: jax.Array
    neighbors: jax.Array | None = None
    group: jax.Array | None = None
    up_idx: jax.Array | None = None
    up_weight: jax.Array | None = None


def build_geometry(xyz: jax.Array, cfg: PointTransformerConfig, *,
                   neighbors: tuple[bool, ...] | None = None,
                   upsample: bool = False) -> tuple[Level, ...]:
    """Sampling, k-NN and interpolation of every stage for ``xyz [B, N, 3]`` (no gradient).

    ``neighbors[l]``: whether stage l needs its own k-NN (default: where ``blocks[l] > 1``);
    ``upsample``: also the 3-NN interpolation of each stage into the previous one (U-Net).
    """
    xyz = lax.stop_gradient(jnp.asarray(xyz, jnp.float32))
    if xyz.ndim != 3 or xyz.shape[-1] != 3:
        raise ValueError(f"xyz must be [B, N, 3], got shape {xyz.shape}")
    n = xyz.shape[1]
    if n % cfg.total_stride:
        raise ValueError(f"the point count {n} must be divisible by prod(strides)="
                         f"{cfg.total_stride} (strides {cfg.strides}); crop to a multiple")
    if neighbors is None:
        neighbors = tuple(b > 1 for b in cfg.blocks)
    bknn = partial(knn, budget=cfg.knn_budget)
    levels, prev = [], xyz
    for l, (s, k) in enumerate(zip(cfg.strides, cfg.nsample)):
        cur, group = prev, None
        if s > 1:
            m = prev.shape[1] // s
            pick = (farthest_point_sampling(prev, m) if cfg.sampling == "fps"
                    else jnp.broadcast_to(jnp.arange(m) * s, (prev.shape[0], m)))
            cur = gather(prev, pick)
            group = bknn(cur, prev, k)[0]
        nbr = bknn(cur, cur, k)[0] if neighbors[l] else None
        up_idx = up_w = None
        if upsample and l > 0:
            up_idx, d2 = bknn(prev, cur, min(3, cur.shape[1]))
            # pointops.interpolation: weights 1 / (euclidean distance + 1e-8), normalised
            w = 1.0 / (jnp.sqrt(d2) + 1e-8)
            up_w = w / jnp.sum(w, axis=-1, keepdims=True)
        levels.append(Level(cur, nbr, group, up_idx, up_w))
        prev = cur
    return tuple(levels)


# ----------------------------------------------------------------------------- layers

class Norm(nnx.Module):
    """Per-channel norm over all leading axes: BatchNorm (official), LayerNorm, or identity."""

    def __init__(self, kind: str, dim: int, *, rngs: nnx.Rngs):
        self.kind = kind
        if kind == "batch":  # PyTorch momentum 0.1 == flax momentum 0.9
            self.norm = nnx.BatchNorm(dim, momentum=0.9, epsilon=1e-5, rngs=rngs)
        elif kind == "layer":
            self.norm = nnx.LayerNorm(dim, epsilon=1e-5, rngs=rngs)
        elif kind == "none":
            self.norm = None
        else:
            raise ValueError(f"unknown norm {kind!r}; valid: batch, layer, none")

    def __call__(self, x: jax.Array, *, deterministic: bool | None = None) -> jax.Array:
        if self.kind == "batch":
            return self.norm(x, use_running_average=deterministic)
        return x if self.norm is None else self.norm(x)


class VectorAttention(nnx.Module):
    """Vector self-attention over k-NN (the official ``PointTransformerLayer``).

    ``delta = MLP(p_j - p_i)``; ``w = softmax_j(MLP(k_j - q_i + delta))`` per channel of
    ``dim / share_planes`` weight groups; ``y_i = sum_j w ⊙ (v_j + delta)`` with each weight
    shared by ``share_planes`` channels. Permutation-equivariant over points.
    """

    def __init__(self, dim: int, share_planes: int, norm: str, *, rngs: nnx.Rngs):
        if dim % share_planes:
            raise ValueError(f"dim={dim} must be divisible by share_planes={share_planes}")
        self.share = share_planes
        self.q, self.k, self.v = (nnx.Linear(dim, dim, rngs=rngs) for _ in range(3))
        self.pos1 = nnx.Linear(3, 3, rngs=rngs)
        self.pos_norm = Norm("batch" if norm == "batch" else "none", 3, rngs=rngs)
        self.pos2 = nnx.Linear(3, dim, rngs=rngs)
        self.w_norm1 = Norm(norm, dim, rngs=rngs)
        self.w1 = nnx.Linear(dim, dim // share_planes, rngs=rngs)
        self.w_norm2 = Norm(norm, dim // share_planes, rngs=rngs)
        self.w2 = nnx.Linear(dim // share_planes, dim // share_planes, rngs=rngs)

    def __call__(self, x, xyz, neighbors, *, deterministic=None):
        det = deterministic
        q, k, v = self.q(x), self.k(x), self.v(x)
        kj, vj = gather(k, neighbors), gather(v, neighbors)  # [B, N, K, C]
        rel = gather(xyz, neighbors) - xyz[:, :, None, :]
        delta = self.pos2(jax.nn.relu(self.pos_norm(self.pos1(rel), deterministic=det)))
        w = kj - q[:, :, None, :] + delta
        w = self.w1(jax.nn.relu(self.w_norm1(w, deterministic=det)))
        w = self.w2(jax.nn.relu(self.w_norm2(w, deterministic=det)))
        w = jax.nn.softmax(w, axis=2)  # over the neighbours
        b, n, kk, c = vj.shape
        vals = (vj + delta).reshape(b, n, kk, self.share, c // self.share)
        return jnp.einsum("bnksc,bnkc->bnsc", vals, w).reshape(b, n, c)


class PointTransformerBlock(nnx.Module):
    """Residual bottleneck: Linear-Norm-ReLU, vector attention-Norm-ReLU, Linear-Norm, + x, ReLU."""

    def __init__(self, dim: int, share_planes: int, norm: str, *, rngs: nnx.Rngs):
        self.linear1 = nnx.Linear(dim, dim, use_bias=False, rngs=rngs)
        self.norm1 = Norm(norm, dim, rngs=rngs)
        self.attn = VectorAttention(dim, share_planes, norm, rngs=rngs)
        self.norm2 = Norm(norm, dim, rngs=rngs)
        self.linear3 = nnx.Linear(dim, dim, use_bias=False, rngs=rngs)
        self.norm3 = Norm(norm, dim, rngs=rngs)

    def __call__(self, x, xyz, neighbors, *, deterministic=None):
        det = deterministic
        h = jax.nn.relu(self.norm1(self.linear1(x), deterministic=det))
        h = jax.nn.relu(self.norm2(self.attn(h, xyz, neighbors, deterministic=det),
                                   deterministic=det))
        h = self.norm3(self.linear3(h), deterministic=det)
        return jax.nn.relu(h + x)


class TransitionDown(nnx.Module):
    """Stride 1: Linear-Norm-ReLU. Stride s > 1: max over the k-NN group of Linear-Norm-ReLU of
    ``[p_j - p_i, x_j]`` at the sampled points (the sampling itself is in the geometry)."""

    def __init__(self, in_dim: int, out_dim: int, stride: int, norm: str, *, rngs: nnx.Rngs):
        self.stride = stride
        extra = 3 if stride > 1 else 0
        self.linear = nnx.Linear(in_dim + extra, out_dim, use_bias=False, rngs=rngs)
        self.norm = Norm(norm, out_dim, rngs=rngs)

    def __call__(self, x, prev_xyz, level: Level, *, deterministic=None):
        if self.stride > 1:
            rel = gather(prev_xyz, level.group) - level.xyz[:, :, None, :]
            x = jnp.concatenate([rel, gather(x, level.group)], axis=-1)  # [B, M, K, 3 + C]
        h = jax.nn.relu(self.norm(self.linear(x), deterministic=deterministic))
        return jnp.max(h, axis=2) if self.stride > 1 else h


class TransitionUp(nnx.Module):
    """Decoder entry. Head (``out_dim`` None): ``x = MLP([x, MLP(mean_n x)])``. Otherwise
    ``Linear-Norm-ReLU(skip) + interpolate_3NN(Linear-Norm-ReLU(coarse))``."""

    def __init__(self, in_dim: int, out_dim: int | None, norm: str, *, rngs: nnx.Rngs):
        self.head = out_dim is None
        d = in_dim if self.head else out_dim
        self.linear1 = nnx.Linear(2 * in_dim if self.head else d, d, rngs=rngs)
        self.norm1 = Norm(norm, d, rngs=rngs)
        self.linear2 = nnx.Linear(in_dim, d, rngs=rngs)
        self.norm2 = Norm("none" if self.head else norm, d, rngs=rngs)

    def __call__(self, x, coarse=None, level: Level | None = None, *, deterministic=None):
        det = deterministic
        if self.head:
            g = jax.nn.relu(self.linear2(jnp.mean(x, axis=1, keepdims=True)))
            x = jnp.concatenate([x, jnp.broadcast_to(g, x.shape)], axis=-1)
            return jax.nn.relu(self.norm1(self.linear1(x), deterministic=det))
        c = jax.nn.relu(self.norm2(self.linear2(coarse), deterministic=det))
        up = jnp.sum(gather(c, level.up_idx) * level.up_weight[..., None], axis=2)
        return jax.nn.relu(self.norm1(self.linear1(x), deterministic=det)) + up


class _Stage(nnx.Module):
    """A transition (down or up) followed by Point Transformer blocks at one resolution."""

    def __init__(self, transition, dim, num_blocks, cfg, *, rngs):
        self.transition = transition
        self.blocks = nnx.List([PointTransformerBlock(dim, cfg.share_planes, cfg.norm, rngs=rngs)
                                for _ in range(num_blocks)])

    def run_blocks(self, x, level: Level, deterministic):
        for blk in self.blocks:
            x = blk(x, level.xyz, level.neighbors, deterministic=deterministic)
        return x


# ----------------------------------------------------------------------------- networks

class PointTransformerEncoder(nnx.Module):
    """Encoder: ``(xyz [B, N, 3], features [B, N, in_channels])`` -> coarsest points and features.

    ``__call__`` returns ``(xyz [B, N / prod(strides), 3], x [B, N / prod(strides), planes[-1]])``
    (N/64 tokens for strides [1, 4, 4, 4]); :meth:`levels` returns every stage's features.
    ``in_channels`` may be 0 (xyz only).
    """

    def __init__(self, cfg: PointTransformerConfig, in_channels: int, *, rngs: nnx.Rngs):
        self.cfg = cfg
        self.in_channels = in_channels
        stages, d = [], 3 + in_channels
        for l, planes in enumerate(cfg.planes):
            td = TransitionDown(d, planes, cfg.strides[l], cfg.norm, rngs=rngs)
            stages.append(_Stage(td, planes, cfg.blocks[l] - 1, cfg, rngs=rngs))
            d = planes
        self.stages = nnx.List(stages)

    def geometry(self, xyz: jax.Array) -> tuple[Level, ...]:
        """What this encoder needs of :func:`build_geometry`."""
        return build_geometry(xyz, self.cfg)

    def _inputs(self, xyz, features):
        xyz = jnp.asarray(xyz, jnp.float32)
        if self.in_channels == 0:
            return xyz
        if features is None or features.shape[-1] != self.in_channels:
            got = None if features is None else features.shape
            raise ValueError(f"expected per-point features [B, N, {self.in_channels}], got {got}")
        return jnp.concatenate([xyz, jnp.asarray(features, jnp.float32)], axis=-1)

    def levels(self, xyz, features=None, *, geometry=None, deterministic=None):
        """Features of every stage, finest first: tuple of ``[B, N_l, planes[l]]``."""
        geometry = self.geometry(xyz) if geometry is None else geometry
        x, prev_xyz, out = self._inputs(xyz, features), geometry[0].xyz, []
        for stage, level in zip(self.stages, geometry):
            x = stage.transition(x, prev_xyz, level, deterministic=deterministic)
            x = stage.run_blocks(x, level, deterministic)
            out.append(x)
            prev_xyz = level.xyz
        return tuple(out)

    def __call__(self, xyz, features=None, *, geometry=None, deterministic=None):
        geometry = self.geometry(xyz) if geometry is None else geometry
        xs = self.levels(xyz, features, geometry=geometry, deterministic=deterministic)
        return geometry[-1].xyz, xs[-1]


class PointTransformerUNet(nnx.Module):
    """Encoder-decoder: per-point features ``[B, N, planes[0]]`` (``__call__``) or every decoder
    stage's output (:meth:`levels`, finest first), as the official segmentation network."""

    def __init__(self, cfg: PointTransformerConfig, in_channels: int, *, rngs: nnx.Rngs):
        self.cfg = cfg
        self.encoder = PointTransformerEncoder(cfg, in_channels, rngs=rngs)
        n, stages = len(cfg.planes), []
        for l in range(n):
            out = None if l == n - 1 else cfg.planes[l]
            tu = TransitionUp(cfg.planes[min(l + 1, n - 1)], out, cfg.norm, rngs=rngs)
            stages.append(_Stage(tu, cfg.planes[l], cfg.decoder_blocks - 1, cfg, rngs=rngs))
        self.decoder = nnx.List(stages)

    def geometry(self, xyz: jax.Array) -> tuple[Level, ...]:
        """What this U-Net needs of :func:`build_geometry`."""
        dec = self.cfg.decoder_blocks > 1
        return build_geometry(xyz, self.cfg, upsample=True,
                              neighbors=tuple(dec or b > 1 for b in self.cfg.blocks))

    def decode(self, xs, geometry, *, deterministic=None):
        """Decoder over encoder features ``xs`` (finest first) -> decoder features, finest first."""
        n = len(xs)
        out = [None] * n
        for l in reversed(range(n)):
            stage = self.decoder[l]
            if l == n - 1:
                x = stage.transition(xs[l], deterministic=deterministic)
            else:
                x = stage.transition(xs[l], out[l + 1], geometry[l + 1],
                                     deterministic=deterministic)
            out[l] = stage.run_blocks(x, geometry[l], deterministic)
        return tuple(out)

    def levels(self, xyz, features=None, *, geometry=None, deterministic=None):
        geometry = self.geometry(xyz) if geometry is None else geometry
        xs = self.encoder.levels(xyz, features, geometry=geometry, deterministic=deterministic)
        return self.decode(xs, geometry, deterministic=deterministic)

    def __call__(self, xyz, features=None, *, geometry=None, deterministic=None):
        return self.levels(xyz, features, geometry=geometry, deterministic=deterministic)[0]
