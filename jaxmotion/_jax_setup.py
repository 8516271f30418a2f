"""Process-level JAX settings for the command-line entry points."""

from __future__ import annotations

import functools
import os
import platform
from pathlib import Path

import numpy as np


@functools.lru_cache(maxsize=1)
def host_key() -> str:
    """A short fingerprint of this machine's CPU (model and instruction-set flags) and jaxlib.

    XLA's cache key holds the platform and jaxlib version but not the host CPU's features, so a
    CPU executable compiled on one machine can abort the process that loads it on another (a
    home directory shared between machines, a container image that carries its cache). The
    compiled executables are therefore kept per host."""
    import hashlib

    import jaxlib

    parts = [platform.machine(), platform.processor(), getattr(jaxlib, "__version__", "?")]
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith(("model name", "flags", "Features", "CPU part")):
                parts.append(line.split(":", 1)[-1].strip())
                if len(parts) > 6:  # the first processor's lines are enough
                    break
    except OSError:  # not Linux: the platform strings above stand in
        pass
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:12]


def enable_compilation_cache(path: str | None = None) -> Path:
    """Turn on JAX's persistent compilation cache so a second run of a command skips XLA
    compilation. Returns jaxmotion's cache root (default ``~/.cache/jaxmotion/xla``, or
    ``$JAXMOTION_CACHE``); XLA's executables go to ``executables-<host_key()>/`` under it.
    ``JAXMOTION_CACHE=off`` runs without any cache on disk (the root is then a folder in the
    system's temporary directory, removed at exit); ``JAXMOTION_XLA_CACHE=off`` keeps
    jaxmotion's own caches (traced programs, text embeddings) but not XLA's executables (the
    test suite runs so: XLA's CPU runtime has crashed deserialising a large executable written
    earlier in the same process)."""
    import jax

    setting = path or os.environ.get("JAXMOTION_CACHE", "")
    if setting.strip().lower() in _OFF:
        return _scratch_root()
    cache = Path(setting or Path.home() / ".cache/jaxmotion/xla")
    executables = cache / f"executables-{host_key()}"
    try:
        executables.mkdir(parents=True, exist_ok=True)
    except OSError:
        return cache  # read-only home: run without the cache
    if os.environ.get("JAXMOTION_XLA_CACHE", "").strip().lower() in _OFF:
        return cache
    jax.config.update("jax_compilation_cache_dir", str(executables))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return cache


_OFF = ("off", "0", "none", "false")


@functools.lru_cache(maxsize=1)
def _scratch_root() -> Path:
    import atexit
    import shutil
    import tempfile

    root = Path(tempfile.mkdtemp(prefix="jaxmotion-cache-"))
    atexit.register(shutil.rmtree, root, ignore_errors=True)
    return root


def seed_key_data(seed: int) -> np.ndarray:
    """``jax.random.key_data(jax.random.key(seed))`` computed on the host (``uint32[2]``):
    the eager ops cost a compilation each in every fresh process (~0.1 s together). The
    default threefry key of a seed ``0 <= seed < 2**31`` is ``[0, seed]``; other seeds, another
    PRNG implementation or 64-bit mode go through JAX."""
    import jax

    seed = int(seed)
    if (0 <= seed < 2**31 and not jax.config.jax_enable_x64
            and jax.config.jax_default_prng_impl == "threefry2x32"):
        return np.array([0, seed], np.uint32)
    return np.asarray(jax.random.key_data(jax.random.key(seed)))
