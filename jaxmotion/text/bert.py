"""The all-MiniLM-L6-v2 network (a 6-layer BERT) in Flax NNX, and loading its weights.

Kept apart from :mod:`jaxmotion.text.minilm` (tokenisation, configuration, the cached
one-sentence program), which imports it only when a network is built: a repeated or cached
sentence never imports Flax.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.text.bert_config import BertConfig, hf_parameter_names

__all__ = ["BertLayer", "MiniLM", "load_minilm_weights"]

# Full float32 matmuls also on accelerators (TF32 would cost the 1e-4 cosine budget).
_PREC = jax.lax.Precision.HIGHEST


def _linear(i, o, rngs):
    return nnx.Linear(i, o, precision=_PREC, rngs=rngs)


class BertLayer(nnx.Module):
    """Post-LN transformer block: x = LN(x + Attn(x)); x = LN(x + FF(x))."""

    def __init__(self, cfg: BertConfig, *, rngs: nnx.Rngs):
        d = cfg.hidden
        self.heads = cfg.heads
        self.query = _linear(d, d, rngs)
        self.key = _linear(d, d, rngs)
        self.value = _linear(d, d, rngs)
        self.attn_out = _linear(d, d, rngs)
        self.attn_norm = nnx.LayerNorm(d, epsilon=cfg.eps, rngs=rngs)
        self.ff_in = _linear(d, cfg.intermediate, rngs)
        self.ff_out = _linear(cfg.intermediate, d, rngs)
        self.ff_norm = nnx.LayerNorm(d, epsilon=cfg.eps, rngs=rngs)

    def __call__(self, x, bias):
        """x [B, T, D], bias [B, 1, 1, T] additive attention mask → [B, T, D]."""
        b, t, d = x.shape
        h = self.heads

        def split(y):  # [B, T, D] -> [B, H, T, D/H]
            return y.reshape(b, t, h, d // h).transpose(0, 2, 1, 3)

        q, k, v = split(self.query(x)), split(self.key(x)), split(self.value(x))
        logits = jnp.einsum("bhqd,bhkd->bhqk", q, k, precision=_PREC) / np.sqrt(d // h)
        weights = jax.nn.softmax(logits + bias, axis=-1)
        ctx = jnp.einsum("bhqk,bhkd->bhqd", weights, v, precision=_PREC)
        ctx = ctx.transpose(0, 2, 1, 3).reshape(b, t, d)
        x = self.attn_norm(x + self.attn_out(ctx))
        ff = self.ff_out(jax.nn.gelu(self.ff_in(x), approximate=False))
        return self.ff_norm(x + ff)


class MiniLM(nnx.Module):
    """BERT encoder + masked mean pooling + L2 normalisation (sentence-transformers)."""

    def __init__(self, cfg: BertConfig = BertConfig(), *, rngs: nnx.Rngs):
        self.cfg = cfg
        self.word = nnx.Embed(cfg.vocab_size, cfg.hidden, rngs=rngs)
        self.position = nnx.Embed(cfg.max_positions, cfg.hidden, rngs=rngs)
        self.token_type = nnx.Embed(cfg.type_vocab, cfg.hidden, rngs=rngs)
        self.embed_norm = nnx.LayerNorm(cfg.hidden, epsilon=cfg.eps, rngs=rngs)
        self.layers = nnx.List([BertLayer(cfg, rngs=rngs) for _ in range(cfg.layers)])

    def hidden_states(self, ids, mask):
        """ids [B, T] int32, mask [B, T] (1 real, 0 padding) → last hidden states [B, T, D]."""
        t = ids.shape[1]
        # Single-sentence inputs: token type 0 everywhere, positions 0..T-1.
        x = self.word(ids) + self.position(jnp.arange(t))[None] + self.token_type.embedding[0]
        x = self.embed_norm(x)
        # HF BERT adds finfo(float32).min at padded keys: exp() of it is exactly 0.
        bias = jnp.where(mask[:, None, None, :] > 0, 0.0, jnp.finfo(jnp.float32).min)
        for layer in self.layers:
            x = layer(x, bias)
        return x

    def __call__(self, ids, mask):
        """ids [B, T] int32, mask [B, T] → unit-norm sentence embeddings [B, D] float32."""
        return self.pool(self.hidden_states(ids, mask), mask)

    @staticmethod
    def pool(x, mask):
        """Hidden states x [B, T, D] → the unit-norm mean over the real tokens [B, D]
        (sentence-transformers' mean pooling and normalisation)."""
        m = mask.astype(x.dtype)[..., None]
        mean = (x * m).sum(1) / jnp.maximum(m.sum(1), 1e-9)
        norm = jnp.linalg.norm(mean, axis=-1, keepdims=True)
        return mean / jnp.maximum(norm, 1e-12)  # torch.nn.functional.normalize


# Present in the checkpoint but unused by mean pooling (or buffers, not weights).
_UNUSED = ("embeddings.position_ids", "pooler.dense.weight", "pooler.dense.bias")


def load_minilm_weights(folder) -> MiniLM:
    """Build :class:`MiniLM` from ``folder``'s config.json and model.safetensors.

    Every parameter must be found with the right shape and every tensor of the
    file must be used (except the pooler and buffers), else ValueError.
    """
    from safetensors.numpy import load_file

    folder = Path(folder)
    cfg = BertConfig.from_hf(folder / "config.json")
    tensors = load_file(str(folder / "model.safetensors"))
    # Build only shapes (no random init of 12M parameters), then fill them in.
    model = nnx.eval_shape(lambda: MiniLM(cfg, rngs=nnx.Rngs(0)))
    graphdef, state = nnx.split(model)
    flat = dict(nnx.to_flat_state(state))
    names = hf_parameter_names(cfg)
    if set(flat) != set(names):
        raise AssertionError(f"parameter map out of date: {set(flat) ^ set(names)}")
    used = set()
    for path, var in flat.items():
        hf, transpose = names[path]
        if hf not in tensors:
            raise ValueError(f"{folder}/model.safetensors has no tensor {hf!r}")
        arr = np.asarray(tensors[hf], np.float32)
        arr = arr.T if transpose else arr
        want = tuple(var.get_value().shape)
        if arr.shape != want:
            raise ValueError(f"{hf}: shape {arr.shape}, expected {want}")
        var.set_value(jnp.asarray(arr))
        used.add(hf)
    left = set(tensors) - used - set(_UNUSED)
    if left:
        raise ValueError(f"unexpected tensors in {folder}/model.safetensors: {sorted(left)}")
    return nnx.merge(graphdef, nnx.from_flat_state(flat))


