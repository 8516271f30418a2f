"""The object classifier of object discovery: an instance's shape descriptors -> its category.

:class:`ObjectClassifier` (Flax NNX) is a small MLP over the z-scored descriptors of
:func:`jaxmotion.scene.segment.object_features` (size, height profile, horizontal surfaces,
distance to the walls; no colour), trained on the synthetic rooms' instances as segmentation
finds them in degraded scans (``python -m jaxmotion.train --config configs/objects.py``,
:mod:`jaxmotion.data.object_features`). Inference needs no Flax: :func:`load_object_classifier`
reads the weights file and runs the same layers in NumPy (tested equal), so segmenting a room
costs no network library's start-up.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

__all__ = ["OBJECTS_VERSION", "ObjectClassifierConfig", "NumpyObjectClassifier",
           "load_object_classifier", "shipped_object_classifier"]

OBJECTS_VERSION = "jm-objects-1"
_SHIPPED = Path(__file__).resolve().parent.parent / "assets" / "objects.safetensors"


@dataclasses.dataclass(frozen=True)
class ObjectClassifierConfig:
    """``hidden`` width of each of ``layers`` hidden layers (GELU, layer norm), ``dropout``;
    ``num_features`` in, ``num_classes`` out."""

    num_features: int = 28
    num_classes: int = 20
    hidden: int = 128
    layers: int = 2
    dropout: float = 0.1


def make_object_classifier(cfg: ObjectClassifierConfig, *, rngs):
    """The Flax NNX module (imported on use: inference does not need Flax)."""
    from flax import nnx

    class ObjectClassifier(nnx.Module):
        def __init__(self, cfg, *, rngs):
            self.cfg = cfg
            dims = [cfg.num_features] + [cfg.hidden] * cfg.layers
            self.hidden = nnx.List([nnx.Linear(a, b, rngs=rngs) for a, b in zip(dims, dims[1:])])
            self.norms = nnx.List([nnx.LayerNorm(cfg.hidden, rngs=rngs)
                                   for _ in range(cfg.layers)])
            self.drop = nnx.Dropout(cfg.dropout, rngs=rngs)
            self.out = nnx.Linear(dims[-1], cfg.num_classes, rngs=rngs)

        def __call__(self, x, *, deterministic=None):
            """Logits ``[B, C]`` of z-scored features ``x [B, F]``."""
            import jax

            for lin, norm in zip(self.hidden, self.norms):
                x = self.drop(jax.nn.gelu(norm(lin(x)), approximate=False),
                              deterministic=deterministic)
            return self.out(x)

    return ObjectClassifier(cfg, rngs=rngs)


class NumpyObjectClassifier:
    """The trained classifier in NumPy: ``clf(features [M, F]) -> probabilities [M, C]``;
    ``categories`` names the columns."""

    def __init__(self, tensors: dict, config: dict):
        self.categories = tuple(config["categories"])
        self.mean = np.asarray(tensors["feature_mean"], np.float64)
        self.std = np.asarray(tensors["feature_std"], np.float64)
        layers = int(config["model"]["layers"])
        get = lambda name: np.asarray(tensors[f"params/{name}"], np.float64)  # noqa: E731
        self.layers = [(get(f"hidden/{i}/kernel"), get(f"hidden/{i}/bias"),
                        get(f"norms/{i}/scale"), get(f"norms/{i}/bias")) for i in range(layers)]
        self.head = (get("out/kernel"), get("out/bias"))

    def __call__(self, features) -> np.ndarray:
        from scipy.special import erf

        x = (np.asarray(features, np.float64) - self.mean) / self.std
        for w, b, scale, shift in self.layers:
            h = x @ w + b
            mu, var = h.mean(-1, keepdims=True), h.var(-1, keepdims=True)
            h = (h - mu) / np.sqrt(var + 1e-6) * scale + shift
            x = 0.5 * h * (1.0 + erf(h / np.sqrt(2.0)))
        logits = x @ self.head[0] + self.head[1]
        logits -= logits.max(-1, keepdims=True)
        p = np.exp(logits)
        return p / p.sum(-1, keepdims=True)


def load_object_classifier(path=None) -> NumpyObjectClassifier:
    """The classifier of a training run (its workdir or ``model.safetensors``), or the
    shipped one (``jaxmotion/assets/objects.safetensors``) when ``path`` is None."""
    from jaxmotion.models.weights import load_weights, weights_path

    path = _SHIPPED if path is None else weights_path(path)
    tensors, config = load_weights(path)
    if config.get("objects_version") != OBJECTS_VERSION:
        raise ValueError(f"{path}: not an object classifier of this version "
                         f"({config.get('objects_version')!r}, want {OBJECTS_VERSION!r}); "
                         "train it with 'python -m jaxmotion.train --config configs/objects.py'")
    return NumpyObjectClassifier(tensors, config)


def shipped_object_classifier() -> Path:
    """The shipped weights file."""
    return _SHIPPED
