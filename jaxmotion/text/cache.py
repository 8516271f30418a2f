"""On-disk cache of sentence embeddings, so training never re-encodes a text.

Layout: a folder of ``.npz`` shards, each holding ``keys`` ``[K]`` (64-char hex
strings) and ``emb`` ``[K, D]`` float32. A key is
``sha256(model name, weights checksum, text)``, so embeddings of different
models or weight files never mix, and a shard can hold any of them. Every
:meth:`EmbeddingCache.put` writes one new shard through
:func:`jaxmotion._atomic.atomic_open` (temp file + rename): a crash leaves either
no shard or a complete one, and concurrent writers never clobber each other
(two writers of the same texts write identical, redundant shards).

All shards are read into memory when the cache is opened (45k texts × 384
floats ≈ 70 MB). :meth:`EmbeddingCache.compact` merges them into one shard.
"""

from __future__ import annotations

import hashlib
import warnings
import zipfile
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open

__all__ = ["EmbeddingCache", "TokenCache", "cache_key", "encode_cached", "pad_tokens"]


def cache_key(model_name: str, checksum: str, text: str) -> str:
    """Hex sha256 of (model name, weights checksum, text); NUL-separated, UTF-8."""
    h = hashlib.sha256()
    for part in (model_name, checksum, text):
        h.update(part.encode("utf-8", "surrogatepass"))
        h.update(b"\0")
    return h.hexdigest()


class EmbeddingCache:
    """A folder of embedding shards, with ``hits`` / ``misses`` counters.

    ``get(keys)`` → ``{key: vector}`` for those present; ``put(keys, emb)``
    writes one shard; ``encode(encoder, texts)`` does both around an encoder.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.hits = 0
        self.misses = 0
        self._mem: dict[str, np.ndarray] = {}
        self._loaded: set[str] = set()
        self.refresh()

    def refresh(self) -> None:
        """Read shards written since the last refresh (e.g. by another process)."""
        if not self.path.is_dir():
            return
        for shard in sorted(self.path.glob("*.npz")):
            if shard.name in self._loaded or shard.name.startswith("tok-"):  # TokenCache's
                continue
            try:
                with np.load(shard, allow_pickle=False) as z:
                    keys, emb = z["keys"], z["emb"]
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as e:
                # not ours, or damaged by something else: skip, never crash training
                warnings.warn(f"skipping unreadable embedding shard {shard}: {e}", stacklevel=2)
                continue
            for k, v in zip(keys.tolist(), emb):
                self._mem[k] = v
            self._loaded.add(shard.name)

    def __len__(self) -> int:
        return len(self._mem)

    def __contains__(self, key: str) -> bool:
        return key in self._mem

    def get(self, keys) -> dict[str, np.ndarray]:
        """The cached vectors among ``keys``; counts hits and misses."""
        keys = list(keys)
        hit = [k in self._mem for k in keys]  # per requested key, duplicates included
        self.hits += sum(hit)
        self.misses += len(keys) - sum(hit)
        return {k: self._mem[k] for k, h in zip(keys, hit) if h}

    def put(self, keys, emb) -> Path | None:
        """Store ``emb[i]`` under ``keys[i]`` in a new shard, written atomically."""
        keys = list(keys)
        emb = np.asarray(emb, np.float32)
        if emb.ndim != 2 or emb.shape[0] != len(keys):
            raise ValueError(f"emb must be [{len(keys)}, D], got {emb.shape}")
        if not keys:
            return None
        name = hashlib.sha256("\n".join(keys).encode()).hexdigest()[:24] + ".npz"
        shard = self.path / name
        with atomic_open(shard, "wb") as f:
            np.savez(f, keys=np.array(keys, dtype="<U64"), emb=emb)
        for k, v in zip(keys, emb):
            self._mem[k] = v
        self._loaded.add(name)
        return shard

    def compact(self) -> None:
        """Rewrite all shards as one (atomically written before the old ones go)."""
        self.refresh()
        old = [self.path / n for n in self._loaded]
        if len(old) <= 1:
            return
        keys = sorted(self._mem)
        self._loaded = set()
        new = self.put(keys, np.stack([self._mem[k] for k in keys]))
        for p in old:
            if p != new:
                p.unlink(missing_ok=True)

    def encode(self, encoder, texts) -> np.ndarray:
        """``encoder(texts)`` with cached rows reused; new ones encoded once and stored."""
        texts = list(texts)
        keys = [cache_key(encoder.name, encoder.checksum, t) for t in texts]
        found = self.get(keys)
        missing = {}  # key -> text, deduplicated, first-seen order
        for k, t in zip(keys, texts):
            if k not in found:
                missing.setdefault(k, t)
        if missing:
            new = encoder(list(missing.values()))
            self.put(list(missing), new)
            found.update(zip(missing, new))
        out = np.zeros((len(texts), encoder.dim), np.float32)
        for i, k in enumerate(keys):
            out[i] = found[k]
        return out


def encode_cached(encoder, texts, cache_dir) -> np.ndarray:
    """Embed ``texts`` ``[B, D]`` with ``encoder``, reusing/filling the cache in ``cache_dir``."""
    return EmbeddingCache(cache_dir).encode(encoder, texts)


def pad_tokens(states, max_tokens: int, dim: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A list of ``[n_i, D]`` token states -> ``(tokens [B, max_tokens, D] float32,
    mask [B, max_tokens] bool)``: the first ``max_tokens`` of each, zero-padded."""
    if max_tokens < 1:
        raise ValueError(f"max_tokens must be >= 1, got {max_tokens}")
    d = dim if dim is not None else (states[0].shape[-1] if len(states) else 0)
    out = np.zeros((len(states), max_tokens, d), np.float32)
    mask = np.zeros((len(states), max_tokens), bool)
    for i, s in enumerate(states):
        n = min(len(s), max_tokens)
        out[i, :n] = s[:n]
        mask[i, :n] = True
    return out, mask


class TokenCache:
    """A folder of per-token text state shards (word-level text conditioning).

    Each shard holds ``keys [K]``, ``lengths [K]`` and ``states [sum(lengths), D]`` float16:
    every text's token states, all of its tokens, concatenated. Keys are
    :func:`cache_key` of ``"<encoder name>:tokens"``, so they never collide with the pooled
    embeddings of :class:`EmbeddingCache` (the two may share a folder). Shards are written
    atomically, as :class:`EmbeddingCache`'s.

    States are stored in float16 (half the disk and memory: 12k texts of ~16 tokens are
    ~150 MB); :meth:`encode` rounds freshly computed states through float16 too, so a text
    gets the same values whether it was cached or not.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.hits = 0
        self.misses = 0
        self._mem: dict[str, np.ndarray] = {}
        self._loaded: set[str] = set()
        self.refresh()

    def refresh(self) -> None:
        """Read shards written since the last refresh."""
        if not self.path.is_dir():
            return
        for shard in sorted(self.path.glob("tok-*.npz")):
            if shard.name in self._loaded:
                continue
            try:
                with np.load(shard, allow_pickle=False) as z:
                    keys, lengths, states = z["keys"], z["lengths"], z["states"]
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as e:
                warnings.warn(f"skipping unreadable token shard {shard}: {e}", stacklevel=2)
                continue
            offsets = np.concatenate([[0], np.cumsum(lengths)])
            for i, k in enumerate(keys.tolist()):
                self._mem[k] = states[offsets[i]:offsets[i + 1]]
            self._loaded.add(shard.name)

    def __len__(self) -> int:
        return len(self._mem)

    def get(self, keys) -> dict[str, np.ndarray]:
        """The cached ``[n, D]`` float16 states among ``keys``; counts hits and misses."""
        keys = list(keys)
        found = {k: self._mem[k] for k in keys if k in self._mem}
        self.hits += sum(k in found for k in keys)
        self.misses += sum(k not in found for k in keys)
        return found

    def put(self, keys, states) -> Path | None:
        """Store ``states[i]`` (``[n_i, D]``) under ``keys[i]`` in one new shard."""
        keys = list(keys)
        if len(states) != len(keys):
            raise ValueError(f"{len(keys)} keys but {len(states)} state arrays")
        if not keys:
            return None
        states = [np.asarray(s, np.float16) for s in states]
        lengths = np.array([len(s) for s in states], np.int64)
        name = "tok-" + hashlib.sha256("\n".join(keys).encode()).hexdigest()[:24] + ".npz"
        shard = self.path / name
        with atomic_open(shard, "wb") as f:
            np.savez(f, keys=np.array(keys, dtype="<U64"), lengths=lengths,
                     states=np.concatenate(states, axis=0))
        for k, v in zip(keys, states):
            self._mem[k] = v
        self._loaded.add(name)
        return shard

    def states(self, encoder, texts) -> list[np.ndarray]:
        """Per text, its token states ``[n_i, D]`` float16 (cached ones reused, new ones
        computed with ``encoder.token_states`` once and stored)."""
        texts = list(texts)
        keys = [cache_key(encoder.name + ":tokens", encoder.checksum, t) for t in texts]
        found = self.get(keys)
        missing: dict[str, str] = {}
        for k, t in zip(keys, texts):
            if k not in found:
                missing.setdefault(k, t)
        if missing:
            self.put(list(missing), encoder.token_states(list(missing.values())))
        return [self._mem[k] for k in keys]

    def encode(self, encoder, texts, max_tokens: int) -> tuple[np.ndarray, np.ndarray]:
        """``(tokens [B, max_tokens, D] float32, mask [B, max_tokens] bool)`` for ``texts``."""
        return pad_tokens(self.states(encoder, texts), max_tokens, encoder.dim)
