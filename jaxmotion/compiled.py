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

__all__ = ["CONSTS_SUFFIX", "LIFT_BYTES", "cached_call", "cached_program", "code_digest",
           "digest", "prefetch", "prefetched", "release", "specs_of"]


def digest(*parts) -> str:
    """sha256 over strings and files (for the names of cached compiled programs); a file's
    bytes are hashed once per process while its size and modification time stay the same."""
    import hashlib

    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, Path):
            st = part.stat()
            h.update(_file_sha256(str(part), st.st_size, st.st_mtime_ns))
        else:
            h.update(repr(part).encode())
        h.update(b"\0")
    return h.hexdigest()[:32]


@functools.cache
def _file_sha256(path: str, size: int, mtime_ns: int) -> bytes:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).digest()


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """sha256 of jaxmotion's own sources: a cached program is never reused after the code that
    traced it changed (an edit without a version bump included)."""
    root = Path(__file__).parent  # the jaxmotion package
    return digest(*(x for f in sorted(root.rglob("*.py")) for x in (str(f.relative_to(root)), f)))


#: Constants (weights) of at least this many bytes in all leave a cached program as its
#: arguments, kept beside it in a ``.safetensors`` file (see :func:`cached_call`).
LIFT_BYTES = 1 << 20
#: The suffix of the file of a program's lifted constants (beside its ``.jaxexport``).
CONSTS_SUFFIX = ".safetensors"


def cached_call(cache_dir: Path | None, name: str, fingerprint: str, build, args):
    """``build()(*args)`` through a serialized ``jax.export`` artefact in ``cache_dir``
    (:func:`cached_program` for ``args``' shapes, then called on them)."""
    return cached_program(cache_dir, name, fingerprint, build, specs_of(args))(*args)


def specs_of(args):
    """``args`` as ``jax.ShapeDtypeStruct`` leaves (the shapes a program is kept for)."""
    import jax

    # an array's own dtype: np.asarray of a device array would wait for it and copy it over
    return jax.tree.map(lambda a: jax.ShapeDtypeStruct(
        np.shape(a), a.dtype if hasattr(a, "dtype") else np.asarray(a).dtype), args)


def cached_program(cache_dir: Path | None, name: str, fingerprint: str, build, specs):
    """The compiled ``build()`` for arguments of shapes ``specs``, through a serialized
    ``jax.export`` artefact in ``cache_dir``: a callable taking the arguments.

    A new process otherwise spends seconds re-tracing the samplers and the LBFGS fit (and
    building the networks) before the persistent compilation cache can even be consulted;
    the artefact holds the traced program, so a repeated command only deserializes it and
    loads its executable from XLA's cache. ``fingerprint`` must change with anything else
    that changes the program (weights, sampler, versions); argument shapes and jaxmotion's
    sources are added here. A program :func:`prefetch` started loading is taken from there;
    a program is loaded once per process. Without a cache folder (``cache_dir=None``) the
    program is traced and compiled in memory, and kept for the process as well (the last
    :data:`MEMORY_PROGRAMS`), so a repeated call with the same fingerprint and shapes does not
    trace and compile it again.

    The constants the traced program closes over (the networks' weights) are lifted out of it
    when they come to :data:`LIFT_BYTES` or more: the program takes them as arguments and they
    are kept beside it (``<artefact>.safetensors``: read without Python's parser, which
    NumPy's ``.npy`` headers go through and which is not safe to run on two threads at once
    in Python 3.11 and 3.12). A program with its weights baked in compiles to
    an executable of their size, and loading that took longer than running it; the weights
    themselves load in milliseconds. The numbers are the same either way.
    """
    path = _artefact(cache_dir, name, fingerprint, specs)
    if path is None:
        import jax

        key = f"{name}-{_shapes_digest(fingerprint, specs)}"
        if key not in _IN_MEMORY:
            while len(_IN_MEMORY) >= MEMORY_PROGRAMS:
                _IN_MEMORY.pop(next(iter(_IN_MEMORY)))
            _IN_MEMORY[key] = jax.jit(_load_program(None, build, specs))
        else:
            _IN_MEMORY[key] = _IN_MEMORY.pop(key)  # the most recently used, kept longest
        return _IN_MEMORY[key]
    if str(path) in _LOADED:
        return _LOADED[str(path)]
    pending = _PENDING.pop(str(path), None)
    if pending is not None and pending.exception() is None:  # waits for it
        program = pending.result()
    else:  # a failed prefetch's error surfaces here
        program = _load_program(path, build, specs)
    _LOADED[str(path)] = program
    return program


def prefetch(cache_dir: Path | None, name: str, fingerprint: str, specs) -> bool:
    """Start loading the kept program :func:`cached_program` will be asked for (same
    arguments but ``build``) in a background thread, so that reading it, lowering it and
    loading its executable overlap the work before it is called. Only a program already on
    disk is prefetched (tracing stays on the caller's thread). Returns whether it started."""
    path = _artefact(cache_dir, name, fingerprint, specs)
    if path is None or not path.is_file() or str(path) in _PENDING or str(path) in _LOADED:
        return False
    import threading
    from concurrent.futures import Future

    future: Future = Future()

    def load():
        try:
            future.set_result(_load_program(path, None, specs))
        except BaseException as e:  # noqa: BLE001 - handed to the caller by cached_program
            future.set_exception(e)

    _PENDING[str(path)] = future
    threading.Thread(target=load, name=f"prefetch {name}", daemon=True).start()
    return True


def when_loaded(fn):
    """Call ``fn()`` once the programs :func:`prefetch` started have loaded (or failed): on a
    background thread while some are still loading, else at once on this one. Returns a
    :class:`~concurrent.futures.Future` of its result (``.result()`` waits for it and raises
    its exception).

    ``generate`` starts the video's renderer so: its start-up (numba, ~0.5 s of a core)
    otherwise competes with the executables' loads that the sampling waits for, and fits
    beside the sampling instead."""
    import threading
    from concurrent.futures import Future, wait

    done: Future = Future()
    loading = [f for f in _PENDING.values() if not f.done()]

    def run():
        wait(loading)
        try:
            done.set_result(fn())
        except BaseException as e:  # noqa: BLE001 - handed to the caller by .result()
            done.set_exception(e)

    if loading:
        threading.Thread(target=run, name="after the programs' loads", daemon=True).start()
    else:
        run()
    return done


#: Programs :func:`prefetch` is loading, by artefact path, until :func:`cached_program` takes
#: them.
_PENDING: dict = {}
#: Programs :func:`cached_program` loaded in this process, by artefact path.
_LOADED: dict = {}
#: Programs :func:`cached_program` traced without a cache folder, by name and fingerprint.
_IN_MEMORY: dict = {}
#: How many programs traced without a cache folder a process keeps.
MEMORY_PROGRAMS = 16


def release() -> None:
    """Drop the programs this process loaded (their executables and weights); the next call
    of each loads it from disk again (or traces it again, without a cache folder)."""
    _LOADED.clear()
    _IN_MEMORY.clear()


def prefetched() -> tuple[str, ...]:
    """The artefacts :func:`prefetch` started loading that no :func:`cached_program` call has
    taken yet (a prefetch for shapes that never came)."""
    return tuple(_PENDING)


def _shapes_digest(fingerprint: str, specs) -> str:
    import jax

    return digest(fingerprint, code_digest(),
                  [(s.shape, str(s.dtype)) for s in jax.tree.leaves(specs)])


def _artefact(cache_dir, name: str, fingerprint: str, specs) -> Path | None:
    if cache_dir is None:
        return None
    return Path(cache_dir) / f"{name}-{_shapes_digest(fingerprint, specs)}.jaxexport"


def _load_program(path: Path | None, build, specs):
    """The compiled program kept at ``path`` (traced with ``build()`` and kept there when it
    is not; ``build=None``: only read). ``path=None``: traced and run without a cache."""
    import jax

    exp = None
    if path is not None and path.is_file():
        consts_path = path.with_suffix(CONSTS_SUFFIX)
        try:
            from jax import export as jexport

            exp = jexport.deserialize(bytearray(path.read_bytes()))
            consts = _read_consts(consts_path)
        except Exception:  # a stale or damaged artefact is rebuilt below
            if build is None:
                raise
            path.unlink(missing_ok=True)
            consts_path.unlink(missing_ok=True)
            exp = None
    if exp is None:
        if build is None:
            raise FileNotFoundError(path)
        exp, consts = _export(path, build, specs)
    if path is None:  # no cache: the program as export runs it
        return exp.call if consts is None else functools.partial(exp.call, consts)
    call_specs = specs if consts is None else (specs_of(consts), *specs)
    program = jax.jit(exp.call).lower(*call_specs).compile(compiler_options())
    return program if consts is None else functools.partial(program, consts)


def compiler_options() -> dict:
    """XLA options the kept programs compile with. On CPU, LLVM's ``-O1``: the two sampler
    programs of a first ``generate`` then compile in about a fifth less time (compiles timed
    in process on a fresh cache; the end-to-end ``benchmarks/generate.py`` cold figure is
    too noisy to show it) and run as fast (both stages: within 3 %). ``XLA_FLAGS`` that
    name the level keep theirs."""
    import os

    import jax

    if (jax.default_backend() != "cpu"
            or "xla_backend_optimization_level" in os.environ.get("XLA_FLAGS", "")):
        return {}
    return {"xla_backend_optimization_level": 1}


def _read_consts(consts_path: Path):
    """The lifted constants kept beside a program, or None when it keeps its own."""
    if not consts_path.is_file():
        return None
    from safetensors.numpy import load

    arrays = load(consts_path.read_bytes())
    return tuple(arrays[f"c{i}"] for i in range(len(arrays)))


def _export(path: Path | None, build, specs):
    """Trace ``build()`` for ``specs``, lift its large constants, and keep the exported
    program (and the constants) at ``path`` when there is one and its folder takes it:
    ``(exported, consts or None)``."""
    import jax
    from jax import export as jexport

    fn, consts = _lift_constants(build(), specs)
    if consts is None:
        exp = jexport.export(jax.jit(fn))(*specs)
    else:
        exp = jexport.export(jax.jit(fn))(specs_of(consts), *specs)
    if path is None:
        return exp, consts
    consts_path = path.with_suffix(CONSTS_SUFFIX)
    try:
        from jaxmotion._atomic import atomic_open

        if consts is not None:  # written first: a program is only read with its weights
            from safetensors.numpy import save

            blob = save({f"c{i}": np.ascontiguousarray(c) for i, c in enumerate(consts)})
            with atomic_open(consts_path, "wb") as f:
                f.write(blob)
        else:
            consts_path.unlink(missing_ok=True)
        with atomic_open(path, "wb") as f:
            f.write(exp.serialize())
    except (OSError, ImportError, ValueError, TypeError):
        pass  # a read-only cache, no flatbuffers, a dtype safetensors lacks: run uncached
    return exp, consts


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
