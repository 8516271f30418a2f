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

__all__ = ["EmbeddingCache", "cache_key", "encode_cached"]


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
            if shard.name in self._loaded:
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
