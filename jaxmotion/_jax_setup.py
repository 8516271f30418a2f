"""Process-level JAX settings for the command-line entry points."""

from __future__ import annotations

import os
from pathlib import Path


def enable_compilation_cache(path: str | None = None) -> Path:
    """Turn on JAX's persistent compilation cache (default ``~/.cache/jaxmotion/xla``,
    or ``$JAXMOTION_CACHE``) so a second run of a command skips XLA compilation."""
    import jax

    cache = Path(path or os.environ.get("JAXMOTION_CACHE", Path.home() / ".cache/jaxmotion/xla"))
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:
        return cache  # read-only home: run without the cache
    jax.config.update("jax_compilation_cache_dir", str(cache))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return cache
