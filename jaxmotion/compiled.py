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

__all__ = ["LIFT_BYTES", "cached_call", "code_digest", "digest"]


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


#: Constants (weights) of at least this many bytes in all leave a cached program as its
#: arguments, kept beside it in a ``.npz`` (see :func:`cached_call`).
LIFT_BYTES = 1 << 20


def cached_call(cache_dir: Path | None, name: str, fingerprint: str, build, args):
    """``build()(*args)`` through a serialized ``jax.export`` artefact in ``cache_dir``.

    A new process otherwise spends seconds re-tracing the samplers and the LBFGS fit (and
    building the networks) before the persistent compilation cache can even be consulted;
    the artefact holds the traced program, so a repeated command only deserializes it.
    ``fingerprint`` must change with anything else that changes the program (weights,
    sampler, versions); argument shapes and jaxmotion's sources are added here.

    The constants the traced program closes over (the networks' weights) are lifted out of it
    when they come to :data:`LIFT_BYTES` or more: the program takes them as arguments and they
    are kept beside it (``<artefact>.npz``). A program with its weights baked in compiles to
    an executable of their size, and loading that from XLA's cache took longer than running
    it (0.66 s of a 1.8 s sampling, for 21 MB of weights); the weights themselves load in
    milliseconds. The numbers are the same either way.
    """
    import jax
    from jax import export as jexport

    specs = jax.tree.map(lambda a: jax.ShapeDtypeStruct(np.shape(a), np.asarray(a).dtype), args)
    fingerprint = digest(fingerprint, code_digest(),
                         [(s.shape, str(s.dtype)) for s in jax.tree.leaves(specs)])
    path = None if cache_dir is None else Path(cache_dir) / f"{name}-{fingerprint}.jaxexport"
    consts_path = None if path is None else path.with_suffix(".npz")
    if path is not None and path.is_file():
        try:
            exp = jexport.deserialize(bytearray(path.read_bytes()))
            if consts_path.is_file():
                with np.load(consts_path, allow_pickle=False) as z:
                    consts = tuple(z[f"c{i}"] for i in range(len(z.files)))
                return exp.call(consts, *args)
            return exp.call(*args)
        except Exception:  # noqa: BLE001 - a stale or damaged artefact is rebuilt below
            path.unlink(missing_ok=True)
            consts_path.unlink(missing_ok=True)
    fn, consts = _lift_constants(build(), specs)
    if consts is None:
        exp = jexport.export(jax.jit(fn))(*specs)
    else:
        const_specs = tuple(jax.ShapeDtypeStruct(c.shape, c.dtype) for c in consts)
        exp = jexport.export(jax.jit(fn))(const_specs, *specs)
    if path is not None:
        try:
            from jaxmotion._atomic import atomic_open

            if consts is not None:  # written first: a program is only read with its weights
                with atomic_open(consts_path, "wb") as f:
                    np.savez(f, **{f"c{i}": c for i, c in enumerate(consts)})
            else:
                consts_path.unlink(missing_ok=True)
            with atomic_open(path, "wb") as f:
                f.write(exp.serialize())
        except (OSError, ImportError):
            pass  # a read-only cache, or no flatbuffers to serialize with: run uncached
    return exp.call(*args) if consts is None else exp.call(consts, *args)


def _lift_constants(fn, specs):
    """``(fn, None)``, or ``(lifted, consts)`` where ``lifted(consts, *args) == fn(*args)``
    with the array constants ``fn`` closes over as the numpy arrays ``consts`` (when they come
    to :data:`LIFT_BYTES` or more and all are plain numpy dtypes)."""
    import jax

    closed, out_shape = jax.make_jaxpr(fn, return_shape=True)(*specs)
    try:
        consts = tuple(np.asarray(c) for c in closed.consts)
    except (TypeError, ValueError):  # e.g. a PRNG key array: keep the program as it is
        return fn, None
    if sum(c.nbytes for c in consts) < LIFT_BYTES or any(c.dtype == object for c in consts):
        return fn, None
    jaxpr, out_tree = closed.jaxpr, jax.tree.structure(out_shape)

    def lifted(cs, *a):
        return jax.tree.unflatten(out_tree, jax.core.eval_jaxpr(jaxpr, list(cs),
                                                                *jax.tree.leaves(a)))

    return lifted, consts
