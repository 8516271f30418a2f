"""One instruction as the models' text condition: checked, embedded, cached on disk.

:func:`check_text` normalises whitespace and refuses what the encoder cannot read (not a string,
empty, longer than its token limit) with a :class:`~jaxmotion.errors.GenerateError`, before any
model is loaded; :func:`embed_one` gives the condition for a batch of one through the on-disk
caches (a repeated sentence never loads the encoder).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.errors import GenerateError

__all__ = ["check_text", "embed_one", "text_encoder"]


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


def check_text(text) -> str:
    if not isinstance(text, str):
        raise GenerateError(f"text must be a string, got {type(text).__name__}")
    text = " ".join(text.split())
    if not text:
        raise GenerateError('text is empty; describe the motion, e.g. "sit on the chair"')
    from jaxmotion.text.minilm import max_seq_length

    n, limit = len(_tokenizer().encode(text).ids), max_seq_length()
    if n > limit:
        raise GenerateError(f"text is too long ({n} tokens; the text encoder reads at most "
                            f"{limit}): shorten it to one or two sentences")
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
    :meth:`~jaxmotion.pipelines.affordance.AffordancePipeline.embed_text`). Both go through the project's
    on-disk caches (:class:`~jaxmotion.text.EmbeddingCache`,
    :class:`~jaxmotion.text.TokenCache`), keyed by the weights file's size and mtime (its
    checksum would mean reading 90 MB): a repeated command never loads the encoder. A new
    sentence goes through the encoder's traced program kept beside them (``programs/``,
    :func:`jaxmotion.text.minilm.encode_one_cached`: the same numbers, without building the
    network in every new process)."""
    from jaxmotion.text import EmbeddingCache, TokenCache, cache_key, pad_tokens
    from jaxmotion.text.minilm import encode_one_cached, minilm_dir

    programs = None if cache_dir is None else Path(cache_dir).parent / "programs"

    def pooled():
        if programs is None:
            return text_encoder()([text])[0]
        return encode_one_cached(text, programs)

    def words():
        if programs is None:
            return text_encoder().token_states([text])[0]
        return encode_one_cached(text, programs, tokens=True)

    if cache_dir is None:
        emb, states = pooled(), (words() if text_tokens else None)
    else:
        st = (minilm_dir() / "model.safetensors").stat()
        version = f"size={st.st_size},mtime={st.st_mtime_ns}"
        emb = _cached_one(EmbeddingCache(cache_dir), cache_key(TEXT_ENCODER, version, text), pooled)
        states = None
        if text_tokens:
            states = _cached_one(TokenCache(cache_dir.parent / (cache_dir.name + "-tokens")),
                                 cache_key(f"{TEXT_ENCODER}:tokens", version, text), words)
    emb = np.asarray(emb, np.float32)[None]
    if not text_tokens:
        return emb
    tokens, mask = pad_tokens([states], int(text_tokens), emb.shape[1])
    return {"pooled": emb, "tokens": tokens, "mask": mask}
