"""The sentence encoder's network (:mod:`jaxmotion.text.bert`) for one sentence in NumPy.

``generate`` encodes one new sentence per run. Through XLA that meant loading a compiled
program (0.6–0.8 s on a 2-core CPU, longer while the samplers' programs load beside it) for a
forward pass that takes milliseconds; here the same network runs on the host in float32, as
XLA runs it (30–40 ms for 7–30 tokens on one core), on the weights mapped from
``model.safetensors`` (nothing is copied: a new process maps them in milliseconds).

One sentence needs no padding: its tokens attend to each other only (a padded batch gives
padded keys exactly zero weight), so the result is the batch encoder's up to float rounding
(see ``tests/test_text.py``).
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
    """The weights of a BERT for :func:`encode_tokens`: its configuration and its tensors by
    their names in the file, float32 as stored (the dense kernels ``[out, in]``, as torch
    keeps them), mapped from the file rather than copied."""

    def __init__(self, cfg: BertConfig, tensors: dict[str, np.ndarray]):
        self.cfg = cfg
        self._t = tensors

    def __getitem__(self, name: str) -> np.ndarray:
        return self._t[name]

    def words(self, ids) -> np.ndarray:
        """The word-table rows of ``ids`` ``[len(ids), hidden]``."""
        table = self._t[_WORDS]
        bad = [int(i) for i in ids if not 0 <= int(i) < len(table)]
        if bad:
            raise ValueError(f"token id {bad[0]} is outside the word table ({len(table)} rows)")
        return table[np.asarray(ids, np.int64)]


def load_weights(folder) -> BertWeights:
    """The weights of the BERT in ``folder`` (``config.json``, ``model.safetensors``), mapped
    once per process while the file is unchanged (its size and modification time key it)."""
    path = Path(folder) / "model.safetensors"
    st = path.stat()
    return _load(str(path), st.st_size, st.st_mtime_ns)


#: safetensors' dtype names NumPy reads as they are (anything else is refused).
_DTYPES = {"F32": np.float32, "F16": np.float16, "F64": np.float64}


@functools.lru_cache(maxsize=2)
def _load(path: str, size: int, mtime_ns: int) -> BertWeights:
    """The file's tensors as views of a read-only memory map (safetensors: an 8-byte header
    length, a JSON header of names, dtypes, shapes and byte offsets, then the data), float16
    or float64 ones turned to float32."""
    import json

    from jaxmotion.text.bert_config import hf_parameter_names

    cfg = BertConfig.from_hf(Path(path).parent / "config.json")
    data = np.memmap(path, dtype=np.uint8, mode="r")
    try:
        n = int(data[:8].view("<u8")[0])
        header = json.loads(bytes(data[8:8 + n]))
    except (ValueError, IndexError) as e:
        raise ValueError(f"{path}: not a safetensors file ({e})") from None
    tensors = {}
    for name, _ in hf_parameter_names(cfg).values():
        info = header.get(name)
        if info is None:
            raise ValueError(f"{path} has no tensor {name!r}: not a BERT of this "
                             "configuration")
        dtype = _DTYPES.get(info["dtype"])
        if dtype is None:
            raise ValueError(f"{path}: tensor {name!r} is {info['dtype']}; the encoder reads "
                             f"{', '.join(_DTYPES)}")
        begin, end = (8 + n + int(o) for o in info["data_offsets"])
        t = data[begin:end].view(np.dtype(dtype).newbyteorder("<")).reshape(info["shape"])
        tensors[name] = t if dtype == np.float32 else t.astype(np.float32)
    return BertWeights(cfg, tensors)


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
            return y @ w[pre + name + ".weight"].T + w[pre + name + ".bias"]

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
    erf = _ERF(x.astype(np.float64) / math.sqrt(2.0)).astype(x.dtype)
    return 0.5 * x * (1.0 + erf)
