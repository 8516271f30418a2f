"""One instruction as the models' text condition: checked, embedded, cached on disk.

:func:`check_text` normalises the text (Unicode folding, whitespace) and refuses what the
encoder cannot read (not a string, not valid Unicode, empty, no word it knows, longer than its
token limit) with a :class:`~jaxmotion.errors.GenerateError`, before any model is loaded;
:func:`embed_one` gives the condition for a batch of one through the on-disk
caches (a repeated sentence never loads the encoder).
"""

from __future__ import annotations

import functools
import unicodedata
from pathlib import Path

import numpy as np

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.errors import GenerateError

__all__ = ["blank_condition", "check_text", "embed_one", "pooled_text", "text_encoder"]


@functools.lru_cache(maxsize=1)
def text_encoder():
    from jaxmotion.text import load_text_encoder

    return load_text_encoder(TEXT_ENCODER)


@functools.lru_cache(maxsize=1)
def _tokenizer():
    """MiniLM's tokenizer without truncation (to count tokens before the encoder is loaded)."""
    from tokenizers import Tokenizer

    from jaxmotion.text.minilm import minilm_dir

    tok = Tokenizer.from_file(str(minilm_dir() / "tokenizer.json"))
    tok.no_truncation()
    tok.no_padding()
    return tok


_EXAMPLE = 'describe the motion in English words, e.g. "sit on the chair"'


def check_text(text) -> str:
    """``text`` as the models read it, or :class:`GenerateError` saying why it cannot be used.

    The text is Unicode compatibility-folded (NFKC: full-width letters and ligatures become
    the letters the encoder knows), control and format characters (zero-width spaces, byte
    order marks) are dropped and whitespace is collapsed. Refused: not a string, not valid
    Unicode (a lone surrogate), empty after that, no word the encoder knows (only symbols,
    emoji or scripts outside its vocabulary), longer than the encoder's token limit.
    """
    if not isinstance(text, str):
        raise GenerateError(f"text must be a string, got {type(text).__name__}; {_EXAMPLE}")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as e:
        raise GenerateError(f"text is not valid Unicode ({e.reason} at character {e.start}, "
                            f"{text[e.start]!r}); pass the text as UTF-8") from None
    text = unicodedata.normalize("NFKC", text)
    text = "".join(" " if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") else c
                   for c in text)
    text = " ".join(text.split())
    if not text:
        raise GenerateError(f"text is empty (after dropping control characters); {_EXAMPLE}")
    from jaxmotion.text.minilm import max_seq_length

    tok = _tokenizer()
    try:
        encoding = tok.encode(text)
    except Exception as e:  # noqa: BLE001 - the tokenizer's own errors, said as one line
        raise GenerateError(f"the text encoder's tokenizer cannot read the text ({e}); "
                            f"{_EXAMPLE}") from None
    n, limit = len(encoding.ids), max_seq_length()
    if n > limit:
        raise GenerateError(f"text is too long ({n} tokens; the text encoder reads at most "
                            f"{limit}): shorten it to one or two sentences")
    if not any(any(ch.isalnum() for ch in t) for t in encoding.tokens
               if t not in ("[CLS]", "[SEP]", "[UNK]", "[PAD]")):
        raise GenerateError(f"text {text[:60]!r} has no word the text encoder knows (only "
                            f"symbols, emoji or letters outside its vocabulary); {_EXAMPLE}")
    return text


def _cached_one(cache, key, compute):
    """``cache``'s entry ``key``, or ``compute()``'s value, then stored under it (a read-only
    cache is fine: the value is just not kept)."""
    found = cache.get([key])
    if key in found:
        return found[key]
    value = compute()
    try:
        cache.put([key], [value])
    except OSError:
        pass
    return value


def embed_one(text: str, cache_dir: Path | None, text_tokens: int = 0):
    """The text condition of ``text`` for a batch of one: the MiniLM embedding ``[1, 384]``,
    or, for an ADM that reads ``text_tokens`` > 0 token states, ``{"pooled" [1, 384],
    "tokens" [1, L, 384], "mask" [1, L]}`` (as
    :meth:`~jaxmotion.pipelines.affordance.AffordancePipeline.embed_text`). Both go through
    the project's on-disk caches (:class:`~jaxmotion.text.EmbeddingCache`,
    :class:`~jaxmotion.text.TokenCache`) when ``cache_dir`` is given, keyed by the weights
    file's size and mtime (its checksum would mean reading 90 MB). A new sentence is encoded
    on the host (:func:`jaxmotion.text.minilm.encode_one`: the batch encoder's numbers in tens
    of milliseconds, with no network to build or program to load)."""
    from jaxmotion.text import EmbeddingCache, TokenCache, cache_key, pad_tokens
    from jaxmotion.text.minilm import encode_one, weights_version

    def pooled():
        return encode_one(text)

    def words():
        return encode_one(text, tokens=True)

    if cache_dir is None:
        emb, states = pooled(), (words() if text_tokens else None)
    else:
        version = weights_version()
        emb = _cached_one(EmbeddingCache.shared(cache_dir), cache_key(TEXT_ENCODER, version, text),
                          pooled)
        states = None
        if text_tokens:
            states = _cached_one(TokenCache.shared(cache_dir.parent / (cache_dir.name + "-tokens")),
                                 cache_key(f"{TEXT_ENCODER}:tokens", version, text), words)
    emb = np.asarray(emb, np.float32)[None]
    if not text_tokens:
        return emb
    tokens, mask = pad_tokens([states], int(text_tokens), emb.shape[1])
    return {"pooled": emb, "tokens": tokens, "mask": mask}


def blank_condition(text_tokens: int = 0, dim: int = 384):
    """A text condition of :func:`embed_one`'s shapes and dtypes for ``text_tokens``, all
    zeros: what a compiled program is looked up by before the sentence is encoded."""
    from jaxmotion.text import pad_tokens

    emb = np.zeros((1, dim), np.float32)
    if not text_tokens:
        return emb
    tokens, mask = pad_tokens([np.zeros((0, dim), np.float32)], int(text_tokens), dim)
    return {"pooled": emb, "tokens": tokens, "mask": mask}


def pooled_text(text):
    """The pooled sentence embedding ``[B, D]`` of a text condition (an array, or the
    word-level mapping ``{"pooled", "tokens", "mask"}``), which is all the AMDM and the
    object-centric models read."""
    return text["pooled"] if isinstance(text, dict) else text
