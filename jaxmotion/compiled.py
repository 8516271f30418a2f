"""Compiled programs kept on disk: a new process skips tracing the samplers and the body fit.

``generate`` (and anything else with a fixed program) calls :func:`cached_call`: the traced
program (weights included) is serialized with ``jax.export`` into a folder next to the
persistent XLA compilation cache, keyed by a fingerprint of everything that shapes it
(:func:`digest`: weights files, sampler settings, versions) plus the argument shapes and
jaxmotion's own sources (:func:`code_digest`), so a cached program is never reused after the
code that traced it changed.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

__all__ = ["cached_call", "code_digest", "digest"]


def digest(*parts) -> str:
    """sha256 over strings and files (for the names of cached compiled programs)."""
    import hashlib

    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, Path):
            h.update(part.read_bytes())
        else:
            h.update(repr(part).encode())
        h.update(b"\0")
    return h.hexdigest()[:32]


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """sha256 of jaxmotion's own sources: a cached program is never reused after the code that
    traced it changed (an edit without a version bump included)."""
    root = Path(__file__).parent  # the jaxmotion package
    return digest(*(x for f in sorted(root.rglob("*.py")) for x in (str(f.relative_to(root)), f)))


def cached_call(cache_dir: Path | None, name: str, fingerprint: str, build, args):
    """``build()(*args)`` through a serialized ``jax.export`` artefact in ``cache_dir``.

    A new process otherwise spends seconds re-tracing the samplers and the LBFGS fit (and
    building the networks) before the persistent compilation cache can even be consulted;
    the artefact holds the traced program (weights included), so a repeated command only
    deserializes it. ``fingerprint`` must change with anything else that changes the program
    (weights, sampler, versions); argument shapes and jaxmotion's sources are added here.
    """
    import jax
    from jax import export as jexport

    specs = jax.tree.map(lambda a: jax.ShapeDtypeStruct(np.shape(a), np.asarray(a).dtype), args)
    fingerprint = digest(fingerprint, code_digest(),
                         [(s.shape, str(s.dtype)) for s in jax.tree.leaves(specs)])
    path = None if cache_dir is None else Path(cache_dir) / f"{name}-{fingerprint}.jaxexport"
    if path is not None and path.is_file():
        try:
            return jexport.deserialize(bytearray(path.read_bytes())).call(*args)
        except Exception:  # noqa: BLE001 - a stale or damaged artefact is rebuilt below
            path.unlink(missing_ok=True)
    exp = jexport.export(jax.jit(build()))(*specs)
    if path is not None:
        try:
            from jaxmotion._atomic import atomic_open

            with atomic_open(path, "wb") as f:
                f.write(exp.serialize())
        except (OSError, ImportError):
            pass  # a read-only cache, or no flatbuffers to serialize with: run uncached
    return exp.call(*args)
