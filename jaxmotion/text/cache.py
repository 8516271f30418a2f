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
floats ≈ 70 MB). :meth:`EmbeddingCache.compact` merges them into one shard, and a cache
that has grown past :data:`MAX_SHARDS` shards is merged by the write that passes it, so a
cache that gains a shard for every new sentence (``generate``'s) stays a few files for every
new process to read. :meth:`EmbeddingCache.shared` keeps one opened cache per folder in a
process.
"""

from __future__ import annotations

import hashlib
import warnings
import zipfile
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion._npio import load_npz

__all__ = ["MAX_SHARDS", "EmbeddingCache", "TokenCache", "cache_key", "close_shared",
           "dataset_cache_dir", "encode_cached", "pad_tokens"]

#: A cache of more shards than this is merged into one by the write that passes it.
MAX_SHARDS = 32


def cache_key(model_name: str, checksum: str, text: str) -> str:
    """Hex sha256 of (model name, weights checksum, text); NUL-separated, UTF-8."""
    h = hashlib.sha256()
    for part in (model_name, checksum, text):
        h.update(part.encode("utf-8", "surrogatepass"))
        h.update(b"\0")
    return h.hexdigest()


class _ShardCache:
    """A folder of ``.npz`` shards read into memory (``key -> array``), with ``hits`` /
    ``misses`` counters. Subclasses name their shards (``_PREFIX``), read one shard's entries
    (``_entries``) and write their own layout (``put``, through :meth:`_write`)."""

    _PREFIX = ""  # shard file names start with it
    _KIND = ""  # for the warning about an unreadable shard

    def __init__(self, path):
        self.path = Path(path)
        self.hits = 0
        self.misses = 0
        self._mem: dict[str, np.ndarray] = {}
        self._loaded: set[str] = set()
        self.refresh()

    @classmethod
    def shared(cls, path):
        """This process's opened cache of the folder ``path`` (opened on the first call; later
        calls read only the shards written since, by other processes)."""
        key = (cls, str(Path(path).expanduser().resolve()))
        cache = _OPEN.get(key)
        if cache is None:
            cache = _OPEN[key] = cls(path)
        else:
            cache.refresh()
        return cache

    def _owns(self, name: str) -> bool:
        return name.startswith(self._PREFIX)

    def _entries(self, z):
        """``(key, array)`` pairs of an open shard; KeyError if it is not this cache's."""
        raise NotImplementedError

    def refresh(self) -> None:
        """Read shards written since the last refresh (e.g. by another process)."""
        if not self.path.is_dir():
            return
        for shard in sorted(self.path.glob(f"{self._PREFIX}*.npz")):
            if shard.name in self._loaded or not self._owns(shard.name):
                continue
            try:
                with load_npz(shard, allow_pickle=False) as z:
                    entries = list(self._entries(z))
            except FileNotFoundError:  # merged away by another process's compact meanwhile
                continue
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as e:
                # not ours, or damaged by something else: skip, never crash training
                warnings.warn(f"skipping unreadable {self._KIND} shard {shard}: {e}",
                              stacklevel=2)
                continue
            self._mem.update(entries)
            self._loaded.add(shard.name)

    def __len__(self) -> int:
        return len(self._mem)

    def __contains__(self, key: str) -> bool:
        return key in self._mem

    def get(self, keys) -> dict[str, np.ndarray]:
        """The cached arrays among ``keys``; counts hits and misses."""
        keys = list(keys)
        hit = [k in self._mem for k in keys]  # per requested key, duplicates included
        self.hits += sum(hit)
        self.misses += len(keys) - sum(hit)
        return {k: self._mem[k] for k, h in zip(keys, hit) if h}

    def _write(self, keys, values, **arrays) -> Path:
        """One new shard of ``keys`` and ``arrays``, written atomically; ``values[i]`` is then
        what ``keys[i]`` holds in memory."""
        name = self._PREFIX + hashlib.sha256("\n".join(keys).encode()).hexdigest()[:24] + ".npz"
        shard = self.path / name
        with atomic_open(shard, "wb") as f:
            np.savez(f, keys=np.array(keys, dtype="<U64"), **arrays)
        self._mem.update(zip(keys, values))
        self._loaded.add(name)
        if len(self._loaded) > MAX_SHARDS:
            return self.compact()
        return shard

    def put(self, keys, values) -> Path | None:
        raise NotImplementedError

    def compact(self) -> Path | None:
        """Rewrite all shards as one (written atomically before the old ones go; shards that
        another process writes meanwhile are left alone). Returns the merged shard."""
        self.refresh()
        old = [self.path / n for n in self._loaded]
        if len(old) <= 1:
            return old[0] if old else None
        keys = sorted(self._mem)
        self._loaded = set()
        new = self.put(keys, [self._mem[k] for k in keys])
        for p in old:
            if p != new:
                p.unlink(missing_ok=True)
        return new

    @staticmethod
    def _missing(keys, texts, found) -> dict[str, str]:
        """``key -> text`` of the texts not in ``found``: deduplicated, first-seen order."""
        missing: dict[str, str] = {}
        for k, t in zip(keys, texts):
            if k not in found:
                missing.setdefault(k, t)
        return missing


class EmbeddingCache(_ShardCache):
    """A folder of embedding shards, with ``hits`` / ``misses`` counters.

    ``get(keys)`` → ``{key: vector}`` for those present; ``put(keys, emb)``
    writes one shard; ``encode(encoder, texts)`` does both around an encoder.
    """

    _KIND = "embedding"

    def _owns(self, name: str) -> bool:
        return not name.startswith(TokenCache._PREFIX)  # a folder may hold both kinds

    def _entries(self, z):
        return zip(z["keys"].tolist(), z["emb"])

    def put(self, keys, emb) -> Path | None:
        """Store ``emb[i]`` under ``keys[i]`` in a new shard, written atomically."""
        keys = list(keys)
        emb = np.asarray(emb, np.float32)
        if emb.ndim != 2 or emb.shape[0] != len(keys):
            raise ValueError(f"emb must be [{len(keys)}, D], got {emb.shape}")
        if not keys:
            return None
        return self._write(keys, emb, emb=emb)

    def encode(self, encoder, texts) -> np.ndarray:
        """``encoder(texts)`` with cached rows reused; new ones encoded once and stored."""
        texts = list(texts)
        keys = [cache_key(encoder.name, encoder.checksum, t) for t in texts]
        found = self.get(keys)
        missing = self._missing(keys, texts, found)
        if missing:
            new = encoder(list(missing.values()))
            self.put(list(missing), new)
            found.update(zip(missing, new))
        out = np.zeros((len(texts), encoder.dim), np.float32)
        for i, k in enumerate(keys):
            out[i] = found[k]
        return out


def dataset_cache_dir(data_dir, workdir, name: str, fallback: str) -> Path:
    """Where a training run keeps a text cache: ``<data_dir>/.cache/<name>``, shared by every
    run on the dataset, or ``<workdir>/<fallback>`` when the dataset is read-only. Every task
    and the evaluator go through this, so they read and fill the same caches."""
    cache_dir = Path(data_dir) / ".cache" / name
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
    except OSError:  # read-only dataset
        cache_dir = Path(workdir) / fallback
    return cache_dir


def encode_cached(encoder, texts, cache_dir) -> np.ndarray:
    """Embed ``texts`` ``[B, D]`` with ``encoder``, reusing/filling the cache in ``cache_dir``."""
    return EmbeddingCache(cache_dir).encode(encoder, texts)


def pad_tokens(states, max_tokens: int, dim: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A list of ``[n_i, D]`` token states -> ``(tokens [B, max_tokens, D] float32,
    mask [B, max_tokens] bool)``: the first ``max_tokens`` of each, zero-padded. Values are
    rounded through float16, as :class:`TokenCache` stores them, so a text gets the same
    condition whether its states come from the cache or straight from the encoder."""
    if max_tokens < 1:
        raise ValueError(f"max_tokens must be >= 1, got {max_tokens}")
    d = dim if dim is not None else (states[0].shape[-1] if len(states) else 0)
    out = np.zeros((len(states), max_tokens, d), np.float32)
    mask = np.zeros((len(states), max_tokens), bool)
    for i, s in enumerate(states):
        n = min(len(s), max_tokens)
        out[i, :n] = np.asarray(s[:n], np.float16)
        mask[i, :n] = True
    return out, mask


class TokenCache(_ShardCache):
    """A folder of per-token text state shards (word-level text conditioning).

    Each shard holds ``keys [K]``, ``lengths [K]`` and ``states [sum(lengths), D]`` float16:
    every text's token states, all of its tokens, concatenated. Keys are
    :func:`cache_key` of ``"<encoder name>:tokens"``, so they never collide with the pooled
    embeddings of :class:`EmbeddingCache` (the two may share a folder). Shards are written
    atomically, as :class:`EmbeddingCache`'s.

    States are stored in float16 (half the disk and memory: 12k texts of ~16 tokens are
    ~150 MB); :func:`pad_tokens`, which every consumer goes through, rounds fresh states the
    same way.
    """

    _PREFIX = "tok-"
    _KIND = "token"

    def _entries(self, z):
        keys, lengths, states = z["keys"], z["lengths"], z["states"]
        offsets = np.concatenate([[0], np.cumsum(lengths)])
        return ((k, states[offsets[i]:offsets[i + 1]]) for i, k in enumerate(keys.tolist()))

    def put(self, keys, states) -> Path | None:
        """Store ``states[i]`` (``[n_i, D]``) under ``keys[i]`` in one new shard."""
        keys = list(keys)
        if len(states) != len(keys):
            raise ValueError(f"{len(keys)} keys but {len(states)} state arrays")
        if not keys:
            return None
        states = [np.asarray(s, np.float16) for s in states]
        return self._write(keys, states, lengths=np.array([len(s) for s in states], np.int64),
                           states=np.concatenate(states, axis=0))

    def states(self, encoder, texts) -> list[np.ndarray]:
        """Per text, its token states ``[n_i, D]`` float16 (cached ones reused, new ones
        computed with ``encoder.token_states`` once and stored)."""
        texts = list(texts)
        keys = [cache_key(encoder.name + ":tokens", encoder.checksum, t) for t in texts]
        missing = self._missing(keys, texts, self.get(keys))
        if missing:
            self.put(list(missing), encoder.token_states(list(missing.values())))
        return [self._mem[k] for k in keys]

    def encode(self, encoder, texts, max_tokens: int) -> tuple[np.ndarray, np.ndarray]:
        """``(tokens [B, max_tokens, D] float32, mask [B, max_tokens] bool)`` for ``texts``."""
        return pad_tokens(self.states(encoder, texts), max_tokens, encoder.dim)


_OPEN: dict[tuple, _ShardCache] = {}  # _ShardCache.shared's opened caches


def close_shared() -> None:
    """Forget the caches :meth:`EmbeddingCache.shared` / :meth:`TokenCache.shared` opened (their
    entries leave memory; the next call reads the folder again, as a new process would)."""
    _OPEN.clear()
