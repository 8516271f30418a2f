"""Inference weights as one ``model.safetensors`` file (small, portable, no optimiser state).

Every training run writes ``<workdir>/model.safetensors`` next to its Orbax
checkpoints whenever it checkpoints: the weights used for inference (EMA when
enabled) and BatchNorm statistics, flattened to ``"path/to/param": array``,
with the run's ``config.json`` in the file's metadata. Later stages load frozen
networks from it (ADM's backbone, AMDM's ADM), and the shipped default models
are such files.
"""

from __future__ import annotations

import json
from pathlib import Path

import jax
import numpy as np

from jaxmotion._atomic import atomic_open

__all__ = ["apply_weights", "flatten_state", "load_weights", "save_weights"]


def _key(path) -> str:
    parts = []
    for p in path:
        for attr in ("key", "name", "idx"):
            if hasattr(p, attr):
                parts.append(str(getattr(p, attr)))
                break
        else:
            parts.append(str(p))
    if parts and parts[-1] == "value":  # the Variable's own leaf
        parts.pop()
    return "/".join(parts)


def flatten_state(state) -> dict[str, np.ndarray]:
    """``nnx.State`` (or nested dict of arrays) -> ``{"a/b/c": numpy array}``."""
    flat = {}
    for path, leaf in jax.tree_util.tree_flatten_with_path(state)[0]:
        flat[_key(path)] = np.asarray(jax.device_get(leaf))
    return flat


def save_weights(path, params, batch_stats, config: dict, extra: dict | None = None) -> Path:
    """Write inference weights and the config atomically to ``path`` (safetensors).

    ``extra``: more named arrays (e.g. ``{"stats/motion_mean": ...}``) stored as they are.
    """
    from safetensors.numpy import save

    tensors = {f"params/{k}": v for k, v in flatten_state(params).items()}
    tensors.update({f"batch_stats/{k}": v for k, v in flatten_state(batch_stats).items()})
    tensors.update({k: np.asarray(v) for k, v in (extra or {}).items()})
    tensors = {k: np.ascontiguousarray(v) for k, v in tensors.items()}
    data = save(tensors, metadata={"config": json.dumps(config), "format": "jaxmotion-weights-1"})
    with atomic_open(path, "wb") as f:
        f.write(data)
    return Path(path)


def weights_path(path) -> Path:
    """A ``.safetensors`` file as given, or a training workdir's ``model.safetensors``."""
    path = Path(path)
    return path if path.suffix == ".safetensors" else path / "model.safetensors"


def read_config(path) -> dict:
    """The config stored in a weights file (or workdir), without reading its tensors."""
    from safetensors import safe_open

    path = weights_path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no trained weights here")
    with safe_open(str(path), framework="numpy") as f:
        meta = f.metadata() or {}
    if "config" not in meta:
        raise ValueError(f"{path}: not a jaxmotion weights file (no config in its metadata)")
    return json.loads(meta["config"])


def load_weights(path) -> tuple[dict[str, np.ndarray], dict]:
    """Read ``(flat tensors, config dict)`` from a ``model.safetensors``."""
    from safetensors import safe_open

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"{path}: no trained weights here; train the model first "
            "(python -m jaxmotion.train --config configs/<name>.py workdir=...)")
    with safe_open(str(path), framework="numpy") as f:
        meta = f.metadata() or {}
        tensors = {k: f.get_tensor(k) for k in f.keys()}
    if "config" not in meta:
        raise ValueError(f"{path}: not a jaxmotion weights file (no config in its metadata)")
    return tensors, json.loads(meta["config"])


def apply_weights(module, tensors: dict[str, np.ndarray], *, prefix: str = "",
                  source: str = "weights"):
    """Load flat tensors into ``module`` in place (params and batch stats); strict on names/shapes.

    ``prefix`` selects a sub-tree of the file (e.g. weights saved from a wrapper module).
    """
    from flax import nnx

    for kind, filt in (("params", nnx.Param), ("batch_stats", nnx.BatchStat)):
        state = nnx.state(module, filt)
        missing, bad = [], []
        new_leaves = []
        leaves_with_path = jax.tree_util.tree_flatten_with_path(state)[0]
        for path, leaf in leaves_with_path:
            name = f"{kind}/{prefix}{_key(path)}"
            if name not in tensors:
                missing.append(name)
                new_leaves.append(leaf)
                continue
            value = tensors[name]
            if value.shape != tuple(leaf.shape):
                bad.append(f"{name}: file {value.shape} vs model {tuple(leaf.shape)}")
            new_leaves.append(np.asarray(value, dtype=leaf.dtype))
        if missing or bad:
            raise ValueError(
                f"{source} do not match the model built from their config: "
                f"{len(missing)} missing (e.g. {missing[:3]}), {len(bad)} with other shapes "
                f"(e.g. {bad[:3]}); was the file written by another version or config?")
        treedef = jax.tree_util.tree_structure(state)
        nnx.update(module, jax.tree_util.tree_unflatten(treedef, new_leaves))
    return module


def compact_weights(src, dst, *, dtype=np.float16) -> Path:
    """Copy a ``model.safetensors`` with its parameters (``params/`` and any ``*/params/``
    tensors) cast to ``dtype`` — half the size for shipping; :func:`apply_weights` casts them
    back to the model's dtype on load. Statistics and batch-norm state keep their dtype."""
    from safetensors.numpy import save

    tensors, config = load_weights(src)
    out = {}
    for k, v in tensors.items():
        is_param = k.startswith("params/") or "/params/" in k
        out[k] = np.ascontiguousarray(v.astype(dtype) if is_param and v.dtype.kind == "f" else v)
    data = save(out, metadata={"config": json.dumps(config), "format": "jaxmotion-weights-1"})
    with atomic_open(dst, "wb") as f:
        f.write(data)
    return Path(dst)


def abstract_module(ctor):
    """``ctor()`` without running its initialisers (``nnx.eval_shape``), for loading weights.

    Building a model eagerly compiles one small XLA program per initialiser shape (seconds
    for a Point Transformer); an abstract build costs nothing. Fill its parameters and batch
    statistics with :func:`apply_weights`; any other state (dropout RNG streams, counters) is
    given concrete placeholders here.
    """
    import jax.numpy as jnp
    from flax import nnx

    module = nnx.eval_shape(ctor)

    def fill(x):
        if not isinstance(x, jax.ShapeDtypeStruct):
            return x
        if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key):
            return jax.random.split(jax.random.key(0), x.shape) if x.shape else jax.random.key(0)
        return jnp.zeros(x.shape, x.dtype)

    rest = nnx.state(module, nnx.Not(nnx.Any(nnx.Param, nnx.BatchStat)))
    nnx.update(module, jax.tree.map(fill, rest))
    return module
