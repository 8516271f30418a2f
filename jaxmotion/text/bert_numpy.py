"""The sentence encoder's network (:mod:`jaxmotion.text.bert`) for one sentence in NumPy.

``generate`` encodes one new sentence per run. Through XLA that meant loading a compiled
program (0.6–0.8 s on a 2-core CPU, longer while the samplers' programs load beside it) for a
forward pass that takes milliseconds; here the same network runs on the host in float64
(30–80 ms for 7–30 tokens), reading only the weights it needs from ``model.safetensors``:
the layers (44 MB) and the rows of the word table the sentence's tokens name.

One sentence needs no padding: its tokens attend to each other only (a padded batch gives
padded keys exactly zero weight), so the result is the batch encoder's up to float rounding
(the pooled embedding within ~2e-7, the token states within ~3e-6; see ``tests/test_text.py``).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from jaxmotion.text.bert_config import BertConfig

__all__ = ["BertWeights", "encode_tokens", "load_weights"]

_WORDS = "embeddings.word_embeddings.weight"


class BertWeights:
    """The weights of a BERT for :func:`encode_tokens`: its configuration, the layers'
    tensors (float64, the dense kernels turned to ``[in, out]``) and the word table read row
    by row from the file."""

    def __init__(self, path: Path, cfg: BertConfig, tensors: dict[str, np.ndarray]):
        self.path, self.cfg = Path(path), cfg
        self._t = tensors
        self._rows: dict[int, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        return self._t[name]

    def words(self, ids) -> np.ndarray:
        """The word-table rows of ``ids`` ``[len(ids), hidden]`` float64 (read once each)."""
        missing = sorted({int(i) for i in ids} - self._rows.keys())
        if missing:
            from safetensors import safe_open

            with safe_open(str(self.path), framework="numpy") as f:
                table = f.get_slice(_WORDS)
                rows = table.get_shape()[0]
                for i in missing:
                    if not 0 <= i < rows:
                        raise ValueError(f"token id {i} is outside the word table ({rows} rows)")
                    self._rows[i] = np.asarray(table[i:i + 1][0], np.float64)
        return np.stack([self._rows[int(i)] for i in ids])


def load_weights(folder) -> BertWeights:
    """The weights of the BERT in ``folder`` (``config.json``, ``model.safetensors``), read
    once per process while the file is unchanged (its size and modification time key it)."""
    path = Path(folder) / "model.safetensors"
    st = path.stat()
    return _load(str(path), st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=2)
def _load(path: str, size: int, mtime_ns: int) -> BertWeights:
    from safetensors import safe_open

    from jaxmotion.text.bert_config import hf_parameter_names

    cfg = BertConfig.from_hf(Path(path).parent / "config.json")
    needed = {name: turn for name, turn in hf_parameter_names(cfg).values() if name != _WORDS}
    tensors = {}
    with safe_open(path, framework="numpy") as f:
        missing = sorted(set(needed) - set(f.keys()))
        if missing:
            raise ValueError(f"{path} has no tensor {missing[0]!r} (and {len(missing) - 1} "
                             "more): not a BERT of this configuration")
        for name, turn in needed.items():
            t = f.get_tensor(name).astype(np.float64)
            tensors[name] = np.ascontiguousarray(t.T) if turn else t
    return BertWeights(Path(path), cfg, tensors)


def encode_tokens(ids, weights: BertWeights) -> tuple[np.ndarray, np.ndarray]:
    """One tokenised sentence (``[CLS] … [SEP]`` ids) through the network:
    ``(pooled [hidden], states [len(ids), hidden])`` float32 — the unit-norm mean of the last
    hidden states (sentence-transformers' embedding) and the states themselves."""
    ids = np.asarray(ids, np.int64)
    cfg, w = weights.cfg, weights
    t, d, h = len(ids), cfg.hidden, cfg.heads
    if t == 0 or t > cfg.max_positions:
        raise ValueError(f"a sentence of {t} tokens: the encoder reads 1 to "
                         f"{cfg.max_positions}")
    x = (weights.words(ids) + w["embeddings.position_embeddings.weight"][:t]
         + w["embeddings.token_type_embeddings.weight"][0])
    x = _layer_norm(x, w, "embeddings.LayerNorm", cfg.eps)
    for i in range(cfg.layers):
        pre = f"encoder.layer.{i}."

        def dense(y, name):
            return y @ w[pre + name + ".weight"] + w[pre + name + ".bias"]

        def heads(y):  # [T, D] -> [H, T, D/H]
            return y.reshape(t, h, d // h).transpose(1, 0, 2)

        q, k, v = (heads(dense(x, f"attention.self.{n}")) for n in ("query", "key", "value"))
        logits = q @ k.transpose(0, 2, 1) / math.sqrt(d // h)
        e = np.exp(logits - logits.max(-1, keepdims=True))
        ctx = ((e / e.sum(-1, keepdims=True)) @ v).transpose(1, 0, 2).reshape(t, d)
        x = _layer_norm(x + dense(ctx, "attention.output.dense"), w,
                        pre + "attention.output.LayerNorm", cfg.eps)
        x = _layer_norm(x + dense(_gelu(dense(x, "intermediate.dense")), "output.dense"), w,
                        pre + "output.LayerNorm", cfg.eps)
    mean = x.mean(0)
    pooled = mean / max(float(np.linalg.norm(mean)), 1e-12)
    return pooled.astype(np.float32), x.astype(np.float32)


def _layer_norm(x, w, name, eps):
    mu = x.mean(-1, keepdims=True)
    var = np.square(x - mu).mean(-1, keepdims=True)
    return (x - mu) / np.sqrt(var + eps) * w[name + ".weight"] + w[name + ".bias"]


_ERF = np.frompyfunc(math.erf, 1, 1)


def _gelu(x):
    """The exact (erf) GELU, as BERT's ``"gelu"``."""
    return 0.5 * x * (1.0 + _ERF(x / math.sqrt(2.0)).astype(np.float64))
